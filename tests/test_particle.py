"""The particle step: exact arcs against a fine numerical integration, limits, lag, seeding."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from companion.core.particle import ParticleParams, ParticleState, step
from companion.core.wind import Wind

PARAMS = ParticleParams(airspeed_m_s=20.0, max_turn_rate_rad_s=0.35)


def integrate_ode(pos, heading, u, wind, duration, tau=0.0, u0=0.0):
    """Reference: eq. 1 (with an optional first-order lag on u) by RK45 at tight tolerance."""

    def f(_t, x):
        _, _, th, ur = x
        rate = ur if tau > 0 else u
        v = 20.0 * np.exp(1j * th) + wind
        dur = (u - ur) / tau if tau > 0 else 0.0
        return [v.real, v.imag, rate, dur]

    sol = solve_ivp(f, (0, duration), [pos.real, pos.imag, heading, u0], rtol=1e-11, atol=1e-9)
    return complex(sol.y[0, -1], sol.y[1, -1]), sol.y[2, -1]


@pytest.mark.parametrize("u", [0.0, 0.1, -0.3, 0.35])
def test_exact_arc_matches_fine_integration(u):
    wind = Wind.from_meteo(7.0, 230.0).vector
    st = ParticleState.at(100.0, -50.0, 0.7)
    for _ in range(40):  # 40 steps of 0.25 s = 10 s
        st = step(st, u, PARAMS, wind, 0.25)
    pos, heading = integrate_ode(100.0 - 50.0j, 0.7, u, wind, 10.0)
    assert abs(complex(st.pos_m) - pos) < 1e-6
    assert float(np.angle(np.exp(1j * (st.heading_rad - heading)))) == pytest.approx(0, abs=1e-9)


def test_one_big_step_equals_many_small_ones():
    wind = 3.0 - 4.0j
    a = step(ParticleState.at(0, 0, 1.0), 0.2, PARAMS, wind, 10.0)
    b = ParticleState.at(0, 0, 1.0)
    for _ in range(1000):
        b = step(b, 0.2, PARAMS, wind, 0.01)
    assert abs(complex(a.pos_m) - complex(b.pos_m)) < 1e-9


def test_still_air_circle_radius():
    st = ParticleState.at(0.0, 0.0, 0.0)
    pts = []
    for _ in range(int(2 * np.pi / 0.2 / 0.05)):
        st = step(st, 0.2, PARAMS, 0j, 0.05)
        pts.append(complex(st.pos_m))
    centre = 0 + 1j * 20.0 / 0.2  # right turn from heading North: centre due East
    assert np.allclose(np.abs(np.array(pts) - centre), 100.0, atol=1e-8)


def test_turn_rate_limit_and_non_finite_commands():
    st = ParticleState.at([0, 0, 0], [0, 0, 0], [0, 0, 0])
    out = step(st, [5.0, -5.0, np.nan], PARAMS, 0j, 1.0)
    assert np.allclose(out.turn_rate_rad_s, [0.35, -0.35, 0.0])
    assert np.allclose(out.heading_rad, [0.35, -0.35, 0.0])


def test_first_order_lag_heading_and_position():
    params = ParticleParams(20.0, 0.35, lag_s=0.8)
    wind = Wind.from_meteo(5.0, 180.0).vector
    st = ParticleState.at(0.0, 0.0, 0.0)
    for _ in range(500):
        st = step(st, 0.3, params, wind, 0.01)
    pos, heading = integrate_ode(0j, 0.0, 0.3, wind, 5.0, tau=0.8)
    assert float(st.heading_rad) == pytest.approx(heading, abs=1e-9)  # heading is exact
    assert abs(complex(st.pos_m) - pos) < 0.01  # position: mean-rate arc per step


def test_gusts_are_seeded_by_the_one_generator():
    params = ParticleParams(20.0, 0.35, gust_std_m_s=2.0)

    def run(seed):
        rng = np.random.default_rng(seed)
        st = ParticleState.at([0.0] * 3, [0.0] * 3, [0.0] * 3)
        for _ in range(200):
            st = step(st, 0.1, params, 0j, 0.1, rng)
        return st.pos_m

    assert np.array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))
    with pytest.raises(ValueError, match="Generator"):
        step(ParticleState.at(0, 0, 0), 0.0, params, 0j, 0.1)


def test_bad_params_rejected():
    with pytest.raises(ValueError):
        ParticleParams(0.0, 0.3)
    with pytest.raises(ValueError):
        ParticleParams(20.0, float("nan"))
