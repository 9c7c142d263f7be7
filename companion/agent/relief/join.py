"""Where a relieving spare meets its member's slot, where a relieved UAV leaves the loop, and
the turn rates that fly a relief's legs to a point or round a holding point (pure geometry;
docs/energy.md, "Reliefs"). Positions complex m (north + i east), angles rad, times s.

The coverage revisit counts from the start of one pass over a loop point to the next, so an
aircraft that sees a point just before the one due there lengthens the next interval, and one
whose sensor disc joins two others' passes over a point makes them one: a spare flies in to
its *lane* (the loop offset outward by more than its sensor radius, where its sensor sees no
loop point), from outside and with the traffic, ahead of its slot; it rides the lane until
the slot comes alongside (far ahead of it, losing the lead in full turns outward that keep its
sensor off the loop, :func:`full_turn_clear`) and only then turns in, behind it. A relieved
UAV, dropped back
behind its relief, leaves the loop straight out to its lane where its way on to its base
stays off the loop (:func:`way_out`), or crosses the loop to such a point behind a member
and before the next (:func:`crossing`).
"""

from __future__ import annotations

import cmath
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
    lane_m: float = 0.0,
    early_s: float = 0.0,
    clear_m: float = math.inf,
    wait_factor: float = 0.0,
) -> tuple[complex, float] | None:
    """(point, slack s): where a slot now at ``slot_phase_rad`` (rad) will be, or beside it
    on the lane ``lane_m`` (m) outside the loop (farther by what its turn along the lane
    takes at its approach angle, turning at ``max_u``), when a UAV at ``pos_m`` (m) heading
    ``heading_rad`` (rad) gets there ``early_s`` (s) before it, turning at ``max_u`` (rad/s)
    (the wind drifting it meanwhile) and then flying straight (the first such time, 1 s
    resolution), and how much earlier still it would be there (s). ``outside``: only points
    it reaches from outside the loop and with the traffic: its straight leg then stays
    farther than ``lane_m`` from every loop point (it starts and ends beyond the loop's
    tangent line there by more, the loop convex). Its turns are :func:`turn_signs`' with
    ``clear_m`` (m). Of the points that fit, the one with the least ``tau + wait_factor *
    slack`` (``tau`` when the slot is there, s): a spare that waits in its lane for its slot
    waits ``wait_factor`` + 1 times its slack (0: the first to fit). None when none fits."""
    tau = np.arange(0.0, 2.0 * patrol.period_s + 600.0, 1.0)
    phase = slot_phase_rad + TWO_PI * tau / patrol.period_s
    on_loop = patrol.point_at_phase(phase)
    t, n = _tangent_outward(patrol.course_at_phase(phase), on_loop, patrol.centre_m)
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    radius_m = patrol.airspeed_m_s / max_u
    out_m = lane_m
    for _ in range(2 if lane_m > 0.0 else 1):  # again with the pad for its approach angle
        pts = on_loop + out_m * n
        err = np.asarray(wrap_pi(np.angle(pts - pos_m) - heading_rad))
        sign = turn_signs(pos_m, h, err, patrol, radius_m, clear_m)
        turn, leg = turn_then_straight(pos_m, h, sign, pts, radius_m)
        turn_s = turn / max_u
        leg = leg - patrol.wind.vector * np.where(np.isfinite(turn_s), turn_s, 0.0)  # drift
        cos_in = np.abs((leg.conjugate() * t).real) / np.maximum(np.abs(leg), 1e-9)
        out_m = lane_m + radius_m * (1.0 - cos_in)  # its turn along the lane goes in this far
    gs = groundspeed_from_course(patrol.airspeed_m_s, np.angle(leg), patrol.wind)
    flight = turn_s + np.abs(leg) / gs + early_s
    ok = flight <= tau
    if outside:
        ok &= ((leg.conjugate() * n).real < 0.0) & ((leg.conjugate() * t).real >= 0.0)
    if not ok.any():
        return None
    slack = tau - flight
    cost = np.full(tau.shape, np.inf)
    cost[ok] = tau[ok] + wait_factor * slack[ok]
    k = int(np.argmin(cost))
    return complex(pts[k]), float(slack[k])


def turn_signs(
    pos_m: complex,
    heading: complex,
    err_rad: np.ndarray,
    patrol: Patrol,
    radius_m: float,
    clear_m: float,
) -> np.ndarray:
    """The way (+1 right, -1 left) a UAV at ``pos_m`` (m) heading along the unit ``heading``
    turns, at ``radius_m`` (m), to point ``err_rad`` (rad, positive right) further round:
    the shorter way, but a turn of over 90 deg goes away from the loop unless the circle
    the other way stays ``clear_m`` (m) outside it (its sensor then sees no loop point)."""
    away = away_sign(pos_m, heading, patrol)
    short = np.where(err_rad < 0.0, -1.0, 1.0)
    toward = pos_m - away * radius_m * 1j * heading  # the centre of the turn towards the loop
    p, _, n = loop_frame(toward, patrol)
    toward_clear = math.isfinite(clear_m) and dot(toward - p, n) - radius_m >= clear_m
    return np.where((np.abs(err_rad) > math.pi / 2) & (not toward_clear), away, short)


def away_sign(pos_m: complex, heading: complex, patrol: Patrol) -> float:
    """The way (+1 towards ``1j`` times the unit ``heading``, -1 the other) a UAV at
    ``pos_m`` (m) turns away from the loop: towards the loop's outward normal nearest it."""
    return 1.0 if dot(1j * heading, loop_frame(pos_m, patrol)[2]) >= 0.0 else -1.0


def turn_then_straight(
    pos_m: complex, heading: complex, sign: np.ndarray, target_m: np.ndarray, radius_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """(turn rad, straight leg m as a vector): the path from ``pos_m`` (m) heading along the
    unit ``heading`` that turns at ``radius_m`` (m) right (``sign`` +1: the heading angle
    grows, north towards east) or left (-1) until it points at ``target_m`` (m), then flies
    straight to it (the turn-and-straight leg of a Dubins path, in still air). A target
    inside the turn's circle cannot be reached so: its turn is inf."""
    centre = pos_m + sign * radius_m * 1j * heading
    rel = target_m - centre
    dist = np.abs(rel)
    leg_m = np.sqrt(np.maximum(dist**2 - radius_m**2, 0.0))
    at = rel / (radius_m + sign * 1j * leg_m)  # where it leaves the circle, unit from centre
    along = sign * 1j * at  # its heading there
    turn = np.mod(sign * np.angle(along / heading), TWO_PI)
    turn = np.where(dist < radius_m, np.inf, turn)
    return turn, leg_m * along


def lane_point(patrol: Patrol, phase_rad: float, lane_m: float) -> complex:
    """The point ``lane_m`` (m) outward of the loop point at time-phase ``phase_rad`` (rad),
    along the loop's outward normal there (m)."""
    on_loop = patrol.point_at_phase(np.array([phase_rad]))
    _, n = _tangent_outward(patrol.course_at_phase(np.array([phase_rad])), on_loop,
                            patrol.centre_m)  # fmt: skip
    return complex(on_loop[0] + lane_m * n[0])


def onto_lane(
    pos_m: complex, heading_rad: float, patrol: Patrol, lane_m: float, max_u: float
) -> bool:
    """Whether a UAV at ``pos_m`` (m) heading ``heading_rad`` (rad), flying in from outside
    the loop, must turn onto the lane ``lane_m`` (m) out now, wherever it meets it (its
    flight is not quite the one planned: a take-off run, gusts): heading in, it is no
    farther out than the lane and what its turn onto the lane takes at its angle to the
    loop there, turning at ``max_u`` (rad/s)."""
    foot, t, n = loop_frame(pos_m, patrol)
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    out_m = dot(pos_m - foot, n)
    if out_m <= 0.0 or dot(h, n) >= 0.0:
        return False
    radius_m = patrol.airspeed_m_s / max_u
    return out_m - lane_m <= radius_m * (1.0 - abs(dot(h, t)))


def lane_target(
    patrol: Patrol,
    own_phase_rad: float,
    behind_rad: float,
    lane_m: float,
    turn_in: bool,
    lookahead_s: float,
) -> tuple[complex, float]:
    """(point m, lead rad): what a spare riding its lane ``lane_m`` (m) out, at time-phase
    ``own_phase_rad`` (rad), steers for, and its lead on the point where it turns in
    (``behind_rad``, rad) for its airspeed. Until it may turn in: the lane point
    ``lookahead_s`` (s) ahead, and its lead ahead of that point, 0 to 2 pi, so it slows
    and lets the point come up (the lane is longer than the loop by 2 pi times its offset,
    so it falls back even without the airspeed; a point that passed it comes round again).
    Once it may (``turn_in``): the loop point as far ahead as its lane is out (in at 45 deg)
    and its signed lead, so it closes on the point."""
    if turn_in:
        ahead = own_phase_rad + TWO_PI * lane_m / patrol.length_m
        return complex(patrol.point_at_phase(ahead)), float(wrap_pi(own_phase_rad - behind_rad))
    ahead = own_phase_rad + TWO_PI * lookahead_s / patrol.period_s
    return lane_point(patrol, ahead, lane_m), float(np.mod(own_phase_rad - behind_rad, TWO_PI))


def loop_frame(point_m: complex, patrol: Patrol) -> tuple[complex, complex, complex]:
    """(loop point, unit tangent in the sense of travel, unit outward normal) nearest
    ``point_m`` (m); outward points away from the loop's centre."""
    near = patrol.nearest(point_m)
    t = complex(math.cos(near.course_rad), math.sin(near.course_rad))
    n = 1j * t
    if dot(n, near.point_m - patrol.centre_m) < 0.0:
        n = -n
    return near.point_m, t, n


def inside(point_m: complex, patrol: Patrol) -> bool:
    """Whether ``point_m`` (m) is inside ``patrol``'s loop: its offset from the nearest loop
    point is inward."""
    return patrol.nearest_canon(complex(patrol.to_canon(point_m)))[1] < 0.0


def dot(a: complex, b: complex) -> float:
    """The dot product of two plane vectors given as complex numbers."""
    return (a.conjugate() * b).real


def way_out(
    pos_m: complex,
    base_m: complex,
    patrol: Patrol,
    lane_m: float,
    clear_m: float,
    radius_m: float,
) -> bool:
    """Whether a UAV at ``pos_m`` (m, on the loop) may leave for ``base_m`` (m) by flying
    straight out to its lane (``lane_m`` m out, along the outward normal), then turning
    the shorter way at ``radius_m`` (m) to point at the base and flying straight to it:
    the base lies outward, and that turn and leg keep at least ``clear_m`` (m) from the
    loop (sampled every 10 m or so: the distance to a loop is not monotonic along a path
    that passes it). Its sensor then leaves the loop beside it and stays off it."""
    _, _, n = loop_frame(pos_m, patrol)
    if dot(base_m - pos_m, n) <= 0.0:
        return False
    start = pos_m + lane_m * n
    sign = -1.0 if float(wrap_pi(cmath.phase(base_m - start) - cmath.phase(n))) < 0.0 else 1.0
    turn, _ = turn_then_straight(start, n, np.array([sign]), np.array([base_m]), radius_m)
    if not np.isfinite(turn[0]):
        return False  # the base is inside its turn
    centre = start + sign * radius_m * 1j * n
    arc = np.linspace(0.0, float(turn[0]), max(2, int(float(turn[0]) * radius_m / 10.0) + 1))
    path = list(centre + (start - centre) * np.exp(1j * sign * arc))
    end = complex(path[-1])
    steps = max(2, int(abs(base_m - end) / 10.0))
    path += [end + (base_m - end) * k / steps for k in range(steps + 1)]
    return all(abs(patrol.nearest_canon(complex(patrol.to_canon(q)))[1]) >= clear_m for q in path)


def full_turn_clear(
    pos_m: complex,
    heading_rad: float,
    sign: float,
    patrol: Patrol,
    max_u: float,
    clear_m: float,
) -> bool:
    """Whether one full turn at ``max_u`` (rad/s; ``sign`` +1 toward ``1j`` times the
    heading, -1 the other way) from ``pos_m`` (m) heading ``heading_rad`` (rad), at
    ``patrol``'s airspeed and drifting with its wind, stays outside the loop by at least
    ``clear_m`` (m) all the way round (sampled every half second)."""
    v = patrol.airspeed_m_s
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    centre = pos_m + sign * (v / max_u) * 1j * h  # the turn's centre in the air
    t = np.arange(0.0, TWO_PI / max_u + 0.5, 0.5)
    path = centre + (pos_m - centre) * np.exp(1j * sign * max_u * t) + patrol.wind.vector * t
    return all(patrol.nearest_canon(complex(patrol.to_canon(complex(q))))[1] >= clear_m
               for q in path)  # fmt: skip


def crossing(
    pos_m: complex,
    heading_rad: float,
    base_m: complex,
    member_phases_rad: list[float],
    patrol: Patrol,
    behind_s: float,
    clear_s: float,
    lane_m: float,
    clear_m: float,
    max_u: float,
    count: int = 256,
) -> tuple[complex, float] | None:
    """(loop point m, flight s): where a UAV at ``pos_m`` (m, inside the loop or on it)
    heading ``heading_rad`` (rad) that must fly home to ``base_m`` (m) crosses the loop out
    behind a member. It turns the shorter way at ``max_u`` (rad/s), then flies straight at
    the plan's airspeed in the wind (drifting in its turn) to a loop point it meets from
    inside, at most 45 deg off the outward normal, at least ``behind_s`` (s) after the
    last member (at ``member_phases_rad`` now, rad, flying the loop at its nominal rate)
    passed it and at least ``clear_s`` (s) before the next one does; from there it has a
    :func:`way_out` (``lane_m``, ``clear_m``, m). Of those (``count`` loop points, equally
    spaced in time), the one from which it is home soonest, with its flight time there.
    None when none fits, or no member is on the loop."""
    if not member_phases_rad:
        return None
    period = patrol.period_s
    phase = np.arange(count) * TWO_PI / count
    on_loop = patrol.point_at_phase(phase)
    _, n = _tangent_outward(patrol.course_at_phase(phase), on_loop, patrol.centre_m)
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    err = np.asarray(wrap_pi(np.angle(on_loop - pos_m) - heading_rad))
    radius_m = patrol.airspeed_m_s / max_u
    turn, leg = turn_then_straight(pos_m, h, np.where(err < 0.0, -1.0, 1.0), on_loop, radius_m)
    turn_s = np.where(np.isfinite(turn), turn / max_u, np.inf)
    leg = leg - patrol.wind.vector * np.where(np.isfinite(turn_s), turn_s, 0.0)
    to_base = base_m - on_loop
    gs_in = groundspeed_from_course(patrol.airspeed_m_s, np.angle(leg), patrol.wind)
    gs_home = groundspeed_from_course(patrol.airspeed_m_s, np.angle(to_base), patrol.wind)
    flight = turn_s + np.abs(leg) / gs_in
    home = flight + np.abs(to_base) / gs_home
    steep = (leg.conjugate() * n).real >= math.cos(math.pi / 4) * np.abs(leg)
    ok = steep & np.isfinite(flight) & ((to_base.conjugate() * n).real > 0.0)
    since = np.full(count, np.inf)  # s since the last member passed it, at its arrival
    until = np.full(count, np.inf)  # s until the next one does
    f = np.where(ok, flight, 0.0)
    for m in member_phases_rad:
        ahead = np.mod(phase - m, TWO_PI) * period / TWO_PI  # s until member m gets there
        r = np.mod(ahead - f, period)
        until = np.minimum(until, r)
        since = np.minimum(since, period - r)
    ok &= (since >= behind_s) & (until >= clear_s)
    for k in np.argsort(np.where(ok, home, np.inf)):
        if not ok[k]:
            return None
        if way_out(complex(on_loop[k]), base_m, patrol, lane_m, clear_m, radius_m):
            return complex(on_loop[k]), float(flight[k])
    return None


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
