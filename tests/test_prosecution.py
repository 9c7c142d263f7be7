"""The prosecution seam (pure): the intercept of the track, its re-planning, the search, the end.

The intercept of a moving intruder is checked independently of the planner: its segments are
flown through the particle model (exact arcs, :func:`companion.core.particle.step_one`) and
the aircraft must end within the sensor footprint of where the intruder truly is then.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.alerts.paths import intercept, turn_rate_at
from companion.agent.alerts.prosecution import Prosecution, is_moving
from companion.agent.alerts.search import SEARCH_SIGMAS, Search, needs_search
from companion.agent.away import Prosecuting, Searching
from companion.agent.events import (
    PlanFailed,
    PlanMade,
    ProsecutionEnd,
    Replan,
    SearchStarted,
    SiteCovered,
)
from companion.agent.fix import Fix
from companion.core.particle import ParticleParams, step_one
from companion.core.wind import heading_from_course
from companion.group.messages import Track
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission
from companion.planner import Plan

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
P = MISSION.patrol
R_S = MISSION.sensor.footprint_radius_m
MAX_U = MISSION.vehicles.max_turn_rate_rad_s
T0_S = 100.0
HOLD_S = 0.1
SYSID = 3


def on_loop(phase_rad: float) -> tuple[complex, float]:
    """A position (m) on the loop and the air heading (rad) that flies its tangent."""
    course = float(P.course_at_phase(phase_rad))
    heading = float(heading_from_course(P.airspeed_m_s, course, P.wind))
    return complex(P.point_at_phase(phase_rad)), heading


def outside_site(phase_rad: float, out_m: float = 50.0) -> complex:
    loop = complex(P.point_at_phase(phase_rad))
    return loop + out_m * (loop - P.centre_m) / abs(loop - P.centre_m)


def still(site_m: complex, t_s: float = T0_S, sigma_m: float = 2.0) -> Track:
    """A still intruder seen well: small uncertainty, no speed."""
    return Track(t_s, site_m, 0j, sigma_m, 0.05, 20)


PROSECUTION = Prosecution(sysid=SYSID, max_u=MAX_U, sensor_m=R_S, replan_s=1.0, hold_s=HOLD_S)


def at(t_s: float, pos_m: complex, heading_rad: float) -> Fix:
    return Fix(t_s, pos_m, heading_rad, P)


class Pros:
    """One prosecution: the logic and the mode's record it flies (prosecuting, then
    searching once the step begins a search), as the Agent's pilot holds them."""

    def __init__(self, site_m: complex, search_max_s: float = 60.0) -> None:
        self.away: Prosecuting | Searching = Prosecuting(
            "1-1", site_m, VirtualParticle(0.0, T0_S, P.period_s), search_max_s=search_max_s
        )

    def start(self, t_s, pos, heading, track):
        return PROSECUTION.start(self.away, at(t_s, pos, heading), track)

    def replan(self, t_s, pos, heading, track):
        return PROSECUTION.replan(self.away, at(t_s, pos, heading), track)

    def step(self, t_s, pos, heading, track, alert_t_s, loop_u=0.0):
        """The step of the mode it is in: (turn rate, events, whether the search began)."""
        fix = at(t_s, pos, heading)
        if isinstance(self.away, Searching):
            u, events = PROSECUTION.search(self.away, fix, track, alert_t_s)
            return u, events, False
        u, events, search = PROSECUTION.step(self.away, fix, track, alert_t_s, loop_u)
        if search is None:
            return u, events, False
        self.away = Searching.begin(self.away, search)  # path_flown: the search's first leg
        return PROSECUTION.search_step(self.away, fix), events, True

    def region_checked(self, t_s):
        return PROSECUTION.region_checked(self.away, t_s)

    def not_found(self, t_s):
        return PROSECUTION.not_found(self.away, t_s)

    def end(self, t_s, seen_at_m, alert_t_s, outcome):
        return PROSECUTION.end(self.away, t_s, seen_at_m, alert_t_s, outcome)

    def cancel(self, t_s, by_sysid):
        return PROSECUTION.cancel(self.away, t_s, by_sysid)


def prosecution(site_m: complex, search_max_s: float = 60.0) -> Pros:
    return Pros(site_m, search_max_s)


def started(track: Track | None = None) -> tuple[Pros, complex, float, Track]:
    pos, heading = on_loop(0.0)
    site = outside_site(math.pi / 2)
    track = track or still(site)
    pros = prosecution(site)
    assert [type(e) for e in pros.start(T0_S, pos, heading, track)] == [PlanMade]
    return pros, pos, heading, track


def test_start_plans_and_flies_the_path_between_replans():
    pos, heading = on_loop(0.0)
    site = outside_site(math.pi / 2)
    pros = prosecution(site)
    away = pros.away
    (ev,) = pros.start(T0_S, pos, heading, still(site))
    assert ev == PlanMade(
        t_s=T0_S,
        sysid=SYSID,
        alert_id="1-1",
        planned_time_s=round(away.plan.time_s, 3),
        path_type=away.plan.family,
    )
    assert away.planned_time_s == away.plan.time_s > 0 and away.plan_t0_s == T0_S
    u, events, began = pros.step(T0_S + 0.5, pos, heading, still(site), T0_S)
    assert events == [] and not began and u == turn_rate_at(away.plan, 0.5, HOLD_S)


def test_a_much_longer_replan_on_the_same_track_keeps_the_path_in_force():
    pros, pos, heading, track = started()
    plan = pros.away.plan
    assert pros.replan(T0_S + 1.0, pos, heading + math.pi, track) == []  # a turn longer
    assert pros.away.plan is plan and pros.away.last_plan_s == T0_S + 1.0
    (ev,) = pros.replan(T0_S + 2.0, pos, heading, track)
    assert isinstance(ev, Replan) and pros.away.plan_t0_s == T0_S + 2.0


def test_a_newer_track_replans_at_once():
    pros, pos, heading, track = started()
    newer = Track(T0_S + 0.3, track.pos_m + 30.0, 0j, 2.0, 0.05, 25)
    _, events, _ = pros.step(T0_S + 0.3, pos, heading, newer, T0_S)
    assert [type(e) for e in events] == [Replan]
    assert pros.away.plan_track_t_s == newer.t_s


def test_no_path_is_reported_on_the_first_plan_only():
    site = outside_site(0.0)
    pros = prosecution(site)
    (ev,) = pros.start(T0_S, site, 0.0, still(site))  # already on the site
    assert isinstance(ev, PlanFailed) and ev.reason
    assert pros.away.plan is None
    assert pros.replan(T0_S + 1.0, site, 0.0, still(site)) == []
    u, _, began = pros.step(T0_S + 1.5, site, 0.0, still(site), None)
    assert u is None and not began  # no path, and the site under the sensor: cleared


def test_the_intruder_is_covered_once_within_the_sensor_of_its_prediction():
    pros, _, heading, track = started()
    near = track.pos_m + 0.9 * R_S
    _, events, _ = pros.step(T0_S + 0.5, near, heading, track, T0_S - 2.0)
    assert (
        SiteCovered(
            t_s=T0_S + 0.5,
            sysid=SYSID,
            alert_id="1-1",
            response_time_s=2.5,
            planned_time_s=round(pros.away.planned_time_s, 3),
        )
        in events
    )
    _, again, _ = pros.step(T0_S + 0.6, near, heading, track, T0_S - 2.0)
    assert not [e for e in again if isinstance(e, SiteCovered)]


def test_a_well_known_still_intruder_not_seen_at_the_end_of_the_path_is_cleared():
    pros, pos, heading, track = started()
    t_end = T0_S + pros.away.plan.time_s
    u, _, began = pros.step(t_end, pos, heading, track, None)
    assert u is None and not began  # three sigma fit inside the footprint: no search
    events = pros.end(t_end, None, None, "cleared")  # no record: the start stands in
    assert events == [
        ProsecutionEnd(
            t_s=t_end,
            sysid=SYSID,
            alert_id="1-1",
            outcome="cleared",
            planned_time_s=round(pros.away.planned_time_s, 3),
            response_time_s=round(t_end - T0_S, 3),
        )
    ]


def searchable(site_m: complex) -> Track:
    """A still intruder whose place is known only to 17 m (a far, blurred sighting) but whose
    stillness is well known: its region outgrows the footprint, slowly enough to search."""
    return Track(T0_S, site_m, 0j, 17.0, 0.2, 8)


def test_a_track_a_search_can_cover_is_searched_then_cleared():
    site = outside_site(math.pi / 2)
    pros, pos, heading, _ = started()
    t_end = T0_S + pros.away.plan.time_s
    track = searchable(site)
    assert needs_search(track, t_end, R_S)
    u, events, began = pros.step(t_end, pos, heading, track, T0_S)
    assert began and u is not None and isinstance(events[-1], SearchStarted)
    assert isinstance(pros.away, Searching) and pros.away.search.k == 0
    # the search ends by its time bound at the latest
    t = t_end + 0.1
    while t < t_end + 61.0:
        u, _, _ = pros.step(t, pos, heading, track, T0_S)
        if u is None:
            break
        t += 1.0
    assert u is None and t - t_end <= 60.5
    (end,) = pros.end(t, None, T0_S, "cleared")
    assert end.searched_s == pytest.approx(t - t_end, abs=0.2) and end.searched_s > 1.0
    assert end.search_end in ("covered", "time")


def test_a_track_whose_region_outgrows_any_search_is_cleared_at_once():
    """One short pass (1 m/s of velocity error) reached half a minute later: the region grows
    faster than the footprint can ever sweep it, so the perimeter is not made to pay for a
    search that cannot cover it."""
    site = outside_site(math.pi / 2)
    vague = Track(T0_S, site, 0j, 5.0, 1.0, 3)
    pros, pos, heading, _ = started(vague)
    t_end = T0_S + pros.away.plan.time_s
    assert needs_search(vague, t_end, R_S)
    u, events, began = pros.step(t_end, pos, heading, vague, T0_S)
    # no search began: none is logged, the mode does not become "searching"
    assert u is None and not began and not isinstance(pros.away, Searching)
    assert not any(isinstance(e, SearchStarted) for e in events)
    (end,) = pros.end(t_end, None, T0_S, "cleared")
    # the clear says why it did not search, distinct from a search flown and then outpaced
    assert (end.search_end, end.searched_s) == ("outpaced_at_start", None)


def test_not_found_is_cleared_only_where_the_sensor_covered_the_region_else_lost():
    """Generated mission 70: a vehicle seen for 1.1 s, its region outgrowing any search when
    the prosecutor got there, was "cleared" with the vehicle 51 m away (r_s 40 m). A
    prosecution that did not cover its prediction's region now ends "lost" (whereabouts
    unknown), and "cleared" only where it covered it: no search needed, or one flown to
    "covered". A mover is searched along its road first, and that alone never clears."""
    site = outside_site(math.pi / 2)
    # a mover seen briefly, reached late: its region outgrows any spiral, but it is searched
    # along its predicted paths first (issue 47); not found there either, still "lost"
    vehicle = Track(T0_S, site, 6.0 + 0j, 3.0, 2.5, 5)
    pros, pos, heading, _ = started(vehicle)
    t_end = T0_S + pros.away.plan.time_s
    u, _, began = pros.step(t_end, pos, heading, vehicle, T0_S)
    assert u is not None and began and isinstance(pros.away, Searching)
    search = pros.away.search
    assert search.on_road() and not search.outpaced(t_end)
    t_s = t_end + search.max_s
    assert search.finished(t_s) == "time"
    assert not pros.region_checked(t_s) and pros.not_found(t_s) == "lost"
    # not covered: outpaced before any search began (no speed to search along, a wide
    # velocity error: a point seen briefly, reached late)
    blur = Track(T0_S, site, 0.5 + 0j, 3.0, 2.5, 5)
    pros, pos, heading, _ = started(blur)
    t_end = T0_S + pros.away.plan.time_s
    u, _, _ = pros.step(t_end, pos, heading, blur, T0_S)
    assert u is None and pros.away.outpaced_at_start
    assert not pros.region_checked(t_end) and pros.not_found(t_end) == "lost"
    (end,) = pros.end(t_end, None, T0_S, pros.not_found(t_end))
    assert (end.outcome, end.search_end) == ("lost", "outpaced_at_start")
    # covered: a well-seen still intruder under the footprint needs no search
    pros, pos, heading, track = started(still(site))
    t_end = T0_S + pros.away.plan.time_s
    assert pros.step(t_end, pos, heading, track, T0_S)[0] is None
    assert pros.region_checked(t_end) and pros.not_found(t_end) == "cleared"
    # a search flown: to "covered" it clears; stopped by its time bound first, lost
    track = searchable(site)
    for k, outcome in ((12, "cleared"), (0, "lost")):
        pros = prosecution(site, search_max_s=30.0)
        search = Search(track, T0_S, R_S, 80.0, 30.0, P.airspeed_m_s, k=k)
        pros.away = Searching.begin(pros.away, search)
        t_s = T0_S + 31.0
        why = pros.away.search.finished(t_s)
        assert why == ("covered" if k else "time")
        assert pros.not_found(t_s) == outcome, why


def test_a_clear_that_needed_no_search_names_no_search_end():
    """A well-seen still intruder, not found under the footprint: cleared with no search
    and no reason for one (not mistaken for a search outpaced at its start)."""
    site = outside_site(math.pi / 2)
    pros, pos, heading, track = started(still(site))
    t_end = T0_S + pros.away.plan.time_s
    assert not needs_search(track, t_end, R_S)
    u, events, began = pros.step(t_end, pos, heading, track, T0_S)
    assert u is None and not began and not any(isinstance(e, SearchStarted) for e in events)
    (end,) = pros.end(t_end, None, T0_S, "cleared")
    assert (end.search_end, end.searched_s) == (None, None)


@pytest.mark.parametrize("vel_sigma", [0.2, 0.5, 0.8, 1.2])
@pytest.mark.parametrize("age_s", [5.0, 15.0, 30.0])
def test_outpaced_agrees_with_the_swept_and_grown_areas_on_a_grid_of_futures(vel_sigma, age_s):
    """``outpaced`` (a closed-form maximum) against brute force: the swept area (the
    footprint's disc plus the sweep rate, frozen at now) and the region's area on a fine grid
    of future times; outpaced exactly when no future has the swept area ahead."""
    track = Track(0.0, 0j, 0j, 3.0, vel_sigma, 10)
    s = Search(track, t0_s=age_s, sensor_m=R_S, turn_radius_m=80.0, max_s=600.0, speed_m_s=20.0)
    for now in (age_s, age_s + 4.0, age_s + 12.0):
        rate = s.sweep_rate_m2_s(now)
        future = np.linspace(now, now + 2000.0, 20_001)  # every 0.1 s
        swept = math.pi * R_S**2 + rate * (future - s.t0_s)
        area = math.pi * SEARCH_SIGMAS**2 * np.array([track.sigma_m(t) ** 2 for t in future])
        ahead = swept - area
        if abs(ahead.max()) > 50.0:  # away from the boundary, where the grid decides
            assert s.outpaced(now) == (ahead.max() < 0.0)


def test_a_sighting_ends_it_seen_and_covers_the_site():
    pros, _, _, track = started()
    events = pros.end(T0_S + 5.0, track.pos_m + 10.0, T0_S - 1.0, "tracking")
    assert pros.away.covered
    assert [(e.name, e.response_time_s) for e in events] == [
        ("site_covered", 6.0),
        ("prosecution_end", 6.0),
    ]
    assert events[-1].outcome == "tracking" and events[-1].searched_s is None


def test_a_cancel_names_who_cleared_it():
    pros, _, _, _ = started()
    (ev,) = pros.cancel(T0_S + 3.0, 255)
    assert ev.to_record() == {
        "t_s": T0_S + 3.0,
        "event": "prosecution_end",
        "sysid": SYSID,
        "alert_id": "1-1",
        "outcome": "cancelled",
        "by_sysid": 255,
        "planned_time_s": round(pros.away.planned_time_s, 3),
    }


def fly(plan: Plan, pos_m: complex, heading_rad: float, dt_s: float = 0.05) -> complex:
    """Fly ``plan``'s segments through the particle model (exact arcs); the end position."""
    params = ParticleParams(P.airspeed_m_s, MAX_U)
    for seg in plan.segments:
        left = seg.duration_s
        while left > 1e-12:
            h = min(dt_s, left)
            pos_m, heading_rad = step_one(
                pos_m, heading_rad, seg.turn_rate_rad_s, params, P.wind.vector, h
            )
            left -= h
    return pos_m


@pytest.mark.parametrize("seed", range(12))
def test_the_intercept_flown_meets_the_moving_intruder_within_the_sensor(seed: int):
    """A walker or a car anywhere near the loop, any start on the loop: flown through the
    particle model, the intercept ends within the footprint of the intruder's true place."""
    rng = np.random.default_rng(seed)
    pos, heading = on_loop(float(rng.uniform(0, 2 * math.pi)))
    where = complex(P.point_at_phase(float(rng.uniform(0, 2 * math.pi))))
    where += complex(*rng.uniform(-150.0, 150.0, 2))
    speed = float(rng.uniform(0.5, 10.0))
    vel = speed * complex(math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a))
    truth = Track(T0_S, where, vel, 0.0, 0.0, 10)
    assert is_moving(truth)
    plan = intercept(P, pos, heading, truth, T0_S, MAX_U, along_loop=False)
    assert isinstance(plan, Plan)
    end = fly(plan, pos, heading)
    assert abs(end - truth.predict(T0_S + plan.time_s)) < 0.2 * R_S


def test_a_still_track_is_flown_along_the_loop_and_a_noisy_still_one_is_not_moving():
    assert not is_moving(Track(0.0, 0j, 0.2 + 0.1j, 2.0, 0.1, 20))  # slow: a still intruder
    assert not is_moving(Track(0.0, 0j, 1.0 + 0j, 2.0, 0.5, 5))  # within three sigma
    assert is_moving(Track(0.0, 0j, 1.5 + 0j, 2.0, 0.3, 25))


def test_the_search_spiral_covers_the_predicted_region_as_it_grows():
    """The spiral's waypoints, in the track's moving frame, move out one swath a turn and
    stay round the prediction; the search is done once its footprint reaches three sigma.
    (The spiral alone: a moving track is searched along its road first,
    ``tests/test_search_road.py``.)"""
    track = Track(0.0, 1000 + 500j, 1.0 + 1.0j, 5.0, 0.5, 10)
    s = Search(track, t0_s=0.0, sensor_m=R_S, turn_radius_m=64.0, max_s=600.0, road=False)
    radii = [s.radius_m(k) for k in range(40)]
    assert radii[0] == pytest.approx(R_S) and all(b > a for a, b in itertools.pairwise(radii))
    for k in range(40):
        off = s.waypoint_m(30.0, k) - track.predict(30.0)
        assert abs(off) == pytest.approx(radii[k], rel=1e-9)
    # done when the flown spiral plus the footprint reaches three sigma, not before
    t = 40.0
    need = SEARCH_SIGMAS * track.sigma_m(t)
    s.k = next(k for k in range(1, 40) if radii[k - 1] + R_S >= need)
    assert s.finished(t) == "covered"
    s.k -= 1
    assert s.finished(t) is None
    assert s.finished(600.0) in ("covered", "time")


LOOP_U = 0.0123  # a turn rate no path would give: the one the Agent passes for the loop


@pytest.mark.parametrize("ahead_rad", [0.3, 1.0])
def test_a_still_site_within_the_sensors_reach_of_the_loop_is_checked_from_the_loop(ahead_rad):
    """A decoy 20 m outside the loop (r_s 50 m), ahead: the prosecutor stays on the loop,
    flying the turn rate it is given, until it has passed the site's loop point, with its
    sensor over the site on the way; then cleared with no search (a still, well-seen site).
    Its plan is the loop's time to there, and the quickest path's time is logged beside it."""
    site = outside_site(ahead_rad, out_m=20.0)
    pos, heading = on_loop(0.0)
    pros = prosecution(site)
    (plan,) = pros.start(T0_S, pos, heading, still(site))
    # the loop point nearest the site, by brute force over 20 000 phases, at T / 2 pi
    grid = np.linspace(0.0, 2 * math.pi, 20_001)
    nearest = grid[np.argmin(np.abs(P.point_at_phase(grid) - site))]
    off_m = float(np.min(np.abs(P.point_at_phase(grid) - site)))  # about 19 m
    loop_s = nearest * P.period_s / (2 * math.pi)
    assert plan.path_type == "loop" and plan.planned_time_s == pytest.approx(loop_s, rel=0.02)
    assert plan.quickest_time_s is not None and loop_s <= 1.2 * plan.quickest_time_s
    covered, u, t = False, LOOP_U, T0_S
    for psi in np.linspace(0.0, nearest + 0.05, 200):
        pos, heading = on_loop(float(psi))
        t = T0_S + float(psi) * P.period_s / (2 * math.pi)
        u, events, began = pros.step(t, pos, heading, still(site), T0_S, LOOP_U)
        covered = covered or any(isinstance(e, SiteCovered) for e in events)
        assert not began
        if u is None:
            break
        assert u == LOOP_U and abs(pos - site) >= off_m - 0.01  # on the loop, never nearer
    assert covered and u is None and psi >= nearest
    (end,) = pros.end(t, None, T0_S, "cleared")
    assert end.search_end is None and end.searched_s is None


@pytest.mark.parametrize(
    ("track", "why"),
    [
        (Track(T0_S, outside_site(1.0, 45.0), 0j, 2.0, 0.05, 20), "farther than 0.8 r_s"),
        (Track(T0_S, outside_site(1.0, 20.0), 3.0 + 0j, 1.0, 0.1, 20), "moving"),
        (Track(T0_S, outside_site(-0.5, 20.0), 0j, 2.0, 0.05, 20), "behind: most of a loop"),
    ],
)
def test_a_site_the_loop_does_not_check_soon_enough_is_intercepted(track, why):
    pos, heading = on_loop(0.0)
    pros = prosecution(track.pos_m)
    (plan,) = pros.start(T0_S, pos, heading, track)
    assert plan.path_type != "loop" and plan.quickest_time_s is None, why
    u, _, _ = pros.step(T0_S + 0.1, pos, heading, track, T0_S, LOOP_U)
    assert u != LOOP_U, why


def test_a_mover_no_path_reaches_is_lost_not_cleared():
    """Generated mission 0 (``bench/alerts.py --kinds paths-all``): a vehicle's first
    sighting, a point near the loop ahead, is checked from the loop; its next track drives
    away at 13.7 m/s into the wind of an 18 m/s UAV, and the intercept has no path. The
    prosecution ended at once as if its path were flown: "cleared", nothing looked at. It
    is outpaced: "lost"."""
    pos, heading = on_loop(0.0)
    site = outside_site(0.3, out_m=20.0)
    pros = prosecution(site)
    (plan,) = pros.start(T0_S, pos, heading, still(site))
    assert plan.path_type == "loop"
    away_dir = (site - pos) / abs(site - pos)
    runner = Track(T0_S + 1.0, site, 1.5 * P.airspeed_m_s * away_dir, 2.0, 0.3, 30)
    assert is_moving(runner)
    u, _, began = pros.step(T0_S + 1.0, pos, heading, runner, T0_S, LOOP_U)
    assert pros.away.plan is None and u is None and not began
    assert not pros.region_checked(T0_S + 1.0) and pros.not_found(T0_S + 1.0) == "lost"
    (end,) = pros.end(T0_S + 1.0, None, T0_S, pros.not_found(T0_S + 1.0))
    assert (end.outcome, end.search_end) == ("lost", "outpaced_at_start")


FENCE = MISSION.fence.fence if MISSION.fence is not None else None
FENCED = Prosecution(
    sysid=SYSID, max_u=MAX_U, sensor_m=R_S, replan_s=1.0, hold_s=HOLD_S, fence=FENCE
)


def test_an_intercept_that_meets_its_vehicle_beyond_the_fence_is_not_flown():
    """Generated mission 28 on loops up to 25 km flew a 714 s intercept of a 15 m/s vehicle
    driving out of the base and was 9.6 km from the loop at the end of the run. A moving
    intruder met beyond the fence (or within a turn of its edge) leaves the defended region
    first, as a tracker stops there: nothing is flown, and the end says why ("lost", not
    "cleared": nothing was looked at). Driving in, the same vehicle is intercepted."""
    assert FENCE is not None
    pos, heading = on_loop(0.0)
    site = outside_site(math.pi / 2, 100.0)
    out = (site - P.centre_m) / abs(site - P.centre_m)
    leaving = Track(T0_S, site, 12.0 * out, 2.0, 0.3, 20)
    away = Prosecuting("1-1", site, VirtualParticle(0.0, T0_S, P.period_s), search_max_s=60.0)
    fix = at(T0_S, pos, heading)
    plan = intercept(P, pos, heading, leaving, T0_S, MAX_U, False)
    assert isinstance(plan, Plan)
    # independently of the fence's test: where the vehicle is when the plan ends lies
    # farther from the loop than any vertex of the fence
    meet = site + leaving.vel_m_s * plan.time_s
    fence_reach = max(float(P.nearest(v).distance_m) for v in FENCE.polygon_m)
    assert float(P.nearest(meet).distance_m) > fence_reach
    (ev,) = FENCED.start(away, fix, leaving)
    assert isinstance(ev, PlanFailed) and "outside the fence" in ev.reason
    assert away.plan is None and away.left_fence
    u, events, search = FENCED.step(away, fix, leaving, T0_S)
    assert (u, events, search) == (None, [], None)  # said once, at the plan
    assert FENCED.not_found(away, T0_S) == "lost"
    (end,) = FENCED.end(away, T0_S, None, T0_S, "lost")
    assert (end.outcome, end.search_end, end.searched_s) == ("lost", "left_fence", None)
    # the same vehicle driving in: met inside, flown
    coming = Track(T0_S, site, -12.0 * out, 2.0, 0.3, 20)
    away = Prosecuting("1-2", site, VirtualParticle(0.0, T0_S, P.period_s), search_max_s=60.0)
    (ev,) = FENCED.start(away, fix, coming)
    assert isinstance(ev, PlanMade) and away.plan is not None and not away.left_fence
    assert bool(FENCE.contains(coming.predict(T0_S + away.plan.time_s)))
