"""Flying a returning prosecutor back into its slot (pure; DESIGN section 5, beyond the paper).

While it rejoins, the UAV keeps sharing its virtual particle. It flies the earliest
minimum-time path that meets the slot on time (circling back over the alert site while
none exists yet, e.g. when the slot is still far round the loop), lets the tracking law take
out the residual, and hands back its real state once in the slot. Times are vehicle seconds,
positions complex north + i east metres, angles radians.

"In the slot" is relative to how well this UAV tracks the loop at all: the tolerances grow
with ``REJOIN_TRACKING_K`` x the 95th percentile of its own centre error over the last
``TRACKING_WINDOW_PERIODS`` loop periods on patrol (:class:`TrackingAccuracy`), never below
the simulator-tuned ``REJOIN_CENTRE_M`` / ``REJOIN_PHASE_DEG`` / ``REJOIN_COURSE_DEG`` and
never above ``REJOIN_MAX_TOL_M``. On ArduPlane (centre error about 12 m p50) the fixed 3 m
made a 14.7 s rejoin take 227 s.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from companion.agent.alerts.paths import (
    intercept_slot,
    over_site,
    plan_to_pose,
    remaining_s,
    turn_rate_at,
)
from companion.agent.away import Away
from companion.agent.events import AgentEvent, Rejoined, RejoinPath
from companion.agent.modes import ModeEvent, OwnMode
from companion.core.patrol import Patrol
from companion.guidance.formation import track_command
from companion.guidance.steering import Gains
from companion.guidance.virtual import phase_gap_rad
from companion.planner import NoPath, Plan

REJOIN_CENTRE_M = 3.0  # hand back the real state once this close to the loop centre ...
REJOIN_PHASE_DEG = 1.0  # ... and this close to the virtual particle's phase
REJOIN_TIMEOUT_PERIODS = 3.0  # hand back anyway after this many loop periods
REJOIN_SLOT_FRACTION = 0.2  # ... or once within this fraction of r_s of the slot's point
REJOIN_COURSE_DEG = 1.0  # ... on its course to this tolerance, where the loop's radius of
REJOIN_MAX_RADIUS_M = 2000.0  # curvature is at most this (1 deg of course = 35 m of centre)
# A re-plan replaces the current path only if it is not much longer than what is left of it:
# close to the site a small drift can make the exact final course unreachable by a short
# path, and the "new minimum" is a whole extra loop.
REPLAN_SLACK_S = 2.0
REPLAN_MIN_LEFT_S = 3.0  # no re-planning in the last seconds of a path
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
    how long each command is held (s; a path's turn rate is averaged over it) and its system
    id (the events' ``sysid``)."""

    patrol: Patrol
    gains: Gains
    max_u: float
    sensor_m: float
    replan_s: float
    tracking_p95_m: float = 0.0
    hold_s: float = 0.0
    sysid: int = 0


def rejoin_step(
    ctx: RejoinContext,
    away: Away,
    stage: OwnMode,
    t_s: float,
    pos_m: complex,
    heading_rad: float,
    centre: complex,
    phase: float,
) -> tuple[float | None, list[AgentEvent], list[ModeEvent]]:
    """One rejoin decision in ``stage`` (a rejoin mode of :class:`~companion.agent.modes.OwnMode`).

    Returns:
        The turn rate (rad/s), or None to hand back the real state now; the events to log
        (stamped ``ctx.sysid``, ``away.alert_id``); and the mode events that happened, in
        order, for the Agent to apply (:data:`companion.agent.modes.MODE_TABLE`). Updates
        ``away`` (the paths flown) in place.
    """
    events: list[AgentEvent] = []
    changes: list[ModeEvent] = []
    target = away.virtual.phase(t_s)
    tol = slot_tolerance(ctx.tracking_p95_m, ctx.patrol.length_m, ctx.sensor_m)
    in_slot = (
        abs(centre - ctx.patrol.centre_m) < tol.centre_m
        and abs(phase_gap_rad(phase, target)) < tol.phase_rad
    )
    slot_course = float(ctx.patrol.course_at_phase(target))
    well_conditioned = (
        float(ctx.patrol.shape.radius(ctx.patrol.angle_to_canon(slot_course)))
        <= REJOIN_MAX_RADIUS_M
    )
    if stage is OwnMode.REJOIN_TRACKING and not in_slot and well_conditioned:
        # Where the loop is nearly straight the centre and phase computed from the course
        # are ill-conditioned (d rho / d gamma = R: 0.9 m per 0.001 deg on a 50 km edge),
        # so there the UAV stays on its slot under the tracking law until a bend; where
        # it is curved, being at the slot's point on its course is being in the slot.
        slot = complex(ctx.patrol.point_at_phase(target))
        course = float(
            np.angle(ctx.patrol.airspeed_m_s * np.exp(1j * heading_rad) + ctx.patrol.wind.vector)
        )
        in_slot = (
            abs(pos_m - slot) < tol.slot_m
            and abs(phase_gap_rad(course, slot_course)) < tol.course_rad
        )
    late = t_s - away.rejoin_t0_s > REJOIN_TIMEOUT_PERIODS * ctx.patrol.period_s
    if in_slot or late:
        events.append(
            Rejoined(
                t_s=t_s,
                sysid=ctx.sysid,
                alert_id=away.alert_id,
                in_slot=bool(in_slot),
                rejoin_s=round(t_s - away.rejoin_t0_s, 3),
                tol_m=round(tol.centre_m, 2),
            )
        )
        return None, events, [ModeEvent.IN_SLOT if in_slot else ModeEvent.TIMED_OUT]
    if stage is OwnMode.REJOIN_MERGING:
        left = remaining_s(away.merge, t_s - away.merge_t0_s)
        if left > REPLAN_MIN_LEFT_S and t_s - away.last_check_s >= ctx.replan_s - 1e-9:
            away.last_check_s = t_s  # re-plan to the same meeting point and time
            meet = away.virtual.phase(away.meet_t_s)
            plan = plan_to_pose(
                ctx.patrol,
                pos_m,
                heading_rad,
                complex(ctx.patrol.point_at_phase(meet)),
                float(ctx.patrol.course_at_phase(meet)),
                ctx.max_u,
            )
            if isinstance(plan, Plan) and plan.time_s <= left + REPLAN_SLACK_S:
                away.merge, away.merge_t0_s = plan, t_s
                left = plan.time_s
        if left > 0.0:
            return turn_rate_at(away.merge, t_s - away.merge_t0_s, ctx.hold_s), events, changes
        away.merge, stage = None, OwnMode.REJOIN_TRACKING
        changes.append(ModeEvent.MET_SLOT)
    if stage is OwnMode.REJOIN_TRACKING:
        u = track_command(ctx.patrol, ctx.gains, pos_m, heading_rad, phase, target, ctx.max_u)
        return u, events, changes
    if t_s - away.last_check_s >= ctx.replan_s - 1e-9:
        away.last_check_s = t_s
        found = intercept_slot(ctx.patrol, pos_m, heading_rad, away.virtual.phase, t_s, ctx.max_u)
        if not isinstance(found, NoPath):
            away.merge, away.merge_t0_s = found[0], t_s
            away.meet_t_s = t_s + found[1]
            events.append(
                RejoinPath(
                    t_s=t_s,
                    sysid=ctx.sysid,
                    alert_id=away.alert_id,
                    planned_time_s=round(found[0].time_s, 3),
                    path_type=found[0].family,
                )
            )
            changes.append(ModeEvent.MEET_PATH_FOUND)
            return turn_rate_at(away.merge, 0.0, ctx.hold_s), events, changes
        wait = over_site(ctx.patrol, pos_m, heading_rad, away.site_m, ctx.max_u)
        away.wait, away.wait_t0_s = (wait if isinstance(wait, Plan) else None), t_s
    if away.wait is not None and remaining_s(away.wait, t_s - away.wait_t0_s) > 0.0:
        return turn_rate_at(away.wait, t_s - away.wait_t0_s, ctx.hold_s), events, changes
    return ctx.max_u * 0.5, events, changes  # circle until the next check
