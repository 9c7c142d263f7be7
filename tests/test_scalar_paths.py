"""The control step's float fast paths give the numpy paths' values.

Loops, patrol tables, wind kinematics, the cross-track hold and the particle step take a
shortcut through ``math`` and plain lists for one Python float (issue 13, item 6; issue 46:
the CPU per companion step). Where a shortcut repeats the numpy path's arithmetic in the same
order it gives the same bits (asserted with ``==``); where it uses ``math`` instead of numpy
(``atan2``, ``tanh``: issue 46 released byte identity with older commits) it agrees to
within rounding (``REL``). Checked here against the numpy path on the same scalar given as a
0-d array. (The steering law itself has one path, the scalar one, checked against an array
form in ``tests/test_control_step_math.py``.)
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from companion.core.loops import EllipseLoop, SmoothLoop, rounded_hull
from companion.core.particle import ParticleParams, ParticleState, step, step_one
from companion.core.patrol import Patrol
from companion.core.wind import (
    Wind,
    course_from_heading,
    ground_velocity,
    heading_from_course,
    turn_rate_from_course_rate,
    wrap_2pi,
    wrap_pi,
)
from companion.guidance.steering import Gains, xtrack_course_rate
from companion.link.estimate import Estimator
from companion.mission.model import Origin

N = 400
REL = 1e-12  # relative agreement where math stands in for numpy (the last bits may differ)
ELLIPSE = EllipseLoop(30 + 20j, 800.0, 120.0, 0.3)
HULL = rounded_hull(np.array([0, 900 + 200j, 1200 + 1500j, -300 + 1100j]), 80.0, 5000.0)
SMOOTH = SmoothLoop.of(HULL, np.radians(1.0), grid=1 << 12)
WIND = Wind.from_meteo(5.0, 200.0)


def floats(seed: int, lo: float, hi: float, n: int = N) -> list[float]:
    """``n`` Python floats drawn uniformly from [lo, hi)."""
    return np.random.default_rng(seed).uniform(lo, hi, n).tolist()


@pytest.mark.parametrize("loop", [ELLIPSE, SMOOTH], ids=["ellipse", "smooth"])
def test_loop_offset_and_radius(loop):
    for g in [*floats(1, -8.0, 14.0), 0.0, 2 * np.pi]:
        assert loop.offset(g) == complex(loop.offset(np.asarray(g)))
        assert loop.radius(g) == float(loop.radius(np.asarray(g)))


def test_wrap_and_wind_kinematics():
    for x in floats(2, -50.0, 50.0):
        assert wrap_pi(x) == wrap_pi(np.asarray(x))
        assert wrap_2pi(x) == wrap_2pi(np.asarray(x))
    for h in floats(3, -7.0, 7.0):
        assert ground_velocity(20.0, h, WIND) == complex(ground_velocity(20.0, np.asarray(h), WIND))
        ref = float(course_from_heading(20.0, np.asarray(h), WIND))
        assert course_from_heading(20.0, h, WIND) == pytest.approx(ref, rel=REL, abs=1e-15)
        ref = float(heading_from_course(20.0, np.asarray(h), WIND))
        assert heading_from_course(20.0, h, WIND) == pytest.approx(ref, rel=REL, abs=1e-15)
        nu = 0.05 * h
        ref = float(turn_rate_from_course_rate(20.0, np.asarray(h), np.asarray(nu), WIND))
        assert turn_rate_from_course_rate(20.0, h, nu, WIND) == pytest.approx(ref, rel=REL)


@pytest.mark.parametrize("clockwise", [True, False])
@pytest.mark.parametrize("loop", [ELLIPSE, SMOOTH], ids=["ellipse", "smooth"])
def test_patrol_tables_and_centre(loop, clockwise):
    p = Patrol.build(loop, 20.0, WIND, clockwise)
    for g, t in zip(floats(4, -8.0, 14.0), floats(5, -50.0, 400.0), strict=True):
        assert p.time_along(g) == p.time_along(np.asarray(g))
        assert p.course_after(t) == p.course_after(np.asarray(t))
        assert p.angle_to_canon(g) == p.angle_to_canon(np.asarray(g))
        pos = complex(t, 3 * g - 100)
        assert p.to_canon(pos) == complex(p.to_canon(np.asarray(pos)))
        c, psi = p.centre_and_phase(pos, g)
        c_np, psi_np = p.centre_and_phase(np.asarray(pos), np.asarray(g))
        assert abs(c - complex(c_np)) <= REL * max(1.0, abs(c_np))
        assert abs(math.remainder(psi - float(psi_np), 2 * math.pi)) <= REL * 2 * math.pi


@pytest.mark.parametrize("gains", [Gains(), Gains(speed_authority_m_s=0.0)], ids=["hold", "fixed"])
def test_cross_track_hold(gains):
    rng = np.random.default_rng(6)
    for _ in range(N):
        h = float(rng.uniform(-4, 4))
        xt = (20.0 + h, 30.0 * h, 0.2 * h, 0.1)
        ref = float(xtrack_course_rate(gains, *(np.asarray(v) for v in xt)))
        assert xtrack_course_rate(gains, *xt) == pytest.approx(ref, rel=REL, abs=1e-15)


@pytest.mark.parametrize("lag_s", [0.0, 0.4])
def test_step_one_is_step_of_one_particle(lag_s):
    params = ParticleParams(20.0, 0.35, lag_s=lag_s)
    rng = np.random.default_rng(7)
    wind = WIND.vector
    for k in range(N):
        pos = complex(*rng.uniform(-2000.0, 2000.0, 2))
        h = float(rng.uniform(-4, 4))
        u = [float(rng.uniform(-0.5, 0.5)), 0.0, np.nan, np.inf][k % 4]
        ref = step(ParticleState.at(pos.real, pos.imag, h), u, params, wind, 0.05)
        assert step_one(pos, h, u, params, wind, 0.05) == (complex(ref.pos_m), ref.heading_rad)


def test_estimator_local_frame_is_pymap3d():
    origin = Origin(39.78, -84.1, 250.0)
    est = Estimator(origin, 20.0, WIND)
    for lat, lon, alt in zip(
        floats(8, 39.7, 39.9), floats(9, -84.2, -84.0), floats(10, 200.0, 400.0), strict=True
    ):
        ref = pymap3d.geodetic2ned(lat, lon, alt, origin.lat_deg, origin.lon_deg, origin.alt_m)
        # pymap3d's formulas in math rather than numpy: a micrometre at most (ECEF metres
        # are millions, their last bits a nanometre)
        assert np.allclose(est.ned_of(lat, lon, alt), ref, rtol=0.0, atol=1e-6)
