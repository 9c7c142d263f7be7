"""``companion plan``: minimum-time paths in wind, one case from flags or many as JSON Lines.

Edge of the planner: degrees and JSON here, radians and complex numbers inside. Angles are
compass degrees (0 = North, 90 = East); wind is given by speed and the direction it blows
FROM; segments are air-relative with positive turn rate = right turn.

Input keys (one JSON object per line with ``--batch``; flags use the same names with
dashes): ``start_north_m, start_east_m, start_heading_deg, goal_north_m, goal_east_m,
airspeed_m_s, max_turn_rate_deg_s, wind_speed_m_s, wind_from_deg`` and optionally
``goal_course_deg`` (ground course at arrival) or ``goal_heading_deg`` (air heading at
arrival); neither means a free final heading.

Output: ``{"time_s", "path_type", "segments": [{"turn_rate_deg_s", "duration_s"}, ...]}``.
A bad line, or a case without a path, gives ``{"error": "...", "line": N}`` (N from 1) and
the other lines are still answered, in order.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterable, Iterator
from typing import Any

from companion.contracts.errors import UserError
from companion.core.wind import Wind
from companion.planner import Aircraft, Goal, NoPath, Pose, plan_path

REQUIRED = (
    "start_north_m", "start_east_m", "start_heading_deg", "goal_north_m", "goal_east_m",
    "airspeed_m_s", "max_turn_rate_deg_s", "wind_speed_m_s", "wind_from_deg",
)  # fmt: skip
OPTIONAL = ("goal_course_deg", "goal_heading_deg")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``plan`` sub-command."""
    p = sub.add_parser(
        "plan",
        help="minimum-time path in wind (one case from flags, or JSON Lines with --batch)",
        description="Minimum-time path for a constant-airspeed aircraft in steady wind. "
        "Angles in compass degrees, wind FROM direction; output segments are air-relative "
        "turn rates (positive = right) in flight order.",
    )
    p.add_argument(
        "--batch",
        metavar="FILE",
        help="JSON Lines input ('-' = stdin); one output line per input line, in order",
    )
    for key in REQUIRED + OPTIONAL:
        p.add_argument("--" + key.replace("_", "-"), dest=key, metavar="X", default=None)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Answer one case (flags) or a batch; returns the exit status (1 = no path, single case)."""
    if args.batch is not None:
        given = [k for k in REQUIRED + OPTIONAL if getattr(args, k) is not None]
        if given:
            raise UserError(f"--batch takes no case flags (got --{given[0].replace('_', '-')})")
        if args.batch == "-":
            answer_lines(sys.stdin, sys.stdout)
        else:
            try:
                with open(args.batch, encoding="utf-8") as f:
                    answer_lines(f, sys.stdout)
            except OSError as exc:
                raise UserError(f"cannot read {args.batch}: {exc.strerror}") from None
        return 0
    case: dict[str, Any] = {}
    for key in REQUIRED + OPTIONAL:
        text = getattr(args, key)
        if text is None:
            if key in REQUIRED:
                raise UserError(f"missing --{key.replace('_', '-')} (or use --batch)")
            continue
        try:
            case[key] = float(text)
        except ValueError:
            raise UserError(f"--{key.replace('_', '-')}: not a number: {text!r}") from None
    try:
        out = solve(case)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    print(json.dumps(out))
    return 1 if "error" in out else 0


def answer_lines(lines: Iterable[str], out: Any) -> None:
    """Write one JSON answer per input line to ``out`` (flushed per line)."""
    for answer in answers(lines):
        out.write(json.dumps(answer) + "\n")
        out.flush()


def answers(lines: Iterable[str]) -> Iterator[dict[str, Any]]:
    """One answer dict per JSON Lines input line; errors carry the 1-based line number."""
    for n, line in enumerate(lines, start=1):
        try:
            case = json.loads(line)
        except json.JSONDecodeError as exc:
            yield {"error": f"bad JSON: {exc.msg}", "line": n}
            continue
        try:
            answer = solve(case)
        except ValueError as exc:
            yield {"error": str(exc), "line": n}
            continue
        if "error" in answer:
            answer["line"] = n
        yield answer


def solve(case: Any) -> dict[str, Any]:
    """Plan one case given as a dict of the input keys; raises ``ValueError`` on bad input."""
    if not isinstance(case, dict):
        raise ValueError("each line must be a JSON object")
    unknown = sorted(set(case) - set(REQUIRED) - set(OPTIONAL))
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r}")
    missing = [k for k in REQUIRED if k not in case]
    if missing:
        raise ValueError(f"missing key {missing[0]!r}")
    for key, value in case.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{key} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{key} must be finite, got {value!r}")
    if "goal_course_deg" in case and "goal_heading_deg" in case:
        raise ValueError("give goal_course_deg or goal_heading_deg, not both")
    if case["wind_speed_m_s"] < 0:
        raise ValueError(f"wind_speed_m_s must be >= 0, got {case['wind_speed_m_s']!r}")
    if (case["goal_north_m"], case["goal_east_m"]) == (case["start_north_m"], case["start_east_m"]):
        raise ValueError("the goal equals the start: nothing to plan")
    course = case.get("goal_course_deg")
    heading = case.get("goal_heading_deg")
    result = plan_path(
        Pose(
            complex(case["start_north_m"], case["start_east_m"]),
            math.radians(case["start_heading_deg"]),
        ),
        Goal(
            complex(case["goal_north_m"], case["goal_east_m"]),
            course_rad=None if course is None else math.radians(course),
            heading_rad=None if heading is None else math.radians(heading),
        ),
        Aircraft(float(case["airspeed_m_s"]), math.radians(case["max_turn_rate_deg_s"])),
        Wind.from_meteo(case["wind_speed_m_s"], case["wind_from_deg"]),
    )
    if isinstance(result, NoPath):
        return {"error": f"no path: {result.reason}"}
    return {
        "time_s": result.time_s,
        "path_type": result.family,
        "segments": [
            {"turn_rate_deg_s": math.degrees(s.turn_rate_rad_s), "duration_s": s.duration_s}
            for s in result.segments
        ],
    }
