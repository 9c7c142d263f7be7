"""Staying over a persistent intruder (pure; policy "track").

Once its prosecutor sees the intruder, under the "track" policy it stays over it instead of
handing it on: it leaves the formation (it shares its real state as ``tracking``; the others
splay as N - 1), and flies pass after pass over the predicted track, each pass the
minimum-time path over the predicted position moving at the track's velocity
(:func:`companion.agent.alerts.paths.over_point`), re-planned every ``replan_s`` and at once
on a newer track. Its own sightings on each pass (and anyone else's) keep the track fresh.

It stops when the track is lost (no sighting for ``lost_s``), when the intruder is out of the
fence or nearer its edge than one turn radius (a pass over it would leave the fence), or when
the alert is done (the operator released it, or it was cleared); the pilot then sends "lost"
where it applies and the UAV rejoins into the widest gap of the formation.

Times are vehicle seconds, positions complex north + i east metres, angles radians.
"""

from __future__ import annotations

from companion.agent.alerts.paths import over_point, remaining_s, short_of_fence, turn_rate_at
from companion.agent.away import Tracking
from companion.agent.fix import Fix
from companion.core.fence import Fence
from companion.group.messages import Track
from companion.planner import Plan

TRACK_LOST_S = 45.0  # no sighting of a tracked intruder for this long: lost (s)


class Tracker:
    """The tracking's logic over the mode's record (:class:`~companion.agent.away.Tracking`,
    updated in place), with the UAV's constants.

    Args:
        max_u: turn-rate limit (rad/s).
        replan_s: re-planning period (s).
        hold_s: how long each command is held (s).
        fence: the mission's fence, or None.
        lost_s: no sighting for this long is a lost track (s).
    """

    def __init__(
        self,
        *,
        max_u: float,
        replan_s: float,
        hold_s: float,
        fence: Fence | None,
        lost_s: float = TRACK_LOST_S,
    ) -> None:
        """The UAV's constants; each tracking is the record passed in."""
        self.max_u = max_u
        self.replan_s = replan_s
        self.hold_s = hold_s
        self.fence = fence
        self.lost_s = lost_s

    def why_stop(self, fix: Fix, track: Track, done: bool) -> str | None:
        """Why to stop tracking at ``fix``'s time: "released" (``done``: the alert is
        closed), "lost", "left_fence", or None to go on."""
        t_s, patrol = fix.t_s, fix.patrol
        if done:
            return "released"
        if t_s - track.t_s > self.lost_s:
            return "lost"
        if self.fence is None:
            return None
        turn_r = patrol.turn_radius_m(self.max_u)
        return "left_fence" if short_of_fence(self.fence, track.predict(t_s), turn_r) else None

    def step(self, away: Tracking, fix: Fix, track: Track) -> float:
        """The turn rate (rad/s) of the pass over ``track`` at ``fix``."""
        t_s = fix.t_s
        left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        due = t_s - away.last_plan_s >= self.replan_s - 1e-9
        if away.plan is None or left <= 1e-9 or due or track.t_s > away.plan_track_t_s:
            pred = track.predict(t_s)
            plan = over_point(
                fix.patrol, fix.pos_m, fix.heading_rad, pred, track.vel_m_s, self.max_u
            )
            away.last_plan_s = t_s
            if isinstance(plan, Plan):
                away.plan, away.plan_t0_s, away.plan_track_t_s = plan, t_s, track.t_s
                left = plan.time_s
        if away.plan is None or left <= 1e-9:
            return self.max_u * 0.5  # circle until a pass exists
        return turn_rate_at(away.plan, t_s - away.plan_t0_s, self.hold_s)
