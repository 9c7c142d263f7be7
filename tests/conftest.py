"""Shared fixtures: ``fleet_factory`` starts real fleets and always stops them; ``simulated_run``
is one in-memory run of the ellipse mission, shared by the tests that read a run folder.

Under pytest-xdist (the README's first test command, ``-n 2``), each module runs on one
worker, so its module fixtures run once, and the modules that read ``simulated_run`` share
one worker, so that run is made once.

Real firmware: ``$ARDUPLANE_SITL`` and ``$PX4_SITL_DIR`` are set here, before any test module
is collected, to ``../shared/arduplane/arduplane`` and ``../shared/px4`` beside the clone when
they are unset and those exist (:mod:`tests.firmware_env`); the product itself looks nowhere
else than its flags and those variables. Child processes inherit them."""

from __future__ import annotations

import compileall
from pathlib import Path

import pytest

from tests.firmware_env import provide_firmware
from tests.fleet_harness import FAST, Fleet, start_fleet

provide_firmware()


def _bytecode_for_children() -> None:
    """Compile the product's modules to bytecode once, before the tests start processes.

    Where ``PYTHONDONTWRITEBYTECODE`` is set (as on the CI machine), no process writes its
    bytecode, so every ``companion`` or ``sitl_model`` process a test starts would compile
    some 190 modules from source again: 0.2 s of CPU each. Bytecode written here is read
    by every later import whatever that variable says; a file already compiled is skipped
    (its source's time and size match)."""
    root = Path(__file__).resolve().parents[1]
    for package in ("companion", "sitl_model"):
        compileall.compile_dir(root / package, quiet=2)


_bytecode_for_children()

# the modules that fly fleets of real firmware (PX4, ArduPlane SITL): one worker flies them in
# turn (three PX4 instances at speed factor 3 take 1.3 of the two cores; beside three ArduPlanes
# at 5x, a companion's group traffic was 2 s of vehicle time late and two UAVs took one alert)
FIRMWARE_MODULES = {
    "test_px4",
    "test_px4_fleet",
    "test_px4_relief",
    "test_arduplane",
    "test_arduplane_relief",
}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Group the tests for ``--dist loadgroup``: by module; the modules that use
    ``simulated_run`` together; the firmware fleets together (``FIRMWARE_MODULES``), so no
    two fly at once. First among the hooks: xdist's worker reads the groups in its own hook
    of the same name, registered after this conftest, so called before it."""
    if not config.pluginmanager.hasplugin("xdist"):
        return
    shared = {item.module.__name__ for item in items if "simulated_run" in item.fixturenames}
    for item in items:
        name = item.module.__name__
        group = "simulated_run" if name in shared else name
        if name.rsplit(".", 1)[-1] in FIRMWARE_MODULES:
            group = "firmware"
        item.add_marker(pytest.mark.xdist_group(group))


@pytest.fixture
def fleet_factory(tmp_path):
    """Start fleets; always stop them, assert exit 0 and that no process is left."""
    fleets: list[Fleet] = []

    def make(**kw) -> Fleet:
        f = start_fleet(tmp_path / f"run{len(fleets)}", kw.pop("mission", FAST), **kw)
        fleets.append(f)
        return f

    yield make
    for f in fleets:
        codes = f.stop()
        assert all(p.proc.poll() is not None for p in f.companions)
        assert f.sitl.proc.poll() is not None
        assert codes == [0] * len(codes), codes


@pytest.fixture(scope="session")
def simulated_run(tmp_path_factory):
    """One ``companion simulate missions/ellipse_6uav.yaml --duration 760 --report`` run folder
    (the real companion stack in memory, about 30 s), shared by the tests that read one."""
    from companion.commands.main import main

    out = tmp_path_factory.mktemp("sim") / "run"
    mission = Path(__file__).resolve().parents[1] / "missions" / "ellipse_6uav.yaml"
    assert main(["simulate", str(mission), "--duration", "760", "--out", str(out), "--report"]) == 0
    return out
