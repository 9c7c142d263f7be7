"""The control step's math rewritten in Python scalars (issue 46), against independent forms.

* The nearest loop point (:meth:`Patrol.nearest_canon`, Newton's method from a guess, the
  global search behind it) against a brute-force search of a dense polyline of the loop and
  against scipy's bounded minimisation (:meth:`Patrol.nearest`), for points inside and
  outside, good and bad guesses, every kind of loop, both senses of travel.
* The splay's gradient of one member (:func:`splay_gradient_of`: harmonics by repeated
  products) against the array form (:func:`splay_gradient`: numpy exponentials, or the pair
  table from its size).
* The steering law (:func:`steering_turn_rate`) against the same law written here with
  numpy arrays over many states at once (the form the law had before it was made scalar).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.core.loops import EllipseLoop, SmoothLoop, rounded_hull
from companion.core.patrol import Patrol
from companion.core.wind import Wind, turn_rate_from_course_rate
from companion.guidance.steering import (
    TABLE_FROM_N,
    XTRACK_MAX_ANGLE_RAD,
    XTRACK_SAT_M,
    Gains,
    centre_gain_s_m2,
    hold_applies,
    phase_boost,
    phase_gains_m2_s,
    splay_gradient,
    splay_gradient_of,
    steering_turn_rate,
)

ELLIPSE = EllipseLoop(30 + 20j, 800.0, 120.0, 0.3)
HULL = rounded_hull(np.array([0, 900 + 200j, 1200 + 1500j, -300 + 1100j]), 80.0, 5000.0)
SMOOTH = SmoothLoop.of(HULL, np.radians(1.0), grid=1 << 12)
LOOPS = {"ellipse": ELLIPSE, "hull": HULL, "smooth": SMOOTH}
WIND = Wind.from_meteo(5.0, 200.0)


def _patrol(name: str, clockwise: bool) -> Patrol:
    return Patrol.build(LOOPS[name], 20.0, WIND, clockwise)


def _dense(patrol: Patrol, n: int = 400_000) -> np.ndarray:
    """The loop as a dense polyline in the canonical frame (complex m)."""
    g = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return patrol.shape.centre_m + patrol.shape.offset(g)


@pytest.mark.parametrize("clockwise", [True, False])
@pytest.mark.parametrize("name", list(LOOPS))
def test_nearest_point_from_any_guess_is_the_brute_force_nearest(name, clockwise):
    patrol = _patrol(name, clockwise)
    dense = _dense(patrol)
    rng = np.random.default_rng(11)
    inside_deep = 0
    for k in range(120):
        phase = rng.uniform(0, 2 * np.pi)
        base = complex(patrol.point_at_phase(phase))
        course = float(patrol.course_at_phase(phase))
        # mostly near the loop, some far inside or outside (the rejoin, a fleet's start)
        off = rng.uniform(-60, 60) if k % 3 else rng.uniform(-600, 600)
        point = base + off * 1j * np.exp(1j * course)
        r = complex(patrol.to_canon(point))
        good = float(patrol.angle_to_canon(course)) + rng.normal(0, 0.2)
        for guess in (good, rng.uniform(-10, 10), None):
            patrol._nearest_memo.clear()
            g, d_out = patrol.nearest_canon(r, guess)
            p = patrol.shape.centre_m + complex(patrol.shape.offset(g))
            dist = float(np.min(np.abs(dense - r)))
            spacing = patrol.length_m / dense.size
            assert abs(abs(d_out) - dist) < spacing + 1e-6  # the nearest, not a far normal
            assert abs(abs(r - p) - abs(d_out)) < 1e-6  # the offset is to that point
            outside = abs(r - patrol.shape.centre_m) > abs(p - patrol.shape.centre_m)
            assert (d_out > 0) == outside or abs(d_out) < 1e-6
        inside_deep += off > 150
    assert inside_deep > 0  # the global search was exercised


@pytest.mark.parametrize("name", ["ellipse", "smooth"])
def test_nearest_point_agrees_with_scipys_minimisation(name):
    patrol = _patrol(name, True)
    rng = np.random.default_rng(12)
    for _ in range(40):
        point = complex(patrol.point_at_phase(rng.uniform(0, 2 * np.pi))) + complex(
            *rng.normal(0, 40, 2)
        )
        ref = patrol.nearest(point)
        p = patrol.loop_point(point, float(rng.uniform(0, 2 * np.pi)))
        assert abs(abs(p.offset_m) - ref.distance_m) < 1e-6
        # a minimiser finds a flat minimum's place to about the root of machine precision
        assert abs(math.remainder(p.phase_rad - ref.phase_rad, 2 * np.pi)) < 1e-6


@pytest.mark.parametrize("n", [1, 2, 3, 6, 9, 15, TABLE_FROM_N, 40, 100])
def test_splay_gradient_of_one_member_is_the_array_forms(n):
    patrol = _patrol("ellipse", True)
    k_m = phase_gains_m2_s(patrol, Gains(), n)
    rng = np.random.default_rng(n)
    scale = abs(k_m[0]) * n
    for _ in range(30):
        psi = rng.uniform(-10, 10, n)
        k = int(rng.integers(n))
        others = [float(p) for j, p in enumerate(psi) if j != k]
        got = splay_gradient_of(float(psi[k]), others, float(k_m[0]))
        ref = float(splay_gradient(psi[k], psi, k_m))
        assert abs(got - ref) <= 1e-9 * scale


def _law_arrays(patrol, gains, pos, heading, grad, c_ref, max_u):
    """The steering law over arrays of states (numpy throughout): eq. 19 with the
    cross-track hold, as :func:`steering_turn_rate` documents it, the nearest loop points by
    brute force over a dense polyline."""
    s0, wind = patrol.airspeed_m_s, patrol.wind_canon
    r = np.asarray(patrol.to_canon(pos))
    th = np.asarray(patrol.angle_to_canon(heading))
    v = s0 * np.exp(1j * th) + wind.vector
    s, g = np.abs(v), np.angle(v)
    c = r - patrol.shape.offset(g)
    align = np.real(np.conj(np.exp(1j * g)) * (c - np.asarray(patrol.to_canon(c_ref))))
    big_k = centre_gain_s_m2(patrol, gains)
    radius = patrol.shape.radius(g)
    nu = s / radius * (1.0 + big_k * (s * align - grad))
    if hold_applies(gains, patrol):
        nu = nu - s / radius * big_k * (phase_boost(gains, patrol) - 1.0) * grad
        dense_g = np.linspace(0.0, 2 * np.pi, 200_000, endpoint=False)
        dense = patrol.shape.centre_m + patrol.shape.offset(dense_g)
        dist2 = np.abs(dense[None, :] - r[:, None]) ** 2
        j = np.argmin(dist2, axis=1)
        rows = np.arange(r.size)
        lo, mid, hi = dist2[rows, j - 1], dist2[rows, j], dist2[rows, (j + 1) % dense_g.size]
        # the parabola through the three nodes around the nearest: its vertex
        step = dense_g[1] * 0.5 * (lo - hi) / (lo - 2 * mid + hi)
        g_t = dense_g[j] + step
        p_t = patrol.shape.centre_m + patrol.shape.offset(g_t)
        d_out = np.real(1j * np.conj(np.exp(1j * g_t)) * (r - p_t))  # outward +
        eta = np.angle(np.exp(1j * (g - g_t)))
        w, z = gains.xtrack_bw_rad_s, gains.xtrack_damping
        k_e = np.maximum(2 * z * w - big_k * s * s, 0.0)
        d = XTRACK_SAT_M * np.tanh(d_out / XTRACK_SAT_M)
        nu = nu + w * w / s * d - k_e * np.clip(eta, -XTRACK_MAX_ANGLE_RAD, XTRACK_MAX_ANGLE_RAD)
    u = turn_rate_from_course_rate(s0, th, nu, wind)
    return np.clip(patrol.sense * u, -max_u, max_u)


@pytest.mark.parametrize(
    "gains",
    [Gains(), Gains(speed_authority_m_s=0.0), Gains(centre_form="mean")],
    ids=["hold", "fixed-speed", "mean"],
)
@pytest.mark.parametrize("clockwise", [True, False])
@pytest.mark.parametrize("name", ["ellipse", "smooth"])
def test_scalar_steering_law_is_the_array_form(name, clockwise, gains):
    patrol = _patrol(name, clockwise)
    rng = np.random.default_rng(5)
    n = 200
    phase = rng.uniform(0, 2 * np.pi, n)
    pos = patrol.point_at_phase(phase) + rng.normal(0, 30, n) + 1j * rng.normal(0, 30, n)
    heading = patrol.course_at_phase(phase) + rng.normal(0, 0.3, n)
    grad = rng.normal(0, 2.0 * patrol.airspeed_m_s * patrol.length_m / (2 * np.pi), n)
    c_ref = patrol.centre_m + complex(*rng.normal(0, 10, 2))
    max_u = 0.3
    ref = _law_arrays(patrol, gains, pos, heading, grad, c_ref, max_u)
    for k in range(n):
        got = steering_turn_rate(
            patrol, gains, complex(pos[k]), float(heading[k]), float(grad[k]), c_ref, max_u
        )
        # the reference's nearest point: a parabola's vertex through polyline nodes
        assert got == pytest.approx(float(ref[k]), rel=1e-7, abs=1e-8)
