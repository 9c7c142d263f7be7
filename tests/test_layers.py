"""The layer rule between the companion and the simulator (issue 13), checked on the source.

THE RULE

1. The SHARED PURE LAYER is ``companion.core``, ``companion.mission``, ``companion.planner``
   and ``companion.errors`` (the ``UserError`` base of ``MissionError``): no sockets, no
   clocks, no files, no processes (one entry point reads a file: ``load_mission`` opens the
   mission YAML it is named; ``parse_mission`` is the pure rest). It imports neither
   ``sitl_model`` nor any other part of ``companion``.
2. ``sitl_model`` imports from ``companion`` only the shared layer. One named exception:
   ``sitl_model/cli.py`` reads the link signing key file with ``companion.group.keys``
   (file I/O; the key file's format and permission check keep one home). The
   ``companion.group`` package imports none of its modules, so this loads nothing else.
3. Outside the shared layer, ``companion`` imports ``sitl_model`` only in its composition
   roots, the modules that run a simulator: ``companion/inmemory/``, ``companion/fleet.py``,
   ``companion/arduplane/``, ``companion/commands/simulate.py`` and
   ``companion/commands/fleet.py``. No other exception: the guidance-level particle fleet
   the steering-law tests fly lives in the test tree (``tests/particle_fleet.py``).

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
    "companion.core",
    "companion.mission",
    "companion.planner",
    "companion.errors",
)
COMPOSITION_ROOTS: tuple[str, ...] = (  # companion modules that may import sitl_model
    "companion.inmemory",
    "companion.fleet",
    "companion.arduplane",
    "companion.commands.simulate",
    "companion.commands.fleet",
)
SITL_EXCEPTIONS: dict[str, tuple[str, ...]] = {  # sitl_model module -> companion modules
    "sitl_model.cli": ("companion.group.keys",),
}


RULE_SHARED = "the shared layer imports only the shared layer (rule 1)"
RULE_SITL = "sitl_model imports from companion only the shared layer (rule 2)"
RULE_ROOTS = "only the composition roots import sitl_model (rule 3)"


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
    if top not in ("companion", "sitl_model"):
        return None
    if _within(importer, SHARED):
        return None if _within(imported, SHARED) else RULE_SHARED
    sitl_allowed = SHARED + SITL_EXCEPTIONS.get(importer, ())
    if importer.startswith("sitl_model.") and top == "companion":
        return None if _within(imported, sitl_allowed) else RULE_SITL
    if importer.startswith("companion.") and top == "sitl_model":
        return None if _within(importer, COMPOSITION_ROOTS) else RULE_ROOTS
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
    assert len(files) > 50  # the walk found the packages
    bad = offences(files)
    assert not bad, "imports that break the layer rule:\n" + "\n".join(bad)


def test_the_check_catches_each_kind_of_offence(tmp_path: Path) -> None:
    """The checker flags a bad import of each rule, at any depth, and passes the allowed ones."""
    assert violation("companion.core.wind", "companion.runner.Runner")
    assert violation("companion.planner.planner", "sitl_model.sim")
    assert violation("sitl_model.sim", "companion.group.codec.Signing")
    assert violation("sitl_model.server", "companion.group.keys.load_key")  # cli.py only
    assert violation("companion.agent", "sitl_model.particle")
    assert violation("companion.report.rundata", "sitl_model.sim.TRUTH_COLUMNS")
    assert violation("sitl_model.cli", "companion.group.keys.load_key") is None
    assert violation("sitl_model.sim", "companion.core.particle.step") is None
    assert violation("companion.arduplane.world", "sitl_model.world.World") is None
    assert violation("companion.simulation", "sitl_model.world.World")  # no legacy world
    assert violation("companion.runner", "companion.group.codec") is None
    probe = tmp_path / "companion" / "core" / "probe.py"
    probe.parent.mkdir(parents=True)
    probe.write_text("import numpy\n\n\ndef f():\n    if True:\n        from .. import runner\n")
    bad = offences([probe], root=tmp_path)
    assert bad == [f"companion/core/probe.py:6: from .. import runner  -- {RULE_SHARED}"], bad


_LOADED = """
import importlib, json, pkgutil, sys
import companion.core, companion.errors, companion.mission, companion.planner
names = {}
for pkg in (companion.core, companion.mission, companion.planner):
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
from companion.cli import build_parser
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
    heavy = ("sitl_model", "companion.report", "companion.inmemory", "aiohttp", "matplotlib")
    assert not [m for m in loaded if _within(m, heavy)]
    assert "companion.runner" in loaded  # the check is not vacuous
    out = subprocess.run(
        [sys.executable, "-m", "companion", "--help"], cwd=REPO, capture_output=True, text=True
    ).stdout
    assert all(name in out for name in ("fleet", "simulate", "report", "run", "plan"))
