"""Where a relieving spare meets its member's slot, where a relieved UAV leaves the loop, and
the turn rates that fly a relief's legs to a point or round a holding point (pure geometry;
docs/energy.md, "Reliefs"). Positions complex m (north + i east), angles rad, times s.

The coverage revisit counts from the start of one pass over a loop point to the next, so an
aircraft that sees a point just before the one due there lengthens the next interval: a
spare meets the loop from outside, with the traffic and behind its slot; a relieved UAV
leaves it outward and not against the traffic.
"""

from __future__ import annotations

import math

import numpy as np

from companion.agent.neighbours import Neighbour
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, groundspeed_from_course, wrap_pi

PURSUIT_GAIN_1_S = 1.0  # course error (rad) -> turn rate (rad/s), flying to a point


def slot_phase(member: Neighbour, t_s: float, patrol: Patrol) -> float:
    """Where a member's slot is at ``t_s`` (s): the time-phase (rad) of its shared position
    along the loop, carried on at the nominal rate (its course phase where it shares no
    position: that one is ill-conditioned on the loop's long edges, seconds off there)."""
    st = member.state
    if st.pos_m is None:
        return st.phase_at(st.t_s + (t_s - member.rx_t_s), patrol.period_s)
    return patrol.phase_of_point(st.pos_m) + TWO_PI * (t_s - member.rx_t_s) / patrol.period_s


def meet_point(
    pos_m: complex,
    heading_rad: float,
    slot_phase_rad: float,
    patrol: Patrol,
    max_u: float,
    outside: bool = True,
) -> tuple[complex, float] | None:
    """(loop point, slack s): where a slot now at ``slot_phase_rad`` (rad) will be when a UAV
    at ``pos_m`` (m) heading ``heading_rad`` (rad) gets there, turning at ``max_u`` (rad/s)
    and then flying straight (the first such time, 1 s resolution), and how long before the
    slot it would be there. ``outside``: only points it reaches from outside the loop and
    with the traffic (its straight path then crosses no other loop point, the loop convex).
    None when none fits."""
    tau = np.arange(0.0, 2.0 * patrol.period_s + 600.0, 1.0)
    phase = slot_phase_rad + TWO_PI * tau / patrol.period_s
    pts = patrol.point_at_phase(phase)
    d = pts - pos_m
    course = np.arctan2(d.imag, d.real)
    gs = groundspeed_from_course(patrol.airspeed_m_s, course, patrol.wind)
    err = np.asarray(wrap_pi(course - heading_rad))
    turn = np.abs(err)
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    right = dot(1j * h, loop_frame(pos_m, patrol)[2]) >= 0.0  # a big turn goes away from it
    big = turn > math.pi / 2
    turn = np.where(big, np.where(right, np.mod(err, TWO_PI), np.mod(-err, TWO_PI)), turn)
    flight = np.abs(d) / gs + turn / max_u
    ok = flight <= tau
    if outside:
        t, n = _tangent_outward(patrol.course_at_phase(phase), pts, patrol.centre_m)
        ok &= ((d.conjugate() * n).real < 0.0) & ((d.conjugate() * t).real >= 0.0)
    if not ok.any():
        return None
    k = int(np.argmax(ok))
    return complex(pts[k]), float(tau[k] - flight[k])


def loop_frame(point_m: complex, patrol: Patrol) -> tuple[complex, complex, complex]:
    """(loop point, unit tangent in the sense of travel, unit outward normal) nearest
    ``point_m`` (m); outward points away from the loop's centre."""
    near = patrol.nearest(point_m)
    t = complex(math.cos(near.course_rad), math.sin(near.course_rad))
    n = 1j * t
    if dot(n, near.point_m - patrol.centre_m) < 0.0:
        n = -n
    return near.point_m, t, n


def dot(a: complex, b: complex) -> float:
    """The dot product of two plane vectors given as complex numbers."""
    return (a.conjugate() * b).real


def leaves_outward(pos_m: complex, target_m: complex, patrol: Patrol) -> bool:
    """Whether flying straight from ``pos_m`` (m, on the loop) to ``target_m`` (m) leaves
    the loop outward and not against the traffic: its sensor then sees no loop point before
    the aircraft whose slot it is."""
    _, t, n = loop_frame(pos_m, patrol)
    d = target_m - pos_m
    return dot(d, n) > 0.0 and dot(d, t) >= 0.0


def fly_to(
    pos_m: complex, heading_rad: float, target_m: complex, patrol: Patrol, max_u: float
) -> float:
    """Turn rate (rad/s, within +-``max_u``) that points the ground course of a UAV at
    ``pos_m`` heading ``heading_rad`` at ``target_m``, in ``patrol``'s wind and airspeed."""
    v = patrol.airspeed_m_s * complex(math.cos(heading_rad), math.sin(heading_rad))
    v += patrol.wind.vector
    d = target_m - pos_m
    err = float(wrap_pi(math.atan2(d.imag, d.real) - math.atan2(v.imag, v.real)))
    return max(-max_u, min(max_u, PURSUIT_GAIN_1_S * err))


def orbit(
    pos_m: complex, heading_rad: float, centre_m: complex, patrol: Patrol, max_u: float
) -> float:
    """Turn rate (rad/s) that circles ``centre_m`` clockwise at twice the turn radius of
    ``max_u`` (rad/s) at ``patrol``'s airspeed."""
    radius = 2.0 * patrol.airspeed_m_s / max_u
    d = pos_m - centre_m
    r = abs(d)
    if r < 1e-6:
        return max_u
    bearing = math.atan2(d.imag, d.real)
    course = bearing + math.pi / 2 + math.atan((r - radius) / (0.5 * radius))
    ahead = pos_m + 10.0 * complex(math.cos(course), math.sin(course))
    return fly_to(pos_m, heading_rad, ahead, patrol, max_u)


def _tangent_outward(
    course_rad: np.ndarray, pts_m: np.ndarray, centre_m: complex
) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents of ground course ``course_rad`` (rad) at loop points ``pts_m`` (m), and
    the unit normals there that point away from ``centre_m`` (m)."""
    t = np.cos(course_rad) + 1j * np.sin(course_rad)
    n = 1j * t
    return t, np.where((n.conjugate() * (pts_m - centre_m)).real < 0.0, -n, n)
