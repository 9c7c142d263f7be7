"""Safe, line-aware reading of composed YAML nodes for the mission loader.

The mission file is composed (never constructed) by PyYAML's safe loader with no aliases, a
depth and a node-count limit; these helpers walk the node tree with a tag, key and number
check, read mappings key by key (duplicates and leftover keys are errors) and scalars with
their types and ranges, and turn every problem into one :class:`MissionError` naming the
file, the dotted field and the line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, TypeVar

import yaml

from companion.mission.errors import MissionError

C = TypeVar("C", bound=str)  # the values of a Literal of strings (MapReader.choice)

MAX_NODES = 20_000
MAX_DEPTH = 20
_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
}
MAX_KEY_CHARS = 100
MAX_NUMBER_CHARS = 100
MAX_SHOWN_CHARS = 60  # longest value quoted in a message


class _GuardedLoader(yaml.SafeLoader):
    """PyYAML's safe loader whose (recursive) composer refuses aliases and stops at a depth
    and a node count; it tracks the dotted field being composed for its messages."""

    def __init__(self, text: str, file: str) -> None:
        super().__init__(text)
        self.file = file
        self.path = ""
        self.depth = 0
        self.nodes = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        """Compose one node (``index``: its key node in a mapping, its position in a list)."""
        outer = self.path
        if isinstance(index, yaml.ScalarNode):
            name = _field_name(index.value)
            self.path = f"{outer}.{name}" if outer else name
        elif isinstance(index, int):
            self.path = f"{outer}[{index}]"
        line = self.peek_event().start_mark.line + 1
        try:
            if self.check_event(yaml.AliasEvent):
                raise MissionError(
                    self.file, self.path, "YAML anchors and aliases are not allowed", line
                )
            self.nodes += 1
            if self.nodes > MAX_NODES:
                raise MissionError(self.file, "", f"more than {MAX_NODES} YAML nodes", line)
            if self.depth >= MAX_DEPTH:
                raise MissionError(self.file, "", f"nested deeper than {MAX_DEPTH} levels", line)
            self.depth += 1
            try:
                return super().compose_node(parent, index)
            finally:
                self.depth -= 1
        finally:
            self.path = outer


def compose(text: str, file: str) -> yaml.Node | None:
    """Compose (never construct) one YAML document; None if it is empty.

    The composer refuses aliases and stops at :data:`MAX_DEPTH` levels and
    :data:`MAX_NODES` nodes, so neither shared nodes, deep nesting nor a flood of nodes can
    exhaust the stack or memory.

    Raises:
        MissionError: an alias, too deep or too many nodes (with the line).
        yaml.YAMLError: a reader, scanner or parser error, for the caller to place.
    """
    loader = _GuardedLoader(text, file)
    try:
        return loader.get_single_node()
    finally:
        loader.dispose()


def check_tree(root: yaml.Node, file: str) -> None:
    """Refuse foreign tags, odd keys and unreadable numbers (aliases are refused earlier).

    The message names the dotted field where the problem sits (when it is under a key).
    """
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:  # depth first, in document order (the first problem in the file is named)
        node, path = stack.pop()
        line = node.start_mark.line + 1
        kinds = {yaml.ScalarNode: _SCALAR_TAGS, yaml.SequenceNode: {"tag:yaml.org,2002:seq"}}
        allowed = kinds.get(type(node), {"tag:yaml.org,2002:map"})
        if node.tag not in allowed:
            raise MissionError(file, path, f"YAML tag {_show(node.tag)} is not allowed", line)
        children: list[tuple[yaml.Node, str]] = []
        if isinstance(node, yaml.ScalarNode):
            _check_scalar(node, file, path)
        elif isinstance(node, yaml.SequenceNode):
            children = [(child, f"{path}[{i}]") for i, child in enumerate(node.value)]
        elif isinstance(node, yaml.MappingNode):
            for k, v in node.value:
                key = _scalar(k) if isinstance(k, yaml.ScalarNode) else None
                if isinstance(key, str) and _field_name(key) != key:
                    raise MissionError(
                        file,
                        path,
                        f"key {_show(key)} is not a field name (expected a short printable name)",
                        k.start_mark.line + 1,
                    )
                sub = (f"{path}.{key}" if path else key) if isinstance(key, str) else path
                children += [(k, path), (v, sub)]
        stack.extend(reversed(children))


def _check_scalar(node: yaml.ScalarNode, file: str, path: str) -> None:
    """A number must be short enough to read (Python refuses ints of > 4300 digits)."""
    line = node.start_mark.line + 1
    numeric = node.tag in ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")
    if numeric and len(node.value) > MAX_NUMBER_CHARS:
        raise MissionError(
            file,
            path,
            f"a number written with {len(node.value)} characters "
            f"(expected at most {MAX_NUMBER_CHARS})",
            line,
        )
    try:
        _scalar(node)
    except (ValueError, OverflowError) as exc:
        raise MissionError(file, path, f"unreadable value ({_show(str(exc))})", line) from None


def _field_name(key: str) -> str:
    """``key`` if it can be printed as a field name, else a short repr of it."""
    return key if len(key) <= MAX_KEY_CHARS and key.isprintable() else _show(key)


def _show(v: Any) -> str:
    """``repr(v)`` cut to :data:`MAX_SHOWN_CHARS` characters (messages stay one short line)."""
    r = repr(v)
    return r if len(r) <= MAX_SHOWN_CHARS else f"{r[: MAX_SHOWN_CHARS - 5]}...{r[-2:]}"


_CONSTRUCT = yaml.constructor.SafeConstructor()


def _scalar(node: yaml.Node) -> Any:
    return _CONSTRUCT.construct_object(node, deep=True)


def _kind(node: yaml.Node) -> str:
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if isinstance(node, yaml.SequenceNode):
        return "a list"
    v = _scalar(node)
    return "nothing" if v is None else f"{type(v).__name__} {_show(v)}"


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
            raise self.error(key, f"expected one of {', '.join(choices)}, got {_show(v)}")
        if len(v) > 10_000:
            raise self.error(key, "string longer than 10000 characters")
        return v

    def choice(self, key: str, default: C, choices: tuple[C, ...]) -> C:
        """``key``'s string, one of ``choices`` (a ``Literal``'s values), or ``default``."""
        value = self.string(key, default, choices)
        return next(c for c in choices if c == value)

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
