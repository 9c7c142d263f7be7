"""The simulator's exact step (sitl_model/physics.py) against independent references: a fine
Runge-Kutta integration of the same equations of motion, the Gauss-Markov gust's moments by
numerical integration of its covariance, and the 50 Hz model (Simulation.step) it replaces."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.core.particle import ParticleParams, ParticleState
from companion.core.wind import wrap_pi
from sitl_model.autopilot import Mode
from sitl_model.geo import LocalFrame
from sitl_model.params import Params
from sitl_model.physics import Airspeed, advance, gust_step
from sitl_model.sim import DT_S, SENSOR_EVERY, Simulation, VehicleSetup


# ---- the particle over one step, against RK4 ---------------------------------------------------
def _rk4(
    pos: complex,
    theta: float,
    u: float,
    s: float,
    cmd: float,
    lag_s: float,
    va: float,
    tau_a: float,
    wind: complex,
    h: float,
    dt: float = 2e-4,
) -> tuple[complex, float, float, float]:
    """The equations of motion integrated with classical RK4 (state r, theta, u, s):
    dr = s exp(i theta) + w, dtheta = u, du = (c - u) / lag (u = c without lag),
    ds = (va - s) / tau_a."""

    def f(y: np.ndarray) -> np.ndarray:
        _x, _y, th, uu, ss = y
        v = ss * complex(math.sin(th) * 1j + math.cos(th)) + wind
        du = 0.0 if lag_s <= 0 else (cmd - uu) / lag_s
        return np.array([v.real, v.imag, uu if lag_s > 0 else cmd, du, (va - ss) / tau_a])

    y = np.array([pos.real, pos.imag, theta, u if lag_s > 0 else cmd, s])
    n = round(h / dt)
    for _ in range(n):
        k1 = f(y)
        k2 = f(y + 0.5 * dt * k1)
        k3 = f(y + 0.5 * dt * k2)
        k4 = f(y + dt * k3)
        y = y + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return complex(y[0], y[1]), float(y[2]), float(y[3]), float(y[4])


@pytest.mark.parametrize(
    ("lag_s", "start_m_s", "h_s"),
    [
        (0.0, 20.0, 0.1),  # the arc (closed form)
        (0.0, 20.0, 1.0),
        (0.0, 14.0, 0.1),  # airspeed relaxing, no lag (closed form)
        (0.0, 11.0, 2.0),
        (0.5, 20.0, 0.1),  # ArduPlane's lag
        (0.5, 11.0, 0.5),
        (0.05, 20.0, 0.1),  # a lag shorter than the step: several panels
        (2.0, 20.0, 0.1),
    ],
)
def test_the_exact_step_lands_where_a_fine_rk4_integration_does(
    lag_s: float, start_m_s: float, h_s: float
) -> None:
    rng = np.random.default_rng(7)
    n = 5
    theta0 = rng.uniform(-math.pi, math.pi, n)
    u0 = rng.uniform(-0.3, 0.3, n)
    cmd = rng.uniform(-0.3, 0.3, n)
    pos0 = rng.normal(0, 500, n) + 1j * rng.normal(0, 500, n)
    wind = 4.0 - 3.0j
    va = np.full(n, 20.0)
    tau = np.full(n, 3.0)
    speed = Airspeed(np.full(n, start_m_s), va, tau)
    pp = ParticleParams(20.0, 0.35, lag_s)
    state = ParticleState(pos0, theta0, u0 if lag_s > 0 else np.zeros(n), np.zeros(n, complex))
    new = advance(state, cmd, pp, wind, h_s, speed, max_wind_ratio=0.9)
    for i in range(n):
        p, th, u, s = _rk4(pos0[i], theta0[i], u0[i], start_m_s, cmd[i], lag_s, 20.0, 3.0,
                           wind, h_s)  # fmt: skip
        assert abs(new.pos_m[i] - p) < 1e-6, (i, new.pos_m[i] - p)
        assert abs(float(wrap_pi(new.heading_rad[i] - th))) < 1e-9
        assert abs(new.turn_rate_rad_s[i] - u) < 1e-9
        assert abs(speed.at(h_s)[i] - s) < 1e-9


def test_the_turn_rate_is_limited_and_a_nan_command_flies_wings_level() -> None:
    pp = ParticleParams(20.0, 0.2)
    state = ParticleState.at([0.0, 0.0], [0.0, 0.0], [0.0, 0.0])
    speed = Airspeed(np.full(2, 20.0), np.full(2, 20.0), np.full(2, 3.0))
    new = advance(state, np.array([5.0, np.nan]), pp, 0j, 0.1, speed, 0.9)
    assert new.turn_rate_rad_s.tolist() == [0.2, 0.0]
    assert new.heading_rad[0] == pytest.approx(0.02, abs=1e-15)
    assert new.pos_m[1] == pytest.approx(2.0, abs=1e-12)  # 20 m/s north for 0.1 s


# ---- the gust over one step ---------------------------------------------------------------------
def _ou_moments(sigma: float, tau: float, h: float, m: int = 4000) -> tuple[float, float, float]:
    """Conditional (co)variances of g(h) and int_0^h g given g(0), per axis, by numerical
    integration of the covariance kernel sigma^2 (exp(-|t-s|/tau) - exp(-(t+s)/tau))."""
    t = (np.arange(m) + 0.5) * h / m  # midpoints
    k = lambda a, b: sigma**2 * (np.exp(-np.abs(a - b) / tau) - np.exp(-(a + b) / tau))  # noqa: E731
    var_g = float(k(h, h))
    cov = float(np.sum(k(h, t)) * h / m)
    var_i = float(np.sum(k(t[:, None], t[None, :])) * (h / m) ** 2)
    return var_g, cov, var_i


@pytest.mark.parametrize(("sigma", "tau", "h"), [(1.5, 5.0, 0.1), (1.5, 5.0, 3.0), (2.0, 0.3, 0.1)])
def test_the_gust_and_its_mean_over_a_step_have_the_gauss_markov_moments(
    sigma: float, tau: float, h: float
) -> None:
    n = 200_000
    g0 = np.full(n, 0.7 - 0.4j)
    g1, mean = gust_step(g0, sigma, tau, h, np.random.default_rng(3))
    integral = mean * h
    phi = math.exp(-h / tau)
    assert np.mean(g1).real == pytest.approx(phi * 0.7, abs=4 * sigma / math.sqrt(n))
    assert np.mean(integral).imag == pytest.approx(
        -0.4 * tau * (1 - phi), abs=4 * sigma * h / math.sqrt(n)
    )
    var_g, cov, var_i = _ou_moments(sigma, tau, h)
    for part in (np.real, np.imag):  # each axis on its own
        a, b = part(g1 - phi * g0), part(integral - tau * (1 - phi) * g0)
        assert np.var(a) == pytest.approx(var_g, rel=0.02)
        assert np.var(b) == pytest.approx(var_i, rel=0.02)
        assert np.mean(a * b) == pytest.approx(cov, rel=0.03)


def test_many_short_gust_steps_add_up_to_one_long_step() -> None:
    """Chaining 50 steps of 0.1 s gives the distribution of one 5 s step (the integral's
    variance from the first step's formula, the last gust's from the process's)."""
    n, sigma, tau = 100_000, 1.5, 5.0
    rng = np.random.default_rng(11)
    g = np.zeros(n, complex)
    total = np.zeros(n, complex)
    for _ in range(50):
        g, mean = gust_step(g, sigma, tau, 0.1, rng)
        total += mean * 0.1
    var_g, _, var_i = _ou_moments(sigma, tau, 5.0)
    assert np.var(g.real) == pytest.approx(var_g, rel=0.02)
    assert np.var(total.real) == pytest.approx(var_i, rel=0.02)


# ---- the simulation: n steps at once against n steps of 20 ms ------------------------------------
def _sim(params: dict[str, float], mode: Mode = Mode.GUIDED) -> Simulation:
    vehicles = [VehicleSetup(i + 1, 300.0 * i, -200.0 * i, 40.0 * i, 100.0) for i in range(6)]
    return Simulation(vehicles, Params(params), LocalFrame(39.8, -84.0, 250.0), start_mode=mode)


def _setpoints(sim: Simulation, t_s: float) -> None:
    """Each vehicle's GUIDED turn rate changes every 0.1 s (what companions send)."""
    from sitl_model.autopilot import Setpoint, SetpointKind

    for i, ap in enumerate(sim.autopilots):
        rate = 0.2 * math.sin(0.3 * t_s + i)
        ap.setpoint(Setpoint(SetpointKind.TURN_RATE, rate), t_s)


@pytest.mark.parametrize(
    ("params", "tol_m"),
    [
        ({"SIM_WIND_SPD": 6.0, "SIM_WIND_DIR": 200.0}, 1e-6),  # arcs: the same to rounding
        ({"SIM_LAG": 0.5, "SIM_WIND_SPD": 6.0}, 0.05),  # 50 Hz mean-rate arcs vs exact
    ],
)
def test_steps_at_once_follow_the_50hz_model_under_setpoints(params, tol_m) -> None:
    """Turn-rate setpoints every 0.1 s for 120 s: advance(5) flies where 5 x step() does
    (to rounding for arcs; with a lag, within the 50 Hz model's own error)."""
    a, b = _sim(params), _sim(params)
    while a.t_s < 120.0 - 1e-9:
        _setpoints(a, a.t_s)
        _setpoints(b, b.t_s)
        a.advance(SENSOR_EVERY)
        for _ in range(SENSOR_EVERY):
            b.step()
        assert a.steps == b.steps
    assert np.max(np.abs(a.state.pos_m - b.state.pos_m)) < tol_m
    assert np.max(np.abs(wrap_pi(a.state.heading_rad - b.state.heading_rad))) < 1e-6
    assert a.truth_rows()[0].split(",")[0] == b.truth_rows()[0].split(",")[0] == "120.000"


@pytest.mark.parametrize(
    ("mode", "tol_m"),
    [
        (Mode.LOITER, 1.0),
        # a waypoint is found reached up to 0.08 s later than at 50 Hz (1.6 m at 20 m/s;
        # ArduPlane's navigation runs at 10 Hz too): the along-track offset of a few legs
        (Mode.AUTO, 2.5),
        # no setpoint: the entry course held, then GUID_TIMEOUT's loiter (the step that
        # holds the timeout is taken at 50 Hz: the loiter starts at the same instant)
        (Mode.GUIDED, 0.5),
    ],
)
def test_the_autopilots_own_loops_at_the_control_rate_stay_near_the_50hz_model(mode, tol_m) -> None:
    """Loiter, waypoints and GUIDED's course hold decide every 0.1 s with held gains: after
    60 s the tracks are within metres of the 50 Hz model's."""
    a, b = _sim({"SIM_WIND_SPD": 5.0}), _sim({"SIM_WIND_SPD": 5.0})
    for sim in (a, b):
        if mode is Mode.AUTO:
            pts = [(k + 1, complex(800 * math.cos(k), 800 * math.sin(k))) for k in range(4)]
            for ap in sim.autopilots:
                ap.set_waypoints(pts, 0.0, sim.obs(0))
        for i, ap in enumerate(sim.autopilots):
            ap.set_mode(mode, 0.0, sim.obs(i))
    while a.t_s < 60.0 - 1e-9:
        a.advance(SENSOR_EVERY)
        for _ in range(SENSOR_EVERY):
            b.step()
    assert np.max(np.abs(a.state.pos_m - b.state.pos_m)) < tol_m


def test_a_guided_timeout_inside_a_step_fires_at_the_50hz_instant() -> None:
    """The last setpoint at 0 s: GUID_TIMEOUT (3 s) expires inside the step from 3.0 s; that
    step is taken at 50 Hz, so the loiter starts at 3.02 s, as with single steps."""
    from sitl_model.autopilot import Setpoint, SetpointKind

    a, b = _sim({}), _sim({})
    for sim in (a, b):
        for ap in sim.autopilots:
            ap.setpoint(Setpoint(SetpointKind.TURN_RATE, 0.05), 0.0)
    times = {}
    for name, sim, n in (("at once", a, SENSOR_EVERY), ("50 Hz", b, 1)):
        while sim.t_s < 4.0 - 1e-9:
            sim.advance(n)
            for e in sim.drain_events():
                if e.event == "guided_timeout":
                    times.setdefault(name, e.t_s)
    assert times["at once"] == times["50 Hz"] == pytest.approx(3.02)
    assert np.max(np.abs(a.state.pos_m - b.state.pos_m)) < 1e-6


def test_advance_takes_only_a_divisor_of_the_sensor_period() -> None:
    sim = _sim({})
    with pytest.raises(ValueError, match="divide"):
        sim.advance(3)
    sim.advance(5)
    assert sim.steps == 5 and sim.t_s == pytest.approx(5 * DT_S)
