"""``companion run`` lifecycle against the real simulator: bad input exits 2, it waits for a
late autopilot, survives the autopilot's restart (reconnect without restarting), and stops
cleanly on SIGINT and SIGTERM (exit 0, logs flushed, the tlog readable by pymavlink)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil
from test_companion_fleet import FAST, Companion, companion_cli, free_udp_port

from sitl_model.testing import SitlProcess, free_base_port


def events(path: Path) -> list[dict]:
    return [json.loads(ln) for ln in path.read_text().splitlines()]


def wait_for(cond, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.1)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mission", str(FAST)], "give --key-file FILE (or --insecure"),
        (["--mission", str(FAST), "--insecure", "--faults", "loss=2"], "--faults"),
        (["--mission", str(FAST), "--insecure", "--group", "10.0.0.1:14600"], "multicast"),
        (["--mission", "/nonexistent.yaml", "--insecure"], "nonexistent"),
        (["--mission", str(FAST), "--insecure", "--max-prosecutors", "0"], "max-prosecutors"),
    ],
)
def test_bad_input_exits_2_with_one_line(args, message):
    r = companion_cli("run", "--connect", "udpout:127.0.0.1:9", *args)
    assert r.returncode == 2
    assert message in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


def test_late_autopilot_restart_and_clean_stop(tmp_path):
    base = free_base_port(1)
    log = tmp_path / "c1"
    c = Companion(
        [
            "--connect", f"udpout:127.0.0.1:{base}",
            "--mission", str(FAST),
            "--insecure",
            "--group", f"239.255.14.9:{free_udp_port()}",
            "--log-dir", str(log),
            "--faults", "loss=0.1,jitter=0.2,dup=0.01,reorder=0.05,seed=1",
            "--status-interval", "1",
        ]
    )  # fmt: skip
    try:
        c.wait_ready()
        time.sleep(4.0)  # longer than the link timeout: the link is re-opened meanwhile
        sim_args = ("--vehicles", "1", "--speedup", "10", "--base-port", str(base))
        with SitlProcess(*sim_args):
            wait_for(lambda: any("auth=commanding" in ln for ln in c.lines), 20, "no command")
        # the autopilot is gone: the companion notices, keeps running, and relinks
        wait_for(lambda: "link_lost" in (log / "events.jsonl").read_text(), 20, "no loss")
        assert c.proc.poll() is None
        with SitlProcess(*sim_args) as sim2:
            n = len(c.lines)
            wait_for(lambda: any("auth=commanding" in ln for ln in c.lines[n:]), 20, "no relink")
            time.sleep(1.0)
            c.proc.send_signal(signal.SIGINT)
            c.proc.wait(10)
            assert sim2.proc.poll() is None
    finally:
        code = c.stop()
    assert code == 0
    evs = events(log / "events.jsonl")
    names = [e["event"] for e in evs]
    assert names[0] == "start" and names[-1] == "stop"
    assert names.count("link_lost") >= 1
    ups = [e for e in evs if e["event"] == "authority" and e["after"] == "commanding"]
    assert len(ups) >= 2  # commanding again after the autopilot came back
    # the tlog holds both directions and pymavlink reads it
    tl = mavutil.mavlink_connection(str(log / "autopilot.tlog"))
    kinds = set()
    while (m := tl.recv_match()) is not None:
        kinds.add((m.get_type(), m.get_srcComponent()))
    tl.close()
    assert ("SET_ATTITUDE_TARGET", 191) in kinds and ("HEARTBEAT", 191) in kinds
    assert ("GLOBAL_POSITION_INT", 1) in kinds and ("SYSTEM_TIME", 1) in kinds
    r = subprocess.run(
        [
            str(Path(sys.executable).parent / "mavlogdump.py"),
            "--types",
            "SYSTEM_TIME",
            str(log / "autopilot.tlog"),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0 and "SYSTEM_TIME" in r.stdout


def test_loop_from_the_autopilots_stored_mission(tmp_path):
    """Without --mission the loop is the hull of the autopilot's stored waypoints."""
    base = free_base_port(1)
    log = tmp_path / "c1"
    sim_args = ("--mission", str(FAST), "--speedup", "10", "--base-port", str(base))
    with SitlProcess(*sim_args, vehicles=6):
        c = Companion(
            [
                "--connect", f"udpout:127.0.0.1:{base}",
                "--insecure",
                "--group", f"239.255.14.10:{free_udp_port()}",
                "--log-dir", str(log),
                "--status-interval", "1",
            ]
        )  # fmt: skip
        try:
            wait_for(lambda: any("setpoints=" in ln and "auth=commanding" in ln
                                 for ln in c.lines), 40, "no command")  # fmt: skip
        finally:
            code = c.stop()
    assert code == 0
    text = "".join(c.lines)
    assert "auth=commanding" in text
    evs = events(log / "events.jsonl")
    assert any(e["event"] == "link_up" and e["autopilot_sysid"] == 1 for e in evs)
    final = [ln for ln in c.lines if ln.startswith("companion final")][-1]
    assert int(final.split("setpoints=")[1].split()[0]) > 10
