"""The simulator's world and sensors as they are: GPS errors, changing wind, the WIND estimate.

All in process (``Simulation`` + ``Telemetry``, no sockets). Statistical checks use a fixed
seed and generous bounds; expected values come from the formulas in ``docs/sitl.md``, not
from the code under test.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from companion.contracts.simulator import TRUTH_COLUMNS, TRUTH_COLUMNS_NO_WIND, TRUTH_HEADER
from companion.core.wind import Wind
from companion.report.rundata import load_run
from sitl_model.cli import build, build_parser, main
from sitl_model.disturbances import ErrorParams, SensorErrors, WindProfile, wind_speed_from
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.params import ParamError, Params
from sitl_model.sim import DT_S, Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

REPO = Path(__file__).resolve().parents[1]
ELLIPSE = str(REPO / "missions/ellipse_6uav.yaml")
FRAME = LocalFrame(*DEFAULT_ORIGIN)


def fleet(n: int, seed: int = 0, **params: float) -> tuple[Simulation, Telemetry]:
    """``n`` vehicles 300 m apart heading North in GUIDED, with parameter overrides."""
    setups = [VehicleSetup(i + 1, 0.0, 300.0 * i, 0.0, 100.0) for i in range(n)]
    sim = Simulation(setups, Params(params), FRAME, seed=seed)
    return sim, Telemetry(sim)


def run_until(sim: Simulation, t_s: float) -> None:
    while sim.t_s < t_s - 1e-9:
        sim.step()


def true_velocity(sim: Simulation) -> np.ndarray:
    """Ground velocity from heading, airspeed and the truth wind (m/s), independently."""
    return 20.0 * np.exp(1j * sim.state.heading_rad) + sim.wind_true_m_s


def local_m(lat_e7: int, lon_e7: int, alt_mm: int) -> complex:
    """A message's geodetic position in the local frame (complex m), by pymap3d directly."""
    o = DEFAULT_ORIGIN
    n, e, _ = pymap3d.geodetic2ned(lat_e7 * 1e-7, lon_e7 * 1e-7, alt_mm * 1e-3, *o)
    return complex(float(n), float(e))


def decorrelation_time_s(x: np.ndarray, dt_s: float, lag: int) -> float:
    """``-lag dt / ln(rho(lag))`` of zero-mean series (time, series) pooled: e-folding time (s)."""
    rho = np.sum(x[lag:] * x[:-lag]) / np.sum(x * x)
    return -lag * dt_s / math.log(rho)


# ----------------------------------------------------------------------------- GPS errors


def test_gps_errors_have_the_set_statistics_in_every_message():
    sigma, tau, vsigma = 2.0, 1.0, 0.5
    sim, tm = fleet(16, seed=7, SIM_GPS_NOISE=sigma, SIM_GPS_TAU=tau, SIM_GPS_VNOISE=vsigma)
    pos_err, vel_err = [], []
    while sim.t_s < 120.0:
        for _ in range(10):  # 5 Hz, as LOCAL_POSITION_NED streams
            sim.step()
        truth_v = true_velocity(sim)
        pe, ve = [], []
        for i in range(16):
            lp = tm.local_position_ned(i)
            p = complex(lp.x, lp.y)
            v = complex(lp.vx, lp.vy)
            if sim.steps % 200 == 0:  # every message of a step carries the same error
                gp, raw, hud = tm.global_position_int(i), tm.gps_raw_int(i), tm.vfr_hud(i)
                g = local_m(gp.lat, gp.lon, gp.alt)
                r = local_m(raw.lat, raw.lon, raw.alt)
                assert abs(g - p) < 0.02 and abs(r - p) < 0.02
                assert abs(complex(gp.vx, gp.vy) / 100.0 - v) < 0.01
                assert abs(raw.vel / 100.0 - abs(v)) < 0.01
                assert abs(hud.groundspeed - abs(v)) < 1e-9
                cog = math.radians(raw.cog / 100.0)
                assert abs(np.angle(v * np.exp(-1j * cog))) < 1e-3
            pe.append(p - complex(sim.state.pos_m[i]))
            ve.append(v - complex(truth_v[i]))
        pos_err.append(pe)
        vel_err.append(ve)
    pos = np.array(pos_err)  # (time, vehicle) complex, 0.2 s apart
    vel = np.array(vel_err)
    for axis in (pos.real, pos.imag):
        assert np.std(axis) == pytest.approx(sigma, rel=0.15)
        assert decorrelation_time_s(axis, 0.2, 5) == pytest.approx(tau, rel=0.3)
    for axis in (vel.real, vel.imag):
        assert np.std(axis) == pytest.approx(vsigma, rel=0.1)
        x = axis - axis.mean()
        assert abs(np.sum(x[1:] * x[:-1]) / np.sum(x * x)) < 0.05  # white: no memory
    # the truth log stays the truth
    row = sim.truth_rows()[3].split(",")
    truth = complex(float(row[2]), float(row[3]))
    assert truth == pytest.approx(complex(sim.state.pos_m[3]), abs=1e-3)


def test_gps_errors_change_at_the_10_hz_epochs_and_hold_between():
    sim, tm = fleet(2, SIM_GPS_NOISE=2.0, SIM_GPS_VNOISE=0.3)
    run_until(sim, 1.0)  # an epoch
    held = tm.local_position_ned(0)
    err = (sim.errors.gps_pos_m.copy(), sim.errors.gps_vel_m_s.copy())
    for _ in range(4):
        sim.step()
        np.testing.assert_array_equal(sim.errors.gps_pos_m, err[0])
        np.testing.assert_array_equal(sim.errors.gps_vel_m_s, err[1])
    sim.step()
    assert np.all(sim.errors.gps_pos_m != err[0]) and np.all(sim.errors.gps_vel_m_s != err[1])
    moved = tm.local_position_ned(0)
    assert (moved.vx, moved.vy) != (held.vx, held.vy)


def test_no_gps_error_by_default():
    sim, tm = fleet(2)
    run_until(sim, 2.0)
    lp = tm.local_position_ned(1)
    assert complex(lp.x, lp.y) == complex(sim.state.pos_m[1])
    assert complex(lp.vx, lp.vy) == pytest.approx(complex(true_velocity(sim)[1]), abs=1e-9)


def test_camera_geolocation_carries_the_vehicles_gps_error():
    sim, tm = fleet(1, SIM_GPS_NOISE=5.0)
    run_until(sim, 1.0)
    site = 120.0 + 40.0j
    m = tm.camera_tracking(0, site, 0j, 10.0)
    seen = local_m(m.lat, m.lon, round(m.alt * 1000))
    assert seen - site == pytest.approx(complex(sim.errors.gps_pos_m[0]), abs=0.03)
    assert abs(sim.errors.gps_pos_m[0]) > 0.1


def test_same_seed_same_truth_with_every_disturbance_on():
    on = dict(
        SIM_WIND_SPD=5.0, SIM_WIND_TURB=1.5, SIM_GPS_NOISE=2.0, SIM_GPS_VNOISE=0.15,
        SIM_WDRIFT_SPD=2.0, SIM_WDRIFT_DIR=30.0, SIM_WSTEP_T=3.0, SIM_WSTEP_SPD=3.0,
    )  # fmt: skip

    def flight(seed: int) -> tuple[list[str], list[str]]:
        sim, tm = fleet(3, seed=seed, **on)
        rows, msgs = [], []
        while sim.t_s < 8.0:
            sim.step()
            if sim.steps % 5 == 0:
                rows += sim.truth_rows()
                msgs += [str(tm.global_position_int(i)) + str(tm.wind(i)) for i in range(3)]
        return rows, msgs

    a, b, c = flight(11), flight(11), flight(12)
    assert a == b
    assert a[0] != c[0] and a[1] != c[1]


def test_sensor_errors_do_not_change_the_gusts():
    """Sensor errors draw from streams of their own: the same seed blows the same gusts."""
    plain, _ = fleet(3, seed=5, SIM_WIND_TURB=1.0)
    noisy, _ = fleet(3, seed=5, SIM_WIND_TURB=1.0, SIM_GPS_NOISE=3.0, SIM_GPS_VNOISE=0.2)
    run_until(plain, 5.0)
    run_until(noisy, 5.0)
    np.testing.assert_array_equal(plain.state.gust_m_s, noisy.state.gust_m_s)


# --------------------------------------------------------------------------------- wind


def test_drift_formula_at_known_times():
    """speed = S + A_s sin(2 pi t/T + pi/4), from = D + A_d cos(2 pi t/T + pi/4)."""
    w = WindProfile(5.0, 200.0, drift_speed_m_s=2.0, drift_dir_deg=30.0, drift_period_s=600.0)
    assert wind_speed_from(0.0, w) == pytest.approx((5.0 + 2.0 / 2**0.5, 200.0 + 30.0 / 2**0.5))
    assert wind_speed_from(75.0, w) == pytest.approx((7.0, 200.0))
    assert wind_speed_from(225.0, w) == pytest.approx((5.0, 170.0))
    assert wind_speed_from(375.0, w) == pytest.approx((3.0, 200.0))
    # never both drifts at zero: the world is off the forecast at every moment
    t = np.linspace(0.0, 600.0, 601)
    drifts = [wind_speed_from(x, w) for x in t]
    off = [abs(s - 5.0) / 2.0 + abs(d - 200.0) / 30.0 for s, d in drifts]
    assert min(off) > 0.9
    # the simulator blows it: the mean wind and the truth log's wind (no gusts here)
    sim, _ = fleet(1, SIM_WIND_SPD=5.0, SIM_WIND_DIR=200.0, SIM_WDRIFT_SPD=2.0, SIM_WDRIFT_DIR=30)
    run_until(sim, 75.0)
    want = Wind.from_meteo(7.0, 200.0).vector
    assert sim.wind_m_s == pytest.approx(want, abs=1e-9)
    row = sim.truth_rows()[0].split(",")
    assert complex(float(row[10]), float(row[11])) == pytest.approx(want, abs=2e-3)


def test_the_vehicle_moves_with_the_drifting_wind():
    """Ground displacement minus the air path equals the integral of the formula's wind."""
    sim, _ = fleet(1, SIM_WIND_SPD=6.0, SIM_WIND_DIR=90.0, SIM_WDRIFT_SPD=3.0, SIM_WDRIFT_T=20.0)
    run_until(sim, 4.0)
    p0, air = complex(sim.state.pos_m[0]), 0j
    w = WindProfile(6.0, 90.0, drift_speed_m_s=3.0, drift_period_s=20.0)
    expected = 0j
    while sim.t_s < 14.0 - 1e-9:
        t0, h0 = sim.t_s, float(sim.state.heading_rad[0])
        sim.step()
        h1 = float(sim.state.heading_rad[0])
        air += 20.0 * DT_S * np.exp(1j * 0.5 * (h0 + h1))
        expected += Wind.from_meteo(*wind_speed_from(t0, w)).vector * DT_S
    assert complex(sim.state.pos_m[0]) - p0 - air == pytest.approx(expected, abs=0.05)
    assert abs(expected) > 50.0


def test_wind_step_at_the_set_time():
    sim, _ = fleet(
        1, SIM_WIND_SPD=5.0, SIM_WIND_DIR=90.0, SIM_WSTEP_T=10.0, SIM_WSTEP_SPD=3.0,
        SIM_WSTEP_DIR=45.0,
    )  # fmt: skip
    run_until(sim, 9.98)
    assert sim.wind_m_s == pytest.approx(Wind.from_meteo(5.0, 90.0).vector, abs=1e-9)
    sim.step()
    assert sim.t_s == pytest.approx(10.0)
    assert sim.wind_m_s == pytest.approx(Wind.from_meteo(8.0, 135.0).vector, abs=1e-9)
    # a step that would reverse the wind stops at calm
    w = WindProfile(2.0, 0.0, step_t_s=1.0, step_speed_m_s=-5.0)
    assert wind_speed_from(2.0, w)[0] == 0.0
    assert not WindProfile(5.0, 0.0, step_t_s=0.0, step_speed_m_s=3.0).varies


def test_wind_never_reaches_the_airspeed():
    sim, _ = fleet(2, SIM_WIND_SPD=30.0, SIM_WIND_TURB=3.0)
    run_until(sim, 5.0)
    assert np.all(np.abs(sim.wind_true_m_s) <= 0.9 * 20.0 + 1e-9)
    assert np.all(np.abs(true_velocity(sim)) >= 2.0 - 1e-9)
    capped = [e for e in sim.drain_events() if e.event == "wind_capped"]
    assert len(capped) == 1 and capped[0].sysid is None


def test_truth_log_wind_columns_are_the_wind_that_moved_the_vehicle():
    sim, _ = fleet(2, SIM_WIND_SPD=4.0, SIM_WIND_DIR=90.0, SIM_WIND_TURB=1.0)
    run_until(sim, 3.0)
    assert TRUTH_HEADER.split(",") == list(TRUTH_COLUMNS)
    assert TRUTH_COLUMNS[-2:] == ("wind_north_m_s", "wind_east_m_s")
    for line in sim.truth_rows():
        r = dict(zip(TRUTH_COLUMNS, line.split(","), strict=True))
        ground = float(r["groundspeed_m_s"]) * np.exp(1j * np.radians(float(r["course_deg"])))
        air = 20.0 * np.exp(1j * np.radians(float(r["heading_deg"])))
        wind = complex(float(r["wind_north_m_s"]), float(r["wind_east_m_s"]))
        assert ground - air == pytest.approx(wind, abs=5e-3)
        assert wind.imag < -2.0  # from the East: the air moves West


@pytest.mark.parametrize("header", [TRUTH_COLUMNS, TRUTH_COLUMNS_NO_WIND])
def test_run_folders_with_and_without_the_wind_columns_are_read(tmp_path, header):
    (tmp_path / "mission.yaml").write_text(Path(ELLIPSE).read_text())
    row = ["0.100", "1", "10.000", "20.000", "100.00", "0.0", "0.0", "20.0", "0.0", "GUIDED"]
    row += ["1.000", "-2.000"][: len(header) - len(row)]
    (tmp_path / "truth.csv").write_text(",".join(header) + "\n" + ",".join(row) + "\n")
    run = load_run(tmp_path)
    assert run.tracks[1].pos_m[0] == 10.0 + 20.0j


# -------------------------------------------------------------------------- WIND estimate


def test_wind_estimate_lags_a_step_with_its_time_constant():
    tau = 10.0
    sim, tm = fleet(
        1, SIM_WIND_SPD=4.0, SIM_WIND_DIR=90.0, SIM_WSTEP_T=5.0, SIM_WSTEP_SPD=4.0,
        SIM_WEST_TAU=tau, SIM_WEST_ERR=0.0,
    )  # fmt: skip
    run_until(sim, 4.98)
    m = tm.wind(0)
    assert (m.speed, m.direction, m.speed_z) == pytest.approx((4.0, 90.0, 0.0))  # FROM the East
    for t in (5.0 + tau, 5.0 + 2 * tau, 5.0 + 5 * tau):
        run_until(sim, t)
        m = tm.wind(0)
        assert m.speed == pytest.approx(8.0 - 4.0 * math.exp(-(t - 5.0) / tau), abs=1e-6)
        assert m.direction == pytest.approx(90.0, abs=1e-6)
    # and the truth moved at once
    assert sim.wind_m_s == pytest.approx(-8.0j, abs=1e-9)


@pytest.mark.parametrize("from_deg", [0.0, 45.0, 200.0, 315.0])
def test_wind_message_reports_where_the_wind_comes_from(from_deg):
    sim, tm = fleet(1, SIM_WIND_SPD=6.0, SIM_WIND_DIR=from_deg, SIM_WEST_ERR=0.0)
    run_until(sim, 1.0)
    m = tm.wind(0)
    assert m.speed == pytest.approx(6.0)
    assert (m.direction - from_deg + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-6)


def test_wind_estimate_error_statistics():
    """Reported - lagged truth: Gauss-Markov, sigma SIM_WEST_ERR per axis, correlation 60 s."""
    n, sigma = 400, 0.3
    truth = np.full(n, 3.0 + 1.0j)
    errs = SensorErrors(
        ErrorParams(wind_est_tau_s=10.0, wind_est_sigma_m_s=sigma),
        truth,
        np.random.default_rng(1),
        np.random.default_rng(2),
    )
    cfg = ErrorParams(wind_est_tau_s=10.0, wind_est_sigma_m_s=sigma)
    samples = []
    for k in range(15000):  # 300 s at 50 Hz
        errs.step(cfg, truth, DT_S)
        if k % 50 == 0:
            samples.append(errs.wind_reported_m_s - truth)
    e = np.array(samples)
    assert np.std(e.real) == pytest.approx(sigma, rel=0.1)
    assert np.std(e.imag) == pytest.approx(sigma, rel=0.1)
    assert decorrelation_time_s(e.real, 1.0, 30) == pytest.approx(60.0, rel=0.35)


def test_default_wind_estimate_is_close_but_not_the_truth():
    sim, tm = fleet(4, seed=3, SIM_WIND_SPD=5.0, SIM_WIND_DIR=180.0)
    run_until(sim, 2.0)
    speeds = [tm.wind(i).speed for i in range(4)]
    assert all(abs(s - 5.0) < 1.5 for s in speeds)
    assert len({round(s, 6) for s in speeds}) == 4  # one estimate per vehicle


# ----------------------------------------------------------------------------- parameters


@pytest.mark.parametrize(
    ("name", "bad"),
    [
        ("SIM_GPS_NOISE", -0.1),
        ("SIM_GPS_TAU", 0.0),
        ("SIM_GPS_VNOISE", 11.0),
        ("SIM_WDRIFT_SPD", -1.0),
        ("SIM_WDRIFT_DIR", 181.0),
        ("SIM_WDRIFT_T", 0.0),
        ("SIM_WSTEP_T", -1.0),
        ("SIM_WSTEP_SPD", 51.0),
        ("SIM_WSTEP_DIR", -181.0),
        ("SIM_WEST_TAU", -1.0),
        ("SIM_WEST_ERR", math.nan),
    ],
)
def test_out_of_range_disturbance_params_are_refused(name, bad, capsys):
    p = Params()
    with pytest.raises(ParamError):
        p.set(name, bad)
    assert main(["--param", f"{name}={bad}", "--no-control"]) == 2
    assert name in capsys.readouterr().err


def test_defaults_and_units():
    p = Params()
    want = {
        "SIM_GPS_NOISE": 0.0, "SIM_GPS_TAU": 30.0, "SIM_GPS_VNOISE": 0.0,
        "SIM_WDRIFT_SPD": 0.0, "SIM_WDRIFT_DIR": 0.0, "SIM_WDRIFT_T": 600.0,
        "SIM_WSTEP_T": 0.0, "SIM_WSTEP_SPD": 0.0, "SIM_WSTEP_DIR": 0.0,
        "SIM_WEST_TAU": 10.0, "SIM_WEST_ERR": 0.3,
    }  # fmt: skip
    assert {k: p[k] for k in want} == want
    assert all(len(n) <= 16 for n in Params.names())


def test_explicit_param_overrides_the_missions_wind():
    """The robustness bench flies a world whose wind differs from the mission's forecast."""
    args = build_parser().parse_args(["--mission", ELLIPSE])
    sim, _, _ = build(args)
    assert (sim.params["SIM_WIND_SPD"], sim.params["SIM_WIND_DIR"]) == (5.0, 180.0)
    for extra in ([], ["--wind-speed", "1", "--wind-from", "10"]):
        argv = ["--mission", ELLIPSE, *extra, "--param", "SIM_WIND_SPD=8"]
        argv += ["--param", "SIM_WIND_DIR=225", "--param", "SIM_WDRIFT_SPD=2"]
        sim, _, _ = build(build_parser().parse_args(argv))
        assert (sim.params["SIM_WIND_SPD"], sim.params["SIM_WIND_DIR"]) == (8.0, 225.0)
        assert sim.params["SIM_WDRIFT_SPD"] == 2.0
        w = WindProfile.from_params(sim.params)
        assert sim.wind_m_s == pytest.approx(Wind.from_meteo(*wind_speed_from(0.0, w)).vector)
