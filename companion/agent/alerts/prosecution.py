"""Flying a tasked UAV to its alert's site (pure; DESIGN section 4).

A prosecutor flies the minimum-time path to the site (arriving along the loop's tangent),
re-planned every ``replan_s`` from its measured state, and logs the site as covered once
its sensor reaches it. The prosecution ends on re-detection (confirmed), at the path's end
(cleared) or when someone else clears the alert first (cancelled); the :class:`Agent
<companion.agent.agent.Agent>` then changes its mode, sends the alert and starts the rejoin
(:mod:`companion.agent.rejoin`). Times are vehicle seconds, positions complex north + i east
metres, angles radians.

The state lives in the UAV's :class:`~companion.agent.away.Away` record (plan, when it
was made, the planned time, whether the site is covered), which the rejoin then carries on.
Every method returns the typed events (:mod:`companion.agent.events`) it made, for the Agent to log.
"""

from __future__ import annotations

from typing import Literal

from companion.agent.alerts.paths import plan_to_site, remaining_s, turn_rate_at
from companion.agent.away import Away
from companion.agent.events import (
    AgentEvent,
    PlanFailed,
    PlanMade,
    ProsecutionEnd,
    Replan,
    SiteCovered,
)
from companion.agent.rejoin import REPLAN_SLACK_S
from companion.core.patrol import Patrol
from companion.planner import NoPath

REPLAN_SLACK_FRACTION = 0.2  # with REPLAN_SLACK_S: how much longer a re-plan may be

Outcome = Literal["confirmed", "cleared"]
Events = list[AgentEvent]  # the events to log, for the alert flown to


class Prosecution:
    """One prosecution: the path to the site, its re-planning and how it ends.

    Every method returns the events to log, stamped with this UAV's ``sysid`` and the alert
    id (:attr:`alert_id`, which follows a renamed alert).

    Args:
        away: the away record (alert id, site, virtual particle, plan); updated in place.
        sysid: this UAV's system id (the events' ``sysid``).
        max_u: turn-rate limit (rad/s).
        sensor_m: sensor footprint radius (m): the site is covered within it.
        replan_s: re-planning period (s).
        hold_s: how long each command is held (s): a path's turn rate is averaged over it.
    """

    def __init__(
        self,
        away: Away,
        *,
        sysid: int,
        max_u: float,
        sensor_m: float,
        replan_s: float,
        hold_s: float,
    ) -> None:
        """Nothing planned yet: call :meth:`start`."""
        self.away = away
        self.sysid = int(sysid)
        self.max_u = max_u
        self.sensor_m = sensor_m
        self.replan_s = replan_s
        self.hold_s = hold_s

    @property
    def alert_id(self) -> str:
        """The alert flown to."""
        return self.away.alert_id

    @property
    def site_m(self) -> complex:
        """The site flown to (complex m)."""
        return self.away.site_m

    def start(self, patrol: Patrol, t_s: float, pos_m: complex, heading_rad: float) -> Events:
        """The first plan from ``pos_m`` (m) and ``heading_rad`` (rad) at ``t_s`` (s):
        a "plan" event, or "plan_failed" when there is no path."""
        return self.replan(patrol, t_s, pos_m, heading_rad, first=True)

    def replan(
        self, patrol: Patrol, t_s: float, pos_m: complex, heading_rad: float, first: bool = False
    ) -> Events:
        """Plan again from the measured state at ``t_s`` (s). A new path replaces the one in
        force only if it is not much longer than what is left of it (drift can make the old
        path's ending infeasible: then it keeps flying that one)."""
        away = self.away
        plan = plan_to_site(patrol, pos_m, heading_rad, away.site_m, self.max_u)
        away.last_plan_s = t_s
        if isinstance(plan, NoPath):
            return [PlanFailed(**self._head(t_s), reason=plan.reason)] if first else []
        if not first and away.plan is not None:
            left = remaining_s(away.plan, t_s - away.plan_t0_s)
            if plan.time_s > left + max(REPLAN_SLACK_S, REPLAN_SLACK_FRACTION * left):
                return []
        away.plan, away.plan_t0_s = plan, t_s
        if first:
            away.planned_time_s = plan.time_s
        kind = PlanMade if first else Replan
        return [
            kind(**self._head(t_s), planned_time_s=round(plan.time_s, 3), path_type=plan.family)
        ]

    def step(
        self,
        patrol: Patrol,
        t_s: float,
        pos_m: complex,
        heading_rad: float,
        alert_t_s: float | None,
    ) -> tuple[float | None, Events]:
        """One step at ``t_s`` (s): the turn rate (rad/s) along the path, or None once the
        path is flown (or none exists): the site is cleared, call :meth:`end`.

        ``alert_t_s`` is the alert's time (s) for the response time; None: its record is
        gone, the prosecution's start stands in.
        """
        away = self.away
        events: Events = []
        if not away.covered and abs(pos_m - away.site_m) <= self.sensor_m:
            away.covered = True
            events.append(self._covered(t_s, alert_t_s))
        left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        if t_s - away.last_plan_s >= self.replan_s - 1e-9 and (
            away.plan is None or left > self.replan_s
        ):
            events += self.replan(patrol, t_s, pos_m, heading_rad)
            left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        if away.plan is None or left <= 1e-9:
            return None, events
        return turn_rate_at(away.plan, t_s - away.plan_t0_s, self.hold_s), events

    def end(
        self, t_s: float, seen_at_m: complex | None, alert_t_s: float | None
    ) -> tuple[Outcome, Events]:
        """The prosecution ends at ``t_s`` (s): "confirmed" when the sensor sees the intruder
        at ``seen_at_m`` (m; covers the site too), else "cleared". ``alert_t_s`` as in
        :meth:`step`."""
        away = self.away
        events: Events = []
        if seen_at_m is not None and not away.covered:
            away.covered = True
            events.append(self._covered(t_s, alert_t_s))
        outcome: Outcome = "confirmed" if seen_at_m is not None else "cleared"
        events.append(
            ProsecutionEnd(
                **self._head(t_s),
                outcome=outcome,
                planned_time_s=round(away.planned_time_s, 3),
                response_time_s=round(t_s - self._alert_t(alert_t_s), 3),
            )
        )
        return outcome, events

    def cancel(self, t_s: float, by_sysid: int) -> Events:
        """The alert was cleared by ``by_sysid`` (the operator, or another UAV) while this
        UAV flies to it, seen at ``t_s`` (s): nothing left to do there."""
        return [
            ProsecutionEnd(
                **self._head(t_s),
                outcome="cancelled",
                by_sysid=by_sysid,
                planned_time_s=round(self.away.planned_time_s, 3),
            )
        ]

    def _head(self, t_s: float) -> dict:
        """What every event of this prosecution carries: time (s), sysid, alert id."""
        return {"t_s": t_s, "sysid": self.sysid, "alert_id": self.alert_id}

    def _alert_t(self, alert_t_s: float | None) -> float:
        return alert_t_s if alert_t_s is not None else self.away.virtual.t0_s

    def _covered(self, t_s: float, alert_t_s: float | None) -> SiteCovered:
        return SiteCovered(
            **self._head(t_s),
            response_time_s=round(t_s - self._alert_t(alert_t_s), 3),
            planned_time_s=round(self.away.planned_time_s, 3),
        )
