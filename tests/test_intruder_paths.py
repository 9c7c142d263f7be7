"""Intruders on paths (``kind: path``): the mission's form, their motion, and the world that
moves them (companion/mission/model.py ``Intruder``, sections/scenario.py, sitl_model/world.py).

The expected positions, velocities and times are worked out here from the legs' points and
speeds with ``math.hypot`` (the schedule: a leg of length d at speed v takes d / v s, then
its wait), not taken from the model's knots.
"""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from companion.mission import Intruder, parse_mission
from companion.mission.model import Leg
from sitl_model.world import World

# the issue's truck: appears at (-1846.5, -789.0) at 2400 s
START = complex(-1846.5, -789.0)
P1, P2, P3 = complex(-1500.0, -500.0), complex(-1200.0, -900.0), complex(-900.0, -600.0)
ARRIVE1 = 2400.0 + abs(P1 - START) / 8.0
ARRIVE2 = ARRIVE1 + abs(P2 - P1) / 8.0
LEAVE2 = ARRIVE2 + 40.0
ARRIVE3 = LEAVE2 + abs(P3 - P2) / 2.0

TRUCK = """\
    - id: truck
      kind: path
      appear_t_s: 2400.0
      north_m: -1846.5          # where it appears (or lat_deg / lon_deg)
      east_m: -789.0
      path:                     # then each leg in turn, straight, at that point's speed
        - {north_m: -1500.0, east_m: -500.0, speed_m_s: 8.0}
        - {north_m: -1200.0, east_m: -900.0, speed_m_s: 8.0, wait_s: 40.0}   # stops 40 s
        - {north_m: -900.0, east_m: -600.0, speed_m_s: 2.0}
      vanish_t_s: 2700.0        # optional; otherwise it stays at its last point
"""


def mission_with(intruders: str):
    """A small valid mission (an ellipse, three UAVs) with these scenario intruder lines."""
    text = f"""\
version: 1
name: paths
origin: {{lat_deg: 39.8, lon_deg: -84.0, alt_m: 200}}
perimeter:
  ellipse: {{semi_major_m: 2500, semi_minor_m: 2200}}
wind: {{speed_m_s: 5, from_deg: 180}}
vehicles:
  count: 3
  airspeed_m_s: 20
  max_turn_rate_deg_s: 18
  initial: {{line: {{from: {{north_m: 0, east_m: -300}}, to: {{north_m: 0, east_m: 300}},
    heading_deg: 0}}}}
sensor: {{footprint_radius_m: 50}}
scenario:
  duration_s: 3000
  intruders:
{intruders}"""
    return parse_mission(text, "paths.yaml")


def truck() -> Intruder:
    return mission_with(TRUCK).intruders[0]


def test_the_issues_form_parses_into_legs():
    it = truck()
    assert it.kind == "path" and it.appear_t_s == 2400.0 and it.vanish_t_s == 2700.0
    assert (it.north_m, it.east_m) == (-1846.5, -789.0)
    assert it.path == (
        Leg(-1500.0, -500.0, 8.0),
        Leg(-1200.0, -900.0, 8.0, 40.0),
        Leg(-900.0, -600.0, 2.0),
    )


def test_it_moves_along_its_legs_and_waits_exactly():
    it = truck()
    assert it.position_m(0.0) == START  # before it appears: where it appears
    assert it.position_m(2400.0) == START
    assert it.position_m(ARRIVE1) == pytest.approx(P1, abs=1e-9)
    half = 2400.0 + 0.5 * (ARRIVE1 - 2400.0)
    assert it.position_m(half) == pytest.approx((START + P1) / 2, abs=1e-9)
    for t in (ARRIVE2, ARRIVE2 + 1.0, LEAVE2 - 1e-6):  # the 40 s stop
        assert it.position_m(t) == pytest.approx(P2, abs=1e-6)
        assert it.velocity_at_m_s(t) == 0j
    assert it.position_m(LEAVE2) == pytest.approx(P2, abs=1e-9)  # off again, at 2 m/s
    assert it.velocity_at_m_s(LEAVE2) == pytest.approx((P3 - P2) / abs(P3 - P2) * 2.0)
    three_quarters = LEAVE2 + 0.75 * (ARRIVE3 - LEAVE2)
    assert it.position_m(three_quarters) == pytest.approx(P2 + 0.75 * (P3 - P2), abs=1e-9)
    assert it.position_m(ARRIVE3 + 1000.0) == P3  # then stays at its last point
    assert it.path_end_t_s == pytest.approx(ARRIVE3)


def test_its_velocity_is_each_legs_direction_at_its_speed():
    it = truck()
    legs = [(START, P1, 8.0, 2400.0, ARRIVE1), (P1, P2, 8.0, ARRIVE1, ARRIVE2),
            (P2, P3, 2.0, LEAVE2, ARRIVE3)]  # fmt: skip
    for a, b, speed, t0, t1 in legs:
        want = (b - a) / abs(b - a) * speed
        for f in (0.0, 0.3, 0.99):
            assert it.velocity_at_m_s(t0 + f * (t1 - t0)) == pytest.approx(want, abs=1e-9)
    assert it.velocity_at_m_s(2399.0) == 0j and it.velocity_at_m_s(ARRIVE3 + 1.0) == 0j
    assert it.velocity_at_m_s(ARRIVE2 + 20.0) == 0j  # waiting
    assert it.velocity_m_s == pytest.approx((P1 - START) / abs(P1 - START) * 8.0)
    assert it.max_speed_m_s == pytest.approx(8.0)
    assert it.max_speed_between_m_s(ARRIVE2 + 1.0, LEAVE2 - 1.0) == 0.0  # only the stop
    assert it.max_speed_between_m_s(ARRIVE2 + 1.0, ARRIVE3) == pytest.approx(2.0)


def test_positions_at_many_times_are_the_positions_at_each():
    it = truck()
    t = np.linspace(2300.0, 2800.0, 997)
    assert np.allclose(it.positions_m(t), [it.position_m(float(x)) for x in t], atol=1e-9)
    moving = Intruder("m", "moving", 10.0, 5.0, -3.0, 1.5, -0.5)
    t = np.linspace(0.0, 50.0, 11)
    assert np.array_equal(moving.positions_m(t), [moving.position_m(float(x)) for x in t])


def test_the_other_kinds_move_as_before():
    moving = Intruder("m", "moving", 10.0, 5.0, -3.0, 1.5, -0.5)
    assert moving.position_m(30.0) == complex(5.0 + 1.5 * 20.0, -3.0 - 0.5 * 20.0)
    assert moving.position_m(0.0) == complex(5.0, -3.0)
    assert moving.velocity_at_m_s(1e6) == moving.velocity_m_s == complex(1.5, -0.5)
    still = Intruder("s", "static", 0.0, 1.0, 2.0)
    assert still.position_m(100.0) == 1 + 2j and still.velocity_at_m_s(5.0) == 0j


def test_a_path_without_vanish_stays_and_a_leg_may_only_wait():
    lines = (
        "    - {id: w, kind: path, appear_t_s: 10, north_m: 0, east_m: 0, path: [\n"
        "        {north_m: 0, east_m: 0, speed_m_s: 1, wait_s: 30},\n"
        "        {north_m: 30, east_m: 40, speed_m_s: 5}]}\n"
    )
    it = mission_with(lines).intruders[0]
    assert it.vanish_t_s is None and it.present(1e5)
    assert it.position_m(39.0) == 0j and it.velocity_at_m_s(39.0) == 0j  # waits 10-40 s
    assert it.position_m(41.0) == pytest.approx(complex(3.0, 4.0))  # 5 m/s from 40 s
    assert it.path_end_t_s == pytest.approx(50.0) and it.position_m(1e4) == 30 + 40j


def test_legs_given_in_lat_lon_are_read_in_the_local_frame():
    local = mission_with(
        "    - {id: a, kind: path, appear_t_s: 0, north_m: 0, east_m: 0,"
        " path: [{north_m: 1000, east_m: 500, speed_m_s: 5}]}\n"
    ).intruders[0]
    lat, lon, _ = pymap3d.ned2geodetic(1000.0, 500.0, 0.0, 39.8, -84.0, 200.0)
    geo = mission_with(
        "    - {id: a, kind: path, appear_t_s: 0, lat_deg: 39.8, lon_deg: -84.0,"
        f" path: [{{lat_deg: {lat:.9f}, lon_deg: {lon:.9f}, speed_m_s: 5}}]}}\n"
    ).intruders[0]
    assert geo.path[0].point_m == pytest.approx(local.path[0].point_m, abs=0.01)
    assert abs(geo.position_m(100.0)) == pytest.approx(500.0, abs=0.01)


def test_the_world_moves_a_path_intruder_and_reports_where_it_is():
    it = truck()
    world = World((it,))
    r_s = 50.0
    far = np.array([1e5 + 0j])
    sightings, events = world.update(2399.9, far, r_s)
    assert sightings == [] and events == []  # not there yet
    sightings, events = world.update(2400.0, far, r_s)
    assert [(e.event, e.pos_m) for e in events] == [("intruder_appeared", START)]
    # a UAV over it half-way along the first leg sees it there, moving along the leg
    t = 2400.0 + 0.5 * (ARRIVE1 - 2400.0)
    sightings, events = world.update(t, np.array([(START + P1) / 2 + 10j]), r_s)
    (s,) = sightings
    assert s.pos_m == pytest.approx((START + P1) / 2) and s.distance_m == pytest.approx(10.0)
    assert s.vel_m_s == pytest.approx((P1 - START) / abs(P1 - START) * 8.0)
    assert [e.event for e in events] == ["detection"]
    # over it while it waits: still, at its second point
    sightings, events = world.update(ARRIVE2 + 5.0, np.array([P2]), r_s)
    assert sightings[0].pos_m == pytest.approx(P2) and sightings[0].vel_m_s == 0j
    # lost, then gone at vanish_t_s where its third leg has brought it
    _, events = world.update(2699.0, far, r_s)
    assert [e.event for e in events] == ["detection_lost"]
    _, events = world.update(2700.0, far, r_s)
    want = P2 + (P3 - P2) / abs(P3 - P2) * 2.0 * (2700.0 - LEAVE2)
    assert [e.event for e in events] == ["intruder_vanished"]
    assert events[0].pos_m == pytest.approx(want)
    assert ARRIVE3 > 2700.0  # (it vanished on its way)
