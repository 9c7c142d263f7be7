"""``companion fleet --autopilot px4``: three real PX4 SITL (SIH) aircraft fly the ellipse.

The paper's ellipse cut to three UAVs, in still air (``tests/data/ellipse_3uav_still.yaml``: a
copy of the three-UAV mission with zero wind, since PX4's SIH simulates none), 500 s of
vehicle time at speed factor 3: the fleet takes off, the companions enter OFFBOARD, the
aircraft keep to the loop and splay out, the decoy (at 400 s) is answered by exactly one UAV,
the instances' clocks stay together, and every process and PX4 lock is gone at the end. Its
figures are printed (``pytest -m integration -s tests/test_px4_fleet.py``); the goals of
issue 23 are published in docs/px4.md, not asserted as timings.

Skipped, with the reason, without a PX4 SITL folder (``$PX4_SITL_DIR``, which
``tests/conftest.py`` sets to ``../shared/px4`` beside the clone where that exists). About 3
minutes of wall time on the 2-core machine.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from companion.commands.fleet import NOT_HELD
from companion.link.px4 import OFFBOARD_CUSTOM_MODE
from companion.mission import load_mission
from companion.sim.px4 import sitl
from tests.fleet_harness import run_to_end
from tests.flown import fleet_flights
from tests.px4_harness import px4_missing

# real processes, sockets, the wall clock; alone: real PX4 SITL, free-running
pytestmark = [pytest.mark.integration, pytest.mark.alone]

REPO = Path(__file__).resolve().parents[1]
MISSION = REPO / "tests" / "data" / "ellipse_3uav_still.yaml"
ALERT_T_S = load_mission(MISSION).intruders[0].appear_t_s  # the decoy appears (400 s)
DURATION_S = ALERT_T_S + 100.0  # answered, checked and back in the slot (about 50 s)
SETTLE_S = 60.0  # vehicle s in OFFBOARD before the airspeed and altitude are judged


@pytest.mark.slow
@pytest.mark.skipif(px4_missing() is not None, reason=f"no PX4 SITL: {px4_missing()}")
def test_three_px4_aircraft_converge_on_the_ellipse_and_one_answers_the_alert(tmp_path: Path):
    from companion.report.metrics import formation_series, loop_geometry
    from companion.report.rundata import load_run

    out = tmp_path / "run"
    t0 = time.monotonic()
    r = run_to_end(
        [sys.executable, "-m", "companion", "fleet", str(MISSION), "--autopilot", "px4",
         "--duration", f"{DURATION_S:g}", "--out", str(out), "--no-progress"],
        1200, cwd=REPO,
    )  # fmt: skip
    wall = time.monotonic() - t0
    # a firmware fleet says whether it held the patrol (the goals, 10 m p95 and 1.15
    # T/N), and exits 3 when not: a loaded 2-core machine may not hold them, which the
    # assertions below bound more loosely; the line and the status must agree
    verdicts = [ln for ln in r.stdout.splitlines() if ln.startswith("fleet: patrol ")]
    assert r.returncode in (0, NOT_HELD) and len(verdicts) == 1, r.stdout + r.stderr
    assert (r.returncode == 0) == verdicts[0].startswith("fleet: patrol held"), verdicts
    info = json.loads((out / "run_info.json").read_text())
    nums = [int(x) for x in re.search(r"numbers ([0-9,]+)", r.stdout).group(1).split(",")]
    metrics = json.loads((out / "metrics.json").read_text())
    run = load_run(out)
    period = run.mission.patrol.period_s
    taken = [
        e["t_s"]
        for e in run.events
        if e.get("event") == "authority" and e.get("after") == "commanding"
    ]
    series = formation_series(run)
    t, splay = series["t_s"], series["splay_deg"]
    t_cmd = max(taken)  # every companion commands from here
    first = (t >= t_cmd + period) & (t < t_cmd + 2 * period)
    last = (t >= ALERT_T_S - period) & (t < ALERT_T_S)  # the loop period before the decoy
    splay_first, splay_last = float(np.median(splay[first])), float(np.median(splay[last]))
    _, loop = loop_geometry(run.mission.patrol)
    xt = {}  # per sysid, over the two loop periods before the decoy: the settled loop
    for sysid, tr in run.tracks.items():
        keep = (tr.t_s >= ALERT_T_S - 2 * period) & (tr.t_s < ALERT_T_S)
        xt[sysid] = loop.distance_m(tr.pos_m[keep])
    xt_all = np.concatenate(list(xt.values()))
    alerts = metrics["alerts"]
    answered = {a.sysid for a in run.away_windows()}
    sk = info["clock_skew_s"]
    lost = [e for e in run.events if e.get("event") in ("override", "offboard_refused")]
    print(
        f"\nPX4 x3 (SIH, still air), {DURATION_S:.0f} s at speed factor 3 in {wall:.0f} s of wall "
        f"time; all in OFFBOARD at {t_cmd:.0f} s; splay {splay_first:.1f} deg -> "
        f"{splay_last:.1f} deg (medians over the 2nd loop period after that and the one before "
        f"{ALERT_T_S:.0f} s); convergence (strict rule) {metrics['convergence_time_s']} s; "
        f"cross-track median {np.median(xt_all):.1f} m, p95 {np.percentile(xt_all, 95):.1f} m, "
        f"max {xt_all.max():.1f} m over {ALERT_T_S - 2 * period:.0f}-{ALERT_T_S:.0f} s; clocks "
        f"apart {sk['median']:.3f} s median, {sk['p95']:.3f} s p95, {sk['max']:.3f} s max; "
        f"speed-ups {info['achieved_speedup']}; paused {info['paused_wall_s']} wall s"
    )
    for key in ("settle_time_s", "cross_track_p95_m", "coverage_revisit_ratio",
                "coverage_revisit_ratio_excl_alerts", "longest_unseen_ratio",
                "window_splay_error_median_deg", "fraction_within_bounds_excl_alerts"):  # fmt: skip
        print(f"  report {key}: {metrics.get(key)}")
    print(f"  took control at {sorted(round(x, 1) for x in taken)} s; left OFFBOARD: {lost}")
    for a in alerts:
        print(
            f"  alert {a['alert_id']}: UAV {a['prosecutor_sysid']} planned "
            f"{a['planned_time_s']} s, response {a['response_time_s']} s, {a['outcome']}, "
            f"rejoined after {a['rejoin_time_s']} s"
        )
    assert metrics["truth_source"].startswith("telemetry") and "still air" in info["truth_source"]
    assert len(taken) == 3 and not lost, lost
    # the loop under the sensor (its footprint radius, 50 m); the 10 m goal is published
    assert float(np.percentile(xt_all, 95)) <= 50.0, "the aircraft do not keep to the loop"
    assert splay_last < max(0.9 * splay_first, 5.0), "the aircraft do not splay out"
    assert len(alerts) == 1 and len(answered) == 1, (alerts, answered)
    a = alerts[0]
    assert a["response_time_s"] is not None
    assert a["response_time_s"] <= 1.5 * a["planned_time_s"] + 5.0
    assert sk["median"] < 0.25 and sk["p95"] < 1.0, "the instances' clocks drifted apart"
    # Each aircraft as the default PX4 profile flies it (attitude with thrust, the companion's
    # own airspeed and height holds; docs/px4.md): one setpoint per 10 Hz estimate, the
    # mission's airspeed and its altitude held over the loop periods before the decoy, and
    # nothing reported ignored or refused. (A one-aircraft flight, tests/test_px4.py, proves
    # this apart; it is left to the extended tier: this run flies the same, three times.)
    flights = fleet_flights(
        out, run.mission, OFFBOARD_CUSTOM_MODE, SETTLE_S, DURATION_S - ALERT_T_S
    )
    for sysid, f in flights.items():
        print(
            f"  UAV {sysid} in OFFBOARD after {SETTLE_S:.0f} s until the decoy: cross-track "
            f"p95 {f['xt_p95_m']:.1f} m, max {f['xt_max_m']:.1f} m (settled loop: max "
            f"{xt[sysid].max():.1f} m); airspeed "
            f"{f['airspeed_err_mean_m_s']:+.2f} m/s mean error; altitude "
            f"{f['alt_err_mean_m']:+.2f} m mean; {f['setpoints_per_s']:.1f} setpoints/s; "
            f"health {f['health']}"
        )
    ignored = [e for e in run.events if e.get("event") == "profile_ignored"]
    assert not ignored, ignored
    for sysid, f in flights.items():
        # PX4 leaves OFFBOARD below 2 Hz; the companion sends one per 10 Hz estimate while it
        # keeps up. Counted in OFFBOARD: 10.0/s with this test alone (2026-12-06; 9.3-9.9/s with
        # one aircraft, docs/px4.md). At speed factor 3 beside the CI's other tests the
        # companions are starved of CPU and drop estimates: 7.7-7.8/s in the fresh-clone CI of
        # 900888e (counted then over the whole run). A load figure, not a fault: the floor is
        # PX4's own 2 Hz with a margin, and the flight's quality is asserted above.
        assert f["setpoints_per_s"] >= 5.0, (sysid, f)
        # on the settled loop (2.6-5.0 m measured); from 60 s in OFFBOARD an aircraft may still
        # be closing on the loop from PX4's loiter (25.9 m once in CI, 3.8 m the whole fleet's
        # max over the settled window of that same run)
        assert xt[sysid].max() < 10.0, (sysid, xt[sysid].max())
        assert abs(f["airspeed_err_mean_m_s"]) < 1.5 and abs(f["alt_err_mean_m"]) < 5.0, f
    # nothing left behind: every PX4 lock removed, every instance's ports free again
    assert len(nums) == 3 and all(sitl.instance_busy(i) is None for i in nums), nums
    assert "unclean exits" not in r.stdout


def _left_behind(out: Path) -> list[str]:
    """Processes still running whose command line or working directory is under ``out``."""
    left = []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmd = (proc / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            cwd = str((proc / "cwd").resolve())
        except OSError:
            continue
        if str(out) in cmd or cwd.startswith(str(out)):
            left.append(f"{proc.name}: {cmd[:120]}")
    return left


def _start_fleet(out: Path, *extra: str) -> tuple[subprocess.Popen, list[int]]:
    """``companion fleet`` (one UAV) in the background, until it names its PX4 instances."""
    p = subprocess.Popen(
        [sys.executable, "-m", "companion", "fleet", str(REPO / "tests/data/ellipse_1uav.yaml"),
         "--autopilot", "px4", "--out", str(out), "--no-progress", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
    )  # fmt: skip
    for line in p.stdout:
        found = re.search(r"numbers ([0-9,]+)", line)
        if found:
            return p, [int(x) for x in found.group(1).split(",")]
    raise AssertionError(f"no PX4 instances started: {p.wait(60)} {p.stderr.read()}")


@pytest.mark.skipif(px4_missing() is not None, reason=f"no PX4 SITL: {px4_missing()}")
def test_sigterm_during_the_take_off_stops_every_process_by_pid(tmp_path: Path):
    out = tmp_path / "run"
    p, nums = _start_fleet(out)
    time.sleep(5.0)  # PX4 booting, the world process connected, the bring-up waiting for home
    p.send_signal(15)
    rest, err = p.communicate(timeout=90)
    assert p.returncode == 130, rest + err
    assert "SIGTERM: stopping every process" in rest
    assert all(sitl.instance_busy(i) is None for i in nums), nums
    assert _left_behind(out) == []


@pytest.mark.skipif(px4_missing() is not None, reason=f"no PX4 SITL: {px4_missing()}")
def test_offboard_refused_is_one_line_and_exit_2_with_nothing_left(tmp_path: Path):
    # COM_OF_LOSS_T 0: PX4's offboard check (commander, offboardCheck.cpp) counts a setpoint
    # as recent while now < its time + COM_OF_LOSS_T, so with 0 none ever is and every
    # request is refused (3 of 3 runs; 0.01 s, used before, let one through now and then)
    out = tmp_path / "run"
    p, nums = _start_fleet(out, "--sim-param", "COM_OF_LOSS_T=0")
    rest, err = p.communicate(timeout=300)
    lines = err.strip().splitlines()
    print(f"\n{lines}")
    assert p.returncode == 2, rest + err
    assert len(lines) == 1 and "OFFBOARD" in lines[0], lines
    assert all(sitl.instance_busy(i) is None for i in nums), nums
    assert _left_behind(out) == []
