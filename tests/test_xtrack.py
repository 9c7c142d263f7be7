"""The cross-track hold added to the law and its geometry (companion/guidance/steering.py).

Independent checks: the nearest loop point against a brute-force search of a dense
polyline and against ``Patrol.nearest`` (scipy's bounded minimisation); the hold's closed
loop integrated here with plain kinematics (frequency from the period, damping from the
overshoot); the phase boost from its formula.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from companion.guidance.steering import (
    Gains,
    cross_track,
    hold_applies,
    phase_boost,
    xtrack_course_rate,
)
from companion.mission import load_mission

MISSIONS = ["missions/ellipse_6uav.yaml", "missions/wpafb_4uav.yaml"]


@pytest.mark.parametrize("path", MISSIONS)
def test_nearest_point_and_offset_match_brute_force(path):
    patrol = load_mission(path).patrol
    rng = np.random.default_rng(4)
    dense = patrol.point_at_phase(np.linspace(0, 2 * np.pi, 200_000, endpoint=False))
    for _ in range(30):
        ph = rng.uniform(0, 2 * np.pi)
        base = complex(patrol.point_at_phase(ph))
        course = float(patrol.course_at_phase(ph))
        off = rng.uniform(-80, 80)  # positive: to the right of travel (inside, clockwise loop)
        pt = base + off * 1j * np.exp(1j * course)
        d_out, _eta = cross_track(patrol, pt, float(patrol.course_at_phase(ph)))
        brute = float(np.min(np.abs(dense - pt)))
        assert abs(abs(d_out) - brute) < 0.05 + 1e-6 * patrol.length_m
        assert math.copysign(1, d_out) == -math.copysign(1, off)
        assert abs(patrol.nearest(pt).distance_m - abs(d_out)) < 1e-3


def test_hold_closes_a_second_order_loop_with_the_asked_frequency_and_damping():
    """Straight path, integrated here: d' = -s sin(eta), eta' = hold(d, eta) + the law's own
    course feedback K s^2 (which the hold subtracts from its damping term)."""
    g = Gains(xtrack_bw_rad_s=0.25, xtrack_damping=0.5)
    s, dt, k_law = 20.0, 0.01, 0.05
    d, eta = 10.0, 0.0
    ds = []
    for _ in range(int(80 / dt)):
        nu = float(xtrack_course_rate(g, s, d, eta, k_law)) - k_law * eta
        eta += nu * dt
        d += -s * math.sin(eta) * dt
        ds.append(d)
    ds = np.array(ds)
    crossings = np.flatnonzero(np.diff(np.sign(ds)) != 0) * dt
    period = 2 * (crossings[1] - crossings[0])
    assert period == pytest.approx(2 * math.pi / (0.25 * math.sqrt(1 - 0.25)), rel=0.05)
    overshoot = -ds[ds < 0].min() / 10.0
    assert overshoot == pytest.approx(math.exp(-math.pi * 0.5 / math.sqrt(0.75)), rel=0.1)


def test_hold_saturates_far_from_the_loop_and_is_off_at_zero_bandwidth():
    g = Gains()
    near = float(xtrack_course_rate(g, 20.0, 40.0, 0.0, 0.0))
    far = float(xtrack_course_rate(g, 20.0, 4000.0, 0.0, 0.0))
    assert 0 < far < 1.4 * near  # tanh saturation, not proportional
    off = Gains(xtrack_bw_rad_s=0.0)
    assert float(xtrack_course_rate(off, 20.0, 50.0, 0.3, 0.0)) == 0.0
    with pytest.raises(ValueError):
        Gains(xtrack_bw_rad_s=-0.1)


def test_phase_boost_restores_the_phase_authority_the_hold_takes():
    ellipse = load_mission("missions/ellipse_6uav.yaml")
    r = ellipse.patrol.length_m / (2 * math.pi)
    w = ellipse.gains.xtrack_bw_rad_s
    expected = 1 + (w * r / 20.0) ** 2  # (w R / s0)^2 at the mean radius, here about 21
    assert phase_boost(ellipse.gains, ellipse.patrol) == pytest.approx(expected)
    off = dataclasses.replace(ellipse.gains, xtrack_bw_rad_s=0.0)
    assert phase_boost(off, ellipse.patrol) == 1.0
    wpafb = load_mission("missions/wpafb_4uav.yaml")
    assert phase_boost(wpafb.gains, wpafb.patrol) == 25.0  # capped on a 24.7 km loop
    assert hold_applies(ellipse.gains, ellipse.patrol)
    fixed_speed = dataclasses.replace(wpafb.gains, speed_authority_m_s=0.0)
    assert not hold_applies(fixed_speed, wpafb.patrol)  # would need a boost of about 870
    assert hold_applies(wpafb.gains, wpafb.patrol)  # the airspeed holds the phase instead
    mean = dataclasses.replace(ellipse.gains, centre_form="mean")
    assert not hold_applies(mean, ellipse.patrol)
