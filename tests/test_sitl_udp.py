"""Integration tests: the real ``python -m sitl_model`` over loopback UDP at a speed-up."""

from __future__ import annotations

import csv
import itertools
import json
import math
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from sitl_model.codec import Decoder
from sitl_model.codec import dialect as d
from sitl_model.telemetry import CAPABILITIES
from sitl_model.testing import REPO, MavClient, SitlProcess

pytestmark = pytest.mark.integration

GUIDED, LOITER, AUTO, RTL = 15, 12, 10, 11


@pytest.fixture(scope="module")
def sitl_main(tmp_path_factory):
    """Two vehicles at 20x with truth and events logs (shared by the protocol tests)."""
    tmp = tmp_path_factory.mktemp("sitl_main")
    proc = SitlProcess(
        "--speedup",
        "20",
        "--truth-log",
        str(tmp / "truth.csv"),
        "--events-log",
        str(tmp / "events.jsonl"),
        "--status-interval",
        "1",
        vehicles=2,
    )
    proc.tmp = tmp
    yield proc
    assert proc.stop() == 0


@pytest.fixture
def sitl_client(sitl_main):
    """A client of vehicle 1 (closed after the test)."""
    c = MavClient(sitl_main.port(0))
    c.match("HEARTBEAT")
    yield c
    c.close()


def set_mode(c: MavClient, mode: int, target: int = 1):
    return c.command_long(d.MAV_CMD_DO_SET_MODE, 1, mode, target=target)


def status_counts(proc: SitlProcess) -> dict[str, int]:
    line = proc.control("status")
    return {
        k: int(v)
        for k, v in (w.split("=") for w in line.split() if "=" in w)
        if k in ("rx", "tx", "bad", "foreign", "refused", "unsupported")
    }


def events(proc: SitlProcess, want=None) -> list[dict]:
    """The events log so far; waits up to 2 s until ``want(events)`` holds (or, given a
    string, until an event of that name is there). The log is flushed at 10 Hz."""
    path = proc.tmp / "events.jsonl"
    if isinstance(want, str):
        name = want
        want = lambda evs: any(e["event"] == name for e in evs)  # noqa: E731
    deadline = time.monotonic() + 2.0
    while True:
        evs = [json.loads(x) for x in path.read_text().splitlines() if x.strip()]
        if want is None or want(evs) or time.monotonic() > deadline:
            return evs
        time.sleep(0.05)


def read_truth(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------- telemetry


def test_heartbeat_and_streamed_telemetry(sitl_main):
    c = MavClient(sitl_main.port(1))
    try:
        hb = c.match("HEARTBEAT", cond=lambda m: m.get_srcSystem() == 2)
        assert (hb.type, hb.autopilot, hb.custom_mode) == (1, 3, GUIDED)
        assert hb.get_srcComponent() == 1
        st = c.match("SYSTEM_TIME")
        assert st.time_unix_usec == SIM_EPOCH_UNIX_S * 1_000_000 + st.time_boot_ms * 1000
        want = {"SYS_STATUS", "GPS_RAW_INT", "GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"}
        want |= {"ATTITUDE", "VFR_HUD", "EXTENDED_SYS_STATE", "WIND", "MISSION_CURRENT"}
        seen: set[str] = set()
        deadline = time.monotonic() + 5
        while not want <= seen and time.monotonic() < deadline:
            seen |= {m.get_type() for m in c.recv(0.2)}
        assert want <= seen
        home = c.command_long(d.MAV_CMD_REQUEST_MESSAGE, d.MAVLINK_MSG_ID_HOME_POSITION, target=2)
        assert home.result == d.MAV_RESULT_ACCEPTED
        assert c.match("HOME_POSITION").latitude != 0
    finally:
        c.close()


def test_a_steps_telemetry_shares_one_datagram_with_rising_sequence_numbers(sitl_main):
    """GLOBAL_POSITION_INT and ATTITUDE (both 5 Hz, in phase) leave in one datagram per
    step, whole frames that any MAVLink parser reads; each component numbers its frames."""
    c = MavClient(sitl_main.port(0))
    try:
        c.drain()
        c.sock.settimeout(2.0)
        dec = Decoder()
        counts, seqs = [], []
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            msgs, bad = dec.decode(c.sock.recv(65535))
            assert bad == 0
            counts.append(len(msgs))
            seqs += [m.get_seq() for m in msgs if m.get_srcComponent() == 1]
            if {"GLOBAL_POSITION_INT", "ATTITUDE"} <= {m.get_type() for m in msgs}:
                break
        else:
            raise AssertionError(f"no datagram held both reports: frames per datagram {counts}")
        steps = [(b - a) % 256 for a, b in itertools.pairwise(seqs)]
        # one number per frame sent (replies to another peer would take some in between)
        assert steps and all(1 <= k <= 8 for k in steps) and sorted(steps)[len(steps) // 2] == 1
    finally:
        c.close()


def test_truth_log_columns_and_rate(sitl_main):
    time.sleep(0.6)
    rows = read_truth(sitl_main.tmp / "truth.csv")
    assert list(rows[0]) == [
        "t_s", "sysid", "north_m", "east_m", "alt_m", "heading_deg", "course_deg",
        "groundspeed_m_s", "turn_rate_deg_s", "mode", "wind_north_m_s", "wind_east_m_s",
    ]  # fmt: skip
    t1 = [float(r["t_s"]) for r in rows if r["sysid"] == "1"]
    span = t1[-1] - t1[0]
    assert span > 5 and (len(t1) - 1) / span >= 10 - 1e-6


def test_autopilot_version_and_message_interval(sitl_client):
    c = sitl_client
    ack = c.command_long(d.MAV_CMD_REQUEST_MESSAGE, d.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert ack.result == d.MAV_RESULT_ACCEPTED
    av = c.match("AUTOPILOT_VERSION")
    assert av.capabilities == CAPABILITIES
    for cap in ("MAVLINK2", "MISSION_INT", "COMMAND_INT", "PARAM_FLOAT", "SET_ATTITUDE_TARGET"):
        assert av.capabilities & getattr(d, "MAV_PROTOCOL_CAPABILITY_" + cap)
    assert c.command_long(d.MAV_CMD_REQUEST_MESSAGE, 99999).result == d.MAV_RESULT_DENIED
    ack = c.command_long(d.MAV_CMD_SET_MESSAGE_INTERVAL, d.MAVLINK_MSG_ID_ATTITUDE, 50_000)
    assert ack.result == d.MAV_RESULT_ACCEPTED
    stamps = []
    c.match("ATTITUDE")
    while len(stamps) < 20:
        stamps.append(c.match("ATTITUDE").time_boot_ms)
    # 20 Hz on a 50 Hz physics grid: 40/60 ms gaps, 50 ms on average
    assert (stamps[-1] - stamps[0]) / (len(stamps) - 1) == pytest.approx(50, abs=3)
    c.command_long(d.MAV_CMD_SET_MESSAGE_INTERVAL, d.MAVLINK_MSG_ID_ATTITUDE, 0)
    ack = c.command_long(d.MAV_CMD_GET_MESSAGE_INTERVAL, d.MAVLINK_MSG_ID_ATTITUDE)
    assert ack.result == d.MAV_RESULT_ACCEPTED
    assert c.match("MESSAGE_INTERVAL").interval_us == 200_000


# ------------------------------------------------------------------------------- modes


def test_mode_changes_acked_and_heartbeat_follows(sitl_main, sitl_client):
    c = sitl_client
    assert set_mode(c, LOITER).result == d.MAV_RESULT_ACCEPTED
    c.match("HEARTBEAT", cond=lambda m: m.custom_mode == LOITER)
    c.send(d.MAVLink_set_mode_message(1, d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, RTL))
    ack = c.match("COMMAND_ACK", cond=lambda m: m.command == d.MAVLINK_MSG_ID_SET_MODE)
    assert ack.result == d.MAV_RESULT_ACCEPTED
    c.match("HEARTBEAT", cond=lambda m: m.custom_mode == RTL)
    assert set_mode(c, 5).result == d.MAV_RESULT_DENIED  # FBWA: not modelled
    ack = c.command_long(d.MAV_CMD_NAV_RETURN_TO_LAUNCH)
    assert ack.result == d.MAV_RESULT_ACCEPTED
    ack = c.command_long(d.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    assert ack.result == d.MAV_RESULT_DENIED  # no disarming in flight unless forced
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED

    def loiter_to_rtl(evs: list[dict]) -> bool:
        return any(e.get("from") == "LOITER" and e.get("to") == "RTL" for e in evs)

    assert loiter_to_rtl(events(sitl_main, loiter_to_rtl))


def test_setpoints_refused_outside_guided(sitl_main, sitl_client):
    c = sitl_client
    assert set_mode(c, LOITER).result == d.MAV_RESULT_ACCEPTED
    c.send(d.MAVLink_command_int_message(1, 1, 0, 43002, 0, 0, 0, 90, 5, 0, 0, 0, 0))
    ack = c.match("COMMAND_ACK", cond=lambda m: m.command == 43002)
    assert ack.result == d.MAV_RESULT_DENIED
    before = status_counts(sitl_main)["refused"]
    q = [math.cos(0.2), math.sin(0.2), 0, 0]  # 23 deg right bank
    c.send(d.MAVLink_set_attitude_target_message(0, 1, 1, 0x07, q, 0, 0, 0, 0))
    for _ in range(10):  # a heartbeat already on its way may come before the refusal (load)
        c.match("HEARTBEAT")
        if status_counts(sitl_main)["refused"] > before:
            break
    assert status_counts(sitl_main)["refused"] > before
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED
    c.send(d.MAVLink_command_int_message(1, 1, 0, 43002, 0, 0, 0, 90, 5, 0, 0, 0, 0))
    ack = c.match("COMMAND_ACK", cond=lambda m: m.command == 43002)
    assert ack.result == d.MAV_RESULT_ACCEPTED


def test_guided_timeout_loiters_and_says_so(sitl_main, sitl_client):
    c = sitl_client
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED
    c.drain()
    t_first = c.match("ATTITUDE").time_boot_ms / 1000.0
    for _ in range(30):  # fed every 0.01 s wall = 0.2 s simulated at 20x: no timeout
        c.send(d.MAVLink_set_attitude_target_message(0, 1, 1, 0xFE, [1, 0, 0, 0], 0, 0, 0, 0))
        time.sleep(0.01)
    c.drain()
    t_sent = c.match("ATTITUDE").time_boot_ms / 1000.0  # at most 0.2 s after the last
    text = c.match("STATUSTEXT", timeout_s=3, cond=lambda m: "no setpoint" in m.text).text
    assert "loitering" in text

    def mine(evs: list[dict]) -> list[float]:
        return [e["t_s"] for e in evs if e["event"] == "guided_timeout" and e.get("sysid") == 1]

    times = mine(events(sitl_main, lambda evs: any(t > t_sent for t in mine(evs))))
    assert not [t for t in times if t_first < t < t_sent - 0.5]  # none while it was fed
    assert [t for t in times if t_sent < t < t_sent + 3.5]  # GUID_TIMEOUT = 3 s after the last


# ---------------------------------------------------------------------------- missions


def mission_item(seq: int, north_deg: float) -> d.MAVLink_mission_item_int_message:
    lat, lon = -35.363261 + north_deg, 149.165230
    return d.MAVLink_mission_item_int_message(
        1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 100.0 + seq, 0
    )


def upload(c: MavClient, items: list, stall_after: int | None = None):
    c.send(d.MAVLink_mission_count_message(1, 1, len(items), 0))
    for k in range(len(items)):
        req = c.match("MISSION_REQUEST_INT", cond=lambda m, k=k: m.seq == k)
        if stall_after is not None and k == stall_after:
            return req
        c.send(items[k])
    return c.match("MISSION_ACK")


def download(c: MavClient) -> list:
    c.send(d.MAVLink_mission_request_list_message(1, 1, 0))
    n = c.match("MISSION_COUNT").count
    out = []
    for k in range(n):
        c.send(d.MAVLink_mission_request_int_message(1, 1, k, 0))
        out.append(c.match("MISSION_ITEM_INT", cond=lambda m, k=k: m.seq == k))
    c.send(d.MAVLink_mission_ack_message(1, 1, 0, 0))
    return out


def fields(m) -> tuple:
    return (m.seq, m.frame, m.command, m.x, m.y, m.z, m.param1)


def test_mission_upload_is_atomic_and_auto_flies_it(sitl_main, sitl_client):
    c = sitl_client
    items = [mission_item(k, 0.005 * (k % 2)) for k in range(5)]
    ack = upload(c, items)
    assert ack.type == d.MAV_MISSION_ACCEPTED
    stored = download(c)
    assert [fields(m) for m in stored[1:]] == [fields(m) for m in items[1:]]
    assert fields(stored[0])[:5] == (0, 0, 16, -353632610, 1491652300)  # item 0: home
    # a stalled upload of 6 items is cancelled after retries; the old mission stays
    stalled = [mission_item(k, 0.01) for k in range(6)]
    upload(c, stalled, stall_after=3)
    ack = c.match("MISSION_ACK", timeout_s=8)
    assert ack.type == d.MAV_MISSION_OPERATION_CANCELLED
    assert [fields(m) for m in download(c)] == [fields(m) for m in stored]
    assert set_mode(c, AUTO).result == d.MAV_RESULT_ACCEPTED
    c.match("HEARTBEAT", cond=lambda m: m.custom_mode == AUTO)
    cur = c.match("MISSION_CURRENT")
    assert cur.total == 4 and cur.seq >= 1  # home excluded from the total, never flown
    c.send(d.MAVLink_mission_set_current_message(1, 1, 2))
    c.match("MISSION_CURRENT", cond=lambda m: m.seq == 2)
    c.match("MISSION_ITEM_REACHED", timeout_s=10)
    # clear, then AUTO is refused
    c.send(d.MAVLink_mission_clear_all_message(1, 1, 0))
    assert c.match("MISSION_ACK").type == d.MAV_MISSION_ACCEPTED
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED
    assert set_mode(c, AUTO).result == d.MAV_RESULT_DENIED
    evs = events(sitl_main, "mission_upload_timeout")
    names = [e["event"] for e in evs if e.get("sysid") == 1]
    assert "mission_uploaded" in names and "mission_upload_timeout" in names


# ----------------------------------------------------------------------------- clients


def test_multiple_simultaneous_clients(sitl_main):
    a, b, other = MavClient(sitl_main.port(0)), MavClient(sitl_main.port(0)), None
    try:
        other = MavClient(sitl_main.port(1), sysid=254)
        for cl, sid in ((a, 1), (b, 1), (other, 2)):
            cl.match("GLOBAL_POSITION_INT", cond=lambda m, s=sid: m.get_srcSystem() == s)
        # a's request is answered to a only; both keep receiving telemetry
        a.send(d.MAVLink_param_request_read_message(1, 1, b"SIM_LAG", -1))
        assert a.match("PARAM_VALUE").param_id == "SIM_LAG"
        got_b = {m.get_type() for m in b.collect(0.3)}
        assert "PARAM_VALUE" not in got_b and "GLOBAL_POSITION_INT" in got_b
        # b commands, a sees the effect in the heartbeat
        assert set_mode(b, LOITER).result == d.MAV_RESULT_ACCEPTED
        a.match("HEARTBEAT", cond=lambda m: m.custom_mode == LOITER)
        assert set_mode(a, GUIDED).result == d.MAV_RESULT_ACCEPTED
    finally:
        for cl in (a, b, other):
            if cl:
                cl.close()


def test_params_list_read_set(sitl_client):
    c = sitl_client
    c.send(d.MAVLink_param_request_list_message(1, 1))
    m = c.match("PARAM_VALUE")
    got = {m.param_id: m}
    while len(got) < m.param_count:
        m = c.match("PARAM_VALUE")
        got[m.param_id] = m
    assert {"SIM_WIND_SPD", "SIM_WIND_DIR", "SIM_AIRSPEED", "SIM_TURN_MAX", "SIM_LAG"} <= set(got)
    assert {"GUID_TIMEOUT", "SIM_SENS_RAD", "SIM_TR_EFF", "SIM_CRS_KP"} <= set(got)
    assert {"SIM_GPS_NOISE", "SIM_GPS_TAU", "SIM_GPS_VNOISE", "SIM_WEST_TAU"} <= set(got)
    assert {"SIM_WDRIFT_SPD", "SIM_WDRIFT_DIR", "SIM_WDRIFT_T", "SIM_WSTEP_T"} <= set(got)
    assert all(m.param_count == len(got) for m in got.values())

    def set_param(name: str, value: float) -> float:
        c.send(d.MAVLink_param_set_message(1, 1, name.encode(), value, 9))
        return c.match("PARAM_VALUE", cond=lambda m: m.param_id == name).param_value

    # WIND is an estimate; without its lag and error it reports the wind that was set
    assert [set_param(n, 0.0) for n in ("SIM_WEST_ERR", "SIM_WEST_TAU")] == [0.0, 0.0]
    assert set_param("SIM_WIND_SPD", 4.0) == 4.0
    c.match("WIND", cond=lambda m: abs(m.speed - 4.0) < 1e-6)
    assert set_param("SIM_WIND_SPD", 0.0) == 0.0
    assert set_param("SIM_WEST_TAU", 10.0) == 10.0
    assert set_param("SIM_WEST_ERR", 0.3) == pytest.approx(0.3)


# -------------------------------------------------------------------------- bad input


def test_bad_inputs_are_dropped_refused_and_counted(sitl_main, sitl_client):
    c = sitl_client
    before = status_counts(sitl_main)
    c.send_raw(b"\xfd\x00garbage that is not mavlink")
    c.send_raw(bytes(range(256)))
    c.send_raw(b"")
    hb = d.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)
    c.send_raw(c.enc.pack(hb)[:-4])  # truncated
    # addressed to system 99: dropped without an answer
    c.send(d.MAVLink_command_long_message(99, 1, d.MAV_CMD_DO_SET_MODE, 0, 1, 12, 0, 0, 0, 0, 0))
    # unknown command -> UNSUPPORTED, NaN mode -> DENIED, NaN heading -> DENIED
    assert c.command_long(31999).result == d.MAV_RESULT_UNSUPPORTED
    assert set_mode(c, math.nan).result == d.MAV_RESULT_DENIED
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED
    c.send(d.MAVLink_command_long_message(1, 1, 43002, 0, 0, math.nan, 5, 0, 0, 0, 0))
    assert c.match("COMMAND_ACK", cond=lambda m: m.command == 43002).result == d.MAV_RESULT_DENIED
    c.send(d.MAVLink_command_long_message(1, 1, 43002, 0, 7, 90, 5, 0, 0, 0, 0))
    assert c.match("COMMAND_ACK", cond=lambda m: m.command == 43002).result == d.MAV_RESULT_DENIED
    # NaN and absurd setpoints, NaN parameter
    # (as ArduPlane, the body rates are never read: a bad roll in q is what is refused)
    for q, rate, mask in (([math.nan, 0, 0, 0], 0, 0x23), ([math.nan, 0, 0, 0], 0, 0xFE),
                          ([2, 0, 0, 0], 0, 0xFE), ([0, 0, 0, 0], 0, 0x23)):  # fmt: skip
        c.send(d.MAVLink_set_attitude_target_message(0, 1, 1, mask, q, 0, 0, rate, 0))
    c.send(d.MAVLink_param_set_message(1, 1, b"SIM_LAG", math.nan, 9))
    pv = c.match("PARAM_VALUE", cond=lambda m: m.param_id == "SIM_LAG")
    assert pv.param_value == 0.0
    c.send(d.MAVLink_param_set_message(1, 1, b"SIM_TURN_MAX", 1e9, 9))
    c.match("PARAM_VALUE", cond=lambda m: m.param_id == "SIM_TURN_MAX" and m.param_value == 18)
    c.match("HEARTBEAT")
    with pytest.raises(TimeoutError):
        c.match("COMMAND_ACK", timeout_s=0.3, cond=lambda m: m.command == d.MAV_CMD_DO_SET_MODE)
    after = status_counts(sitl_main)
    assert after["bad"] >= before["bad"] + 3
    assert after["foreign"] >= before["foreign"] + 1
    assert after["unsupported"] >= before["unsupported"] + 1
    assert after["refused"] >= before["refused"] + 9
    assert any("refused=" in ln for ln in sitl_main.stderr_lines)
    # still alive and answering
    assert set_mode(c, GUIDED).result == d.MAV_RESULT_ACCEPTED
    assert sitl_main.proc.poll() is None


# ------------------------------------------------------------------- intruders, sensor


def test_runtime_intruder_is_detected_by_the_camera(sitl_main):
    c = MavClient(sitl_main.port(1), sysid=253)
    try:
        assert set_mode(c, LOITER, target=2).result == d.MAV_RESULT_ACCEPTED
        lp = c.match("LOCAL_POSITION_NED")
        n, e = lp.x + 4 * lp.vx, lp.y + 4 * lp.vy  # where it will be in 4 s: on its loiter
        assert sitl_main.control(f"intruder id=red1 north_m={n:.1f} east_m={e:.1f}").startswith(
            "ok intruder red1"
        )
        assert sitl_main.control("intruder id=red1 north_m=0 east_m=0").startswith("error:")
        trk = c.match("CAMERA_TRACKING_GEO_STATUS", timeout_s=5)
        assert trk.get_srcSystem() == 2 and trk.get_srcComponent() == d.MAV_COMP_ID_CAMERA
        assert trk.tracking_status == d.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
        gpi = c.match("GLOBAL_POSITION_INT")
        lat_m_per_deg = 111_000.0
        assert abs((trk.lat - gpi.lat) * 1e-7 * lat_m_per_deg) < 80
        c.match("STATUSTEXT", cond=lambda m: "red1" in m.text)
        det = [x for x in events(sitl_main, "detection") if x["event"] == "detection"]
        assert det and det[0]["sysid"] == 2 and det[0]["intruder"] == "red1"
        assert set_mode(c, GUIDED, target=2).result == d.MAV_RESULT_ACCEPTED
    finally:
        c.close()


# ------------------------------------------------------------- setpoints over the wire


def turn_rate_msg(u_rad_s: float, target: int = 1):
    q = [1, 0, 0, 0]
    return d.MAVLink_set_attitude_target_message(0, target, 1, 0x83, q, 0, 0, u_rad_s, 0)


def roll_msg(phi_rad: float, target: int = 1):
    q = [math.cos(phi_rad / 2), math.sin(phi_rad / 2), 0, 0]
    return d.MAVLink_set_attitude_target_message(0, target, 1, 0x07, q, 0, 0, 0, 0)


def rows_of(rows: list[dict], sysid: int) -> list[dict]:
    return [r for r in rows if r["sysid"] == str(sysid)]


def fly_setpoints(wind: tuple[float, float] | None, tmp: Path) -> list[dict]:
    """60 s simulated of three vehicles: 1 turns at 10 deg/s, 2 banks 20 deg, 3 holds course
    090 with a 2 m/s^2 lateral-acceleration limit (COMMAND_INT GUIDED_CHANGE_HEADING)."""
    # vehicle 1's body yaw rate is flown only by a rate-controlled autopilot (SIM_RATE_OK=1);
    # as ArduPlane the simulator ignores it (tests/test_arduplane_profiles.py)
    args = ["--speedup", "50", "--param", "GUID_TIMEOUT=1000", "--param", "SIM_RATE_OK=1"]
    args += ["--truth-log", str(tmp)]
    if wind:
        args += ["--wind-speed", str(wind[0]), "--wind-from", str(wind[1])]
    with SitlProcess(*args, vehicles=3) as p:
        c1, c2, c3 = MavClient(p.port(0)), MavClient(p.port(1)), MavClient(p.port(2))
        c1.send(turn_rate_msg(math.radians(10)))
        c2.send(roll_msg(math.radians(20), target=2))
        c3.send(d.MAVLink_command_int_message(3, 1, 0, 43002, 0, 0, 0, 90, 2, 0, 0, 0, 0))
        assert c3.match("COMMAND_ACK").result == d.MAV_RESULT_ACCEPTED
        c1.match("ATTITUDE", cond=lambda m: m.time_boot_ms > 70_000, timeout_s=10)
        for c in (c1, c2, c3):
            c.close()
        assert p.stop() == 0
    return read_truth(tmp)


def check_course_hold(rows: list[dict]) -> None:
    """Vehicle 3: turn rate within a/V = 0.1 rad/s, course settles on 090."""
    rows3 = rows_of(rows, 3)
    assert max(abs(float(r["turn_rate_deg_s"])) for r in rows3) <= math.degrees(0.1) + 1e-3
    assert float(rows3[-1]["course_deg"]) == pytest.approx(90.0, abs=0.5)


def fit_radius(pts: np.ndarray) -> float:
    a = np.column_stack([pts.real, pts.imag, np.ones(len(pts))])
    cx, cy, c = np.linalg.lstsq(a, pts.real**2 + pts.imag**2, rcond=None)[0]
    return math.sqrt(c + cx**2 / 4 + cy**2 / 4)


def test_turn_rate_and_bank_setpoints_fly_circles_in_still_air(tmp_path):
    rows = fly_setpoints(None, tmp_path / "truth.csv")
    for sysid, u_deg in ((1, 10.0), (2, math.degrees(9.80665 * math.tan(math.radians(20)) / 20))):
        turning = [r for r in rows_of(rows, sysid) if float(r["turn_rate_deg_s"]) > 0]
        assert float(turning[-1]["turn_rate_deg_s"]) == pytest.approx(u_deg, rel=1e-4)
        pts = np.array([complex(float(r["north_m"]), float(r["east_m"])) for r in turning])
        assert fit_radius(pts) == pytest.approx(20.0 / math.radians(u_deg), rel=0.01)
    check_course_hold(rows)


def test_turn_rate_setpoint_flies_trochoid_in_wind(tmp_path):
    all_rows = fly_setpoints((6.0, 250.0), tmp_path / "truth.csv")
    check_course_hold(all_rows)
    rows = rows_of(all_rows, 1)
    turning = [r for r in rows if float(r["turn_rate_deg_s"]) > 9.999]
    r0 = turning[0]
    t0 = float(r0["t_s"])
    p0 = complex(float(r0["north_m"]), float(r0["east_m"]))
    th0 = math.radians(float(r0["heading_deg"]))
    u = math.radians(10.0)
    w = 6.0 * np.exp(1j * math.radians(250.0 + 180.0))
    t = np.array([float(r["t_s"]) for r in turning]) - t0
    pts = np.array([complex(float(r["north_m"]), float(r["east_m"])) for r in turning])
    expected = p0 + (20.0 / u) * (-1j) * (np.exp(1j * (th0 + u * t)) - np.exp(1j * th0)) + w * t
    assert t[-1] > 50
    assert np.max(np.abs(pts - expected)) < 0.05  # the log keeps millimetres


# ------------------------------------------------------------------ process lifecycle


def test_sigterm_exits_zero_and_flushes_logs(tmp_path):
    truth = tmp_path / "t.csv"
    p = SitlProcess(
        "--mission", str(REPO / "missions/ellipse_6uav.yaml"), "--speedup", "20",
        "--truth-log", str(truth), "--no-control",
    )  # fmt: skip
    try:
        c = MavClient(p.port(5))
        hb = c.match("HEARTBEAT")
        assert hb.get_srcSystem() == 6
        assert set_mode(c, AUTO, target=6).result == d.MAV_RESULT_ACCEPTED  # preloaded patrol
        assert c.match("MISSION_CURRENT").total == 16
        # the mission's wind as the autopilot estimates it (SIM_WEST_ERR 0.3 m/s per axis)
        c.match("WIND", cond=lambda m: abs(m.speed - 5.0) < 1.5 and abs(m.direction - 180) < 20)
        c.close()
    finally:
        assert p.stop() == 0
    lines = truth.read_text().splitlines()
    assert lines[-1].count(",") == 11 and {r.split(",")[1] for r in lines[1:]} == set("123456")


@pytest.mark.parametrize(
    "args",
    [["--mission", "no/such/file.yaml"], ["--mission", "pyproject.toml"], ["--vehicles", "0"]],
)
def test_bad_arguments_exit_2_with_one_line(args):
    r = subprocess.run(
        [sys.executable, "-m", "sitl_model", *args],
        cwd=REPO,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_sigint_exits_zero_and_gcs_out_gets_every_vehicle():
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.settimeout(5)
    p = SitlProcess("--speedup", "5", "--gcs-out", f"127.0.0.1:{gcs.getsockname()[1]}", vehicles=3)
    try:
        dec = Decoder()
        seen: set[int] = set()
        deadline = time.monotonic() + 5
        while seen != {1, 2, 3} and time.monotonic() < deadline:
            msgs, _ = dec.decode(gcs.recv(65535))
            seen |= {m.get_srcSystem() for m in msgs if m.get_type() == "HEARTBEAT"}
        assert seen == {1, 2, 3}
        p.proc.send_signal(signal.SIGINT)
        assert p.proc.wait(10) == 0
    finally:
        p.stop()
        gcs.close()
