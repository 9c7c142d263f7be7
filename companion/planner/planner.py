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
from companion.planner.model import Aircraft, Goal, NoPath, Plan, Pose, Segment
from companion.planner.paper import Candidate, paper_candidates

FAMILIES = ("all", "paper")


def plan_path(
    start: Pose, goal: Goal, aircraft: Aircraft, wind: Wind, *, families: str = "all"
) -> Plan | NoPath:
    """Minimum-time path from a pose to a (possibly moving) goal in steady wind.

    Args:
        start: start position and air heading.
        goal: goal position, the final course or heading (or neither), its velocity.
        aircraft: airspeed and turn-rate limit.
        wind: steady wind (speed below the airspeed).
        families: ``"all"`` (true minimum over RSR LSL RSL LSR RLR LRL, or RS LS RL LR for a
            free final heading) or ``"paper"`` (only the paper's analytic RSR/LSL of eq. 29;
            needs a final course or heading).

    Returns:
        A :class:`Plan`, or :class:`NoPath` when no path exists (the goal is the start, or
        the goal outruns the aircraft).

    Raises:
        ValueError: bad input, the caller's error: non-finite numbers, ``airspeed <= wind``,
            turn rate <= 0, both final course and heading given, or an unknown ``families``.
    """
    problem = _problem(start, goal, aircraft, wind, families)
    if isinstance(problem, NoPath):
        return problem
    s0, omega = aircraft.airspeed_m_s, aircraft.max_turn_rate_rad_s
    if families == "paper":
        if abs(problem.drift_m_s) >= s0:
            return NoPath("the paper's analytic families need |wind - target velocity| < airspeed")
        cands = paper_candidates(
            problem.goal_m, problem.theta0_rad, problem.final_heading_rad, s0, omega,
            problem.drift_m_s,
        )
    else:
        cands = _all_candidates(problem)
    if not cands:
        return NoPath("no path reaches the goal: it moves away faster than the aircraft can follow")
    best = min(cands, key=lambda c: c[0])
    return _to_plan(best, problem, start.position_m, wind)


def _problem(
    start: Pose, goal: Goal, aircraft: Aircraft, wind: Wind, families: str
) -> Problem | NoPath:
    """Validate the inputs (raising ``ValueError``) and build the air-frame problem; NoPath
    when the goal is the start."""
    if families not in FAMILIES:
        raise ValueError(f"families must be one of {FAMILIES}, got {families!r}")
    numbers = {
        "start.position_m": start.position_m, "start.heading_rad": start.heading_rad,
        "goal.position_m": goal.position_m, "goal.course_rad": goal.course_rad,
        "goal.heading_rad": goal.heading_rad, "goal.velocity_m_s": goal.velocity_m_s,
        "aircraft.airspeed_m_s": aircraft.airspeed_m_s,
        "aircraft.max_turn_rate_rad_s": aircraft.max_turn_rate_rad_s,
        "wind.speed_m_s": wind.speed_m_s, "wind.towards_rad": wind.towards_rad,
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
    s0, omega = aircraft.airspeed_m_s, aircraft.max_turn_rate_rad_s
    if not s0 > 0:
        raise ValueError(f"aircraft.airspeed_m_s must be > 0, got {s0!r}")
    if not omega > 0:
        raise ValueError(f"aircraft.max_turn_rate_rad_s must be > 0, got {omega!r}")
    wind.check_against(s0)
    if goal.course_rad is not None and goal.heading_rad is not None:
        raise ValueError("give goal.course_rad or goal.heading_rad, not both")
    final_heading = goal.heading_rad
    if goal.course_rad is not None:
        final_heading = float(heading_from_course(s0, goal.course_rad, wind))
    if families == "paper" and final_heading is None:
        raise ValueError("families='paper' needs a final course or heading")
    if abs(complex(goal.position_m) - complex(start.position_m)) < 1e-9:
        return NoPath("the goal equals the start: nothing to plan")
    return Problem(
        goal_m=complex(goal.position_m) - complex(start.position_m),
        drift_m_s=wind.vector - complex(goal.velocity_m_s),
        theta0_rad=float(start.heading_rad),
        thetaf_rad=None if final_heading is None else float(final_heading),
        airspeed_m_s=float(s0),
        turn_rate_rad_s=float(omega),
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
