"""The layer rule of the whole house (docs/architecture.md, top), checked on the source.

THE RULE

1. The SHARED PURE LAYER is ``companion.contracts``, ``companion.core``,
   ``companion.guidance``, ``companion.planner`` and ``companion.mission``: what the companion
   and the simulator both build on. It imports nothing of ours outside itself.
2. ``sitl_model`` imports from ``companion`` only the shared layer. One named exception:
   ``sitl_model/cli.py`` reads the link signing key file with ``companion.group.keys``.
3. Only the COMPOSITION ROOTS import ``sitl_model``: ``companion.sim`` (in memory, the UDP
   fleet, ArduPlane) and the commands that start them (``simulate``, ``fleet``,
   ``campaign``).
4. A PURE module imports no EDGE module. The edges are the modules that open sockets,
   start processes, read clocks or write files: ``companion.__main__``,
   ``companion.process``, ``companion.sim``, ``companion.commands``,
   ``companion.dashboard.server``, ``companion.report`` (it reads and writes run folders),
   ``companion.export.runfolder`` and ``companion.export.mcap_file`` (a run read, the MCAP
   written),
   the group's sockets, key files and operator (``group.transport``, ``group.zenoh_socket``,
   ``group.keys``, ``group.operator``), and the autopilot link's connection, tlog and
   mission-protocol client (``link.connection``, ``link.tlog``, ``link.mission_protocol``), and a
   campaign's Dask runs, table and figure (``campaign.execute``, ``campaign.table``,
   ``campaign.figure``). Everything else is pure.
5. ``link`` and ``group`` import no agent (nor anything above them: process, sim, report,
   dashboard, commands); the agent imports no ``link`` (it never knows which autopilot).
6. Nothing imports ``companion.commands`` but ``companion.__main__`` and the commands.
7. Product code imports no test helper (``sitl_model.testing``, ``tests``).

Every ``import x`` and ``from x import y`` counts, at any depth (inside functions and
``if TYPE_CHECKING:`` blocks too). A second test imports the modules and checks what they
load, which also catches a package ``__init__`` that pulls in more than it should.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SHARED: tuple[str, ...] = (
    "companion.contracts",
    "companion.core",
    "companion.guidance",
    "companion.planner",
    "companion.mission",
)
COMPOSITION_ROOTS: tuple[str, ...] = (  # companion modules that may import sitl_model
    "companion.sim",
    "companion.commands.simulate",
    "companion.commands.fleet",
    "companion.commands.campaign",
)
SITL_EXCEPTIONS: dict[str, tuple[str, ...]] = {  # sitl_model module -> companion modules
    "sitl_model.cli": ("companion.group.keys",),
}
EDGES: tuple[str, ...] = (
    "companion.__main__",
    "companion.process",
    "companion.sim",
    "companion.commands",
    "companion.dashboard.server",
    "companion.report",
    "companion.export.runfolder",
    "companion.export.mcap_file",
    "companion.group.transport",
    "companion.group.zenoh_socket",
    "companion.group.keys",
    "companion.group.operator",
    "companion.link.connection",
    "companion.link.serial_device",
    "companion.link.tlog",
    "companion.link.mission_protocol",
    "companion.campaign.execute",
    "companion.campaign.table",
    "companion.campaign.figure",
)
LOWER: tuple[str, ...] = ("companion.link", "companion.group")  # rule 5's packages
ABOVE_LOWER: tuple[str, ...] = (
    "companion.agent",
    "companion.campaign",
    "companion.process",
    "companion.sim",
    "companion.report",
    "companion.dashboard",
    "companion.commands",
)
TEST_HELPERS: tuple[str, ...] = ("sitl_model.testing", "tests")

RULE_SHARED = "the shared layer imports only the shared layer (rule 1)"
RULE_SITL = "sitl_model imports from companion only the shared layer (rule 2)"
RULE_ROOTS = "only the composition roots import sitl_model (rule 3)"
RULE_PURE = "a pure module imports no edge module (rule 4)"
RULE_LOWER = "link and group import nothing above them (rule 5)"
RULE_AGENT = "the agent imports no link (rule 5)"
RULE_COMMANDS = "nothing imports companion.commands (rule 6)"
RULE_TESTS = "product code imports no test helper (rule 7)"


def _within(module: str, prefixes: tuple[str, ...]) -> bool:
    """Whether ``module`` is one of ``prefixes`` or inside one of them."""
    return any(module == p or module.startswith(p + ".") for p in prefixes)


def _module_of(path: Path, root: Path = REPO) -> str:
    """Dotted module name of a source file under ``root`` (the repository)."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, root: Path = REPO) -> Iterator[tuple[int, str, str]]:
    """(line, imported module, the statement as written) of every import in ``path``.

    ``from a.b import c`` yields ``a.b.c`` (a submodule or a name in ``a.b``: both live in
    ``a.b``'s layer); relative imports are resolved against the file's package.
    """
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source, filename=str(path))
    package = _module_of(path, root).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    for node in ast.walk(tree):
        if not isinstance(node, ast.Import | ast.ImportFrom):
            continue
        text = ast.get_source_segment(source, node) or ""
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, text
        else:
            base = node.module or ""
            if node.level:
                anchor = package[: len(package) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                yield node.lineno, f"{base}.{alias.name}", text


def violation(importer: str, imported: str) -> str | None:
    """Which part of the rule ``importer`` importing ``imported`` breaks; None if none."""
    top = imported.split(".")[0]
    if top not in ("companion", "sitl_model", "tests"):
        return None
    if _within(imported, TEST_HELPERS) and not _within(importer, TEST_HELPERS):
        return RULE_TESTS
    if _within(importer, SHARED):
        return None if _within(imported, SHARED) else RULE_SHARED
    if importer.startswith("sitl_model."):
        allowed = SHARED + SITL_EXCEPTIONS.get(importer, ())
        return None if top != "companion" or _within(imported, allowed) else RULE_SITL
    if top == "sitl_model":
        return None if _within(importer, COMPOSITION_ROOTS) else RULE_ROOTS
    if _within(imported, ("companion.commands",)) and not _within(
        importer, ("companion.commands", "companion.__main__")
    ):
        return RULE_COMMANDS
    if _within(importer, LOWER) and _within(imported, ABOVE_LOWER):
        return RULE_LOWER
    if _within(importer, ("companion.agent",)) and _within(imported, ("companion.link",)):
        return RULE_AGENT
    if not _within(importer, EDGES) and _within(imported, EDGES):
        return RULE_PURE
    return None


def offences(files: list[Path], root: Path = REPO) -> list[str]:
    """One line per import that breaks the rule: ``path:line: import ... -- which rule``."""
    out = []
    for path in files:
        importer = _module_of(path, root)
        for line, imported, text in _imports(path, root):
            why = violation(importer, imported)
            if why:
                statement = " ".join(text.split())
                out.append(f"{path.relative_to(root)}:{line}: {statement}  -- {why}")
    return out


def _sources() -> list[Path]:
    return sorted([*(REPO / "companion").rglob("*.py"), *(REPO / "sitl_model").rglob("*.py")])


def test_every_import_follows_the_layer_rule() -> None:
    """Every import statement in companion/ and sitl_model/ keeps the rule."""
    files = _sources()
    assert len(files) > 80  # the walk found the packages
    bad = offences(files)
    assert not bad, "imports that break the layer rule:\n" + "\n".join(bad)


def test_every_module_is_in_a_package_and_every_named_layer_exists() -> None:
    """No loose modules beside the packages (one feature, one package): ``companion/`` holds
    only ``__init__`` and ``__main__``; every package named in the rule is on disk."""
    loose = sorted(p.name for p in (REPO / "companion").glob("*.py"))
    assert loose == ["__init__.py", "__main__.py"], loose
    for name in SHARED + COMPOSITION_ROOTS + EDGES + LOWER + ABOVE_LOWER:
        path = REPO / name.replace(".", "/")
        assert path.is_dir() or path.with_suffix(".py").is_file(), name


PLANTED = {  # (importer, imported) -> the rule it must break
    ("companion.core.wind", "companion.process.runner.Runner"): RULE_SHARED,
    ("companion.guidance.steering", "companion.agent.agent"): RULE_SHARED,
    ("companion.planner.planner", "sitl_model.sim"): RULE_SHARED,
    ("sitl_model.sim", "companion.group.codec.Signing"): RULE_SITL,
    ("sitl_model.server", "companion.group.keys.load_key"): RULE_SITL,  # cli.py only
    ("companion.agent.agent", "sitl_model.particle"): RULE_ROOTS,
    ("companion.report.rundata", "sitl_model.sim.TRUTH_COLUMNS"): RULE_ROOTS,
    ("companion.agent.alerts.tasking", "companion.group.transport.Group"): RULE_PURE,
    ("companion.group.address", "companion.group.zenoh_socket.ZenohSocket"): RULE_PURE,
    ("companion.link.shaping", "companion.link.connection"): RULE_PURE,
    ("companion.dashboard.model", "companion.report.metrics"): RULE_PURE,
    ("companion.link.mission_protocol.fence", "companion.agent.events"): RULE_LOWER,
    ("companion.group.codec", "companion.agent.alerts.record"): RULE_LOWER,
    ("companion.group.transport", "companion.process.runner"): RULE_LOWER,
    ("companion.agent.agent", "companion.link.estimate"): RULE_AGENT,
    ("companion.sim.fleet", "companion.commands.upload.run"): RULE_COMMANDS,
    ("companion.dashboard.server", "companion.commands.alert"): RULE_COMMANDS,
    ("companion.sim.fleet", "sitl_model.testing.free_base_port"): RULE_TESTS,
    ("companion.process.runner", "tests.fleet_harness"): RULE_TESTS,
}
ALLOWED = (
    ("sitl_model.cli", "companion.group.keys.load_key"),
    ("sitl_model.sim", "companion.core.particle.step"),
    ("companion.sim.arduplane.world", "sitl_model.world.World"),
    ("companion.process.runner", "companion.group.codec"),
    ("companion.group.transport", "companion.group.zenoh_socket.ZenohSocket"),
    ("companion.process.runner", "companion.agent.agent.Agent"),
    ("companion.agent.agent", "companion.group.messages.Alert"),
    ("companion.commands.run", "companion.process.runner"),
    ("companion.__main__", "companion.commands.main"),
    ("companion.mission.load", "companion.guidance.steering.Gains"),
    ("companion.sim.fleet", "sitl_model.server.free_base_port"),
)


def test_the_check_catches_each_kind_of_offence(tmp_path: Path) -> None:
    """The checker flags a planted import of each rule, at any depth, with the rule it
    breaks, and passes the allowed ones."""
    for (importer, imported), rule in PLANTED.items():
        assert violation(importer, imported) == rule, (importer, imported)
    for importer, imported in ALLOWED:
        assert violation(importer, imported) is None, (importer, imported)
    assert set(PLANTED.values()) == {
        RULE_SHARED, RULE_SITL, RULE_ROOTS, RULE_PURE, RULE_LOWER, RULE_AGENT, RULE_COMMANDS,
        RULE_TESTS,
    }  # fmt: skip
    probe = tmp_path / "companion" / "core" / "probe.py"
    probe.parent.mkdir(parents=True)
    probe.write_text("import numpy\n\n\ndef f():\n    if True:\n        from .. import process\n")
    bad = offences([probe], root=tmp_path)
    assert bad == [f"companion/core/probe.py:6: from .. import process  -- {RULE_SHARED}"], bad


_LOADED = """
import importlib, json, pkgutil, sys
import companion.contracts, companion.core, companion.guidance, companion.mission
import companion.planner
names = {}
for pkg in (companion.contracts, companion.core, companion.guidance, companion.mission,
            companion.planner):
    for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
        importlib.import_module(m.name)
names["shared"] = sorted(m for m in sys.modules if m.split(".")[0] in ("companion", "sitl_model"))
import sitl_model
for m in pkgutil.walk_packages(sitl_model.__path__, "sitl_model."):
    if not m.name.endswith("__main__"):
        importlib.import_module(m.name)
names["sitl_model"] = sorted(m for m in sys.modules if m.split(".")[0] == "companion")
print(json.dumps(names))
"""


def test_what_the_layers_load_at_run_time() -> None:
    """Importing the shared layer loads nothing else of ours; importing every sitl_model
    module loads only the shared layer and the named exception (package ``__init__``
    files included)."""
    proc = subprocess.run(
        [sys.executable, "-c", _LOADED], cwd=REPO, capture_output=True, text=True, check=True
    )
    loaded = json.loads(proc.stdout)
    shared_ok = ("companion",)  # the package itself (its __init__ imports nothing)
    extra = [m for m in loaded["shared"] if m not in shared_ok and not _within(m, SHARED)]
    assert not extra, f"the shared layer loads: {extra}"
    allowed = SHARED + tuple(x for v in SITL_EXCEPTIONS.values() for x in v)
    extra = [
        m
        for m in loaded["sitl_model"]
        if m not in ("companion", "companion.group") and not _within(m, allowed)
    ]
    assert not extra, f"sitl_model loads: {extra}"


_RUN_LOADS = """
import json, sys
from companion.commands.main import build_parser
build_parser("run")
print(json.dumps(sorted(sys.modules)))
"""


def test_a_companion_process_loads_no_simulator_report_or_web_server() -> None:
    """``companion run`` (the process next to an autopilot) imports only its own command:
    not the simulator, the report and its plots or the web server (about 0.1 s less start-up
    per process); ``companion --help`` still lists every command."""
    proc = subprocess.run(
        [sys.executable, "-c", _RUN_LOADS], cwd=REPO, capture_output=True, text=True, check=True
    )
    loaded = json.loads(proc.stdout)
    heavy = ("sitl_model", "companion.report", "companion.sim", "aiohttp", "matplotlib")
    assert not [m for m in loaded if _within(m, heavy)]
    assert "companion.process.runner" in loaded  # the check is not vacuous
    out = subprocess.run(
        [sys.executable, "-m", "companion", "--help"], cwd=REPO, capture_output=True, text=True
    ).stdout
    assert all(name in out for name in ("fleet", "simulate", "report", "run", "plan"))
