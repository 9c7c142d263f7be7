"""The companion's own wind estimate and heading filter against synthetic tracks.

Tracks are made here with plain kinematics (``v = V e^{i theta} + w``), independent of the
estimator: a known wind, gusts (first-order Gauss-Markov), GPS velocity noise and the
1 cm/s resolution of GLOBAL_POSITION_INT.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from companion.core.wind import Wind
from companion.link.estimate import Estimator
from companion.link.wind_estimate import WindEstimator, wind_from_meteo
from companion.mission.model import Origin

V = 20.0
ORIGIN = Origin(39.78, -84.05, 250.0)


def track(wind: complex, seconds: float, *, rate_hz=10.0, turn=0.12, gust=0.0, vnoise=0.0,
          seed=1):  # fmt: skip
    """(t, heading, ground velocity) of a vehicle circling at ``turn`` rad/s."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n = int(seconds * rate_hz)
    t = np.arange(n) * dt
    heading = (0.3 + turn * t) % (2 * math.pi)
    g = np.zeros(n, dtype=complex)
    a = math.exp(-dt / 5.0)
    for k in range(1, n):
        g[k] = a * g[k - 1] + gust * math.sqrt(1 - a * a) * complex(*rng.standard_normal(2))
    v = V * np.exp(1j * heading) + wind + g
    v = v + vnoise * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    return t, heading, v


def feed(est: WindEstimator, t, heading, v) -> None:
    for tk, hk, vk in zip(t, heading, v, strict=True):
        est.on_attitude(tk, hk)
        est.on_ground_velocity(tk, tk, vk)


def test_air_data_triangle_recovers_a_known_wind():
    wind = wind_from_meteo(6.0, 225.0)  # from the south-west: towards the north-east
    assert wind.real > 0 and wind.imag > 0
    est = WindEstimator(V)
    feed(est, *track(wind, 300.0))
    assert abs(est.own() - wind) < 1e-6


def test_gusts_and_velocity_noise_average_out():
    """1.5 m/s gusts (tau 5 s) and 0.15 m/s velocity noise: over ten seeds the estimate's
    error stays near the averaging limit sigma sqrt(tau_gust / tau_avg) per axis (0.6 m/s)."""
    wind = wind_from_meteo(6.0, 225.0)
    errs = []
    for seed in range(10):
        est = WindEstimator(V, tau_s=30.0)
        feed(est, *track(wind, 300.0, gust=1.5, vnoise=0.15, seed=seed))
        errs.append(abs(est.own() - wind))
    assert np.median(errs) < 1.0
    assert max(errs) < 2.5


def test_own_estimate_waits_until_settled_and_follows_a_step():
    est = WindEstimator(V, tau_s=20.0)
    t, h, v = track(3 + 0j, 10.0)
    feed(est, t, h, v)
    assert est.own() is None  # 10 s of data: not settled yet
    t, h, v = track(3 + 0j, 120.0)
    feed(est, t + 10.0, h, v)
    assert abs(est.own() - 3) < 1e-6
    t, h, v = track(-2 + 4j, 200.0)
    feed(est, t + 200.0, h, v)
    assert abs(est.own() - (-2 + 4j)) < 0.01  # 10 tau later


def test_autopilot_wind_fused_and_bad_values_counted():
    est = WindEstimator(V)
    assert est.on_autopilot_wind(1.0, 5.0, 180.0)  # from the South: towards the North
    assert est.autopilot(2.0) == pytest.approx(5 + 0j)
    assert est.estimate(2.0) == pytest.approx(5 + 0j)
    assert est.autopilot(7.0) is None  # stale
    for speed, frm in [(math.nan, 10.0), (-1.0, 10.0), (25.0, 10.0), (3.0, math.inf)]:
        assert not est.on_autopilot_wind(3.0, speed, frm)
    assert est.counts["bad_autopilot"] == 4
    feed(est, *track(3 + 0j, 200.0))  # own estimate settles at 3 m/s towards the North
    est.on_autopilot_wind(200.0, 5.0, 180.0)
    assert est.estimate(200.0) == pytest.approx(4 + 0j, abs=1e-3)


def gpi(est: Estimator, t: float, pos: complex, vel: complex, att_yaw: float | None):
    lat, lon, alt = pymap3d.ned2geodetic(
        pos.real, pos.imag, -100.0, ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN.alt_m
    )
    ms = round(t * 1000)
    if att_yaw is not None:
        est.on_attitude(ms, att_yaw)
    return est.from_global_position(
        t, ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
        round(vel.real * 100), round(vel.imag * 100), 65535,
    )  # fmt: skip


@pytest.mark.parametrize("tau_s,limit_m", [(3.0, 60.0), (20.0, 40.0)])
def test_heading_filter_on_a_50_km_edge_with_quantised_noisy_velocity(tau_s, limit_m):
    """On an edge of radius 50 km, 1 cm/s resolution and 0.1 m/s of velocity noise become
    hundreds of metres of loop centre through the course; the filtered heading far less
    (the product's 3 s lets gusts through to the law; 20 s would filter more)."""
    wind = Wind.from_meteo(5.0, 180.0)
    radius = 50_000.0
    rng = np.random.default_rng(3)
    rate = V / radius  # the air turn rate of that edge, roughly
    spread_raw, spread_filt = [], []
    for use_attitude in (False, True):
        est = Estimator(ORIGIN, V, wind)
        pos = 0j
        errs = []
        for k in range(3000):  # 300 s at 10 Hz
            t = k * 0.1
            heading = 1.0 + rate * t
            vel = V * np.exp(1j * heading) + wind.vector
            noisy = vel + 0.1 * complex(*rng.standard_normal(2))
            e = gpi(est, t, pos, noisy, heading if use_attitude else None)
            pos += vel * 0.1
            if k > 600:
                errs.append(float(np.angle(np.exp(1j * (e.heading_rad - heading)))))
        (spread_filt if use_attitude else spread_raw).append(np.std(errs) * radius)
    assert spread_raw[0] > 100.0  # hundreds of metres of centre from the course
    assert spread_filt[0] < limit_m
    assert spread_filt[0] < spread_raw[0] / 5


def test_heading_filter_removes_a_constant_attitude_bias():
    wind = Wind.from_meteo(5.0, 180.0)
    est = Estimator(ORIGIN, V, wind, heading_tau_s=20.0)
    bias = math.radians(3.0)
    pos = 0j
    for k in range(2000):  # 200 s, a slow turn
        t = k * 0.1
        heading = 0.5 + 0.05 * t
        vel = V * np.exp(1j * heading) + wind.vector
        e = gpi(est, t, pos, vel, heading + bias)
        pos += vel * 0.1
    assert abs(float(np.angle(np.exp(1j * (e.heading_rad - heading))))) < math.radians(0.05)
    assert e.turn_rate_rad_s == pytest.approx(0.05, abs=0.005)


def test_turn_rate_is_the_attitude_yaw_rate_not_the_gusts():
    """A gust turns the course, not the aircraft: the achieved turn rate (the shaper's
    measurement) follows the attitude's yaw, whatever the course-derived heading does."""
    wind = Wind.from_meteo(5.0, 180.0)
    est = Estimator(ORIGIN, V, wind)
    pos = 0j
    rates = []
    for k in range(600):  # 60 s at 10 Hz, a steady 0.05 rad/s turn in a 2 m/s swinging gust
        t = k * 0.1
        heading = 0.3 + 0.05 * t
        gust = 2.0 * complex(math.cos(0.7 * t), math.sin(1.1 * t))
        vel = V * np.exp(1j * heading) + wind.vector + gust
        e = gpi(est, t, pos, vel, heading)
        pos += vel * 0.1
        if k > 10:
            rates.append(e.turn_rate_rad_s)
    assert max(abs(r - 0.05) for r in rates) < 0.002
