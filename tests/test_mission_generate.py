"""The seeded mission generator (companion/mission/generate.py).

Every check reads the mission back through the loader (``parse_mission``, the product's one
way in) and measures it there: the loop's length and period on the loaded Patrol, the start
poses against the loop's points and tangents, the intruders' true paths against a dense
polyline of the loop. Nothing is taken from the generator's own arithmetic but the metadata
it promises, which is compared with the loaded mission.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from companion.core.fence import point_in_polygon
from companion.mission import parse_mission
from companion.mission.generate import PATH_KINDS, SCENARIO_KINDS, STRAIGHT_KINDS, generate
from companion.mission.generate_paths import BACK_TURN_DEG, STOP_S, TURN_DEG, TURNING_M_S
from companion.mission.model import WaypointPerimeter

SEEDS = range(200)


@pytest.fixture(scope="module")
def sample():
    """(generated, loaded) for 200 seeds: every one must parse."""
    out = []
    for seed in SEEDS:
        g = generate(seed)
        out.append((g, parse_mission(g.text, f"{g.name}.yaml")))
    return out


def loop_polyline(m, count: int = 4096) -> np.ndarray:
    """Points of the loaded loop (complex m), in order, for brute-force distances."""
    return m.patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, count, endpoint=False))


def distance_to_loop_m(m, points: np.ndarray, count: int = 4096) -> np.ndarray:
    """Brute force: each point's distance (m) to the nearest segment of a polyline of
    ``count`` points of the loop (chords of at most 25 km / 4096 = 6 m: within 7 cm of the
    loop on a corner of 70 m)."""
    a = loop_polyline(m, count)
    d = np.roll(a, -1) - a
    out = []
    for chunk in np.array_split(points, max(1, points.size // 256)):
        q = chunk[:, None] - a[None, :]
        u = np.clip((np.conj(d) * q).real / np.abs(d) ** 2, 0.0, 1.0)
        out.append(np.min(np.abs(q - u * d), axis=1))
    return np.concatenate(out)


def test_the_same_seed_gives_the_same_text_and_another_seed_another():
    a, b = generate(7), generate(7)
    assert a.text == b.text and a == b
    assert generate(8).text != a.text
    assert generate(7, kind="vehicle", max_loop_km=3.0) == generate(
        7, kind="vehicle", max_loop_km=3.0
    )


def test_the_scenario_family_changes_only_the_scenario():
    def base(text: str) -> str:  # origin, perimeter, wind, vehicles, sensor
        return text[text.index("origin:") : text.index("scenario:")]

    texts = [generate(11, kind=kind).text for kind in SCENARIO_KINDS]
    assert len({base(t) for t in texts}) == 1
    assert len({t[t.index("scenario:") :] for t in texts}) == len(SCENARIO_KINDS)


@pytest.mark.slow
def test_two_hundred_seeds_parse_and_keep_their_bounds(sample):
    kinds, senses, geo = Counter(), Counter(), Counter()
    yaml_kinds = Counter()
    for g, m in sample:
        shape = m.perimeter.shape
        assert isinstance(shape, WaypointPerimeter)
        assert 3 <= len(shape.waypoints) <= 9 and len(shape.waypoints) == g.waypoints
        assert 1000.0 <= m.patrol.length_m <= 25_000.0
        assert m.patrol.length_m == pytest.approx(g.loop_length_m, rel=1e-9)
        assert m.patrol.period_s == pytest.approx(g.period_s, rel=1e-9)
        assert 3 <= m.vehicles.count <= 12 and m.vehicles.count == g.vehicles
        assert 18.0 <= m.vehicles.airspeed_m_s <= 25.0
        assert m.wind.speed_m_s <= 0.5 * m.vehicles.airspeed_m_s
        assert 40.0 <= m.sensor.footprint_radius_m <= 60.0
        assert m.name == g.name and m.duration_s == g.duration_s
        kinds[g.kind] += 1
        senses[m.perimeter.clockwise] += 1
        geo[shape.waypoints[0].lat_deg is not None] += 1
        yaml_kinds.update(it.kind for it in m.intruders)
    assert set(kinds) == set(STRAIGHT_KINDS)  # a seed alone draws a straight-line family
    assert set(senses) == {True, False} and set(geo) == {True, False}
    assert set(yaml_kinds) == {"static", "moving", "decoy"}
    winds = [m.wind.speed_m_s / m.vehicles.airspeed_m_s for _, m in sample]
    assert max(winds) > 0.4  # the range is used, not only light air
    lengths = [m.patrol.length_m for _, m in sample]
    assert min(lengths) < 2000.0 and max(lengths) > 15_000.0


@pytest.mark.slow
def test_every_intruder_comes_within_the_footprint_of_the_loop(sample):
    for g, m in sample:
        r_s = m.sensor.footprint_radius_m
        plans = {p.id: p for p in g.intruders}
        assert {it.id for it in m.intruders} == set(plans)
        for it in m.intruders:
            end = it.vanish_t_s if it.vanish_t_s is not None else it.appear_t_s
            t = np.arange(it.appear_t_s, end + 2.0, 2.0)  # steps of at most 20 m
            path = np.array([it.position_m(float(x)) for x in t])
            assert distance_to_loop_m(m, path).min() <= r_s, (g.seed, it.id)
            assert it.appear_t_s >= g.settle_s
            assert m.duration_s >= g.period_s * 1.5 + (it.vanish_t_s or it.appear_t_s)


@pytest.mark.slow
def test_walkers_and_vehicles_cross_the_loop_the_way_they_are_said_to(sample):
    speeds = {"walker": [], "vehicle": []}
    crossings = Counter()
    for g, m in sample:
        plans = {p.id: p for p in g.intruders}
        inside_poly = loop_polyline(m, 2048)
        for it in m.intruders:
            plan = plans[it.id]
            if it.kind != "moving":
                assert plan.role in ("static", "decoy") and it.velocity_m_s == 0
                continue
            speeds[plan.role].append(abs(it.velocity_m_s))
            ends = np.array([it.position_m(it.appear_t_s), it.position_m(it.vanish_t_s)])
            start_in, end_in = point_in_polygon(ends, inside_poly)
            assert (start_in, end_in) == (
                (False, True) if plan.crossing == "inward" else (True, False)
            )
            crossings[plan.crossing] += 1
    assert max(speeds["walker"]) <= 2.0 and min(speeds["walker"]) >= 0.5
    assert max(speeds["vehicle"]) <= 10.0 and min(speeds["vehicle"]) >= 3.0
    assert crossings["inward"] > 0 and crossings["outward"] > 0


@pytest.mark.slow
def test_the_uavs_start_in_time_splay_on_the_loop_heading_along_it(sample):
    for g, m in sample[:60]:
        patrol, n = m.patrol, m.vehicles.count
        starts = np.array([complex(p.north_m, p.east_m) for p in m.vehicles.initial])
        assert distance_to_loop_m(m, starts, 1 << 15).max() < 0.02  # on the loop, to 1 cm
        phases = np.array([patrol.phase_of_point(complex(z)) for z in starts])
        gaps = np.diff(np.unwrap(phases))
        assert gaps == pytest.approx(np.full(n - 1, 2 * np.pi / n), abs=1e-3)
        wind = m.wind.wind().vector
        for p, z in zip(m.vehicles.initial, starts, strict=True):
            theta = math.radians(p.heading_deg)
            v = m.vehicles.airspeed_m_s * complex(math.cos(theta), math.sin(theta)) + wind
            # the tangent from two loop points either side, in the sense of travel
            psi = patrol.phase_of_point(complex(z))
            ahead, behind = patrol.point_at_phase(np.array([psi + 1e-4, psi - 1e-4]))
            tangent = ahead - behind
            assert abs(np.angle(v / tangent)) < math.radians(0.05), (g.seed, p)


def test_the_keywords_choose_the_family_and_cap_the_loop():
    for seed in range(12):
        g = generate(seed, kind="walker", max_loop_km=3.0, vehicles=4)
        m = parse_mission(g.text)
        assert m.patrol.length_m <= 3000.0 and m.vehicles.count == 4
        assert [p.role for p in g.intruders] == ["walker"]
        assert [it.kind for it in m.intruders] == ["moving"]
    several = [generate(seed, kind="several", max_loop_km=2.0) for seed in range(6)]
    assert all(2 <= len(g.intruders) <= 3 for g in several)
    decoy = generate(3, kind="decoy", geodetic=True, max_loop_km=4.0)
    m = parse_mission(decoy.text)
    assert m.intruders[0].kind == "decoy" and m.intruders[0].vanish_after_detection_s > 0
    assert m.perimeter.shape.waypoints[0].lat_deg is not None
    assert decoy.metadata()["intruders"][0]["role"] == "decoy"


@pytest.mark.parametrize(
    "kw",
    [
        {"kind": "parachutist"},
        {"max_loop_km": 30.0},
        {"min_loop_km": 0.5},
        {"min_loop_km": 5.0, "max_loop_km": 3.0},
        {"vehicles": 2},
    ],
)
def test_a_bad_keyword_is_refused(kw):
    with pytest.raises(ValueError):
        generate(1, **kw)


# ---- intruders on paths ------------------------------------------------------------------------
PATH_SEEDS = range(12)


@pytest.fixture(scope="module")
def path_sample():
    """(generated, loaded) for every path family on 12 seeds (loops up to 25 km)."""
    return [
        (g, parse_mission(g.text, f"{g.name}.yaml"))
        for seed in PATH_SEEDS
        for g in (generate(seed, kind=kind) for kind in PATH_KINDS)
    ]


def knots(it) -> tuple[np.ndarray, np.ndarray]:
    """A path's points from where it appears (complex m), and its legs' speeds (m/s), read
    from the loaded legs."""
    pts = np.array([complex(it.north_m, it.east_m)] + [leg.point_m for leg in it.path])
    return pts, np.array([leg.speed_m_s for leg in it.path])


def turns_deg(pts: np.ndarray) -> np.ndarray:
    """The turn at each inner point of a polyline (deg, signed)."""
    d = np.diff(pts)
    return np.degrees(np.angle(d[1:] / d[:-1]))


def test_path_families_give_path_intruders_that_cross_the_loop_as_said(path_sample):
    roles = Counter()
    for g, m in path_sample:
        plans = {p.id: p for p in g.intruders}
        loop = loop_polyline(m, 2048)
        r_s = m.sensor.footprint_radius_m
        for it in m.intruders:
            plan = plans[it.id]
            roles[plan.role] += 1
            assert it.kind == "path" and plan.legs == len(it.path) >= 1
            assert it.vanish_t_s == plan.vanish_t_s and it.vanish_t_s > it.path_end_t_s
            t = np.arange(it.appear_t_s, it.path_end_t_s, 1.0)
            inside = point_in_polygon(it.positions_m(t), loop)
            ends = point_in_polygon(it.positions_m(np.array([it.appear_t_s, it.vanish_t_s])), loop)
            want = {"inward": (False, True), "outward": (True, False),
                    "in_and_out": (False, False)}[plan.crossing]  # fmt: skip
            assert tuple(ends) == want, (g.seed, it.id)
            flips = int(np.count_nonzero(inside[1:] != inside[:-1]))
            assert flips == (2 if plan.crossing == "in_and_out" else 1), (g.seed, it.id)
            assert distance_to_loop_m(m, it.positions_m(t)).min() <= r_s
            # it starts and ends clear of the band: each crossing is a whole one
            ends_m = it.positions_m(np.array([it.appear_t_s, it.path_end_t_s]))
            assert distance_to_loop_m(m, ends_m).min() > 1.2 * r_s - 0.1, (g.seed, it.id)
            assert it.appear_t_s >= g.settle_s and m.duration_s >= it.vanish_t_s
            assert plan.speed_m_s == pytest.approx(it.max_speed_m_s, abs=1e-3)
    assert set(roles) == {"turning_vehicle", "stop_and_go", "crosses_back"}


def test_turning_vehicles_turn_30_to_120_deg_at_5_to_15_m_s(path_sample):
    seen = 0
    for g, m in path_sample:
        plans = {p.id: p for p in g.intruders}
        for it in m.intruders:
            if plans[it.id].role != "turning_vehicle":
                continue
            pts, speeds = knots(it)
            turns = np.abs(turns_deg(pts))
            assert turns.size >= 1 and all(leg.wait_s == 0 for leg in it.path)
            assert turns.min() >= TURN_DEG[0] - 0.1 and turns.max() <= TURN_DEG[1] + 0.1
            assert speeds.min() >= TURNING_M_S[0] and speeds.max() <= TURNING_M_S[1]
            seen += 1
    assert seen >= 12


def test_stop_and_go_walkers_stop_and_walk_slowly(path_sample):
    stops = []
    for g, m in path_sample:
        plans = {p.id: p for p in g.intruders}
        for it in m.intruders:
            if plans[it.id].role != "stop_and_go":
                continue
            _, speeds = knots(it)
            waits = [leg.wait_s for leg in it.path if leg.wait_s > 0]
            assert 1 <= len(waits) <= 4 and speeds.min() >= 0.5 and speeds.max() <= 2.0
            assert min(waits) >= STOP_S[0] and max(waits) <= STOP_S[1]
            # while it waits it is still (the loaded intruder, half-way through each stop)
            times, points = it.knots
            for j in range(len(times) - 1):
                if points[j] == points[j + 1] and times[j + 1] > times[j]:
                    mid = 0.5 * (times[j] + times[j + 1])
                    assert it.velocity_at_m_s(mid) == 0j
            stops.append(len(waits))
    assert len(stops) >= 12 and max(stops) >= 2


def test_crossings_that_come_back_turn_120_to_180_deg(path_sample):
    for g, m in path_sample:
        plans = {p.id: p for p in g.intruders}
        for it in m.intruders:
            if plans[it.id].role == "crosses_back":
                pts, _ = knots(it)
                turn = abs(float(turns_deg(pts)[0]))
                assert BACK_TURN_DEG[0] - 0.1 <= turn <= BACK_TURN_DEG[1] + 0.1


def test_several_paths_are_there_at_once(path_sample):
    overlaps = 0
    for g, m in path_sample:
        if g.kind != "paths":
            continue
        assert 2 <= len(m.intruders) <= 3
        first_gone = min(it.vanish_t_s for it in m.intruders)
        overlaps += sum(it.appear_t_s < first_gone for it in m.intruders) >= 2
    assert overlaps >= 10  # of 12: the later ones appear before the first is gone
    assert generate(5, kind="paths") == generate(5, kind="paths")  # seeded
