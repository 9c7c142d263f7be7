"""Where a relieving spare flies in (companion/agent/relief/join.py; docs/energy.md,
"Reliefs"): the turn-and-straight path against a particle flown step by step, and the lane
point a spare flies to against the loop sampled point by point.

The checks do not use the module's own formulas: the path is flown at 1 ms steps (the turn
at the radius, then straight once the heading points at the target) and the distances from
the loop are taken to 20,000 sampled loop points.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.relief.join import meet_point, onto_lane, turn_signs, turn_then_straight
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).resolve().parents[1] / "missions" / "ellipse_relief.yaml")
PATROL = MISSION.patrol
LOOP = PATROL.sample_by_time(20000)
MAX_U = MISSION.vehicles.max_turn_rate_rad_s
RADIUS_M = PATROL.airspeed_m_s / MAX_U
SENSOR_M = MISSION.sensor.footprint_radius_m


def _flown(pos: complex, heading: complex, sign: float, target: complex, radius_m: float):
    """(turn rad, straight m, where the turn ends m): a particle turning at ``radius_m`` the
    ``sign`` way (+1: the heading angle grows) in 1 mm steps until it points at ``target``,
    then straight to it."""
    step = 1e-3
    turned = 0.0
    h = heading
    while True:
        d = target - pos
        cross = (h.conjugate() * d).imag  # > 0: the target lies on the +1 side
        if abs(d) > 0 and (h.conjugate() * d).real > 0 and abs(cross) / abs(d) < 2e-4:
            return turned, abs(d), pos
        if turned > 2.5 * math.pi:
            return math.inf, math.nan, pos
        dth = sign * step / radius_m
        pos += h * step
        h *= complex(math.cos(dth), math.sin(dth))
        turned += abs(dth)


@pytest.mark.parametrize("seed", range(6))
def test_the_turn_and_straight_leg_match_a_particle_flown_step_by_step(seed):
    rng = np.random.default_rng(seed)
    heading = complex(np.exp(1j * rng.uniform(-math.pi, math.pi)))
    for _ in range(4):
        target = complex(*rng.uniform(-120.0, 120.0, 2))
        for sign in (1.0, -1.0):
            turn, leg = turn_then_straight(0j, heading, np.array([sign]), np.array([target]), 20.0)
            flown_turn, flown_leg, _ = _flown(0j, heading, sign, target, 20.0)
            if math.isinf(flown_turn):  # inside the turn's circle: it circles for ever
                assert math.isinf(turn[0])
                continue
            assert turn[0] == pytest.approx(flown_turn, abs=2e-3)
            assert abs(leg[0]) == pytest.approx(flown_leg, abs=0.05)


def _off_loop(points: np.ndarray) -> np.ndarray:
    """Distance (m) of each point from the sampled loop."""
    return np.min(np.abs(np.asarray(points)[:, None] - LOOP[None, :]), axis=1)


def _outside(point: complex) -> bool:
    """Whether ``point`` lies outside the loop (its nearest sample's outward side)."""
    k = int(np.argmin(np.abs(LOOP - point)))
    return abs(point - PATROL.centre_m) > abs(LOOP[k] - PATROL.centre_m)


@pytest.mark.parametrize("seed", range(8))
def test_a_lane_point_is_flown_to_with_the_sensor_off_the_loop_and_before_the_slot(seed):
    """From a point 100-400 m outside the loop, heading anywhere: the lane point lies at
    least the lane's offset out, every point of the straight leg to it (from where its turn,
    drifted by the wind, ends) is farther from the loop than the sensor radius, and the leg
    goes with the traffic."""
    rng = np.random.default_rng(100 + seed)
    lane_m = SENSOR_M + 15.0
    k = int(rng.integers(LOOP.size))
    out = (LOOP[k] - PATROL.centre_m) / abs(LOOP[k] - PATROL.centre_m)
    pos = complex(LOOP[k] + rng.uniform(100.0, 400.0) * out)
    heading_rad = float(rng.uniform(-math.pi, math.pi))
    slot = float(rng.uniform(0.0, 2 * math.pi))
    found = meet_point(pos, heading_rad, slot, PATROL, MAX_U, lane_m=lane_m, early_s=6.0,
                       clear_m=SENSOR_M)  # fmt: skip
    assert found is not None
    point, slack = found
    assert slack >= 0.0
    assert _outside(point) and _off_loop(np.array([point]))[0] >= lane_m - 0.5
    # the straight leg: from where the particle's turn ends (the way the module turns) on
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    err = math.remainder(math.atan2((point - pos).imag, (point - pos).real) - heading_rad,
                         2 * math.pi)  # fmt: skip
    sign = float(turn_signs(pos, h, np.array([err]), PATROL, RADIUS_M, SENSOR_M)[0])
    turned, _, start = _flown(pos, h, sign, point, RADIUS_M)
    start += PATROL.wind.vector * turned / MAX_U  # the wind drifts it through its turn
    along = start + (point - start) * np.linspace(0.0, 1.0, 200)
    assert np.min(_off_loop(along)) > SENSOR_M
    near = int(np.argmin(np.abs(LOOP - point)))
    tangent = LOOP[(near + 1) % LOOP.size] - LOOP[near]  # the sense of travel
    assert ((point - start).conjugate() * tangent).real >= 0.0


def test_a_big_turn_goes_towards_the_loop_only_where_the_sensor_stays_clear_of_it():
    """Heading along the traffic, a target behind: from 400 m out the turn towards the loop
    (its circle's near side 400 - 2 R out) is the shorter one; from 100 m out it would
    bring the sensor over the loop, so it turns away."""
    k = 0
    t = LOOP[1] - LOOP[0]
    t /= abs(t)
    out = (LOOP[k] - PATROL.centre_m) / abs(LOOP[k] - PATROL.centre_m)
    towards = 1.0 if (t.conjugate() * (-out)).imag > 0 else -1.0  # the side the loop is on
    behind = np.array([towards * 0.9 * math.pi])  # a target behind, on the loop's side
    far = turn_signs(complex(LOOP[k] + 400.0 * out), t, behind, PATROL, RADIUS_M, SENSOR_M)
    near = turn_signs(complex(LOOP[k] + 100.0 * out), t, behind, PATROL, RADIUS_M, SENSOR_M)
    assert far[0] == towards and near[0] == -towards


def test_heading_in_it_turns_onto_its_lane_a_turn_radius_out_when_square_to_the_loop():
    """Square to the loop, heading in, a UAV must turn onto its lane one turn radius before
    it (its turn through 90 deg takes that); along the loop, only once at the lane; heading
    out, never."""
    lane_m = SENSOR_M + 15.0
    k = 0
    out = (LOOP[k] - PATROL.centre_m) / abs(LOOP[k] - PATROL.centre_m)
    t = LOOP[1] - LOOP[0]
    inward = math.atan2(-out.imag, -out.real)
    along = math.atan2(t.imag, t.real)

    def onto(off_m: float, heading_rad: float) -> bool:
        return onto_lane(complex(LOOP[k] + off_m * out), heading_rad, PATROL, lane_m, MAX_U)

    assert onto(lane_m + RADIUS_M - 2.0, inward) and not onto(lane_m + RADIUS_M + 2.0, inward)
    assert not onto(lane_m + 10.0, along + 0.05) and not onto(lane_m - 5.0, inward + math.pi)


@pytest.mark.parametrize("seed", range(6))
def test_a_full_turn_is_clear_exactly_where_a_particle_flown_round_it_stays_off_the_loop(seed):
    """``full_turn_clear`` against a particle turned once round at the turn rate in 10 ms
    steps, drifting in the mission's wind, its distance taken to 20,000 sampled loop points:
    from points 40-260 m outside the loop, each way round, the two agree except within a
    metre of the clearance."""
    from companion.agent.relief.join import full_turn_clear

    rng = np.random.default_rng(seed)
    clear_m = 57.5
    for _ in range(6):
        near = LOOP[rng.integers(len(LOOP))]
        out = (near - PATROL.centre_m) / abs(near - PATROL.centre_m)
        pos = complex(near + rng.uniform(40.0, 260.0) * out)
        heading = float(rng.uniform(-math.pi, math.pi))
        for sign in (1.0, -1.0):
            p, h, least = pos, heading, math.inf
            for _ in range(int(2.0 * math.pi / MAX_U / 0.01) + 1):
                least = min(least, float(_off_loop(np.array([p]))[0]))
                p += (PATROL.airspeed_m_s * complex(math.cos(h), math.sin(h))
                      + PATROL.wind.vector) * 0.01  # fmt: skip
                h += sign * MAX_U * 0.01
            if abs(least - clear_m) > 1.0:
                flown_clear = least >= clear_m and _outside(pos)
                assert full_turn_clear(pos, heading, sign, PATROL, MAX_U, clear_m) == flown_clear
