"""Search along the road (issue 47): a moving intruder not where predicted is looked for on
its predicted paths before the spiral. Flown here by an ideal aircraft (straight at its
airspeed to the current waypoint, no turn radius) against truths made by kinematics: a
vehicle that turned 90 deg at a junction at any time since it was seen, one that stopped
anywhere on its way, one on a quarter-turn arc."""

from __future__ import annotations

import cmath
import math
from pathlib import Path

import pytest

from companion.agent.alerts.search import Search
from companion.group.messages import Track

SENSOR_M = 40.0
AIRSPEED = 22.0
V = 10.0 + 0j  # north at 10 m/s
AGE_S = 10.0  # the track's age when the search begins
DT = 0.2


def junction(side: float, tau: float):
    """Turned 90 deg (side +1: towards east) ``tau`` s after the sighting at p0 = 0."""
    return lambda t: V * min(t, tau) + V * 1j * side * max(0.0, t - tau)


def stopped(tau: float):
    return lambda t: V * min(t, tau)


def arc(side: float):
    w = side * (math.pi / 2) / 20.0  # a quarter turn in 20 s
    return lambda t: V * (cmath.exp(1j * w * t) - 1.0) / (1j * w)


def found(truth, road: bool, max_s: float = 60.0, age_s: float = AGE_S) -> bool:
    track = Track(0.0, 0j, V, 3.0, 0.5, 20, manoeuvre_m_s2=1.0)
    t = age_s
    search = Search(track, t, SENSOR_M, 0.0, max_s, AIRSPEED, road=road)
    uav = track.predict(t)  # the intercept flew to the prediction and saw nothing there
    while search.finished(t) is None:
        if abs(uav - truth(t)) <= SENSOR_M:
            return True
        wp = search.waypoint_m(t)
        if abs(uav - wp) <= 0.5 * SENSOR_M:
            search.k += 1
            continue
        step = AIRSPEED * DT
        uav += (wp - uav) / abs(wp - uav) * min(step, abs(wp - uav))
        t += DT
    return False


TRUTHS = (
    [(f"junction {'right' if s > 0 else 'left'} at {tau:.0f} s", junction(s, tau))
     for s in (1.0, -1.0) for tau in (0.0, 3.0, 6.0, 9.0, 12.0)]
    + [(f"stopped at {tau:.0f} s", stopped(tau)) for tau in (0.0, 4.0, 8.0, 12.0)]
    + [(f"arc {'right' if s > 0 else 'left'}", arc(s)) for s in (1.0, -1.0)]
)  # fmt: skip


@pytest.mark.parametrize(("name", "truth"), TRUTHS, ids=[n for n, _ in TRUTHS])
def test_the_road_search_finds_a_vehicle_on_any_of_its_predicted_paths(name, truth):
    assert abs(truth(0.0)) < 1e-9
    assert found(truth, road=True), name


def test_the_spiral_alone_misses_most_of_them():
    missed = [n for n, truth in TRUTHS if not found(truth, road=False)]
    assert len(missed) >= len(TRUTHS) // 2, missed


def test_from_an_older_track_the_road_still_finds_more_than_the_spiral():
    # 15 s old: the paths spread faster than a 22 m/s sensor can sweep them all
    road = sum(found(truth, road=True, age_s=15.0) for _, truth in TRUTHS)
    spiral = sum(found(truth, road=False, age_s=15.0) for _, truth in TRUTHS)
    assert road >= 0.6 * len(TRUTHS) and road > spiral


def test_the_road_turns_first_to_the_side_the_turn_model_turns():
    left = Track(0.0, 0j, V, 3.0, 0.5, 20, "turn", 0.8, -0.1, 1.0)
    right = Track(0.0, 0j, V, 3.0, 0.5, 20, "turn", 0.8, 0.1, 1.0)
    wl = Search(left, 10.0, SENSOR_M, 0.0).waypoint_m(10.0)
    wr = Search(right, 10.0, SENSOR_M, 0.0).waypoint_m(10.0)
    assert wl.imag < 0.0 < wr.imag  # west of the heading north, and east


def test_a_still_track_is_searched_by_the_spiral_alone():
    still = Track(0.0, 0j, 0.2 + 0j, 3.0, 0.5, 20)
    assert Search(still, 10.0, SENSOR_M, 50.0).road_points == 0
    moving = Track(0.0, 0j, V, 3.0, 0.5, 20)
    s = Search(moving, 10.0, SENSOR_M, 50.0)
    assert s.road_points > 0 and s.finished(10.0) is None and not s.outpaced(10.0)
    s.k = s.road_points  # the road flown: then the spiral, bounded as before
    assert s.finished(10.0 + 61.0) in ("time", "outpaced", "covered")


def test_the_prosecutor_flies_first_the_road_point_it_reaches_soonest():
    # a fixed order is not flyable by a turn-rate-limited aircraft through points a turn
    # diameter apart: the prosecutor picks, of the points not flown, the soonest reached
    from companion.agent.alerts.prosecution import Prosecution
    from companion.agent.away import Prosecuting, Searching
    from companion.agent.fix import Fix
    from companion.guidance.virtual import VirtualParticle
    from companion.mission import load_mission

    mission = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
    patrol = mission.patrol
    pros = Prosecution(sysid=1, max_u=0.3, sensor_m=SENSOR_M, replan_s=1.0, hold_s=0.1)
    track = Track(0.0, 0j, V, 3.0, 0.5, 20, manoeuvre_m_s2=1.0)
    for side in (1.0, -1.0):
        search = Search(track, AGE_S, SENSOR_M, 70.0, 60.0, AIRSPEED)
        away = Searching.begin(
            Prosecuting("1-1", 0j, VirtualParticle(0.0, 0.0, patrol.period_s), 60.0), search
        )
        # the UAV beyond the prediction on one side, flying that way
        pos = track.predict(AGE_S) + side * 1j * 80.0
        fix = Fix(AGE_S, pos, math.pi / 2 if side > 0 else -math.pi / 2, patrol)
        assert pros.search_step(away, fix) is not None
        wp = search.waypoint_m(AGE_S)
        assert search.order and wp.imag * side > 0, (side, wp)  # its own side first
    with pytest.raises(ValueError):
        search.pick(search.order[0])  # a point picked twice
