"""Command-line helper shared by ``companion`` and ``sitl-model`` (pure: a parser and argv in,
argv out)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Sequence

__all__ = ["join_negative_values", "parse_battery_used"]

# A value that starts with "-" but is numbers: "-450", "-1e3", "-.5", "-450,0", "-40,-120.5"
_NEGATIVE_VALUE = re.compile(r"^-\.?\d[\d.eE+-]*(,[-+]?\.?\d[\d.eE+-]*)*$")


def _value_options(parser: argparse.ArgumentParser) -> set[str]:
    """Long option strings, in ``parser`` and its sub-commands, that take one value."""
    out: set[str] = set()
    for action in parser._actions:  # argparse has no public walk of its actions
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                out |= _value_options(sub)
        elif action.nargs is None and action.option_strings:
            out |= {s for s in action.option_strings if s.startswith("--")}
    return out


def join_negative_values(parser: argparse.ArgumentParser, argv: Sequence[str]) -> list[str]:
    """``argv`` with ``--opt -450,0`` written as ``--opt=-450,0`` for every option of
    ``parser`` (and its sub-commands) that takes a value.

    argparse reads a token that starts with "-" as an option unless it looks like one
    negative number, so ``--at -450,0`` (a point south of the origin) or ``--start-north
    -1e3`` failed with "expected one argument"; joined, they parse as written.
    """
    takes_value = _value_options(parser)
    out: list[str] = []
    i = 0
    while i < len(argv):
        tok = argv[i]
        if tok == "--":
            out.extend(argv[i:])
            break
        nxt = argv[i + 1] if i + 1 < len(argv) else None
        if tok in takes_value and nxt is not None and _NEGATIVE_VALUE.match(nxt):
            out.append(f"{tok}={nxt}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


def parse_battery_used(text: str) -> tuple[int, float]:
    """``SYSID=MAH`` (``--battery-used``): vehicle ``SYSID`` starts with a battery that has
    already given ``MAH`` (mAh, finite, >= 0), as ``(sysid, mah)``.

    Raises:
        argparse.ArgumentTypeError: not ``SYSID=MAH`` with an integer sysid 1..255 and a
            finite charge >= 0.
    """
    sysid, sep, mah = text.partition("=")
    try:
        out = (int(sysid), float(mah))
    except ValueError:
        out = None
    if not sep or out is None or not 1 <= out[0] <= 255 or not 0.0 <= out[1] < float("inf"):
        raise argparse.ArgumentTypeError(f"expected SYSID=MAH (e.g. 3=5800), got {text!r}")
    return out


def add_battery_used_option(p: argparse.ArgumentParser) -> None:
    """``--battery-used SYSID=MAH`` (repeatable, :func:`parse_battery_used`): a vehicle of
    the simulator's world starts with a used battery that has already given MAH mAh (the
    companions are not told); ``sitl-model``, ``companion simulate`` and ``companion fleet``."""
    p.add_argument(
        "--battery-used",
        type=parse_battery_used,
        action="append",
        default=[],
        metavar="SYSID=MAH",
        help="the simulated vehicle SYSID starts with a used battery that has already given "
        "MAH mAh, e.g. 3=5800 so that it needs a relief early (repeatable; docs/energy.md)",
    )
