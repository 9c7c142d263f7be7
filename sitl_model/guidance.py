"""Lateral guidance laws of the simulated autopilot (pure functions, no state).

Conventions: complex positions ``north + i east`` (m), compass angles (rad, 0 = North,
pi/2 = East), positive turn rate = right turn (rad/s). A guidance law returns the desired
ground course; :func:`course_hold` turns a course error into a turn-rate command.
"""

from __future__ import annotations

import math

from companion.core.wind import wrap_pi


def course_hold(
    target_rad: float,
    course_rad: float,
    kp_1_s: float,
    limit_rad_s: float,
    feedforward_rad_s: float = 0.0,
) -> float:
    """Proportional course hold: ``ff + kp wrap(target - course)``, clipped to +-limit (rad/s)."""
    u = feedforward_rad_s + kp_1_s * float(wrap_pi(target_rad - course_rad))
    return max(-limit_rad_s, min(limit_rad_s, u))


def held_gain(kp_1_s: float, dt_s: float, n: int) -> float:
    """The gain (1/s) of a proportional loop that decides once and holds its command for
    ``n`` steps of ``dt_s`` (s), such that an error decays over the ``n`` steps as it does
    with ``kp_1_s`` decided every step: ``(1 - (1 - kp dt)^n) / (n dt)``; ``kp_1_s`` itself
    for ``n = 1``. (Exact for a heading error flown without lag or limit.)"""
    if n == 1:
        return kp_1_s
    return (1.0 - (1.0 - kp_1_s * dt_s) ** n) / (n * dt_s)


def loiter_centre(pos_m: complex, course_rad: float, radius_m: float, clockwise: bool) -> complex:
    """Centre of a loiter circle of ``radius_m`` (m) tangent to the current course at ``pos_m``."""
    side = math.pi / 2 if clockwise else -math.pi / 2
    return pos_m + radius_m * complex(math.cos(course_rad + side), math.sin(course_rad + side))


def loiter_guidance(
    pos_m: complex,
    centre_m: complex,
    radius_m: float,
    clockwise: bool,
    groundspeed_m_s: float,
) -> tuple[float, float]:
    """Desired course (rad) and course-rate feed-forward (rad/s) to circle ``centre_m``.

    On the circle the desired course is the tangent; outside it bends towards the centre
    (straight at it when far away), inside it bends outwards, with a look-ahead of half the
    radius.
    """
    d = pos_m - centre_m
    dist = abs(d)
    if dist < 1e-6:
        return 0.0, 0.0
    bearing = math.atan2(d.imag, d.real)
    err = dist - radius_m
    delta = math.atan2(err, 0.5 * radius_m)
    sign = 1.0 if clockwise else -1.0
    course = bearing + sign * (math.pi / 2 + delta)
    ff = sign * groundspeed_m_s / radius_m * max(0.0, math.cos(delta))
    return float(wrap_pi(course)), ff


def track_guidance(pos_m: complex, start_m: complex, end_m: complex, lookahead_m: float) -> float:
    """Desired course (rad) to follow the straight leg ``start -> end`` with a look-ahead (m)."""
    leg = end_m - start_m
    length = abs(leg)
    to_end = end_m - pos_m
    if length < 1e-6:
        return math.atan2(to_end.imag, to_end.real)
    t = leg / length
    rel = (pos_m - start_m) * t.conjugate()
    cross_m = rel.imag  # > 0: right of the leg
    return float(wrap_pi(math.atan2(t.imag, t.real) - math.atan2(cross_m, lookahead_m)))


def leg_done(pos_m: complex, start_m: complex, end_m: complex, accept_radius_m: float) -> bool:
    """Whether the leg ends: within the acceptance radius of ``end_m`` or past its end line."""
    if abs(end_m - pos_m) <= accept_radius_m:
        return True
    leg = end_m - start_m
    length = abs(leg)
    if length < 1e-6:
        return False
    along = ((pos_m - start_m) * (leg / length).conjugate()).real
    return along >= length
