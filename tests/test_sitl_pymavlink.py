"""pymavlink's mavutil as a plain ground station against the simulator over UDP.

Connects to each vehicle, checks position and attitude against the truth log (aligned by
``time_boot_ms``), uploads a mission and downloads it back (item 0 replaced by home, as on
ArduPilot; the rest unchanged), changes the mode.
"""

from __future__ import annotations

import csv
import math
import os
import time

import numpy as np
import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.testing import SitlProcess

pytestmark = pytest.mark.integration

N = 2
FRAME = LocalFrame(*DEFAULT_ORIGIN)


@pytest.fixture(scope="module")
def sitl_gcs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sitl_gcs")
    proc = SitlProcess("--speedup", "10", "--truth-log", str(tmp / "truth.csv"), vehicles=N)
    proc.tmp = tmp
    links = []
    try:
        for i in range(N):
            m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{proc.port(i)}", source_system=255)
            m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, 8, 0, 0, 0)
            hb = m.wait_heartbeat(timeout=10)
            assert hb is not None and hb.get_srcSystem() == i + 1
            links.append(m)
        yield proc, links
    finally:
        for m in links:
            m.close()
        assert proc.stop() == 0


def truth_rows(path, sysid: int) -> np.ndarray:
    with open(path) as f:
        rows = [r for r in csv.DictReader(f) if r["sysid"] == str(sysid)]
    cols = ("t_s", "north_m", "east_m", "heading_deg", "turn_rate_deg_s")
    return np.array([[float(r[k]) for k in cols] for r in rows])


def test_position_and_attitude_match_truth(sitl_gcs):
    proc, links = sitl_gcs
    got = []
    for m in links:
        # a mode with a steady turn: CIRCLE flies half the turn-rate limit
        m.set_mode(m.mode_mapping()["CIRCLE"])
        ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
        assert ack is not None and ack.result == mavutil.mavlink.MAV_RESULT_ACCEPTED
        time.sleep(0.2)  # 2 s simulated into the steady turn; drop what was queued before
        while m.recv_match(blocking=False) is not None:
            pass
        for _ in range(6):
            g = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=5)
            a = m.recv_match(type="ATTITUDE", blocking=True, timeout=5)
            got.append((m.target_system, g, a))
    time.sleep(0.3)
    for sysid, g, a in got:
        rows = truth_rows(proc.tmp / "truth.csv", sysid)
        t = g.time_boot_ms / 1000.0
        n = np.interp(t, rows[:, 0], rows[:, 1])
        e = np.interp(t, rows[:, 0], rows[:, 2])
        local = FRAME.to_local(g.lat * 1e-7, g.lon * 1e-7)
        assert abs(local - complex(n, e)) < 0.3  # interpolating 2 m chords of a turn
        assert g.relative_alt == 100_000 + 10_000 * (sysid - 1)
        ta = a.time_boot_ms / 1000.0
        u = math.radians(np.interp(ta, rows[:, 0], rows[:, 4]))
        assert a.roll == pytest.approx(math.atan(20.0 * u / 9.80665), abs=1e-3)
        hdg = np.unwrap(np.radians(rows[:, 3]))
        yaw_err = (a.yaw - np.interp(ta, rows[:, 0], hdg) + math.pi) % (2 * math.pi) - math.pi
        assert abs(yaw_err) < 0.01
    assert any(abs(a.roll) > math.radians(10) for _, _, a in got)


def test_mission_upload_download_and_mode(sitl_gcs):
    _, links = sitl_gcs
    for m in links:
        sysid = m.target_system
        items = [
            mavutil.mavlink.MAVLink_mission_item_int_message(
                sysid,
                1,
                k,
                mavutil.mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                mavutil.mavlink.MAV_CMD_NAV_WAYPOINT,
                int(k == 0),
                1,
                0,
                25.0,
                0,
                0,
                round((DEFAULT_ORIGIN[0] + 0.003 * (k % 2)) * 1e7),
                round((DEFAULT_ORIGIN[1] + 0.003 * (k // 2)) * 1e7),
                150.0,
                0,
            )
            for k in range(5)
        ]
        m.mav.mission_count_send(sysid, 1, len(items), 0)
        for _ in items:
            req = m.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST"], blocking=True, timeout=5
            )
            assert req is not None
            m.mav.send(items[req.seq])
        ack = m.recv_match(type="MISSION_ACK", blocking=True, timeout=5)
        assert ack.type == mavutil.mavlink.MAV_MISSION_ACCEPTED
        m.mav.mission_request_list_send(sysid, 1, 0)
        count = m.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
        assert count.count == len(items)
        back = []
        for k in range(count.count):
            m.mav.mission_request_int_send(sysid, 1, k, 0)
            back.append(m.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=5))
        m.mav.mission_ack_send(sysid, 1, 0, 0)
        keys = ("seq", "frame", "command", "current", "param2", "x", "y", "z")
        assert [[getattr(b, k) for k in keys] for b in back[1:]] == [
            [getattr(i, k) for k in keys] for i in items[1:]
        ]
        home = m.recv_match(type="HOME_POSITION", blocking=True, timeout=10)
        assert (back[0].frame, back[0].command) == (mavutil.mavlink.MAV_FRAME_GLOBAL, 16)
        assert (back[0].x, back[0].y) == (home.latitude, home.longitude)  # item 0 is home
        m.set_mode(m.mode_mapping()["AUTO"])
        deadline = time.monotonic() + 5
        while m.flightmode != "AUTO" and time.monotonic() < deadline:
            m.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
        assert m.flightmode == "AUTO"
        m.set_mode(m.mode_mapping()["GUIDED"])
        while m.flightmode != "GUIDED" and time.monotonic() < deadline:
            m.recv_match(type="HEARTBEAT", blocking=True, timeout=1)
        assert m.flightmode == "GUIDED"
