"""Model-free measures (cross-track, coverage revisit, longest unseen, time within bounds).

The expected figures come from the geometry of synthetic tracks (a circle flown at constant
speed, so pass times and sensor chords are known in closed form) and from brute-force
loops, never from the functions under test.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.events import AlertNew, AlertTasked, LoopFlyable, LoopInfeasible, Rejoined
from companion.mission import load_mission
from companion.report.coverage import (
    UNSEEN_BOUND_RATIO,
    XT_BOUND_M,
    LiveCoverage,
    Polyline,
    loop_points,
    max_unseen_age_s,
    patrol_measures,
    sensor_passes,
)
from companion.report.metrics import (
    alert_answers,
    loop_geometry,
    loop_infeasible_s,
    reference_patrol,
)
from companion.report.rundata import RunData, Track
from tests.test_report import CIRCLE_MISSION  # the same 4-UAV circle mission

ROOT = Path(__file__).resolve().parents[1]
R, S0, N, RS = 300.0, 20.0, 4, 40.0  # circle radius, speed, UAVs, sensor radius
T = 2 * math.pi * R / S0
IDEAL = T / N
DT = 0.1
TIMES = np.round(np.arange(0.0, 600.0 + 1e-9, DT), 3)
# a point is covered while an aircraft on the circle is within RS of it: a chord of the circle
COVER_S = 2 * (2 * math.asin(RS / (2 * R))) * R / S0
POINTS = R * np.exp(1j * 2 * np.pi * np.arange(188) / 188)  # every ~10 m on the circle
CIRCLE = Polyline.of(R * np.exp(1j * 2 * np.pi * np.arange(1885) / 1885))  # every ~1 m


def circle_tracks(radius_m: float = R, n: int = N) -> np.ndarray:
    """(n, S) positions of n UAVs in perfect time splay on a circle (clockwise)."""
    k = np.arange(n)[:, None]
    gamma = 2 * np.pi * (TIMES[None, :] / T - k / N)
    return radius_m * np.exp(1j * (gamma - np.pi / 2))


def measures(pos, away=None, episodes=()):
    away = np.zeros(pos.shape, dtype=bool) if away is None else away
    return patrol_measures(TIMES, pos, away, POINTS, CIRCLE, RS, IDEAL, T, episodes)


def test_polyline_distance_matches_patrol_nearest_on_random_points():
    rng = np.random.default_rng(1)
    for name in ("ellipse_6uav.yaml", "wpafb_4uav.yaml"):
        patrol = load_mission(ROOT / "missions" / name).patrol
        _, poly = loop_geometry(patrol)
        on = patrol.point_at_phase(rng.uniform(0, 2 * np.pi, 60))
        off = rng.normal(0, 1, 60) * rng.choice([1.0, 30.0, 300.0], 60)
        pts = on + off * np.exp(1j * rng.uniform(0, 2 * np.pi, 60))
        got = poly.distance_m(pts)
        want = np.array([patrol.nearest(complex(p)).distance_m for p in pts])
        assert got == pytest.approx(want, abs=5e-3), name


def test_loop_points_are_evenly_spaced_on_the_ellipse():
    m = load_mission(ROOT / "missions" / "ellipse_6uav.yaml")
    patrol = m.patrol
    pts = loop_points(patrol.point_at_phase, patrol.length_m, 10.0)
    a, b = 400.0, 200.0  # semi-axes along North and East, centred on the origin
    z = pts - patrol.centre_m
    assert (z.real / a) ** 2 + (z.imag / b) ** 2 == pytest.approx(np.ones(pts.size), abs=1e-6)
    steps = np.abs(np.diff(np.append(pts, pts[0])))
    assert pts.size == math.ceil(patrol.length_m / 10.0)
    assert steps == pytest.approx(np.full(pts.size, patrol.length_m / pts.size), rel=2e-3)


def test_a_perfect_splay_on_the_loop_reads_revisit_one_and_no_cross_track():
    m = measures(circle_tracks())
    assert m.cross_track_max_m < 2e-3
    assert m.settled and m.settle_time_s == 0.0 and m.window_start_s == pytest.approx(T, abs=DT)
    assert m.coverage_revisit_ratio == pytest.approx(1.0, abs=1.01 * DT / IDEAL)
    assert m.mean_pass_interval_s == pytest.approx(IDEAL, abs=DT)
    assert m.longest_unseen_s == pytest.approx(IDEAL - COVER_S, abs=2.01 * DT)
    assert m.fraction_within_bounds == 1.0 and m.fraction_within_bounds_excl_alerts == 1.0
    assert m.points_never_seen_in_window == 0 and m.coverage_points == POINTS.size


def test_one_uav_missing_doubles_the_worst_interval():
    m = measures(circle_tracks()[:3])  # N = 4 UAVs planned, three fly
    assert m.coverage_revisit_ratio == pytest.approx(2.0, abs=1.01 * DT / IDEAL)
    assert m.longest_unseen_s == pytest.approx(2 * IDEAL - COVER_S, abs=2.01 * DT)
    assert 2 * IDEAL - COVER_S > UNSEEN_BOUND_RATIO * IDEAL  # so never within bounds:
    assert m.fraction_within_bounds == 0.0 and not m.settled
    assert m.window_start_s == pytest.approx(300.0)  # the second half of the run


def test_a_constant_offset_is_the_cross_track():
    m = measures(circle_tracks(R + 20.0))
    for v in (m.cross_track_median_m, m.cross_track_p95_m, m.cross_track_max_m):
        assert v == pytest.approx(20.0, abs=2e-3)
    assert m.fraction_within_bounds == 0.0  # 20 m > the 10 m bound
    assert m.coverage_revisit_ratio == pytest.approx(1.0, abs=1.01 * DT / IDEAL)  # 20 < RS


def test_points_never_seen_are_unseen_since_the_log_began():
    m = measures(circle_tracks(R + 100.0))  # the sensor discs (40 m) never reach the loop
    assert m.points_never_seen_in_window == POINTS.size
    assert m.longest_unseen_s == pytest.approx(TIMES[-1] - TIMES[0])
    assert m.coverage_revisit_ratio is None


def test_one_spike_costs_its_share_of_the_window_not_the_headline():
    pos = circle_tracks()
    spike = (TIMES >= 400.0) & (TIMES < 402.0)
    pos[1, spike] *= (R + 30.0) / R  # 30 m outward for 2 s
    m = measures(pos)
    window = m.window_start_s <= TIMES
    assert m.settled and m.cross_track_max_m == pytest.approx(30.0, abs=2e-3)
    assert m.cross_track_median_m < 2e-3
    assert m.fraction_within_bounds == pytest.approx(1 - spike.sum() / window.sum())
    assert spike.sum() == 20 and XT_BOUND_M < 30.0


def test_alert_episodes_are_reported_both_ways():
    pos = circle_tracks()
    gone = (TIMES >= 300.0) & (TIMES <= 360.0)  # UAV 4 prosecutes, far from the loop
    pos[3, gone] = 5000.0
    away = np.zeros(pos.shape, dtype=bool)
    away[3] = gone
    m = measures(pos, away, [(300.0, 360.0)])
    assert m.cross_track_max_m < 2e-3  # the prosecutor's own distance is not counted
    assert m.coverage_revisit_ratio == pytest.approx(2.0, abs=1.01 * DT / IDEAL)
    assert m.coverage_revisit_ratio_excl_alerts == pytest.approx(1.0, abs=1.01 * DT / IDEAL)
    assert m.longest_unseen_s == pytest.approx(2 * IDEAL - COVER_S, abs=2.01 * DT)
    assert m.longest_unseen_excl_alerts_s == pytest.approx(IDEAL - COVER_S, abs=2.01 * DT)
    assert m.fraction_within_bounds < 1.0 and m.fraction_within_bounds_excl_alerts == 1.0


def test_sensor_passes_against_a_brute_force_coverage_matrix():
    rng = np.random.default_rng(7)
    pts = rng.uniform(-100, 100, 15) + 1j * rng.uniform(-100, 100, 15)
    walk = np.cumsum(rng.normal(0, 8, (3, 400)) + 1j * rng.normal(0, 8, (3, 400)), axis=1)
    passes = sensor_passes(pts, walk, 30.0)
    covered = (np.abs(pts[:, None, None] - walk[None, :, :]) <= 30.0).any(axis=1)
    runs = []
    for p, row in enumerate(covered):
        s = None
        for i, c in enumerate(row):
            if c and s is None:
                s = i
            if not c and s is not None:
                runs.append((p, s, i - 1))
                s = None
        if s is not None:
            runs.append((p, s, row.size - 1))
    assert list(zip(passes.point, passes.start, passes.end, strict=True)) == runs
    assert len(runs) > 20


def test_max_unseen_age_against_brute_force():
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 100, 40)
    b = a + rng.exponential(10, 40)
    b[:3] = np.inf
    t = np.linspace(0, 120, 601)
    want = [max([ti - ai for ai, bi in zip(a, b, strict=True) if ai <= ti < bi] or [0]) for ti in t]
    assert max_unseen_age_s(t, a, b) == pytest.approx(np.array(want))


def test_live_coverage_follows_the_samples():
    pos = circle_tracks()
    live = LiveCoverage(POINTS, CIRCLE, RS)
    for j in range(0, TIMES.size, 37):  # uneven batches of samples, in time order
        sl = slice(j, j + 37)
        t = np.repeat(TIMES[sl], N)
        live.update(t, np.tile(np.arange(1, N + 1), TIMES[sl].size), pos[:, sl].T.ravel())
    assert set(live.cross_track_m) == {1, 2, 3, 4}
    assert max(live.cross_track_m.values()) < 2e-3
    covered = (np.abs(POINTS[:, None, None] - pos[None]) <= RS).any(axis=1)
    last = np.array([TIMES[np.flatnonzero(row)[-1]] for row in covered])
    assert live.longest_unseen_now_s() == pytest.approx(TIMES[-1] - last.min())


def test_alert_answered_by_one_or_by_two(tmp_path):
    mission = load_mission(ROOT / "missions" / "ellipse_6uav.yaml")
    track = Track(1, TIMES, np.zeros(TIMES.size, complex), np.zeros(TIMES.size), np.array([]))

    def tasked(sysid, t):
        ev = AlertTasked(t_s=t, sysid=sysid, alert_id="a", prosecutor_sysid=sysid, policy="next")
        return ev.to_record()

    def back(sysid, t):
        return Rejoined(t_s=t, sysid=sysid, alert_id="a", in_slot=True, rejoin_s=1.0).to_record()

    def new(alert_id):
        site = {"north_m": 0.0, "east_m": 0.0}
        return AlertNew(t_s=9.0, sysid=5, alert_id=alert_id, detector_sysid=5, own=True, **site)

    raised, other = new("a").to_record(), new("b").to_record()
    one = RunData(tmp_path, mission, {1: track}, [raised, tasked(2, 10), back(2, 40)])
    handed_on = [raised, tasked(2, 10), back(2, 40), tasked(3, 41), back(3, 60)]
    two = [raised, tasked(2, 10), tasked(3, 20), back(2, 40), back(3, 50), other]
    assert alert_answers(one)["alerts_not_answered_by_one"] == []
    assert alert_answers(RunData(tmp_path, mission, {1: track}, handed_on)) == {
        "alerts_raised": 1,
        "alerts_answered_by_one": 1,
        "alerts_not_answered_by_one": [],
    }
    assert alert_answers(RunData(tmp_path, mission, {1: track}, two)) == {
        "alerts_raised": 2,
        "alerts_answered_by_one": 0,
        "alerts_not_answered_by_one": ["a", "b"],
    }


def test_the_reference_period_is_the_loop_timed_in_the_true_wind(tmp_path):
    from scipy.special import ellipe

    (tmp_path / "m.yaml").write_text(CIRCLE_MISSION)
    mission = load_mission(tmp_path / "m.yaml")
    beta = 8.0
    # a circle of radius R at airspeed s0 in a wind beta takes T = R / (s0^2 - beta^2) *
    # int_0^2pi sqrt(s0^2 - beta^2 sin^2) = 4 R s0 E(m = beta^2 / s0^2) / (s0^2 - beta^2)
    want = 4 * R * S0 * ellipe((beta / S0) ** 2) / (S0**2 - beta**2)
    zeros = np.zeros(TIMES.size)
    wind = np.where(TIMES < 300.0, 3.0, beta * np.exp(1j * np.radians(45.0)))  # from 225
    windy = Track(1, TIMES, zeros.astype(complex), zeros, np.array([]), wind)
    ref, rule = reference_patrol(RunData(tmp_path, mission, {1: windy}, []))
    assert ref.period_s == pytest.approx(want, rel=1e-6) and rule.startswith("true wind")
    assert ref.wind.speed_m_s == pytest.approx(beta)  # the mean over the second half
    still = Track(1, TIMES, zeros.astype(complex), zeros, np.array([]))
    ref, rule = reference_patrol(RunData(tmp_path, mission, {1: still}, []))
    assert ref.period_s == pytest.approx(2 * math.pi * R / S0) and rule.startswith("mission")


def test_time_the_loop_was_unflyable_is_counted_from_the_lowest_sysid(tmp_path):
    mission = load_mission(ROOT / "missions" / "ellipse_6uav.yaml")
    track = Track(1, TIMES, np.zeros(TIMES.size, complex), np.zeros(TIMES.size), np.array([]))

    def said(name, sysid, t):
        kind = LoopInfeasible if name == "infeasible" else LoopFlyable
        wind = {"wind_speed_m_s": 30.0, "wind_from_deg": 0.0}
        return kind(t_s=t, sysid=sysid, need_deg_s=20.0, limit_deg_s=15.0, **wind).to_record()

    evs = [
        said("infeasible", 2, 100.0), said("infeasible", 3, 100.1), said("flyable", 2, 160.0),
        said("flyable", 3, 150.0), said("infeasible", 2, 300.0), {"event": "other", "t_s": 1.0},
    ]  # fmt: skip
    run = RunData(tmp_path, mission, {1: track}, evs)
    assert loop_infeasible_s(run, 400.0) == pytest.approx(60.0 + 100.0)  # still at the end
    assert loop_infeasible_s(RunData(tmp_path, mission, {1: track}, []), 400.0) == 0.0
