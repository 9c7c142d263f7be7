"""Flying a returning prosecutor back into its slot (pure; DESIGN section 5, beyond the paper).

While it rejoins, the UAV keeps sharing its virtual particle. It flies the earliest
minimum-time path that meets the slot on time (circling back over the alert site while
none exists yet, e.g. when the slot is still far round the loop), lets the tracking law take
out the residual, and hands back its real state once in the slot. Times are vehicle seconds,
positions complex north + i east metres, angles radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from companion.agent_records import Away
from companion.alerts import intercept_slot, over_site, plan_to_pose, remaining_s, turn_rate_at
from companion.core.formation import track_command
from companion.core.patrol import Patrol
from companion.core.steering import Gains
from companion.core.virtual import phase_gap_rad

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


@dataclass(frozen=True)
class RejoinContext:
    """What the rejoin needs of its UAV: loop, gains, turn-rate limit (rad/s), sensor radius
    (m) and re-planning period (s)."""

    patrol: Patrol
    gains: Gains
    max_u: float
    sensor_m: float
    replan_s: float


def rejoin_step(
    ctx: RejoinContext,
    away: Away,
    t_s: float,
    pos_m: complex,
    heading_rad: float,
    centre: complex,
    phase: float,
) -> tuple[float | None, list[tuple[str, dict]]]:
    """One rejoin decision: the turn rate (rad/s), or None to hand back the real state now,
    and the events (name, fields) to log. Updates ``away`` in place."""
    events: list[tuple[str, dict]] = []
    target = away.virtual.phase(t_s)
    in_slot = abs(centre - ctx.patrol.centre_m) < REJOIN_CENTRE_M and abs(
        phase_gap_rad(phase, target)
    ) < np.radians(REJOIN_PHASE_DEG)
    slot_course = float(ctx.patrol.course_at_phase(target))
    well_conditioned = (
        float(ctx.patrol.shape.radius(ctx.patrol.angle_to_canon(slot_course)))
        <= REJOIN_MAX_RADIUS_M
    )
    if away.merged and not in_slot and well_conditioned:
        # Where the loop is nearly straight the centre and phase computed from the course
        # are ill-conditioned (d rho / d gamma = R: 0.9 m per 0.001 deg on a 50 km edge),
        # so there the UAV stays on its slot under the tracking law until a bend; where
        # it is curved, being at the slot's point on its course is being in the slot.
        slot = complex(ctx.patrol.point_at_phase(target))
        course = float(
            np.angle(ctx.patrol.airspeed_m_s * np.exp(1j * heading_rad) + ctx.patrol.wind.vector)
        )
        in_slot = abs(pos_m - slot) < REJOIN_SLOT_FRACTION * ctx.sensor_m and abs(
            phase_gap_rad(course, slot_course)
        ) < np.radians(REJOIN_COURSE_DEG)
    late = t_s - away.rejoin_t0_s > REJOIN_TIMEOUT_PERIODS * ctx.patrol.period_s
    if in_slot or late:
        events.append(
            ("rejoined", {"in_slot": bool(in_slot), "rejoin_s": round(t_s - away.rejoin_t0_s, 3)})
        )
        return None, events
    if away.merge is not None:
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
            if plan is not None and plan.time_s <= left + REPLAN_SLACK_S:
                away.merge, away.merge_t0_s = plan, t_s
                left = plan.time_s
        if left > 0.0:
            return turn_rate_at(away.merge, t_s - away.merge_t0_s), events
        away.merge, away.merged = None, True
    if away.merged:
        return track_command(
            ctx.patrol, ctx.gains, pos_m, heading_rad, phase, target, ctx.max_u
        ), events
    if t_s - away.last_check_s >= ctx.replan_s - 1e-9:
        away.last_check_s = t_s
        found = intercept_slot(ctx.patrol, pos_m, heading_rad, away.virtual.phase, t_s, ctx.max_u)
        if found is not None:
            away.merge, away.merge_t0_s = found[0], t_s
            away.meet_t_s = t_s + found[1]
            events.append(
                (
                    "rejoin_path",
                    {"planned_time_s": round(found[0].time_s, 3), "path_type": found[0].family},
                )
            )
            return turn_rate_at(away.merge, 0.0), events
        away.wait, away.wait_t0_s = (
            over_site(ctx.patrol, pos_m, heading_rad, away.site_m, ctx.max_u),
            t_s,
        )
    if away.wait is not None and remaining_s(away.wait, t_s - away.wait_t0_s) > 0.0:
        return turn_rate_at(away.wait, t_s - away.wait_t0_s), events
    return ctx.max_u * 0.5, events  # circle until the next check
