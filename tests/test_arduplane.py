"""The companion on real ArduPlane firmware (ArduPlane SITL): ``companion fleet --autopilot
arduplane``.

The pure parts (binary look-up, ports, parameters from the mission, clock slewing, truth
interpolation) run everywhere. The rest starts real ``arduplane`` processes and is skipped,
with the reason, where no binary is given (``$ARDUPLANE_SITL``; ``tests/conftest.py`` sets it to
``../shared/arduplane/arduplane`` beside the clone where that exists). Figures print under
``pytest -s``.

Cost on the 2-core CI machine: the bad-input tests a few seconds each (no instance, or one
instance for about 10 s); the three-aircraft ellipse (500 s of vehicle time at 5x) about
2.5 minutes of wall time; the SIGTERM test about 15 s.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from companion.commands.fleet import NOT_HELD
from companion.contracts.errors import UserError
from companion.link.modes import GUIDED
from companion.mission import load_mission
from companion.sim.arduplane import bringup, sitl
from companion.sim.arduplane.world import (
    Sample,
    clocks_now_s,
    handover_cap,
    interpolate,
    slewed_speedups,
)
from tests import firmware_env
from tests.firmware_env import provide_firmware
from tests.fleet_harness import run_to_end
from tests.flown import fleet_flights

# real processes or sockets, wall clock; alone: real ArduPlane SITL, free-running
pytestmark = [pytest.mark.integration, pytest.mark.alone]

REPO = Path(__file__).resolve().parents[1]
MISSION_3 = REPO / "tests" / "data" / "ellipse_3uav.yaml"
ALERT_3_S = load_mission(MISSION_3).intruders[0].appear_t_s  # the decoy appears (400 s)
DURATION_3_S = ALERT_3_S + 100.0  # answered, checked and back in the slot (about 50 s)
SETTLE_S = 60.0  # vehicle s in GUIDED before the airspeed and altitude are judged


def _binary() -> Path | None:
    try:
        return sitl.find_binary(None)
    except UserError:
        return None


BINARY = _binary()
needs_binary = pytest.mark.skipif(
    BINARY is None,
    reason=f"no ArduPlane SITL binary (${sitl.ENV_VAR} unset, none at "
    f"{firmware_env.beside()[sitl.ENV_VAR]})",
)


def _fleet_cli(*args: str, timeout: float = 180.0) -> subprocess.CompletedProcess:
    return run_to_end([sys.executable, "-m", "companion", "fleet", *args], timeout, cwd=REPO)


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.2)
        return s.connect_ex(("127.0.0.1", port)) == 0


# ---- pure -----------------------------------------------------------------------------------
def test_binary_lookup_order_and_errors(tmp_path):
    exe = tmp_path / "arduplane"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(stat.S_IRWXU)
    other = tmp_path / "other"
    other.write_text("#!/bin/sh\n")
    other.chmod(stat.S_IRWXU)
    assert sitl.find_binary(str(exe), env={sitl.ENV_VAR: str(other)}) == exe.resolve()
    assert sitl.find_binary(None, env={sitl.ENV_VAR: str(other)}) == other.resolve()
    # neither given: the product looks nowhere else, even with a binary beside the repository
    with pytest.raises(UserError, match=r"no ArduPlane SITL binary given: pass --arduplane-bin "
                       r"PATH or set \$ARDUPLANE_SITL.*waf"):  # fmt: skip
        sitl.find_binary(None, env={})
    with pytest.raises(UserError, match=r"no such file.*waf"):
        sitl.find_binary(str(tmp_path / "missing"), env={})
    exe.chmod(stat.S_IRUSR | stat.S_IWUSR)
    with pytest.raises(UserError, match="not executable"):
        sitl.find_binary(str(exe), env={})


def test_the_tests_point_arduplane_sitl_at_the_shared_binary_beside_the_clone(tmp_path):
    # tests/conftest.py's provider: ../shared/arduplane/arduplane beside the repository when
    # $ARDUPLANE_SITL is unset and the file exists; a variable already set is kept
    repo = tmp_path / "repo"
    repo.mkdir()
    env: dict[str, str] = {}
    (tmp_path / "shared" / "arduplane").mkdir(parents=True)  # the folder, but no binary
    assert provide_firmware(env, repo) == {} and env == {}
    exe = tmp_path / "shared" / "arduplane" / "arduplane"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(stat.S_IRWXU)
    assert provide_firmware(env, repo) == {sitl.ENV_VAR: str(exe)}
    assert sitl.find_binary(None, env=env) == exe.resolve()
    env = {sitl.ENV_VAR: "/opt/mine/arduplane"}
    assert provide_firmware(env, repo) == {} and env == {sitl.ENV_VAR: "/opt/mine/arduplane"}
    # the provider's root is where pyproject.toml is, so the binary is looked for in ../shared
    # beside it (a move of the look-up once left it one folder too deep, and every ArduPlane
    # test skipped without a word)
    assert (firmware_env.REPO / "pyproject.toml").is_file()
    assert firmware_env.beside()[sitl.ENV_VAR] == (
        firmware_env.REPO.parent / "shared" / "arduplane" / "arduplane"
    )
    assert firmware_env.ARDUPLANE_VAR == sitl.ENV_VAR


def test_mission_parameters_and_homes(tmp_path):
    m = load_mission(MISSION_3)
    p = sitl.mission_params(m, 2, 5.0)
    assert p["AIRSPEED_CRUISE"] == 20.0
    assert p["SIM_WIND_SPD"] == 5.0 and p["SIM_WIND_DIR"] == 180.0
    # the bank that turns at 18 deg/s at ArduPlane's 0.70 of g tan(phi) / V:
    # atan(20 * 0.31416 / (9.80665 * 0.70)) = atan(0.9153) = 42.47 deg (the ideal
    # coordinated bank, 32.6 deg, flew 0.70 x 18 = 12.6 deg/s: docs/arduplane.md)
    assert p["ROLL_LIMIT_DEG"] == pytest.approx(42.5, abs=0.05)
    assert p["TKOFF_ALT"] == 110.0  # the second vehicle's altitude
    assert p["GUIDED_TIMEOUT"] == 5.0
    specs = sitl.instance_specs(m, 40000, tmp_path)
    assert [s.ports.serial1 for s in specs] == [40002, 40012, 40022]
    assert specs[0].home[0] < specs[1].home[0] < specs[2].home[0]  # the line, south to north
    argv = sitl.instance_argv(Path("/x/arduplane"), specs[1], 10.0, 1_767_225_600)
    assert argv[argv.index("--sysid") + 1] == "2"
    assert argv[argv.index("--start-time") + 1] == "1767225600"
    assert "--wipe" in argv


def test_arduplane_parameters_from_the_command_line():
    from companion.sim.arduplane.fleet import parse_param

    assert parse_param("sim_wind_turb=1") == "SIM_WIND_TURB=1"
    assert parse_param("ROLL_LIMIT_DEG = 45") == "ROLL_LIMIT_DEG=45"
    for bad in ("ROLL_LIMIT_DEG", "=3", "X=nan", "A;B=1", "WAY_TOO_LONG_PARAMETER_NAME=1"):
        with pytest.raises(UserError, match="expected NAME=VALUE"):
            parse_param(bad)


def test_clock_slewing_meets_the_slowest():
    clocks = clocks_now_s([(10.0, 100.0, 10.0), (10.1, 99.5, 10.0), (9.9, 101.0, 5.0)], 10.2)
    assert clocks == pytest.approx([102.0, 100.5, 102.5])
    x = slewed_speedups(clocks, 10.0, 0.5)
    assert x[1] == 10.0  # the slowest keeps the speed-up
    assert x[0] == pytest.approx(10.0 * (1 - 1.5 / 10.0))
    assert min(x) >= sitl_min(10.0)
    # each sample halves the lead, so the clocks meet
    t = np.array([0.0, 2.0, 8.0])
    for _ in range(12):
        t = t + 0.5 * np.array(slewed_speedups(list(t), 10.0, 0.5))
    assert t.max() - t.min() < 0.01


def sitl_min(x: float) -> float:
    from companion.sim.arduplane.world import SLEW_MIN

    return SLEW_MIN * x


def test_truth_interpolation_takes_angles_the_short_way():
    a = Sample(1.0, 0j, 100.0, 350.0, 350.0, 20.0)
    b = Sample(2.0, 10 + 20j, 110.0, 10.0, 20.0, 22.0)
    s = interpolate([a, b], 1.5)
    assert s.pos_m == 5 + 10j and s.alt_m == 105.0
    assert s.heading_deg == pytest.approx(0.0) and s.course_deg == pytest.approx(5.0)
    assert interpolate([a, b], 2.5) is None


# ---- bad input: one line, exit 2 ------------------------------------------------------------
def test_missing_and_non_executable_binary_exit_2(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != sitl.ENV_VAR}
    r = run_to_end(
        [sys.executable, "-m", "companion", "fleet", str(MISSION_3), "--autopilot", "arduplane",
         "--out", str(tmp_path / "run0")],
        180.0, cwd=REPO, env=env,
    )  # fmt: skip
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "--arduplane-bin PATH or set $ARDUPLANE_SITL" in r.stderr
    assert not (tmp_path / "run0").exists()
    print(f"\nno binary given: {r.stderr.strip()}")
    r = _fleet_cli(
        str(MISSION_3), "--autopilot", "arduplane", "--arduplane-bin", str(tmp_path / "none")
    )
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "no such file" in r.stderr and "waf" in r.stderr
    f = tmp_path / "arduplane"
    f.write_text("not a program")
    r = _fleet_cli(str(MISSION_3), "--autopilot", "arduplane", "--arduplane-bin", str(f))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "not executable" in r.stderr
    print(f"\nmissing binary: {r.stderr.strip()}")


@needs_binary
def test_port_in_use_exit_2(tmp_path):
    base = sitl.free_base(3)
    with socket.socket() as s:
        s.bind(("0.0.0.0", base + 12))  # instance 1's SERIAL1
        s.listen()
        r = _fleet_cli(
            str(MISSION_3), "--autopilot", "arduplane", "--arduplane-base-port", str(base),
            "--out", str(tmp_path / "run"),
        )  # fmt: skip
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and f"port {base + 12}/tcp" in r.stderr
    print(f"\nport in use: {r.stderr.strip()}")


@needs_binary
def test_an_instance_that_never_arms_is_one_line_and_a_clean_stop(tmp_path, monkeypatch):
    from companion.sim.arduplane.fleet import ArduPlaneFleet
    from companion.sim.fleet import FleetConfig

    monkeypatch.setattr(bringup, "ARM_TIMEOUT_SIM_S", 1.0)  # GPS lock alone takes ~10 s
    monkeypatch.setattr(bringup, "MIN_WALL_TIMEOUT_S", 1.0)
    m = load_mission(MISSION_3)
    fleet = ArduPlaneFleet(FleetConfig(MISSION_3, tmp_path, speedup=1.0), m, say=lambda _: None)
    try:
        with pytest.raises(UserError, match=r"did not arm in TAKEOFF mode within 1 s") as exc:
            fleet.start()
    finally:
        results = fleet.stop()
    assert "\n" not in str(exc.value)
    assert all(p.popen.poll() is not None for p in fleet.procs)
    assert all(rc == 0 for name, rc in results if name.startswith("arduplane"))
    assert not any(_listening(s.ports.serial0) for s in fleet.specs)
    print(f"\nnever arms: {exc.value}")


@pytest.mark.slow
@needs_binary
def test_sigterm_stops_every_instance(tmp_path):
    base = sitl.free_base(3)
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "companion", "fleet", str(MISSION_3), "--autopilot",
            "arduplane", "--arduplane-base-port", str(base), "--out", str(tmp_path / "run"),
            "--no-progress",
        ],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        lines = []
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            lines.append(line)
            if "handing over" in line or not line:
                break
        assert any("handing over" in x for x in lines), "".join(lines)
        time.sleep(2.0)
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, out
    ports = [sitl.InstancePorts.at(base, i) for i in range(3)]
    assert not any(_listening(p.serial0) or _listening(p.serial1) for p in ports)
    assert (tmp_path / "run" / "truth.csv").is_file()
    print(f"\nSIGTERM: exit {proc.returncode}, no instance left on ports {base}..{base + 23}")


def test_the_handover_hold_slows_the_clocks_until_every_instance_is_guided():
    # two of three in GUIDED: still held at the hand-over speed
    assert handover_cap(10.0, 70.0, ["GUIDED", "LOITER", "GUIDED"], 5.0, 0.5) == (0.5, True)
    # all three: released to the run's speed-up
    assert handover_cap(10.0, 70.0, ["GUIDED"] * 3, 5.0, 0.5) == (5.0, False)
    # a companion that never takes control does not hold the run for ever
    assert handover_cap(70.5, 70.0, ["GUIDED", "LOITER", "GUIDED"], 5.0, 0.5) == (5.0, False)
    # never faster than asked: a run at 0.25x is not sped up by the hold
    assert handover_cap(10.0, 70.0, ["LOITER"] * 3, 0.25, 0.5) == (0.25, True)


# ---- the mission on ArduPlane -----------------------------------------------------------------
def _distances_m(run, t_from_s: float, t_to_s: float, whole_seconds: bool = False):
    """Per sysid: (times s, distance m from the loop) in [t_from_s, t_to_s), against the
    report's own polyline of the loop (every sample, or whole seconds only)."""
    from companion.report.metrics import loop_geometry

    _, loop = loop_geometry(run.mission.patrol)
    out = {}
    for sysid, tr in sorted(run.tracks.items()):
        keep = (tr.t_s >= t_from_s) & (tr.t_s < t_to_s)
        if whole_seconds:
            keep &= np.round(tr.t_s * 10) % 10 == 0
        out[sysid] = (tr.t_s[keep], loop.distance_m(tr.pos_m[keep]))
    return out


def _cross_track_m(run, t_from_s: float, t_to_s: float) -> np.ndarray:
    """Distance (m) of every vehicle from the loop, every second in [t_from_s, t_to_s)."""
    return np.concatenate([d for _, d in _distances_m(run, t_from_s, t_to_s, True).values()])


ROUTINE_EVENTS = {"guided_targets", "wind_agreed", "wind_proposed", "replan", "member_joined"}


def _worst_by_uav(run, t_from_s: float, t_to_s: float) -> dict[int, tuple[float, float, float]]:
    """Per sysid: p95 and worst distance from the loop (m), and when the worst was (s)."""
    out = {}
    for sysid, (t, d) in _distances_m(run, t_from_s, t_to_s).items():
        i = int(np.argmax(d))
        out[sysid] = (float(np.percentile(d, 95)), float(d[i]), float(t[i]))
    return out


@pytest.mark.slow
@needs_binary
def test_three_arduplanes_keep_the_loop_splay_and_one_answers_the_alert(tmp_path):
    """The ellipse cut to three UAVs, 500 s of vehicle time at 5x: the aircraft keep to the
    loop and splay out, the decoy (at 400 s) is answered by exactly one UAV, the instances'
    clocks stay together."""
    from companion.report.metrics import formation_series
    from companion.report.rundata import load_run

    out = tmp_path / "run"
    t0 = time.monotonic()
    r = _fleet_cli(
        str(MISSION_3), "--autopilot", "arduplane", "--speedup", "5",
        "--duration", f"{DURATION_3_S:g}", "--out", str(out), "--no-progress", timeout=600,
    )  # fmt: skip
    wall = time.monotonic() - t0
    # a firmware fleet says whether it held the patrol (the goals, 10 m p95 and 1.15
    # T/N), and exits 3 when not: a loaded 2-core machine may not hold them, which the
    # assertions below bound more loosely; the line and the status must agree
    verdicts = [ln for ln in r.stdout.splitlines() if ln.startswith("fleet: patrol ")]
    assert r.returncode in (0, NOT_HELD) and len(verdicts) == 1, r.stdout + r.stderr
    assert (r.returncode == 0) == verdicts[0].startswith("fleet: patrol held"), verdicts
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["truth_source"].startswith("telemetry")
    run = load_run(out)
    series = formation_series(run)
    t, splay = series["t_s"], series["splay_deg"]
    period = run.mission.patrol.period_s
    taken = [
        e["t_s"]
        for e in run.events
        if e.get("event") == "authority" and e.get("after") == "commanding"
    ]
    t_cmd = max(taken)  # every companion commands from here
    first = (t >= t_cmd + period) & (t < t_cmd + 2 * period)
    last = (t >= ALERT_3_S - period) & (t < ALERT_3_S)  # the loop period before the decoy appears
    splay_first, splay_last = float(np.median(splay[first])), float(np.median(splay[last]))
    alerts = metrics["alerts"]
    answered = {a.sysid for a in run.away_windows()}  # from its own tasking to its rejoin
    xt = _cross_track_m(run, ALERT_3_S - 2 * period, ALERT_3_S)
    xt_p95 = float(np.percentile(xt, 95))
    sk = metrics["clock_skew_s"]
    print(
        f"\nArduPlane x3, {DURATION_3_S:.0f} s at 5x in {wall:.0f} s of wall time; all "
        f"commanding at {t_cmd:.0f} s; splay {splay_first:.1f} deg -> {splay_last:.1f} deg "
        f"(medians over the 2nd loop period after that and the one before {ALERT_3_S:.0f} s); "
        f"convergence (strict rule) {metrics['convergence_time_s']} s; cross-track p95 "
        f"{xt_p95:.1f} m over {ALERT_3_S - 2 * period:.0f}-{ALERT_3_S:.0f} s; clocks apart "
        f"{sk['median']:.3f} s median, "
        f"{sk['p95']:.3f} s p95, {sk['max']:.3f} s max; speed-ups {metrics['achieved_speedup']}"
    )
    for key in (
        "settle_time_s", "cross_track_p95_m", "coverage_revisit_ratio", "longest_unseen_ratio",
        "fraction_within_bounds_excl_alerts", "handover",
    ):  # fmt: skip
        if key in metrics:
            print(f"  report {key}: {metrics[key]}")
    print(f"  took control at {sorted(round(x, 1) for x in taken)} s")
    worst_by_uav = _worst_by_uav(run, ALERT_3_S - 2 * period, ALERT_3_S)
    for sysid, (p95, worst, t_worst) in worst_by_uav.items():
        print(f"  UAV {sysid}: p95 {p95:.1f} m, worst {worst:.1f} m at {t_worst:.0f} s")
    notable = [
        (round(e["t_s"], 1), e.get("sysid"), e["event"])
        for e in run.events
        if e.get("event") not in ROUTINE_EVENTS
    ]
    print(f"  other events: {notable}")
    for a in alerts:
        print(
            f"  alert {a['alert_id']}: UAV {a['prosecutor_sysid']} planned "
            f"{a['planned_time_s']} s, response {a['response_time_s']} s, {a['outcome']}, "
            f"rejoined after {a['rejoin_time_s']} s"
        )
    # The loop under the sensor: within its footprint radius (50 m). Not the 10 m goal of the
    # issue, which is published (README, docs/arduplane.md), not asserted: free-running
    # ArduPlane instances on a loaded 2-core machine measured 5.3 and 27.7 m p95 with the
    # same code on 2026-12-01 (36.8 and 56 m before the bank gain learnt the roll lag).
    assert xt_p95 <= 50.0, "the aircraft do not keep to the loop"
    # splayed out, or already splayed by the second loop period (a loaded CI run read 2.2 deg
    # then and 2.2 deg before the decoy, which a plain "10 % less" called a failure)
    assert splay_last < max(0.9 * splay_first, 5.0), "the aircraft do not splay out"
    assert len(alerts) == 1 and len(answered) == 1, (alerts, answered)
    a = alerts[0]
    assert a["response_time_s"] is not None
    assert a["response_time_s"] <= 1.5 * a["planned_time_s"] + 5.0
    assert sk["median"] < 0.25 and sk["p95"] < 1.0, "the instances' clocks drifted apart"
    # The default profile on the real firmware (bank, with the companion's own airspeed and
    # height): over the loop periods before the decoy, each aircraft holds the mission's
    # airspeed and its altitude, its companion identified a turn-rate gain near ArduPlane's
    # 0.70 and reports nothing wrong. (A one-aircraft flight proves this apart, in
    # tests/test_arduplane_profiles.py, left to the extended tier: this run flies the same.)
    flights = fleet_flights(out, run.mission, GUIDED, SETTLE_S, DURATION_3_S - ALERT_3_S)
    for sysid, f in flights.items():
        print(
            f"  UAV {sysid} in GUIDED after {SETTLE_S:.0f} s until the decoy: airspeed "
            f"{f['airspeed_err_mean_m_s']:+.2f} m/s mean error, altitude "
            f"{f['alt_err_mean_m']:+.2f} m mean, {f['alt_err_p95_abs_m']:.2f} m p95; "
            f"{f['setpoints_per_s']:.1f} setpoints/s; gain {f['gain']}, health {f['health']}"
        )
    for sysid, f in flights.items():
        assert abs(f["airspeed_err_mean_m_s"]) < 1.0, (sysid, f)
        assert f["alt_err_p95_abs_m"] < 3.0, (sysid, f)
        assert 0.5 < float(f["gain"]) < 0.9, (sysid, f)
        assert f["health"] == "ok", (sysid, f)
