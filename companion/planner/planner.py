"""``plan_path``: the minimum-time path in steady wind, over every path family.

Conventions: complex positions ``north + i east`` (m), compass angles (rad, 0 = North,
pi/2 = East), positive turn rate = right turn, SI units. Headings are air-relative, courses
are ground tracks; a final ground course is turned into the final air heading with the wind
triangle before planning.
"""

from __future__ import annotations

import cmath
import math

from companion.core.wind import TWO_PI, Wind, heading_from_course
from companion.planner.airframe import Problem, opposite_sense, same_sense, turn_straight, turn_turn
from companion.planner.model import NoPath, Plan, Segment
from companion.planner.paper import Candidate, paper_candidates

FAMILIES = ("all", "paper")


def plan_path(
    start_m: complex,
    start_heading_rad: float,
    goal_m: complex,
    airspeed_m_s: float,
    max_turn_rate_rad_s: float,
    wind: Wind,
    final_course_rad: float | None = None,
    final_heading_rad: float | None = None,
    target_velocity_m_s: complex = 0j,
    families: str = "all",
) -> Plan | NoPath:
    """Minimum-time path from a pose to a (possibly moving) goal in steady wind.

    Args:
        start_m: start position (m, complex north + i east).
        start_heading_rad: start air heading (rad, compass).
        goal_m: goal position at t = 0 (m, complex).
        airspeed_m_s: constant airspeed ``s0`` (m/s), > wind speed.
        max_turn_rate_rad_s: turn-rate limit ``omega`` (rad/s), > 0.
        wind: steady wind (speed below ``airspeed_m_s``).
        final_course_rad: ground course at arrival (rad), or None.
        final_heading_rad: air heading at arrival (rad), or None. At most one of the two;
            neither means a free final heading.
        target_velocity_m_s: the goal's constant ground velocity (m/s, complex); nonzero
            asks for the minimum-time intercept of the moving goal.
        families: ``"all"`` (true minimum over RSR LSL RSL LSR RLR LRL, or RS LS RL LR for a
            free final heading) or ``"paper"`` (only the paper's analytic RSR/LSL of eq. 29;
            needs a final course or heading).

    Returns:
        A :class:`Plan`, or :class:`NoPath` when no path exists (e.g. the goal outruns the
        aircraft).

    Raises:
        ValueError: non-finite inputs, ``airspeed <= wind``, turn rate <= 0, goal equal to
            start, both final course and heading given, or an unknown ``families``.
    """
    problem = _problem(
        start_m, start_heading_rad, goal_m, airspeed_m_s, max_turn_rate_rad_s, wind,
        final_course_rad, final_heading_rad, target_velocity_m_s, families,
    )  # fmt: skip
    if families == "paper":
        if abs(problem.drift_m_s) >= airspeed_m_s:
            return NoPath("the paper's analytic families need |wind - target velocity| < airspeed")
        cands = paper_candidates(
            problem.goal_m, problem.theta0_rad, problem.thetaf_rad, airspeed_m_s,
            max_turn_rate_rad_s, problem.drift_m_s,
        )  # fmt: skip
    else:
        cands = _all_candidates(problem)
    if not cands:
        return NoPath("no path reaches the goal: it moves away faster than the aircraft can follow")
    best = min(cands, key=lambda c: c[0])
    return _to_plan(best, problem, start_m, wind)


def _problem(
    start_m: complex,
    start_heading_rad: float,
    goal_m: complex,
    airspeed_m_s: float,
    max_turn_rate_rad_s: float,
    wind: Wind,
    final_course_rad: float | None,
    final_heading_rad: float | None,
    target_velocity_m_s: complex,
    families: str,
) -> Problem:
    """Validate the inputs (raising ``ValueError``) and build the air-frame problem."""
    if families not in FAMILIES:
        raise ValueError(f"families must be one of {FAMILIES}, got {families!r}")
    numbers = {
        "start_m": start_m, "start_heading_rad": start_heading_rad, "goal_m": goal_m,
        "airspeed_m_s": airspeed_m_s, "max_turn_rate_rad_s": max_turn_rate_rad_s,
        "wind.speed_m_s": wind.speed_m_s, "wind.towards_rad": wind.towards_rad,
        "final_course_rad": final_course_rad, "final_heading_rad": final_heading_rad,
        "target_velocity_m_s": target_velocity_m_s,
    }  # fmt: skip
    for name, value in numbers.items():
        if value is None:
            continue
        try:
            finite = cmath.isfinite(complex(value))
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a number, got {value!r}") from None
        if not finite:
            raise ValueError(f"{name} must be finite, got {value!r}")
    if not airspeed_m_s > 0:
        raise ValueError(f"airspeed_m_s must be > 0, got {airspeed_m_s!r}")
    if not max_turn_rate_rad_s > 0:
        raise ValueError(f"max_turn_rate_rad_s must be > 0, got {max_turn_rate_rad_s!r}")
    wind.check_against(airspeed_m_s)
    if abs(complex(goal_m) - complex(start_m)) < 1e-9:
        raise ValueError("goal_m equals start_m: nothing to plan")
    if final_course_rad is not None and final_heading_rad is not None:
        raise ValueError("give final_course_rad or final_heading_rad, not both")
    if final_course_rad is not None:
        final_heading_rad = float(heading_from_course(airspeed_m_s, final_course_rad, wind))
    if families == "paper" and final_heading_rad is None:
        raise ValueError("families='paper' needs a final course or heading")
    return Problem(
        goal_m=complex(goal_m) - complex(start_m),
        drift_m_s=wind.vector - complex(target_velocity_m_s),
        theta0_rad=float(start_heading_rad),
        thetaf_rad=None if final_heading_rad is None else float(final_heading_rad),
        airspeed_m_s=float(airspeed_m_s),
        turn_rate_rad_s=float(max_turn_rate_rad_s),
    )


def _all_candidates(p: Problem) -> list[Candidate]:
    """Every family's earliest arrivals; the time-parametrised ones only up to the best so far."""
    fixed = p.thetaf_rad is not None
    cands = same_sense(p) + opposite_sense(p) if fixed else turn_straight(p)
    if cands:
        t_max = min(c[0] for c in cands)
    elif abs(p.drift_m_s) < p.airspeed_m_s:
        # a turn-straight path of at most (2 pi + 4) rho + |g| + |d| T metres exists by then
        t_max = ((TWO_PI + 4.0) * p.rho + abs(p.goal_m)) / (p.airspeed_m_s - abs(p.drift_m_s))
    else:
        t_max = math.inf  # the turn-turn intervals are bounded because d != 0
    return cands + turn_turn(p, t_max, to_point=not fixed)


def _to_plan(best: Candidate, p: Problem, start_m: complex, wind: Wind) -> Plan:
    """Turn a candidate into a :class:`Plan`: drop empty pieces, merge equal neighbours."""
    _, word, durations = best
    rate = {"R": p.turn_rate_rad_s, "L": -p.turn_rate_rad_s, "S": 0.0}
    pieces: list[list] = []
    for letter, dur in zip(word, durations, strict=True):
        if dur <= 1e-9:
            continue
        if pieces and pieces[-1][0] == letter:
            pieces[-1][1] += dur
        else:
            pieces.append([letter, dur])
    segments = tuple(Segment(rate[letter], float(dur)) for letter, dur in pieces)
    return Plan(
        time_s=float(sum(s.duration_s for s in segments)),
        family="".join(letter for letter, _ in pieces),
        segments=segments,
        start_m=complex(start_m),
        start_heading_rad=p.theta0_rad,
        airspeed_m_s=p.airspeed_m_s,
        wind_m_s=wind.vector,
    )
