"""Flying a tasked UAV to its intruder (pure; docs/design.md §5, the paper's footnote on
moving threats): intercept, then search.

* **Intercept.** The prosecutor flies the minimum-time intercept of the intruder's predicted
  track (:func:`companion.agent.alerts.paths.intercept`): a still intruder (or a site with no
  track) arriving along the loop's tangent, as the paper does; a moving one at its predicted
  position, moving with it. It re-plans every ``replan_s`` from its measured state and at
  once whenever a newer track is heard (any member's sighting).
* **From the loop.** A still intruder (or a site) within ``LOOP_CHECK_REACH`` r_s of the
  loop is under the sensor of a UAV that flies the loop past it: if flying the loop there
  takes at most ``LOOP_CHECK_FACTOR`` times the minimum-time intercept, the prosecutor stays
  on the loop (the splay's command, :mod:`companion.agent.splay`) until it has passed the
  site's loop point (plan ``path_type`` "loop"). Its stretch of the perimeter is then never
  left unseen; the minimum-time path, which arrives at the site on the loop's tangent, cuts
  a corner of a convex base inside the loop or swings outside it, 65-250 m off the loop in
  four decoy episodes of the generated missions (``docs/alerts.md``).
* **Search.** If the path is flown and the intruder was not under the sensor where predicted,
  and the prediction's uncertainty is wider than the footprint, it searches it
  (:class:`~companion.agent.alerts.search.Search`: for a moving track first along its
  predicted paths, the turn model's arcs, a junction's turn, where it was seen; then an
  outward spiral in the track's moving frame) for a bounded time before it gives up. A
  search that is outpaced before it begins (its sweep can never catch up with the region;
  never one along the road) is not flown: no "search_started", and the clear's
  ``search_end`` is "outpaced_at_start".

The prosecution ends on a sighting of the intruder (the pilot decides: hand it on, or track
it), when the search is done or not needed, when no path reaches a moving intruder (it
drives away faster than the UAV's ground speed that way: "lost", its ``search_end``
"outpaced_at_start"; generated mission 0 of ``--kinds paths-all``, a 13.7 m/s vehicle
driving into the wind of a UAV at 18 m/s airspeed, was "cleared" 1 s after tasking, 165 m
from its prosecutor), when the intercept would meet a moving intruder outside the fence or
nearer its edge than a turn radius (it leaves the defended region before it can be met, as
a tracker stops at the fence: "lost", ``search_end`` "left_fence"; generated mission 28 of
``--kinds paths-all --max-loop-km 25`` flew a 714 s intercept of a 15 m/s vehicle and was
9.6 km from the loop at the end of the run), or when someone else clears the alert first
(cancelled). Not found, it is "cleared" (nothing there) only where the sensor covered the
prediction's region (no search needed, or the search covered it); otherwise it is "lost"
(:meth:`Prosecution.not_found`): whereabouts unknown, not a false alarm. The measured case: a
7.1 m/s vehicle seen for 1.1 s, its search outpaced before it began, was cleared with the
vehicle 51 m from the prosecutor (r_s 40 m; generated mission 70, ``docs/alerts.md``). The
:class:`~companion.agent.pilot.Pilot` then changes its mode, sends the alert and starts the
rejoin (:mod:`companion.agent.rejoin`). Times are vehicle seconds,
positions complex north + i east metres, angles radians.

The state lives in the mode's record (:class:`~companion.agent.away.Prosecuting`, then
:class:`~companion.agent.away.Searching`); a :class:`Prosecution` is the logic over it, with
the UAV's constants. Every method returns the typed events (:mod:`companion.agent.events`) it
made, for the caller to log in order.
"""

from __future__ import annotations

import math
from typing import Literal

from companion.agent.alerts.paths import (
    intercept,
    over_point,
    remaining_s,
    short_of_fence,
    turn_rate_at,
)
from companion.agent.alerts.search import Search, needs_search
from companion.agent.away import Prosecuting, Searching
from companion.agent.events import (
    AgentEvent,
    PlanFailed,
    PlanMade,
    ProsecutionEnd,
    Replan,
    SearchStarted,
    SiteCovered,
)
from companion.agent.fix import Fix
from companion.core.fence import Fence
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.group.messages import Track
from companion.planner import NoPath, Plan

REPLAN_SLACK_S = 2.0  # with REPLAN_SLACK_FRACTION: how much longer a re-plan may be (s)
REPLAN_SLACK_FRACTION = 0.2
MOVING_MIN_M_S = 0.3  # a track is flown as moving above this speed and three sigma of it
WAYPOINT_REACHED_FRACTION = 0.5  # a search waypoint is reached within this part of r_s
OUTPACED_AT_START = "outpaced_at_start"  # search_end of a search needed but never flown
LEFT_FENCE = "left_fence"  # search_end of an intercept that would meet it beyond the fence
LOOP_CHECK_REACH = 0.8  # a still site this many r_s from the loop, or nearer, is checked ...
LOOP_CHECK_FACTOR = 1.2  # ... from the loop if flying the loop there takes at most this many
# times the minimum-time intercept (and at most half a loop period)

Outcome = Literal["confirmed", "cleared", "lost", "tracking"]
Events = list[AgentEvent]  # the events to log, for the alert flown to
Flown = Prosecuting | Searching  # the records a prosecution flies (its two modes)


def is_moving(track: Track) -> bool:
    """Whether ``track`` is flown as a moving intruder: faster than ``MOVING_MIN_M_S`` and
    than three sigma of its velocity (a still one seen with noisy sightings is not)."""
    return abs(track.vel_m_s) > max(MOVING_MIN_M_S, 3.0 * track.vel_sigma_m_s)


def keeps_it(own_sysid: int, others: list[int]) -> int | None:
    """Of two or more UAVs prosecuting one alert, the one that keeps it: the lowest system
    id. Every companion applies it to what the others share, so the pair agrees without a
    message; None when ``own_sysid`` keeps it (``others``: the other prosecutors' sysids).

    Tasking is the same rules on the same shared state (:mod:`companion.agent.alerts.tasking`),
    but the state is not always the same: a member's own phase is exact where the others
    extrapolate a state that is late on a loaded link, so a UAV near the site's phase can be
    "next" for one member and not for another. Then each tasks the other, both time out, and
    each tasks itself (the alert storm on a loaded machine: two UAVs for 13 s). This ends it
    within a state period."""
    lower = [s for s in others if s < own_sysid]
    return min(lower) if lower else None


def loop_check_s(fix: Fix, track: Track, sensor_m: float) -> float | None:
    """How long (s) a UAV at ``fix``, on the loop, takes flying the loop to the loop point
    nearest the prediction of ``track`` at the fix's time, which a sensor of radius
    ``sensor_m`` (m) sees from the loop: the time-phase ahead times ``T / 2 pi``. None
    where the site is not checked from the loop: a moving track, a site farther than
    ``LOOP_CHECK_REACH`` ``sensor_m`` from the loop, a UAV off the loop, or a site more
    than half a loop period ahead."""
    patrol = fix.patrol
    if not _seen_from_loop(patrol, track, fix.t_s, sensor_m):
        return None
    near = patrol.nearest(track.predict(fix.t_s))
    if fix.loop_offset_m > (1.0 - LOOP_CHECK_REACH) * sensor_m:
        return None
    ahead = (float(near.phase_rad) - float(fix.loop_phase_rad)) % TWO_PI
    return ahead * patrol.period_s / TWO_PI if ahead <= math.pi else None


def _seen_from_loop(patrol: Patrol, track: Track, t_s: float, sensor_m: float) -> bool:
    """Whether ``track`` is still and its prediction at ``t_s`` (s) within
    ``LOOP_CHECK_REACH`` ``sensor_m`` (m) of the loop."""
    near = patrol.nearest(track.predict(t_s))
    return not is_moving(track) and near.distance_m <= LOOP_CHECK_REACH * sensor_m


def _passed(fix: Fix, phase_rad: float) -> bool:
    """Whether the loop point of time-phase ``phase_rad`` (rad) is behind ``fix``."""
    return (phase_rad - float(fix.loop_phase_rad)) % TWO_PI > math.pi


class Prosecution:
    """The prosecution's logic: the intercept of the track, its re-planning, the search, the
    end, over the mode's record (:class:`Prosecuting` or :class:`Searching`), updated in
    place.

    Every method returns the events to log, stamped with this UAV's ``sysid`` and the
    record's alert id (which follows a renamed alert).

    Args:
        sysid: this UAV's system id (the events' ``sysid``).
        max_u: turn-rate limit (rad/s).
        sensor_m: sensor footprint radius (m): the intruder is under the sensor within it.
        replan_s: re-planning period (s).
        hold_s: how long each command is held (s): a path's turn rate is averaged over it.
        fence: the mission's fence (None: an intercept is not bounded by one).
    """

    def __init__(
        self,
        *,
        sysid: int,
        max_u: float,
        sensor_m: float,
        replan_s: float,
        hold_s: float,
        fence: Fence | None = None,
    ) -> None:
        """The UAV's constants; the prosecutions themselves are the records passed in."""
        self.sysid = int(sysid)
        self.max_u = max_u
        self.sensor_m = sensor_m
        self.replan_s = replan_s
        self.hold_s = hold_s
        self.fence = fence

    def start(self, away: Prosecuting, fix: Fix, track: Track) -> Events:
        """The first plan from ``fix`` to ``track``: a "plan" event, or "plan_failed" when
        there is no path. The plan is the loop itself (``path_type`` "loop",
        :func:`loop_check_s`) where that checks the site soon enough; then :meth:`step` flies
        the turn rate it is given for the loop."""
        events = self.replan(away, fix, track, first=True)
        if away.plan is None:
            return events
        loop_s = loop_check_s(fix, track, self.sensor_m)
        if loop_s is None or loop_s > LOOP_CHECK_FACTOR * away.plan.time_s:
            return events
        away.check_phase_rad = float(fix.patrol.phase_of_point(track.predict(fix.t_s)))
        away.planned_time_s = loop_s
        return [
            PlanMade(
                **self._head(away, fix.t_s),
                planned_time_s=round(loop_s, 3),
                path_type="loop",
                quickest_time_s=round(away.plan.time_s, 3),
            )
        ]

    def replan(self, away: Prosecuting, fix: Fix, track: Track, first: bool = False) -> Events:
        """Plan the intercept again from the measured state ``fix``. On the same track a new
        path replaces the one in force only if it is not much longer than what is left of it
        (drift can make the old path's ending infeasible: then it keeps flying that one); a
        newer track always replaces it. A moving intruder the path would meet outside the
        fence, or nearer its edge than a turn radius, leaves the defended region first: no
        plan, ``left_fence`` set, and a "plan_failed" that says where."""
        t_s = fix.t_s
        moving = is_moving(track)
        plan = intercept(fix.patrol, fix.pos_m, fix.heading_rad, track, t_s, self.max_u, not moving)
        away.last_plan_s = t_s
        newer = track.t_s > away.plan_track_t_s
        if isinstance(plan, NoPath):
            return [PlanFailed(**self._head(away, t_s), reason=plan.reason)] if first else []
        if moving and self.fence is not None:
            meet = track.predict(t_s + plan.time_s)
            turn_r = fix.patrol.turn_radius_m(self.max_u)
            if short_of_fence(self.fence, meet, turn_r):
                away.plan, away.left_fence = None, True
                reason = (
                    f"the intercept ({plan.time_s:.0f} s) meets it at {meet.real:.0f},"
                    f"{meet.imag:.0f} m, outside the fence or within a turn of its edge"
                )
                return [PlanFailed(**self._head(away, t_s), reason=reason)]
        if not first and not newer and away.plan is not None:
            left = remaining_s(away.plan, t_s - away.plan_t0_s)
            if plan.time_s > left + max(REPLAN_SLACK_S, REPLAN_SLACK_FRACTION * left):
                return []
        away.plan, away.plan_t0_s, away.plan_track_t_s = plan, t_s, track.t_s
        if first:
            away.planned_time_s = plan.time_s
        kind = PlanMade if first else Replan
        return [
            kind(
                **self._head(away, t_s),
                planned_time_s=round(plan.time_s, 3),
                path_type=plan.family,
            )
        ]

    def step(
        self,
        away: Prosecuting,
        fix: Fix,
        track: Track,
        alert_t_s: float | None,
        loop_u: float = 0.0,
    ) -> tuple[float | None, Events, Search | None]:
        """One step of the intercept at ``fix`` towards ``track`` (the newest known);
        ``loop_u``: the turn rate (rad/s) that keeps this UAV on the loop, flown while it
        checks the site from the loop.

        Returns:
            The turn rate (rad/s), or None once there is nothing left to fly; the events;
            and the search to begin now (its "search_started" among the events), or None.
            None and no search: the path is flown and no search needed, or a search was
            needed but outpaced before it began: the intruder was not found, call
            :meth:`end`. A search: the caller enters ``searching`` with it
            (:meth:`Searching.begin`) and flies :meth:`search_step`. ``alert_t_s``: the
            alert's time (s) for the response time (None: its record is gone, the
            prosecution's start stands in).
        """
        t_s = fix.t_s
        events: Events = []
        self._cover(away, fix, track, alert_t_s, events)
        if away.left_fence:  # it leaves the fence before it can be met: not found
            return None, events, None
        if away.check_phase_rad is not None:
            if _passed(fix, away.check_phase_rad):
                away.plan = None  # the loop flown past the site: as a path flown
            elif track.t_s > away.plan_track_t_s and not _seen_from_loop(
                fix.patrol, track, t_s, self.sensor_m
            ):
                away.check_phase_rad, away.plan = None, None  # it moves: intercept it
            else:
                return loop_u, events, None
        left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        due = t_s - away.last_plan_s >= self.replan_s - 1e-9 and left > self.replan_s
        flown_loop = away.check_phase_rad is not None
        if not flown_loop and (away.plan is None or due or track.t_s > away.plan_track_t_s):
            events += self.replan(away, fix, track)
            if away.left_fence:
                return None, events, None
            left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        if away.plan is not None and left > 1e-9:
            return turn_rate_at(away.plan, t_s - away.plan_t0_s, self.hold_s), events, None
        if away.plan is None and not flown_loop and is_moving(track):
            # no path reaches it (it drives away faster than this UAV's ground speed that
            # way): nothing was looked at, so not "cleared" but outpaced, hence "lost"
            away.outpaced_at_start = True
            return None, events, None
        if not needs_search(track, t_s, self.sensor_m):
            return None, events, None
        patrol = fix.patrol
        turn_r = patrol.turn_radius_m(self.max_u)
        search = Search(track, t_s, self.sensor_m, turn_r, away.search_max_s, patrol.airspeed_m_s)
        if search.outpaced(t_s):
            # outpaced before it began: no search is flown (no "search_started"), and the
            # clear says why (``ProsecutionEnd.search_end`` "outpaced_at_start")
            away.outpaced_at_start = True
            return None, events, None
        events.append(
            SearchStarted(
                **self._head(away, t_s),
                sigma_m=round(track.sigma_m(t_s), 1),
                max_s=away.search_max_s,
            )
        )
        return None, events, search

    def search(
        self, away: Searching, fix: Fix, track: Track, alert_t_s: float | None
    ) -> tuple[float | None, Events]:
        """One step of the search at ``fix`` (``track``, ``alert_t_s`` as in :meth:`step`):
        the turn rate (rad/s), or None once the search is over (call :meth:`end`)."""
        events: Events = []
        self._cover(away, fix, track, alert_t_s, events)
        return self.search_step(away, fix), events

    def search_step(self, away: Searching, fix: Fix) -> float | None:
        """Fly the search's current waypoint (the next once it is reached): the turn rate
        (rad/s), or None once the search is over."""
        t_s, pos_m = fix.t_s, fix.pos_m
        search = away.search
        if search.finished(t_s) is not None:
            return None
        if search.on_road() and len(search.order) == search.k:
            self._pick_road_point(search, fix)
            away.plan, away.last_plan_s = None, -1e9
        wp = search.waypoint_m(t_s)
        left = remaining_s(away.plan, t_s - away.plan_t0_s) if away.plan else 0.0
        if abs(pos_m - wp) <= WAYPOINT_REACHED_FRACTION * self.sensor_m or (
            away.plan is not None and left <= 1e-9
        ):
            search.k += 1
            away.plan, away.last_plan_s = None, -1e9
            if search.finished(t_s) is not None:
                return None
            if search.on_road():
                self._pick_road_point(search, fix)
            wp = search.waypoint_m(t_s)
        if away.plan is None or t_s - away.last_plan_s >= self.replan_s - 1e-9:
            vel = search.waypoint_velocity_m_s()
            plan = over_point(fix.patrol, pos_m, fix.heading_rad, wp, vel, self.max_u)
            away.last_plan_s = t_s
            if isinstance(plan, Plan):
                away.plan, away.plan_t0_s = plan, t_s
        if away.plan is None:
            return self.max_u * 0.5  # circle until a path exists
        return turn_rate_at(away.plan, t_s - away.plan_t0_s, self.hold_s)

    def _pick_road_point(self, search: Search, fix: Fix) -> None:
        """The road point (of those not flown) this UAV at ``fix`` reaches soonest: picked
        as the search's current waypoint."""
        best, best_s = None, math.inf
        for i in search.unpicked():
            search.order.append(i)  # tried as the current waypoint
            wp, vel = search.waypoint_m(fix.t_s), search.waypoint_velocity_m_s()
            search.order.pop()
            plan = over_point(fix.patrol, fix.pos_m, fix.heading_rad, wp, vel, self.max_u)
            if isinstance(plan, Plan) and plan.time_s < best_s:
                best, best_s = i, plan.time_s
        search.pick(best if best is not None else search.unpicked()[0])

    @staticmethod
    def region_checked(away: Flown, t_s: float) -> bool:
        """Whether, at ``t_s`` (s), the sensor has covered the prediction's
        ``SEARCH_SIGMAS``-sigma region: no search was needed, or the search ended "covered".
        False when a search was needed and was outpaced (before it began or since) or ran
        out of time, or when the intercept would have met it beyond the fence."""
        if isinstance(away, Searching):
            return away.search.finished(t_s) == "covered"
        return not (away.outpaced_at_start or away.left_fence)

    def not_found(self, away: Flown, t_s: float) -> Literal["cleared", "lost"]:
        """The outcome of a prosecution that did not find its intruder at ``t_s`` (s):
        "cleared" (nothing there) where the sensor covered the prediction's region
        (:meth:`region_checked`), else "lost" (the intruder may be somewhere the sensor did
        not look: not a false alarm)."""
        return "cleared" if self.region_checked(away, t_s) else "lost"

    def end(
        self,
        away: Flown,
        t_s: float,
        seen_at_m: complex | None,
        alert_t_s: float | None,
        outcome: Outcome,
    ) -> Events:
        """The prosecution ends at ``t_s`` (s) with ``outcome``: "confirmed" (seen at
        ``seen_at_m``, m, and handed on), "tracking" (seen, and this UAV stays over it),
        "cleared" (not found where the sensor looked) or "lost" (a mover not found, its
        region not covered: :meth:`not_found`). ``alert_t_s`` as in :meth:`step`."""
        events: Events = []
        if seen_at_m is not None and not away.covered:
            away.covered = True
            events.append(self._covered(away, t_s, alert_t_s))
        searched_s = None
        if isinstance(away, Searching):
            search_end = away.search.finished(t_s)
            searched_s = round(t_s - away.search.t0_s, 3)
        elif away.outpaced_at_start:
            search_end = OUTPACED_AT_START
        else:
            search_end = LEFT_FENCE if away.left_fence else None
        events.append(
            ProsecutionEnd(
                **self._head(away, t_s),
                outcome=outcome,
                planned_time_s=round(away.planned_time_s, 3),
                response_time_s=round(t_s - self._alert_t(away, alert_t_s), 3),
                searched_s=searched_s,
                search_end=search_end,
            )
        )
        return events

    def cancel(self, away: Flown, t_s: float, by_sysid: int) -> Events:
        """The alert was cleared by ``by_sysid`` (the operator, or another UAV) while this
        UAV flies to it, seen at ``t_s`` (s): nothing left to do there."""
        return [
            ProsecutionEnd(
                **self._head(away, t_s),
                outcome="cancelled",
                by_sysid=by_sysid,
                planned_time_s=round(away.planned_time_s, 3),
            )
        ]

    def yield_to(self, away: Flown, t_s: float, sysid: int) -> Events:
        """Another member, ``sysid``, shares at ``t_s`` (s) that it prosecutes the same alert
        and takes it (:func:`keeps_it`): this UAV leaves it to that one."""
        return [
            ProsecutionEnd(
                **self._head(away, t_s),
                outcome="yielded",
                by_sysid=sysid,
                planned_time_s=round(away.planned_time_s, 3),
            )
        ]

    def _head(self, away: Flown, t_s: float) -> dict:
        """What every event of this prosecution carries: time (s), sysid, alert id."""
        return {"t_s": t_s, "sysid": self.sysid, "alert_id": away.alert_id}

    @staticmethod
    def _alert_t(away: Flown, alert_t_s: float | None) -> float:
        return alert_t_s if alert_t_s is not None else away.virtual.t0_s

    def _cover(
        self, away: Flown, fix: Fix, track: Track, alert_t_s: float | None, events: Events
    ) -> None:
        """The sensor over the prediction for the first time: "site_covered"."""
        if not away.covered and abs(fix.pos_m - track.predict(fix.t_s)) <= self.sensor_m:
            away.covered = True
            events.append(self._covered(away, fix.t_s, alert_t_s))

    def _covered(self, away: Flown, t_s: float, alert_t_s: float | None) -> SiteCovered:
        return SiteCovered(
            **self._head(away, t_s),
            response_time_s=round(t_s - self._alert_t(away, alert_t_s), 3),
            planned_time_s=round(away.planned_time_s, 3),
        )
