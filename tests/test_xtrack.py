"""Model-free cross-track (companion/core/steering.py ``cross_track``, ``Patrol.nearest_canon``).

Independent checks: the nearest loop point against a brute-force search of a dense
polyline and against ``Patrol.nearest`` (scipy's bounded minimisation).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.core.steering import cross_track
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
