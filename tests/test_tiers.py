"""The test tiers, checked on the source: a test that starts real processes, opens sockets
or waits on the wall clock is marked ``integration``; one that runs free against the wall
clock where a busy machine changes its outcome (real firmware, a link cut, network
namespaces) is marked ``alone`` too.

The README's test command runs everything but ``alone`` first on two workers (``pytest -n 2
-m 'not alone and not extended'``: the unit and in-memory tests, whose outcome cannot depend
on the machine's load, and the integration tests, lockstepped or bounded generously on the
wall clock), then the ``alone`` tests apart from them, two modules at a time (``-n 2 -m 'alone
and not extended'``: each free-running flight leaves most of a core idle). A
free-running test without the mark would run beside another worker and could fail on a busy
machine; this test catches the module that forgot it.
"""

from __future__ import annotations

import re
from pathlib import Path

TESTS = Path(__file__).resolve().parent

# What a test uses when it starts a process, opens a socket or waits on the wall clock.
WALL_CLOCK = re.compile(
    r"SitlProcess|fleet_factory|start_fleet\(|companion_cli|free_udp_port|Companion\("
    r"|mavlink_connection|socket\.socket\(|Popen\(|time\.sleep\(|time\.monotonic\("
    r"|mavsdk|sync_playwright|ip netns|companion\.sim\.arduplane|ARDUPLANE"
)

# Modules that match but need no mark, and why.
UNMARKED_OK = {
    "test_tiers.py": "names the patterns",
    "test_world_wind.py": "reads the world classes' wind without constructing them",
    "test_layers.py": "names companion.sim.arduplane; its subprocess only imports modules",
}

# What a test uses when it flies real firmware, loads the machine on purpose, or runs a fleet
# free against the wall clock.
FREE_RUNNING = re.compile(
    r"companion\.sim\.arduplane|from companion\.sim\.px4 import|px4_harness|ARDUPLANE"
    r"|lockstep=False|ip netns|\"netns\"|while True: pass"
)

# Modules that match FREE_RUNNING but need no ``alone`` mark, and why.
SHARED_OK = {
    "test_tiers.py": "names the patterns",
    "test_layers.py": "names companion.sim.arduplane; its subprocess only imports modules",
    "test_px4_sitl.py": "the PX4 fleet's pieces without PX4 (stand-in processes, parsing)",
    "test_world_wind.py": "reads the world classes' wind without constructing them",
    "test_lockstep_fleet.py": "lockstepped: its CPU hogs cannot move it or the shared tests",
}

# A mark as written: ``pytestmark = pytest.mark.integration``, a line of a pytestmark list,
# or a decorator.
MARK = re.compile(r"^\s*(pytestmark\s*=\s*\[?\s*|@)?pytest\.mark\.integration\b", re.M)


ALONE = re.compile(r"^\s*(pytestmark\s*=\s*\[.*|@)pytest\.mark\.alone\b", re.M)


def _marked(text: str) -> bool:
    return MARK.search(text) is not None


def test_every_module_that_runs_free_is_marked_alone():
    offenders = []
    for path in sorted(TESTS.glob("test_*.py")):
        text = path.read_text()
        hit = FREE_RUNNING.search(text)
        if hit and ALONE.search(text) is None and path.name not in SHARED_OK:
            offenders.append(f"{path.name} ({hit.group(0)})")
    assert not offenders, "mark these alone (pytestmark or per test): " + ", ".join(offenders)


def test_the_alone_check_sees_an_unmarked_module():
    sample = "def test_x(fleet_factory):\n    fleet_factory(lockstep=False)\n"
    assert FREE_RUNNING.search(sample) and ALONE.search(sample) is None
    assert ALONE.search("pytestmark = [pytest.mark.integration, pytest.mark.alone]\n" + sample)
    assert ALONE.search("@pytest.mark.alone\n" + sample)
    assert ALONE.search('"""says pytest.mark.alone"""\n' + sample) is None


def test_every_module_that_needs_the_wall_clock_is_marked_integration():
    offenders = []
    for path in sorted(TESTS.glob("test_*.py")):
        text = path.read_text()
        hit = WALL_CLOCK.search(text)
        if hit and not _marked(text) and path.name not in UNMARKED_OK:
            offenders.append(f"{path.name} ({hit.group(0)})")
    assert not offenders, "mark these integration (pytestmark or per test): " + ", ".join(offenders)


def test_the_check_sees_an_unmarked_module():
    """The pattern is not dead: it matches what a real-process test writes."""
    sample = "def test_x(fleet_factory):\n    fleet = fleet_factory()\n"
    assert WALL_CLOCK.search(sample) and not _marked(sample)
    assert _marked("pytestmark = pytest.mark.integration\n" + sample)
    assert _marked("@pytest.mark.integration\n" + sample)
    assert not _marked('"""a docstring that says pytest.mark.integration"""\n' + sample)


def test_ci_runs_exactly_the_readmes_test_command():
    """``.ci/run`` ends with the README's quickstart step 2, character for character."""
    root = TESTS.parent
    readme = [ln for ln in (root / "README.md").read_text().splitlines() if "'.[test]'" in ln]
    ci = [ln for ln in (root / ".ci" / "run").read_text().splitlines() if ln.strip()]
    assert len(readme) == 1 and readme[0].startswith("python3 -m venv .venv && ")
    assert ci[-1] == readme[0]
    assert "-n 2 -m 'not alone and not extended'" in ci[-1]  # the two runs, as documented
    assert "-m 'alone and not extended'" in ci[-1]
