"""``companion fleet``: the one-command run, end to end, with real processes over loopback."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[1]
FAST = ROOT / "tests" / "data" / "companion_ellipse_fast.yaml"
pytestmark = [pytest.mark.integration, pytest.mark.slow]


def fleet_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "companion", "fleet", *args]


def leftovers(tag: str) -> list[str]:
    """Processes whose command line mentions ``tag`` (the run's own folder)."""
    out = subprocess.run(["pgrep", "-af", tag], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if "pgrep" not in line]


def test_fleet_runs_the_scenario_and_writes_the_report(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run(
        fleet_cmd(
            str(FAST), "--duration", "320", "--speedup", "20", "--out", str(out), "--no-progress"
        ),
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert leftovers(str(out)) == []
    for name in (
        "truth.csv",
        "events.jsonl",
        "metrics.json",
        "map.png",
        "coverage.png",
        "errors.png",
        "mission.yaml",
    ):
        assert (out / name).is_file(), name
    header = (out / "truth.csv").read_text().splitlines()[0]
    assert header == (
        "t_s,sysid,north_m,east_m,alt_m,heading_deg,course_deg,groundspeed_m_s,turn_rate_deg_s,mode,"
        "wind_north_m_s,wind_east_m_s"
    )
    events = [json.loads(x) for x in (out / "events.jsonl").read_text().splitlines()]
    times = [e["t_s"] for e in events]
    assert times == sorted(times) and times[0] >= 0 and times[-1] <= 330
    assert {e.get("source") for e in events} == {"sim", "companion"}  # both merged
    m = json.loads((out / "metrics.json").read_text())
    decoy = [a for a in m["alerts"] if a["outcome"] == "cleared"]
    assert len(decoy) == 1 and decoy[0]["prosecutor_sysid"] != decoy[0]["detector_sysid"]
    assert decoy[0]["planned_time_s"] > 0
    # every companion's tlog is a MAVLink log pymavlink reads
    tlog = out / "uav1" / "autopilot.tlog"
    log = mavutil.mavlink_connection(str(tlog))
    assert log.recv_match(type="HEARTBEAT") is not None
    assert "wrote" in proc.stdout and "alert" in proc.stdout


def test_sigterm_stops_every_process_and_still_writes_the_report(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen(
        fleet_cmd(
            str(FAST), "--duration", "2000", "--speedup", "10", "--out", str(out), "--no-progress"
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:  # until the companions are flying
            truth = out / "truth.csv"
            if truth.is_file() and truth.stat().st_size > 200_000:
                break
            assert proc.poll() is None, proc.stdout.read()
            time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        output, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, output
    assert "stopping every process" in output
    assert leftovers(str(out)) == []
    assert (out / "metrics.json").is_file() and (out / "events.jsonl").is_file()


def test_bad_mission_starts_nothing(tmp_path):
    bad = ROOT / "tests" / "data" / "bad_missions" / "wind_above_airspeed.yaml"
    proc = subprocess.run(
        fleet_cmd(str(bad), "--out", str(tmp_path / "run")),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "below the airspeed" in proc.stderr
    assert not (tmp_path / "run").exists()
    assert os.path.exists(bad)
