"""``companion run`` lifecycle against the real simulator: bad input exits 2, it waits for a
late autopilot, survives the autopilot's restart (reconnect without restarting), and stops
cleanly on SIGINT and SIGTERM (exit 0, logs flushed, the tlog readable by pymavlink)."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavutil

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.link.mission_protocol.from_autopilot import mission_yaml
from companion.mission import parse_mission
from sitl_model.codec import dialect as d
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.server import free_base_port
from sitl_model.testing import MavClient, SitlProcess
from tests.fleet_harness import FAST, Companion, companion_cli, free_udp_port

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock


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
        timeout=180,
    )
    assert r.returncode == 0 and "SYSTEM_TIME" in r.stdout


def square_wpl(path: Path, half_m: float = 300.0) -> list[tuple[int, int]]:
    """A QGC WPL 110 file (home line, then four corners of a square around the simulator's
    default home at 100 m); returns the corners in degE7 as an autopilot stores them."""
    frame = LocalFrame(*DEFAULT_ORIGIN)
    lat0, lon0, alt0 = DEFAULT_ORIGIN
    rows = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{lat0}\t{lon0}\t{alt0}\t1"]
    corners = []
    for k, (n, e) in enumerate(((1, -1), (1, 1), (-1, 1), (-1, -1)), start=1):
        lat, lon, _ = frame.to_geodetic(n * half_m, e * half_m, 0.0)
        rows.append(f"{k}\t0\t3\t16\t0\t0\t0\t0\t{lat:.7f}\t{lon:.7f}\t100\t1")
        corners.append((round(float(f"{lat:.7f}") * 1e7), round(float(f"{lon:.7f}") * 1e7)))
    path.write_text("\n".join(rows) + "\n")
    return corners


def vehicle_t(line: str) -> float | None:
    """The vehicle time (Unix s) of a ``companion`` status line, if it has one."""
    part = next((p for p in line.split() if p.startswith("t=")), "t=-")
    return None if part == "t=-" else float(part[2:])


def test_loop_from_the_autopilots_stored_mission(tmp_path):
    """``companion upload`` to an ArduPilot (the simulator) leaves home in item 0 and the
    perimeter in items 1..4; ``companion run`` without --mission builds its loop from items
    1..4 (with home, inside the square, the mission loader would refuse it) and flies it."""
    base = free_base_port(1)
    log, truth, wpl = tmp_path / "c1", tmp_path / "truth.csv", tmp_path / "square.waypoints"
    corners = square_wpl(wpl)
    sim_args = ("--speedup", "20", "--base-port", str(base), "--truth-log", str(truth))
    with SitlProcess(*sim_args, vehicles=1):
        url = f"udpout:127.0.0.1:{base}"
        r = companion_cli("upload", str(wpl), "--connect", url, "--sysid", "1", "--listen-s", "10")
        assert r.returncode == 0, r.stderr
        assert r.stdout.startswith(
            "sysid 1: uploaded 4 waypoints, verified (ArduPilot: item 0 "
            "is home at -35.3632610, 149.1652300, 584.0 m AMSL"
        ), r.stdout
        client = MavClient(base)
        try:
            client.send(d.MAVLink_mission_request_list_message(1, 1, 0))
            assert client.match("MISSION_COUNT").count == 5
            items = []
            for k in range(5):
                client.send(d.MAVLink_mission_request_int_message(1, 1, k, 0))
                items.append(client.match("MISSION_ITEM_INT", cond=lambda m, k=k: m.seq == k))
            home = client.match("HOME_POSITION", timeout_s=10)
        finally:
            client.close()
        assert (items[0].command, items[0].frame) == (16, 0)  # NAV_WAYPOINT, GLOBAL
        assert (items[0].x, items[0].y) == (home.latitude, home.longitude)
        assert [(it.x, it.y) for it in items[1:]] == corners
        c = Companion(
            [
                "--connect", url,
                "--insecure",
                "--group", f"239.255.14.10:{free_udp_port()}",
                "--log-dir", str(log),
                "--status-interval", "0.5",
            ]
        )  # fmt: skip

        def commanding() -> list[float]:
            """Vehicle times (s) of the status lines that say it is commanding."""
            return [t for ln in c.lines if "auth=commanding" in ln
                    and (t := vehicle_t(ln)) is not None]  # fmt: skip

        try:
            wait_for(lambda: commanding(), 40, "no command")
            t0 = commanding()[0]  # then 100 s simulated: out from home onto the loop
            wait_for(lambda: commanding()[-1] > t0 + 100.0, 30, "no 100 s of commanding")
            t1 = commanding()[-1] - SIM_EPOCH_UNIX_S  # the truth log's simulated time (s)
        finally:
            code = c.stop()
    assert code == 0
    text = "".join(c.lines)
    assert "loop from the 4 waypoints in system 1's mission items 1..4 (ArduPilot" in text, text
    final = [ln for ln in c.lines if ln.startswith("companion final")][-1]
    assert int(final.split("setpoints=")[1].split()[0]) > 10
    # the loop it flies: the square's rounded hull (built as the companion does, no wind)
    wps = [(x * 1e-7, y * 1e-7) for x, y in corners]
    ring = parse_mission(mission_yaml(1, wps, {"HOME_POSITION": home}), "<loop>")
    ring = ring.patrol.sample_by_time(2000)  # local m from home = the simulator's origin
    with open(truth) as f:
        rows = [r for r in csv.DictReader(f) if r["sysid"] == "1"]
    late = [complex(float(r["north_m"]), float(r["east_m"])) for r in rows
            if t1 - 10.0 <= float(r["t_s"]) <= t1]  # fmt: skip
    assert len(late) > 10
    off = max(float(np.min(np.abs(ring - z))) for z in late)
    assert off < 60.0, off  # on the loop (a GUIDED loiter at home: about 300 m off it)


def test_run_refuses_a_key_file_readable_by_others(tmp_path):
    """A fleet key others can read is refused before anything starts (exit 2, one line)."""
    key = tmp_path / "fleet.key"
    assert companion_cli("keygen", str(key)).returncode == 0
    key.chmod(0o644)
    r = companion_cli(
        "run", "--connect", "udpout:127.0.0.1:9", "--mission", str(FAST), "--key-file", str(key)
    )
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert str(key) in r.stderr and "chmod 600" in r.stderr, r.stderr
