"""The line-based control input (stdin): parse one command line into an action (pure).

Grammar (one command per line, ``key=value`` words, ``#`` starts a comment)::

    intruder id=NAME north_m=N east_m=E [kind=static|moving|decoy]
             [velocity_north_m_s=V] [velocity_east_m_s=V] [appear_t_s=T]
             [vanish_t_s=T] [vanish_after_detection_s=S]
    status
    help

``appear_t_s`` defaults to the current simulated time; ``kind`` defaults to ``moving`` when
a velocity is given, else ``static``. The simulator answers each line on stdout with
``ok ...`` or ``error: ...``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.mission import Intruder

HELP = (
    "commands: intruder id=NAME north_m=N east_m=E [kind=static|moving|decoy] "
    "[velocity_north_m_s=V] [velocity_east_m_s=V] [appear_t_s=T] [vanish_t_s=T] "
    "[vanish_after_detection_s=S] | speedup X | status | help"
)
_FLOATS = (
    "north_m",
    "east_m",
    "velocity_north_m_s",
    "velocity_east_m_s",
    "appear_t_s",
    "vanish_t_s",
    "vanish_after_detection_s",
)


class ControlError(ValueError):
    """A control line that cannot be carried out; the message says why."""


@dataclass(frozen=True)
class Command:
    """A parsed line: ``verb`` in {"intruder", "speedup", "status", "help", ""} and its data."""

    verb: str
    intruder: Intruder | None = None
    speedup: float | None = None


def parse_line(line: str, now_s: float) -> Command:
    """Parse one control line at simulated time ``now_s`` (s)."""
    words = line.split("#", 1)[0].split()
    if not words:
        return Command("")
    verb, args = words[0].lower(), words[1:]
    if verb in ("status", "help"):
        return Command(verb)
    if verb == "speedup":
        try:
            value = float(args[0]) if len(args) == 1 else math.nan
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and 0 < value <= 1e6):
            raise ControlError("speedup takes one number from 0 (exclusive) to 1e6")
        return Command("speedup", speedup=value)
    if verb != "intruder":
        raise ControlError(f"unknown command {verb!r}; {HELP}")
    kv: dict[str, str] = {}
    for w in args:
        if "=" not in w:
            raise ControlError(f"expected key=value, got {w!r}")
        k, v = w.split("=", 1)
        kv[k] = v
    unknown = set(kv) - {"id", "kind", *_FLOATS}
    if unknown:
        raise ControlError(f"unknown keys {sorted(unknown)}")
    for k in ("id", "north_m", "east_m"):
        if k not in kv:
            raise ControlError(f"intruder needs {k}=")
    nums: dict[str, float] = {}
    for k in _FLOATS:
        if k in kv:
            try:
                nums[k] = float(kv[k])
            except ValueError:
                raise ControlError(f"{k} must be a number, got {kv[k]!r}") from None
            if not math.isfinite(nums[k]):
                raise ControlError(f"{k} must be finite")
    moving = nums.get("velocity_north_m_s", 0.0) != 0 or nums.get("velocity_east_m_s", 0.0) != 0
    kind = kv.get("kind", "moving" if moving else "static")
    if kind not in ("static", "moving", "decoy"):
        raise ControlError(f"kind must be static, moving or decoy, got {kind!r}")
    intr = Intruder(
        id=kv["id"],
        kind=kind,  # type: ignore[arg-type]
        appear_t_s=nums.get("appear_t_s", now_s),
        north_m=nums["north_m"],
        east_m=nums["east_m"],
        velocity_north_m_s=nums.get("velocity_north_m_s", 0.0),
        velocity_east_m_s=nums.get("velocity_east_m_s", 0.0),
        vanish_t_s=nums.get("vanish_t_s"),
        vanish_after_detection_s=nums.get("vanish_after_detection_s"),
    )
    return Command("intruder", intr)
