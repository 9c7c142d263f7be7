"""Safe, line-aware reading of composed YAML nodes for the mission loader.

The mission file is composed (never constructed) by PyYAML's safe loader; these helpers walk
the node tree with a size, depth and tag check, read mappings key by key (duplicates and
leftover keys are errors) and scalars with their types and ranges, and turn every problem
into one :class:`MissionError` naming the file, the dotted field and the line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import yaml

from companion.mission.errors import MissionError

MAX_NODES = 20_000
MAX_DEPTH = 20
_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
}


def check_tree(root: yaml.Node, file: str) -> None:
    """Refuse aliases (shared nodes), deep nesting, huge node counts and foreign tags."""
    seen: set[int] = set()
    stack = [(root, 0)]
    while stack:
        node, depth = stack.pop()
        line = node.start_mark.line + 1
        if id(node) in seen:
            raise MissionError(file, "", "YAML anchors and aliases are not allowed", line)
        seen.add(id(node))
        if len(seen) > MAX_NODES:
            raise MissionError(file, "", f"more than {MAX_NODES} YAML nodes", line)
        if depth > MAX_DEPTH:
            raise MissionError(file, "", f"nested deeper than {MAX_DEPTH} levels", line)
        if isinstance(node, yaml.ScalarNode):
            if node.tag not in _SCALAR_TAGS:
                raise MissionError(file, "", f"YAML tag {node.tag!r} is not allowed", line)
        elif isinstance(node, yaml.SequenceNode):
            if node.tag != "tag:yaml.org,2002:seq":
                raise MissionError(file, "", f"YAML tag {node.tag!r} is not allowed", line)
            stack.extend((child, depth + 1) for child in node.value)
        elif isinstance(node, yaml.MappingNode):
            if node.tag != "tag:yaml.org,2002:map":
                raise MissionError(file, "", f"YAML tag {node.tag!r} is not allowed", line)
            for k, v in node.value:
                stack.append((k, depth + 1))
                stack.append((v, depth + 1))


_CONSTRUCT = yaml.constructor.SafeConstructor()


def _scalar(node: yaml.Node) -> Any:
    return _CONSTRUCT.construct_object(node, deep=True)


def _kind(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    v = _scalar(node)
    return "nothing" if v is None else f"{type(v).__name__} {v!r}"


@dataclass
class MapReader:
    """A YAML mapping being read: keys taken so far are checked off; leftovers are errors."""

    node: yaml.MappingNode
    file: str
    path: str
    items: dict[str, tuple[yaml.Node, yaml.Node]] = field(default_factory=dict)

    @classmethod
    def of(cls, node: yaml.Node, file: str, path: str) -> MapReader:
        if not isinstance(node, yaml.MappingNode):
            raise MissionError(
                file,
                path or "(top level)",
                f"expected a mapping, got {_kind(node)}",
                node.start_mark.line + 1,
            )
        m = cls(node, file, path)
        for k, v in node.value:
            key = _scalar(k) if isinstance(k, yaml.ScalarNode) else None
            if not isinstance(key, str):
                raise MissionError(file, path, "keys must be plain strings", k.start_mark.line + 1)
            if key in m.items:
                raise MissionError(file, m.sub(key), "duplicate key", k.start_mark.line + 1)
            m.items[key] = (k, v)
        return m

    @property
    def line(self) -> int:
        return self.node.start_mark.line + 1

    def sub(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def has(self, key: str) -> bool:
        return key in self.items

    def error(self, key: str, message: str) -> MissionError:
        node = self.items.get(key, (None, self.node))[1]
        return MissionError(self.file, self.sub(key), message, node.start_mark.line + 1)

    def node_of(self, key: str) -> yaml.Node:
        if key not in self.items:
            raise MissionError(self.file, self.sub(key), "missing required field", self.line)
        return self.items[key][1]

    def map(self, key: str) -> MapReader:
        return MapReader.of(self.node_of(key), self.file, self.sub(key))

    def seq(self, key: str, max_len: int) -> list[yaml.Node]:
        node = self.node_of(key)
        if not isinstance(node, yaml.SequenceNode):
            raise self.error(key, f"expected a list, got {_kind(node)}")
        if len(node.value) > max_len:
            raise self.error(key, f"expected at most {max_len} entries, got {len(node.value)}")
        return list(node.value)

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        lo: float = -math.inf,
        hi: float = math.inf,
        lo_open: bool = False,
        what: str = "a number",
    ) -> float:
        if key not in self.items:
            if default is None:
                raise MissionError(
                    self.file, self.sub(key), f"missing required field ({what})", self.line
                )
            return default
        return number_at(self.items[key][1], self.file, self.sub(key), lo, hi, lo_open, what)

    def integer(self, key: str, default: int | None = None, *, lo: int, hi: int) -> int:
        if key not in self.items:
            if default is None:
                raise MissionError(self.file, self.sub(key), "missing required field", self.line)
            return default
        return integer_at(self.items[key][1], self.file, self.sub(key), lo, hi)

    def string(self, key: str, default: str | None = None, choices: tuple[str, ...] = ()) -> str:
        if key not in self.items:
            if default is None:
                raise MissionError(self.file, self.sub(key), "missing required field", self.line)
            return default
        node = self.items[key][1]
        v = _scalar(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(v, str):
            raise self.error(key, f"expected a string, got {_kind(node)}")
        if choices and v not in choices:
            raise self.error(key, f"expected one of {', '.join(choices)}, got {v!r}")
        if len(v) > 10_000:
            raise self.error(key, "string longer than 10000 characters")
        return v

    def done(self, allowed: tuple[str, ...]) -> None:
        for key, (k, _) in self.items.items():
            if key not in allowed:
                raise MissionError(
                    self.file,
                    self.sub(key),
                    f"unknown field (expected one of: {', '.join(allowed)})",
                    k.start_mark.line + 1,
                )


def number_at(
    node: yaml.Node, file: str, path: str, lo: float, hi: float, lo_open: bool, what: str
) -> float:
    v = _scalar(node) if isinstance(node, yaml.ScalarNode) else None
    line = node.start_mark.line + 1
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise MissionError(file, path, f"expected {what}, got {_kind(node)}", line)
    v = float(v)
    if not math.isfinite(v):
        raise MissionError(file, path, f"expected a finite number, got {v}", line)
    if v < lo or (lo_open and v == lo) or v > hi:
        lo_s = f"> {lo:g}" if lo_open else f">= {lo:g}"
        rng = f"{lo_s} and <= {hi:g}" if math.isfinite(hi) else lo_s
        rng = rng if math.isfinite(lo) else f"<= {hi:g}"
        raise MissionError(file, path, f"expected {what} {rng}, got {v:g}", line)
    return v


def integer_at(node: yaml.Node, file: str, path: str, lo: int, hi: int) -> int:
    v = _scalar(node) if isinstance(node, yaml.ScalarNode) else None
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise MissionError(
            file,
            path,
            f"expected a whole number from {lo} to {hi}, got {_kind(node)}",
            node.start_mark.line + 1,
        )
    return v
