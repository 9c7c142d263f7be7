"""Flying a returning prosecutor back into its slot (pure; docs/design.md §5, beyond the paper).

While it rejoins, the UAV keeps sharing its virtual particle (its slot), so the others never
react. It returns to the loop first and recovers its slot along it:

1. ``rejoin_to_loop``: the quickest path back onto the loop, to a point ahead on the loop's
   tangent (:func:`companion.agent.alerts.paths.to_loop`), re-planned every ``replan_s`` to
   the same point; a UAV already on the loop skips it.
2. ``rejoin_along_loop``: on the loop, steered by the law with no phase term (the
   cross-track hold keeps it there), its slot recovered by the airspeed (faster when behind,
   slower ahead, within ``Gains.speed_authority_m_s``). Where the airspeed is fixed the
   tracking law recovers it instead, as the paper's law does, off the loop.
3. In its slot, it hands back its real state. A slot too far round the loop for the airspeed
   (more than ``SLOT_RECOVERY_PERIODS`` loop periods at full authority: after a long search
   or a track) is given up on the loop: it hands back its real state there and the formation
   splays round it.

So its stretch of the perimeter is flown again as soon as it can be, never by a wide detour
off the loop: a slot far round the loop is recovered along the loop, where the sensor still
covers the perimeter. Times are vehicle seconds, positions complex north + i east metres,
angles radians.

"In the slot" is relative to how well this UAV tracks the loop at all: the tolerances grow
with ``REJOIN_TRACKING_K`` x the 95th percentile of its own centre error over the last
``TRACKING_WINDOW_PERIODS`` loop periods on patrol (:class:`TrackingAccuracy`), never below
the simulator-tuned ``REJOIN_CENTRE_M`` / ``REJOIN_PHASE_DEG`` / ``REJOIN_COURSE_DEG`` and
never above ``REJOIN_MAX_TOL_M``. On ArduPlane (centre error about 12 m p50) the fixed 3 m
made a 14.7 s rejoin take 227 s.
"""

from __future__ import annotations

import cmath
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from companion.agent.alerts.paths import (
    plan_to_loop_point,
    remaining_s,
    to_loop,
    turn_rate_at,
)
from companion.agent.away import Rejoining, ToLoop
from companion.agent.events import AgentEvent, OnLoop, Rejoined, RejoinPath
from companion.agent.fix import Fix
from companion.agent.modes import ModeEvent
from companion.core.patrol import Patrol
from companion.guidance.formation import track_command
from companion.guidance.steering import (
    Gains,
    slot_speed_offset,
    speed_holds_phase,
    steering_turn_rate,
)
from companion.guidance.virtual import phase_gap_rad
from companion.planner import NoPath, Plan

REJOIN_CENTRE_M = 3.0  # hand back the real state once this close to the loop centre ...
REJOIN_PHASE_DEG = 1.0  # ... and this close to the virtual particle's phase
REJOIN_TIMEOUT_PERIODS = 3.0  # hand back anyway after this many loop periods
REJOIN_SLOT_FRACTION = 0.2  # ... or once within this fraction of r_s of the slot's point
REJOIN_COURSE_DEG = 1.0  # ... on its course to this tolerance, where the loop's radius of
REJOIN_MAX_RADIUS_M = 2000.0  # curvature is at most this (1 deg of course = 35 m of centre)
# A re-plan replaces the current path only if it is not much longer than what is left of it:
# close to the goal a small drift can make the exact final course unreachable by a short
# path, and the "new minimum" is a whole extra loop.
REPLAN_SLACK_S = 2.0
REPLAN_MIN_LEFT_S = 3.0  # no re-planning in the last seconds of a path
SLOT_RECOVERY_PERIODS = 1.0  # a slot the airspeed recovers in at most this many periods is
# kept; one further round the loop is given up for the real state on the loop at once
ON_LOOP_FRACTION = 0.25  # on the loop: within this fraction of r_s of it ...
ON_LOOP_COURSE_RAD = 0.35  # ... on its course to this (20 deg)
REJOIN_TRACKING_K = 1.5  # the slot tolerance: this many times the tracking p95 ...
REJOIN_MAX_TOL_M = 30.0  # ... at most (m)
TRACKING_WINDOW_PERIODS = 1.0  # the tracking accuracy is measured over this many periods


class TrackingAccuracy:
    """The 95th percentile of a UAV's centre error (m) on patrol over a sliding window.

    Args:
        window_s: the window (vehicle s).
    """

    def __init__(self, window_s: float) -> None:
        """Nothing measured yet."""
        self.window_s = float(window_s)
        self._samples: deque[tuple[float, float]] = deque()

    def add(self, t_s: float, centre_error_m: float) -> None:
        """One centre error (m) at vehicle time ``t_s`` (s)."""
        self._samples.append((t_s, float(centre_error_m)))
        while self._samples and self._samples[0][0] < t_s - self.window_s:
            self._samples.popleft()

    def p95_m(self) -> float:
        """The 95th percentile (m); 0 with too few samples (the fixed tolerances apply)."""
        if len(self._samples) < 20:
            return 0.0
        return float(np.percentile([e for _, e in self._samples], 95.0))


@dataclass(frozen=True)
class SlotTolerance:
    """When a rejoining UAV counts as back in its slot: centre error (m), phase error (rad),
    distance to the slot's point (m) and course error (rad)."""

    centre_m: float
    phase_rad: float
    slot_m: float
    course_rad: float


def slot_tolerance(tracking_p95_m: float, loop_length_m: float, sensor_m: float) -> SlotTolerance:
    """The slot tolerances for a UAV whose centre error p95 is ``tracking_p95_m`` (m).

    The centre tolerance is ``max(REJOIN_CENTRE_M, k p95)`` capped at ``REJOIN_MAX_TOL_M``;
    the phase tolerance the same distance along the loop of length ``loop_length_m`` (m);
    the slot-point and course tolerances scale with it from their simulator values.
    """
    tol = min(REJOIN_MAX_TOL_M, max(REJOIN_CENTRE_M, REJOIN_TRACKING_K * tracking_p95_m))
    scale = tol / REJOIN_CENTRE_M
    phase = max(math.radians(REJOIN_PHASE_DEG), 2.0 * math.pi * tol / loop_length_m)
    return SlotTolerance(
        centre_m=tol,
        phase_rad=phase,
        slot_m=max(REJOIN_SLOT_FRACTION * sensor_m, tol),
        course_rad=math.radians(min(10.0, REJOIN_COURSE_DEG * scale)),
    )


@dataclass(frozen=True)
class RejoinContext:
    """What the rejoin needs of its UAV: loop, gains, turn-rate limit (rad/s), sensor radius
    (m), re-planning period (s), its measured tracking accuracy (centre error p95, m),
    how long each command is held (s; a path's turn rate is averaged over it), its system
    id (the events' ``sysid``) and the formation's revisit time T/N (s)."""

    patrol: Patrol
    gains: Gains
    max_u: float
    sensor_m: float
    replan_s: float
    tracking_p95_m: float = 0.0
    hold_s: float = 0.0
    sysid: int = 0
    revisit_s: float = 0.0  # the formation's T/N as this UAV hears it (s); 0: never resume


def rejoin_step(
    ctx: RejoinContext, away: Rejoining, fix: Fix
) -> tuple[float | None, list[AgentEvent], list[ModeEvent]]:
    """One rejoin decision at ``fix`` (read against ``ctx.patrol``), in the stage ``away``
    is in: back onto the loop while it holds its :class:`~companion.agent.away.ToLoop`,
    along the loop once that is dropped.

    Returns:
        The turn rate (rad/s), or None to hand back the real state now; the events to log
        (stamped ``ctx.sysid``, ``away.alert_id``); and the mode events that happened, in
        order, for the caller to apply (:data:`companion.agent.modes.MODE_TABLE`). Updates
        the first stage's record (the path flown) in place.
    """
    fix = fix.against(ctx.patrol)
    t_s = fix.t_s
    events: list[AgentEvent] = []
    changes: list[ModeEvent] = []
    target = away.virtual.phase(t_s)
    tol = slot_tolerance(ctx.tracking_p95_m, ctx.patrol.length_m, ctx.sensor_m)
    in_slot = (
        abs(fix.centre_m - ctx.patrol.centre_m) < tol.centre_m
        and abs(phase_gap_rad(fix.phase_rad, target)) < tol.phase_rad
    )
    slot_course = float(ctx.patrol.course_at_phase(target))
    well_conditioned = (
        float(ctx.patrol.shape.radius(ctx.patrol.angle_to_canon(slot_course)))
        <= REJOIN_MAX_RADIUS_M
    )
    if away.to_loop is None and not in_slot and well_conditioned:
        # Where the loop is nearly straight the centre and phase computed from the course
        # are ill-conditioned (d rho / d gamma = R: 0.9 m per 0.001 deg on a 50 km edge),
        # so there the UAV stays on its slot along the loop until a bend; where it is
        # curved, being at the slot's point on its course is being in the slot.
        slot = complex(ctx.patrol.point_at_phase(target))
        in_slot = (
            abs(fix.pos_m - slot) < tol.slot_m
            and abs(phase_gap_rad(_course(ctx, fix.heading_rad), slot_course)) < tol.course_rad
        )
    late = t_s - away.t0_s > REJOIN_TIMEOUT_PERIODS * ctx.patrol.period_s
    if in_slot or late:
        events.append(_rejoined(ctx, away, t_s, bool(in_slot), tol))
        return None, events, [ModeEvent.IN_SLOT if in_slot else ModeEvent.TIMED_OUT]
    if away.to_loop is not None:
        u = _to_loop(ctx, away.alert_id, away.to_loop, fix, events)
        if u is not None:
            return u, events, changes
        events.append(
            OnLoop(
                t_s=t_s,
                sysid=ctx.sysid,
                alert_id=away.alert_id,
                after_s=round(t_s - away.t0_s, 3),
            )
        )
        if slot_recovery_s(ctx, fix, target) > SLOT_RECOVERY_PERIODS * ctx.patrol.period_s:
            # its slot is too far round the loop for the airspeed: on the loop now, it
            # shares its real state and the formation splays round it (the paper's rejoin)
            events.append(_rejoined(ctx, away, t_s, False, tol))
            return None, events, [ModeEvent.HANDED_BACK]
        changes.append(ModeEvent.ON_LOOP)
    return _along_loop(ctx, fix, target), events, changes


def _rejoined(
    ctx: RejoinContext, away: Rejoining, t_s: float, in_slot: bool, tol: SlotTolerance
) -> Rejoined:
    """The "rejoined" event at ``t_s`` (s): back in its slot, or handing back elsewhere."""
    return Rejoined(
        t_s=t_s,
        sysid=ctx.sysid,
        alert_id=away.alert_id,
        in_slot=in_slot,
        rejoin_s=round(t_s - away.t0_s, 3),
        tol_m=round(tol.centre_m, 2),
    )


def slot_recovery_s(ctx: RejoinContext, fix: Fix, target_phase_rad: float) -> float:
    """How long (s) the airspeed needs to bring a UAV on the loop at ``fix`` into its slot
    at ``target_phase_rad`` (rad): its along-loop distance at full authority; infinite
    where the airspeed is fixed (the tracking law then recovers it off the loop)."""
    a = ctx.gains.speed_authority_m_s if speed_holds_phase(ctx.gains) else 0.0
    own = float(fix.against(ctx.patrol).loop_phase_rad)
    gap_m = abs(phase_gap_rad(own, target_phase_rad)) * ctx.patrol.length_m / (2.0 * math.pi)
    return gap_m / a if a > 0.0 else math.inf


def rejoin_airspeed(ctx: RejoinContext, fix: Fix, target_phase_rad: float) -> float:
    """The airspeed (m/s) that recovers the slot along the loop: the mission's, changed by
    at most ``Gains.speed_authority_m_s``, from where the UAV at ``fix`` is along the loop
    (its nearest loop point's phase) against the slot's phase."""
    own = float(fix.against(ctx.patrol).loop_phase_rad)
    error = phase_gap_rad(own, target_phase_rad)
    return ctx.patrol.airspeed_m_s + slot_speed_offset(ctx.patrol, ctx.gains, error)


def _course(ctx: RejoinContext, heading_rad: float) -> float:
    """The ground course (rad) of air heading ``heading_rad`` in the loop's wind."""
    v = ctx.patrol.airspeed_m_s * cmath.exp(1j * heading_rad) + ctx.patrol.wind.vector
    return float(np.angle(v))


def _on_loop(ctx: RejoinContext, fix: Fix) -> bool:
    """Whether the UAV is on the loop: near it, on its course."""
    near = ctx.patrol.nearest(fix.pos_m)
    course = _course(ctx, fix.heading_rad)
    aligned = abs(phase_gap_rad(course, near.course_rad)) < ON_LOOP_COURSE_RAD
    return near.distance_m < ON_LOOP_FRACTION * ctx.sensor_m and aligned


def _to_loop(
    ctx: RejoinContext, alert_id: str, stage: ToLoop, fix: Fix, events: list[AgentEvent]
) -> float | None:
    """The turn rate (rad/s) of the path back onto the loop, or None once on it."""
    t_s, pos_m, heading_rad = fix.t_s, fix.pos_m, fix.heading_rad
    if stage.plan is None:
        if _on_loop(ctx, fix):
            return None
        found = to_loop(ctx.patrol, pos_m, heading_rad, ctx.max_u)
        if isinstance(found, NoPath):
            return None  # the law takes it back from here
        stage.plan, stage.loop_phase_rad = found
        resume = _resume_plan(ctx, stage, fix)
        if resume is not None:
            stage.plan, stage.loop_phase_rad = resume, stage.left.phase_rad
        stage.plan_t0_s = stage.last_check_s = t_s
        events.append(
            RejoinPath(
                t_s=t_s,
                sysid=ctx.sysid,
                alert_id=alert_id,
                planned_time_s=round(stage.plan.time_s, 3),
                path_type=stage.plan.family,
                resume_after_s=(None if resume is None else round(t_s - float(stage.left.t_s), 3)),
            )
        )
    left = remaining_s(stage.plan, t_s - stage.plan_t0_s)
    if left > REPLAN_MIN_LEFT_S and t_s - stage.last_check_s >= ctx.replan_s - 1e-9:
        stage.last_check_s = t_s  # re-plan to the same loop point from the measured state
        plan = plan_to_loop_point(ctx.patrol, pos_m, heading_rad, stage.loop_phase_rad, ctx.max_u)
        if isinstance(plan, Plan) and plan.time_s <= left + REPLAN_SLACK_S:
            stage.plan, stage.plan_t0_s = plan, t_s
            left = plan.time_s
    if left <= 0.0:
        return None
    return turn_rate_at(stage.plan, t_s - stage.plan_t0_s, ctx.hold_s)


def _resume_plan(ctx: RejoinContext, stage: ToLoop, fix: Fix) -> Plan | None:
    """The path back to where the UAV left its stretch of the loop, if flying it leaves the
    perimeter unseen less long than joining ahead (``stage.plan``); else None.

    A loop point just past where it left was last seen by the UAV ahead, about T/N before
    it left. Back there after ``g`` s away in all, it sees that point again T/N + g after
    the UAV ahead did. Joining ahead instead, the stretch between the two points waits for
    the UAV behind, about 2 T/N, if it is wider than the sensor's swath, and the loop past
    the join is reached as late as the join is behind the slot. Only a short excursion on a
    loop with a long revisit time (large loops, few UAVs) goes back."""
    if stage.left.t_s is None or ctx.revisit_s <= 0.0 or stage.plan is None:
        return None
    gone_s = fix.t_s - stage.left.t_s
    if gone_s >= ctx.revisit_s:
        return None  # already away longer than the UAV behind takes to get there
    patrol = ctx.patrol
    psi0 = stage.left.phase_rad
    back = plan_to_loop_point(patrol, fix.pos_m, fix.heading_rad, psi0, ctx.max_u)
    if not isinstance(back, Plan):
        return None
    resume_s = ctx.revisit_s + gone_s + back.time_s
    along_s = (stage.loop_phase_rad - psi0) % (2.0 * math.pi) * patrol.period_s / (2.0 * math.pi)
    ahead_s = ctx.revisit_s + max(gone_s + stage.plan.time_s - along_s, 0.0)
    if along_s * patrol.length_m / patrol.period_s > 2.0 * ctx.sensor_m:
        ahead_s = max(ahead_s, 2.0 * ctx.revisit_s)
    return back if resume_s < ahead_s else None


def _along_loop(ctx: RejoinContext, fix: Fix, target: float) -> float:
    """The turn rate (rad/s) on the loop: no phase term where the airspeed recovers the
    slot (the cross-track hold keeps it on the loop); the tracking law where it cannot."""
    if speed_holds_phase(ctx.gains):
        return steering_turn_rate(
            ctx.patrol, ctx.gains, fix.pos_m, fix.heading_rad, 0.0, ctx.patrol.centre_m, ctx.max_u
        )
    return track_command(
        ctx.patrol, ctx.gains, fix.pos_m, fix.heading_rad, fix.phase_rad, target, ctx.max_u
    )
