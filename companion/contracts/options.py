"""Options declared once (pure): a frozen record's field with its meaning, unit and bounds.

A configuration record (:class:`companion.agent.config.AgentConfig`,
:class:`companion.link.config.LinkConfig`) declares each option as a dataclass field whose
metadata is a :func:`spec`: what it means, its unit, and its bounds (one of some choices, or a
finite number within limits). :func:`check_bounds`, called from the record's
``__post_init__``, refuses a value out of them with :class:`OptionError`, which names the
field; the command line builds its options from the same metadata
(:mod:`companion.commands.options`), so a bound or a default is written in one place.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any


class OptionError(ValueError):
    """An option given a value out of its bounds.

    Attributes:
        field: the option's field name (``member_timeout_s``).
        why: what is wrong, without the name (``must be at least 0.5 s, got 0.1``).
    """

    def __init__(self, field: str, why: str) -> None:
        """The message is ``"FIELD WHY"``."""
        super().__init__(f"{field} {why}")
        self.field = field
        self.why = why


def spec(
    doc: str,
    *,
    unit: str = "",
    choices: tuple[str, ...] | None = None,
    above: float | None = None,
    at_least: float | None = None,
    at_most: float | None = None,
) -> dict[str, Any]:
    """One option's metadata: what it means (``doc``), its ``unit`` and its bounds: one of
    ``choices``, or a finite number greater than ``above``, at least ``at_least`` and at
    most ``at_most`` (each None: no such bound)."""
    bounds = {"choices": choices, "above": above, "at_least": at_least, "at_most": at_most}
    return {"doc": doc, "unit": unit, **bounds}


def bound_error(value: Any, meta: dict[str, Any]) -> str | None:
    """How ``value`` breaks the bounds in ``meta`` (a :func:`spec`), as ``"must be ...,
    got ..."``, or None when it keeps them."""
    unit = f" {meta['unit']}" if meta["unit"] else ""
    if meta["choices"] is not None:
        if value in meta["choices"]:
            return None
        return f"must be {' or '.join(repr(c) for c in meta['choices'])}, got {value!r}"
    low, above, high = meta["at_least"], meta["above"], meta["at_most"]
    ok = isinstance(value, int | float) and math.isfinite(value)
    ok = ok and (above is None or value > above) and (low is None or value >= low)
    if ok and (high is None or value <= high):
        return None
    if low is not None and high is not None:
        return f"must be between {low:g} and {high:g}{unit}, got {value!r}"
    if above is not None:
        return f"must be > {above:g}{unit}, got {value!r}"
    return f"must be at least {low:g}{unit}, got {value!r}"


def option_flag(name: str) -> str:
    """The command-line flag of the field ``name`` (``member_timeout_s``: ``--member-timeout-s``).
    """
    return "--" + name.replace("_", "-")


def as_argv(record: Any, names: tuple[str, ...]) -> list[str]:
    """The command-line words that give the dataclass ``record``'s fields ``names`` their
    values (``["--policy", "next", "--member-timeout-s", "3.0"]``; a float exactly, as its
    ``repr``), for a child process that parses them back."""
    words: list[str] = []
    for name in names:
        value = getattr(record, name)
        words += [option_flag(name), repr(value) if isinstance(value, float) else str(value)]
    return words


def check_bounds(record: Any) -> None:
    """Check every field of the dataclass ``record`` that has a :func:`spec` against it.

    Raises:
        OptionError: naming the first field out of its bounds.
    """
    for f in fields(record):
        if "doc" not in f.metadata:
            continue
        why = bound_error(getattr(record, f.name), dict(f.metadata))
        if why is not None:
            raise OptionError(f.name, why)
