"""``companion fleet``: the one-command run, end to end, with real processes over loopback."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.fleet_harness import leftovers

ROOT = Path(__file__).resolve().parents[1]
FAST = ROOT / "tests" / "data" / "companion_ellipse_fast.yaml"
pytestmark = [pytest.mark.integration, pytest.mark.slow]


def fleet_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "companion", "fleet", *args]


# ``companion fleet`` end to end (its files, logs, the decoy, the summary) is checked on the
# equivalence test's fleet run: tests/test_inmemory_equivalence.py::fleet_run_is_complete


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
        output, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, output
    assert "stopping every process" in output
    assert leftovers(str(out)) == []
    assert (out / "metrics.json").is_file() and (out / "events.jsonl").is_file()


def test_a_killed_fleet_leaves_no_process_behind(tmp_path):
    """SIGKILL gives the fleet no chance to stop its processes, each in a session of its
    own: the kernel's parent-death signal ends them (companion.process.with_parent). Before
    it, a starved fleet killed by its test left six companions running for 50 minutes."""
    out = tmp_path / "run"
    proc = subprocess.Popen(
        fleet_cmd(str(FAST), "--duration", "2000", "--speedup", "10", "--out", str(out)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        while len(leftovers(str(out))) < 8 and time.monotonic() < deadline:
            assert proc.poll() is None
            time.sleep(0.2)  # the fleet, its simulator and its six companions
        assert len(leftovers(str(out))) == 8, leftovers(str(out))
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 60
    while leftovers(str(out)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert leftovers(str(out)) == []


def test_bad_mission_starts_nothing(tmp_path):
    bad = ROOT / "tests" / "data" / "bad_missions" / "wind_above_airspeed.yaml"
    proc = subprocess.run(
        fleet_cmd(str(bad), "--out", str(tmp_path / "run")),
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "below the airspeed" in proc.stderr
    assert not (tmp_path / "run").exists()
    assert os.path.exists(bad)


def test_a_simulator_slow_to_start_is_waited_for(tmp_path):
    """On a busy machine the simulator can take seconds to import and bind (CI at load 11:
    "no heartbeat within 2 s", and the fleet stopped). Its Python here waits 4 s first: the
    uploads wait for the first HEARTBEAT up to the set-up bound, then every vehicle has its
    perimeter and the companions start."""
    from companion.mission import load_mission
    from companion.sim.fleet import Fleet, FleetConfig

    slow = tmp_path / "python"
    slow.write_text(
        f'#!/bin/sh\ncase "$*" in *sitl_model*) sleep 4;; esac\nexec {sys.executable} "$@"\n'
    )
    slow.chmod(0o755)
    out = tmp_path / "run"
    out.mkdir()
    fleet = Fleet(
        FleetConfig(FAST, out, duration_s=30.0, speedup=10.0, python=str(slow)), load_mission(FAST)
    )
    try:
        fleet.start()
    finally:
        codes = fleet.stop()
    logs = sorted(out.glob("upload_*.log"))
    assert len(logs) == 6 and all("verified" in p.read_text() for p in logs), [
        p.read_text() for p in logs
    ]
    assert all(rc is not None for _, rc in codes), codes
    assert leftovers(str(out)) == []
