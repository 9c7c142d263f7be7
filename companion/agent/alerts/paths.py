"""The paths an alert's prosecutor flies (pure; docs/design.md §5-6), and the geofence check.

Each is the planner's answer (:func:`companion.planner.plan_path`): a ``Plan`` or a
``NoPath``, never None nor an exception.

* The prosecutor plans the minimum-time path to the site, arriving along the loop: final
  ground course = the tangent of C at the point of C nearest the site.
"""

from __future__ import annotations

from companion.core.fence import Fence, signed_distance_m
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, heading_from_course
from companion.group.messages import Track
from companion.planner import Aircraft, Goal, NoPath, Plan, Pose, plan_path

FENCE_STARTS = 12  # loop points the fence check plans from
FENCE_TRACK_STEP_S = 0.5  # path sampling for the fence check (s: 10 m at 20 m/s)
TURN_AIM_ROUNDS = 3  # a turning track's intercept is re-aimed at its arc this many times


def _plan(
    patrol: Patrol, pos_m: complex, heading_rad: float, goal: Goal, max_u: float
) -> Plan | NoPath:
    """The planner's answer from the UAV's pose in the loop's wind: a :class:`Plan`, or
    :class:`NoPath` (also for numbers the planner refuses, e.g. a NaN from a bad estimate:
    in flight that is no path to fly, never an exception)."""
    try:
        return plan_path(
            Pose(pos_m, heading_rad), goal, Aircraft(patrol.airspeed_m_s, max_u), patrol.wind
        )
    except ValueError as exc:
        return NoPath(str(exc))


def plan_to_site(
    patrol: Patrol,
    pos_m: complex,
    heading_rad: float,
    site_m: complex,
    max_turn_rate_rad_s: float,
    site_velocity_m_s: complex = 0j,
) -> Plan | NoPath:
    """Minimum-time path to ``site_m`` arriving along the loop's tangent there.

    The final ground course is the tangent course of C at the point of C nearest the site
    (in the sense of travel), so the prosecutor arrives flying along the perimeter.
    ``site_velocity_m_s`` (m/s): the intruder's ground velocity, for an intercept.
    """
    tangent = patrol.nearest(site_m).course_rad
    goal = Goal(site_m, course_rad=tangent, velocity_m_s=site_velocity_m_s)
    return _plan(patrol, pos_m, heading_rad, goal, max_turn_rate_rad_s)


def intercept(
    patrol: Patrol,
    pos_m: complex,
    heading_rad: float,
    track: Track,
    t_s: float,
    max_u: float,
    along_loop: bool,
) -> Plan | NoPath:
    """Minimum-time intercept of ``track`` predicted from ``t_s`` (s): to its predicted
    position moving at its predicted velocity then (a constant-velocity intercept), with any
    final heading; ``along_loop``: to its position arriving on the loop's tangent there, as
    :func:`plan_to_site` (the paper's arrival, for an intruder that is not moving).

    A track on the turn model is met on its predicted arc (:meth:`Track.predict`, at most
    ``MAX_TURN_RAD`` of turn): the planner's goal moves in a straight line, so the goal is
    re-aimed ``TURN_AIM_ROUNDS`` times at the point of the arc where the last plan ends,
    moving at the arc's velocity there; the plan kept is the one whose end lies nearest the
    arc. (Before, a turning track's intercept was aimed along its velocity at the track's
    time, the heading before the turn, from its position on the arc.)"""
    site = track.predict(t_s)
    if along_loop:
        return plan_to_site(patrol, pos_m, heading_rad, site, max_u)
    vel = track.velocity_at(t_s)
    plan = _plan(patrol, pos_m, heading_rad, Goal(site, velocity_m_s=vel), max_u)
    if track.model != "turn" or not isinstance(plan, Plan):
        return plan
    best, miss = plan, abs(site + vel * plan.time_s - track.predict(t_s + plan.time_s))
    for _ in range(TURN_AIM_ROUNDS):
        t_end = t_s + best.time_s
        v_end = track.velocity_at(t_end)
        aim = track.predict(t_end) - v_end * best.time_s  # moving at v_end, there at t_end
        again = _plan(patrol, pos_m, heading_rad, Goal(aim, velocity_m_s=v_end), max_u)
        if not isinstance(again, Plan):
            break
        off = abs(aim + v_end * again.time_s - track.predict(t_s + again.time_s))
        if off >= miss:
            break
        best, miss = again, off
    return best


def over_point(
    patrol: Patrol,
    pos_m: complex,
    heading_rad: float,
    point_m: complex,
    velocity_m_s: complex,
    max_u: float,
) -> Plan | NoPath:
    """The minimum-time path over ``point_m`` (m) moving at ``velocity_m_s`` (m/s), with any
    final heading (a tracker passing over its intruder, a search waypoint)."""
    return _plan(patrol, pos_m, heading_rad, Goal(point_m, velocity_m_s=velocity_m_s), max_u)


def to_loop(
    patrol: Patrol, pos_m: complex, heading_rad: float, max_u: float, samples: int = 8
) -> tuple[Plan, float] | NoPath:
    """The quickest path back onto the loop, ahead: to one of ``samples`` loop points from
    the nearest one forward over about three turn diameters, arriving on the loop's tangent;
    (plan, the goal's time-phase rad), or :class:`NoPath`."""
    near = patrol.nearest(pos_m)
    turn_r = patrol.turn_radius_m(max_u)
    span = min(TWO_PI / 2, TWO_PI * 6.0 * turn_r / patrol.length_m)  # phase ahead searched
    best: tuple[Plan, float] | None = None
    for k in range(samples):
        psi = float((near.phase_rad + span * k / samples) % TWO_PI)
        plan = plan_to_loop_point(patrol, pos_m, heading_rad, psi, max_u)
        if isinstance(plan, Plan) and (best is None or plan.time_s < best[0].time_s):
            best = (plan, psi)
    return best if best is not None else NoPath("no path back onto the loop ahead")


def fence_refusal(
    patrol: Patrol,
    fence: Fence,
    site_m: complex,
    max_turn_rate_rad_s: float,
    starts: int = FENCE_STARTS,
) -> str | None:
    """Why an alert at ``site_m`` (m) must be refused by the fence, or None to fly it.

    Refused when the site is outside the inclusion polygon or closer to its edge than one turn
    radius at the fastest ground speed (``(s0 + |w|) / omega_max``: room to turn after the
    site), or when the minimum-time path to
    it (:func:`plan_to_site`) from any of ``starts`` points equally spaced in time-phase along
    the loop (flying it, on its tangent) leaves the polygon; the path is sampled every
    :data:`FENCE_TRACK_STEP_S`. Any member may end up prosecuting (the next in sequence, a
    hand-off after a confirmation, a re-queue), so the check does not depend on who is where:
    it is a function of the mission and the site only, and every companion (and the
    operator's ``companion alert --mission``) reaches the same decision.
    """
    site = complex(site_m)
    if not bool(fence.contains(site)):
        return f"site {site.real:.0f},{site.imag:.0f} m is outside the fence"
    turn_r = patrol.turn_radius_m(max_turn_rate_rad_s)
    room = float(signed_distance_m(site, fence.polygon_m))
    if room < turn_r:
        return f"site is {room:.0f} m from the fence; a turn past it needs {turn_r:.0f} m"
    for k in range(starts):
        psi = TWO_PI * k / starts
        start = complex(patrol.point_at_phase(psi))
        course = float(patrol.course_at_phase(psi))
        heading = float(heading_from_course(patrol.airspeed_m_s, course, patrol.wind))
        plan = plan_to_site(patrol, start, heading, site, max_turn_rate_rad_s)
        if not isinstance(plan, Plan):
            continue
        track = plan.ground_track(FENCE_TRACK_STEP_S)
        j = fence.first_outside(track)
        if j is not None:
            out = complex(track[j])
            return (
                f"the minimum-time path from the loop leaves the fence at "
                f"{out.real:.0f},{out.imag:.0f} m"
            )
    return None


def short_of_fence(fence: Fence, point_m: complex, turn_radius_m: float) -> bool:
    """Whether ``point_m`` (m) is outside ``fence`` or nearer its edge than
    ``turn_radius_m`` (m): a pass over it, or the turn after it, would leave the fence."""
    if not bool(fence.contains(point_m)):
        return True
    return float(signed_distance_m(point_m, fence.polygon_m)) < turn_radius_m


def turn_rate_at(plan: Plan, elapsed_s: float, hold_s: float = 0.0) -> float:
    """The plan's turn rate (rad/s) ``elapsed_s`` seconds after its start; 0 past its end.

    ``hold_s`` > 0: the mean over ``[elapsed_s, elapsed_s + hold_s]`` (s), the interval a
    command is held for. The heading then changes by what the plan turns in that interval;
    the rate at its start alone turns a 0.01 s arc at the limit for a whole control period,
    and re-planning every second turned that overshoot into a zig-zag at the limit along
    the straight leg (1.8 deg each way, once a second, in memory)."""
    if hold_s <= 0.0:
        t = 0.0
        for seg in plan.segments:
            t += seg.duration_s
            if elapsed_s < t:
                return float(seg.turn_rate_rad_s)
        return 0.0
    lo, hi = elapsed_s, elapsed_s + hold_s
    turned, t0 = 0.0, 0.0
    for seg in plan.segments:
        t1 = t0 + seg.duration_s
        overlap = min(hi, t1) - max(lo, t0)
        if overlap > 0.0:
            turned += float(seg.turn_rate_rad_s) * overlap
        t0 = t1
    return turned / hold_s


def remaining_s(plan: Plan, elapsed_s: float) -> float:
    """Time left on the plan (s), never negative."""
    return float(max(0.0, plan.time_s - elapsed_s))


def plan_to_pose(
    patrol: Patrol,
    pos_m: complex,
    heading_rad: float,
    goal_m: complex,
    course_rad: float,
    max_u: float,
) -> Plan | NoPath:
    """Minimum-time path to ``goal_m`` (m) arriving on ground course ``course_rad`` (rad)."""
    return _plan(patrol, pos_m, heading_rad, Goal(goal_m, course_rad=course_rad), max_u)


def plan_to_loop_point(
    patrol: Patrol, pos_m: complex, heading_rad: float, phase_rad: float, max_u: float
) -> Plan | NoPath:
    """Minimum-time path onto the loop at time-phase ``phase_rad`` (rad), on its tangent."""
    return plan_to_pose(
        patrol,
        pos_m,
        heading_rad,
        complex(patrol.point_at_phase(phase_rad)),
        float(patrol.course_at_phase(phase_rad)),
        max_u,
    )


def over_site(
    patrol: Patrol, pos_m: complex, heading_rad: float, site_m: complex, max_u: float
) -> Plan | NoPath:
    """The minimum-time path back over ``site_m`` with any final heading (loitering there)."""
    return _plan(patrol, pos_m, heading_rad, Goal(site_m), max_u)
