"""The shape of the per-UAV core stays as issue 45 left it: small typed parts, not mixins.

Checked on the source (``ast``) and on the classes themselves:

* no mixin in ``companion/agent`` and ``companion/process``: a class there inherits from a class
  of ours only when that base is a record (a dataclass: the events' common fields), a
  ``Protocol`` it implements or an exception; behaviour is held (``self.x: X``), never
  inherited;
* no class there with more than 20 instance attributes (distinct ``self.x = ...``);
* ``companion/agent/agent.py`` at most 300 lines;
* the checks that keep the rest true stay configured in ``pyproject.toml``: ruff's McCabe
  complexity (C901) at 15 with no exception for these packages, and mypy on the typed core
  with its strict flags (``ruff check .`` and ``mypy`` run before the tests: README).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import tomllib
from fnmatch import fnmatch
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PARTS = ("companion/agent", "companion/process")
TYPED = ("agent", "process", "core", "guidance", "planner", "mission")
MAX_ATTRIBUTES = 20
MAX_AGENT_LINES = 300
MAX_COMPLEXITY = 15


def sources(*folders: str) -> list[Path]:
    return sorted(p for f in folders for p in (REPO / f).rglob("*.py"))


def attributes_per_class(path: Path) -> dict[str, set[str]]:
    """Class name -> the distinct ``self.x`` it assigns anywhere in its body (``=``, ``+=``,
    annotated, tuple targets)."""
    out = {}
    for cls in [n for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.ClassDef)]:
        names = set()
        for node in ast.walk(cls):
            targets = node.targets if isinstance(node, ast.Assign) else []
            if isinstance(node, ast.AnnAssign | ast.AugAssign):
                targets = [node.target]
            for t in targets:
                for e in t.elts if isinstance(t, ast.Tuple) else [t]:
                    if isinstance(e, ast.Attribute) and getattr(e.value, "id", "") == "self":
                        names.add(e.attr)
        out[cls.name] = names
    return out


def test_the_attribute_count_sees_every_form_of_assignment(tmp_path):
    src = tmp_path / "k.py"
    src.write_text(
        "class K:\n"
        "    def __init__(self):\n"
        "        self.a = 1\n"
        "        self.b: int = 2\n"
        "        self.c, self.d = 3, 4\n"
        "    def more(self):\n"
        "        self.a += 1\n"
        "        self.e = self.f = 0\n"
    )
    assert attributes_per_class(src) == {"K": {"a", "b", "c", "d", "e", "f"}}


def test_no_class_of_the_agent_or_the_process_holds_more_than_20_attributes():
    counts = {
        f"{p.relative_to(REPO)}:{name}": len(attrs)
        for p in sources(*PARTS)
        for name, attrs in attributes_per_class(p).items()
    }
    assert counts["companion/process/runner.py:Runner"] > 10  # the check sees the big ones
    assert counts["companion/agent/agent.py:Agent"] > 10
    assert {k: n for k, n in counts.items() if n > MAX_ATTRIBUTES} == {}


def modules(*folders: str) -> list[str]:
    return [
        ".".join(p.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__")
        for p in sources(*folders)
    ]


def ours(cls: type) -> bool:
    return cls.__module__.split(".")[0] in ("companion", "sitl_model")


@pytest.mark.parametrize("name", modules(*PARTS))
def test_no_class_inherits_behaviour_from_a_class_of_ours(name):
    module = importlib.import_module(name)
    classes = [c for _, c in inspect.getmembers(module, inspect.isclass) if c.__module__ == name]
    for cls in classes:
        for base in cls.__mro__[1:]:
            if not ours(base):
                continue
            record = dataclasses.is_dataclass(base)
            protocol = getattr(base, "_is_protocol", False)
            assert record or protocol or issubclass(base, Exception), (
                f"{name}.{cls.__name__} inherits from {base.__module__}.{base.__name__}, "
                "which is neither a record, a Protocol nor an exception: a mixin"
            )
        own_bases = [b for b in cls.__bases__ if ours(b) and not getattr(b, "_is_protocol", False)]
        assert len(own_bases) <= 1, f"{name}.{cls.__name__}: several bases of ours {own_bases}"


def test_the_agent_module_stays_short():
    lines = (REPO / "companion" / "agent" / "agent.py").read_text().count("\n")
    assert lines <= MAX_AGENT_LINES, lines


def pyproject() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text())


def test_ruff_keeps_the_complexity_limit_on_the_typed_core():
    lint = pyproject()["tool"]["ruff"]["lint"]
    assert "C901" in lint["select"]
    assert lint["mccabe"]["max-complexity"] == MAX_COMPLEXITY
    waived = [pat for pat, rules in lint.get("per-file-ignores", {}).items() if "C901" in rules]
    for path in sources(*(f"companion/{p}" for p in TYPED)):
        rel = str(path.relative_to(REPO))
        assert not [pat for pat in waived if fnmatch(rel, pat)], rel


def test_mypy_checks_the_typed_core_strictly():
    mypy = pyproject()["tool"]["mypy"]
    assert sorted(mypy["files"]) == sorted(f"companion/{p}" for p in TYPED)
    (strict,) = [o for o in mypy["overrides"] if "companion.agent.*" in o["module"]]
    assert sorted(strict["module"]) == sorted(f"companion.{p}.*" for p in TYPED)
    for flag in ("check_untyped_defs", "disallow_untyped_defs", "disallow_incomplete_defs"):
        assert strict[flag] is True, flag
    for o in mypy["overrides"]:  # missing imports are waived for third-party modules only
        if o.get("ignore_missing_imports"):
            assert not [m for m in o["module"] if m.startswith(("companion", "sitl_model"))]


def test_the_typed_core_waives_no_type_error_blindly():
    blanket = [
        f"{p.relative_to(REPO)}:{i}"
        for p in sources(*(f"companion/{p}" for p in TYPED))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if "type: ignore" in line and "type: ignore[" not in line
    ]
    assert blanket == []
