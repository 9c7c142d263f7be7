"""Ground stations see the patrol (issue 14): each companion's STATUSTEXT and NAMED_VALUE_*
(pure mapping from the Agent's events), the simulator forwarding them to its other peers and
``--gcs-out``, and a plain pymavlink GCS on ``--gcs-out`` during a fleet run."""

from __future__ import annotations

import contextlib
import math
import socket
import threading
import time
from dataclasses import dataclass, field

import pytest
from pymavlink import mavutil

from companion.group.messages import MemberState
from companion.link.gcs import (
    ALERT,
    INFO,
    NOTICE,
    WARNING,
    GcsReport,
    event_text,
    phase_error_deg,
)
from companion.mission import load_mission
from sitl_model.codec import dialect
from sitl_model.testing import REPO, MavClient, SitlProcess
from tests.fleet_harness import companion_cli, companion_events, last_truth_time, quiet_mission

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

PAPER = REPO / "missions" / "ellipse_6uav.yaml"


# ---- what each event becomes (pure) ------------------------------------------------------
@pytest.mark.parametrize(
    ("ev", "expected"),
    [
        ({"event": "alert_new", "alert_id": "2-1", "own": True},
         (ALERT, "PP 3: intruder 2-1 at -450,0")),
        ({"event": "alert_new", "alert_id": "2-1", "own": False}, None),
        ({"event": "alert_tasked", "alert_id": "2-1", "prosecutor_sysid": 3},
         (NOTICE, "PP 3: alert 2-1 at -450,0 -> UAV 3")),
        ({"event": "alert_tasked", "alert_id": "2-1", "prosecutor_sysid": 4}, None),
        ({"event": "prosecution_end", "alert_id": "2-1", "outcome": "confirmed"},
         (WARNING, "PP 3: confirmed 2-1 at -450,0")),
        ({"event": "prosecution_end", "alert_id": "2-1", "outcome": "cleared"},
         (INFO, "PP 3: cleared 2-1: nothing seen")),
        ({"event": "alert_refused", "alert_id": "255-9", "reason": "fence"},
         (WARNING, "PP 3: refused 255-9 at -450,0: fence")),
        ({"event": "member_lost", "member_sysid": 5, "members": 5},
         (WARNING, "PP 3: lost UAV 5, 5 on patrol")),
        ({"event": "alert_cleared", "alert_id": "2-1", "detector_sysid": 4}, None),
        ({"event": "replan", "alert_id": "2-1"}, None),
        ({"event": "loop_infeasible", "wind_speed_m_s": 12.2, "need_deg_s": 24.6,
          "limit_deg_s": 18.0},
         (WARNING, "PP 3: wind 12 m/s: loop needs 25 > 18 deg/s")),
        ({"event": "loop_flyable", "wind_speed_m_s": 6.0},
         (INFO, "PP 3: wind 6 m/s: loop flyable again")),
        ({"event": "relief_late", "spare_sysid": 11, "leave_t_s": 912.3, "late_s": 41.6},
         (WARNING, "PP 3: relief 42 s late (spare 11)")),
        ({"event": "relief_late", "spare_sysid": 0, "leave_t_s": 912.3},
         (WARNING, "PP 3: no spare: must leave at 912 s")),
        ({"event": "spare_no_launch", "spare_sysid": 10},
         (WARNING, "PP 3: spare 10 did not launch")),
        ({"event": "relief_refused", "member_sysid": 20, "role": "spare",
          "reason": "not_in_mission"},
         (WARNING, "PP 3: refused UAV 20 as spare: not in mission")),
        ({"event": "relief_launched", "member_sysid": 5, "leave_t_s": 700.0},
         (NOTICE, "PP 3: launched to relieve UAV 5")),
        ({"event": "relief_in_slot", "member_sysid": 5, "took_s": 90.0, "reason": "in_slot"},
         (NOTICE, "PP 3: in UAV 5's slot (in_slot)")),
        ({"event": "relief_in_slot", "member_sysid": 5, "took_s": 11.0, "reason": "no_takeoff"},
         (WARNING, "PP 3: did not take off: unavailable")),
        ({"event": "relief_stood_down", "member_sysid": 5, "rival_sysid": 10, "airborne": False},
         (NOTICE, "PP 3: UAV 10 relieves UAV 5: a spare again")),
        ({"event": "relief_stood_down", "member_sysid": 5, "rival_sysid": 12, "airborne": True},
         (NOTICE, "PP 3: UAV 12 relieves UAV 5: turning back")),
        ({"event": "relieved", "spare_sysid": 10, "margin_s": 20.0, "reason": "relieved"},
         (NOTICE, "PP 3: relieved by UAV 10, going home")),
        ({"event": "relieved", "spare_sysid": 0, "margin_s": 0.0, "reason": "leave_time"},
         (WARNING, "PP 3: leave time: going home unrelieved")),
        ({"event": "relief_landed", "north_m": 1.0, "east_m": 300.0, "ready_t_s": 1900.4},
         (INFO, "PP 3: landed, ready at 1900 s")),
    ],
)  # fmt: skip
def test_event_texts(ev, expected):
    assert event_text(ev, 3, -450 + 0j) == expected


def test_texts_fit_in_50_characters():
    long_id = "x" * 16
    for name in ("alert_new", "alert_tasked", "prosecution_end", "alert_refused"):
        ev = {"event": name, "alert_id": long_id, "own": True, "prosecutor_sysid": 255,
              "outcome": "confirmed", "reason": "fence"}  # fmt: skip
        sev_text = event_text(ev, 255, -123456 - 123456j)
        assert sev_text is not None and len(sev_text[1]) <= 50


def test_phase_error():
    assert phase_error_deg(0.0, []) == 0.0
    six = [k * 2 * math.pi / 6 for k in range(1, 6)]
    assert phase_error_deg(0.0, six) == pytest.approx(0.0, abs=1e-9)
    assert phase_error_deg(-0.1, six) == pytest.approx(math.degrees(0.1))  # lagging


@dataclass
class FakeAgent:
    """What GcsReport reads from an Agent: sysid, formation table, alerts, patrol."""

    sysid: int
    neighbours: dict = field(default_factory=dict)
    alerts: dict = field(default_factory=dict)
    patrol: object = None


@dataclass
class FakeNeighbour:
    state: MemberState
    rx_t_s: float


@dataclass
class FakeOut:
    events: tuple
    broadcast: MemberState
    mode: str = "patrol"


def test_fleet_wide_decisions_are_reported_by_the_lowest_sysid_only_and_values_at_2_hz():
    patrol = load_mission(PAPER).patrol
    refused = ({"event": "alert_refused", "alert_id": "255-1", "reason": "fence",
                "north_m": -900.0, "east_m": 0.0},)  # fmt: skip
    others = {s: FakeNeighbour(MemberState(s, 10.0, 0j, s * 2 * math.pi / 6), 10.0) for s in (3, 4)}
    texts = {}
    for sysid in (2, 3, 4):
        agent = FakeAgent(sysid, {k: v for k, v in others.items() if k != sysid}, {}, patrol)
        if sysid != 2:
            agent.neighbours[2] = FakeNeighbour(MemberState(2, 10.0, 0j, 2.0), 10.0)
        texts[sysid] = GcsReport().texts(10.0, agent, refused)
    assert texts == {2: [(WARNING, "PP 2: refused 255-1 at -900,0: fence")], 3: [], 4: []}
    report = GcsReport()
    agent = FakeAgent(2, dict(others), {}, patrol)
    out = FakeOut((), MemberState(2, 10.0, 0j, 2 * 2 * math.pi / 6))
    sent = [
        report.messages(10.0 + 0.1 * k, 1000 + 100 * k, agent, out, -400 + 0j) for k in range(20)
    ]
    values = [m for batch in sent for m in batch]
    assert len(values) == 4 * 4  # 2 s of vehicle time at 2 Hz, four values each
    named = {m.name: m.value for m in values[:4]}
    assert set(named) == {"pp_phs_err", "pp_xtrk", "pp_mode", "pp_members"}
    assert named["pp_mode"] == 0 and named["pp_members"] == 3
    assert named["pp_xtrk"] == pytest.approx(0.0, abs=0.5)  # (-400, 0) is on the ellipse
    assert all(len(m.name) <= 10 for m in values)


def test_with_reliefs_each_uav_graphs_its_battery_time_to_leave_and_time_to_relief():
    from companion.agent.fix import Fix
    from companion.agent.neighbours import Neighbours
    from companion.agent.relief.duty import Duty
    from companion.group.messages import Energy

    mission = load_mission(REPO / "missions" / "ellipse_relief.yaml")
    patrol = mission.patrol
    duty = Duty(3, mission)
    duty.observe_battery(0.0, 40.0, 6000.0, 12.0)
    heard = Neighbours(3, 3.0)
    spare = MemberState(10, 0.0, 0j, 0.0, "spare", pos_m=300j, energy=Energy("spare", 100.0))
    heard.hear(spare, 0.0)
    pos = complex(patrol.point_at_phase(0.0))
    duty.step(Fix(0.0, pos, 0.0, patrol), heard, mission.gains, True)
    agent = FakeAgent(3, {}, {}, patrol)
    agent.duty = duty
    out = FakeOut((), MemberState(3, 0.0, 0j, 0.0))
    named = {m.name: m.value for m in GcsReport().messages(0.0, 0, agent, out, pos)}
    leave = duty.energy().t_s
    relief = duty.plan.of_member(3)
    assert relief.spare == 10 and not relief.late
    assert named["pp_role"] == 1 and named["pp_batt"] == 40.0
    # 6000 mAh drawn, 2000 mAh to the reserve at 12 A (3.33 mAh/s): 600 s, less the flight
    # home and 30 s (docs/energy.md, "When must a UAV leave?")
    assert named["pp_leave_s"] == pytest.approx(leave, abs=1e-3) and 500.0 < leave < 570.0
    assert (
        named["pp_rlf_s"] == pytest.approx(relief.on_station_t_s) and 0 < named["pp_rlf_s"] < leave
    )
    # a mission without spares sends the four values it always did
    plain = FakeAgent(3, {}, {}, patrol)
    plain.duty = Duty(3, load_mission(PAPER))
    names = {m.name for m in GcsReport().messages(0.0, 0, plain, out, pos)}
    assert names == {"pp_phs_err", "pp_xtrk", "pp_mode", "pp_members"}


def test_statustext_budget():
    report = GcsReport()
    agent = FakeAgent(1)
    evs = tuple({"event": "alert_new", "alert_id": f"1-{k}", "own": True} for k in range(12))
    assert len(report.texts(5.0, agent, evs)) == 5 and report.suppressed == 7
    assert len(report.texts(6.0, agent, evs[:2])) == 2


# ---- the simulator forwards them --------------------------------------------------------
def _udp_listener() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(0.2)
    return s


def test_simulator_forwards_companion_texts_and_values_verbatim():
    gcs = _udp_listener()
    port = gcs.getsockname()[1]
    with SitlProcess("--gcs-out", f"127.0.0.1:{port}", vehicles=1) as sitl:
        other = MavClient(sitl.port(0))  # a ground station on the vehicle's own port
        companion = MavClient(sitl.port(0), sysid=1, compid=191)
        try:
            time.sleep(0.3)
            other.drain()
            sent = [
                dialect.MAVLink_statustext_message(5, b"PP 1: alert 255-1 at -450,0 -> UAV 1"),
                dialect.MAVLink_named_value_float_message(1234, b"pp_xtrk", 3.5),
                dialect.MAVLink_named_value_int_message(1234, b"pp_mode", 1),
            ]
            wire = [companion.enc.pack(m) for m in sent]
            for data in wire:
                companion.send_raw(data)
            got_gcs: list[bytes] = []
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline and not set(wire) <= set(got_gcs):
                with contextlib.suppress(TimeoutError):
                    got_gcs.append(gcs.recv(4096))
            assert set(wire) <= set(got_gcs)  # byte for byte (a signature would survive)
            seen = other.collect(1.0)
            mine = [m for m in seen if m.get_srcComponent() == 191]
            assert sorted(m.get_type() for m in mine) == [
                "NAMED_VALUE_FLOAT", "NAMED_VALUE_INT", "STATUSTEXT"
            ]  # fmt: skip
            assert not [m for m in companion.collect(0.5) if m.get_srcComponent() == 191]
        finally:
            other.close()
            companion.close()
            gcs.close()


# ---- a plain pymavlink GCS during a fleet run --------------------------------------------
class GcsListener:
    """``mavutil`` udpin on a port: what a ground station on ``--gcs-out`` receives."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="ardupilotmega")
        self.texts: list[tuple[int, int, str]] = []  # (sysid, severity, text)
        self.values: dict[tuple[int, str], float] = {}
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            m = self.conn.recv_match(
                type=["STATUSTEXT", "NAMED_VALUE_FLOAT", "NAMED_VALUE_INT"],
                blocking=True,
                timeout=0.2,
            )
            if m is None or m.get_srcComponent() != 191:
                continue
            if m.get_type() == "STATUSTEXT":
                self.texts.append((m.get_srcSystem(), m.severity, m.text))
            else:
                self.values[m.get_srcSystem(), m.name] = m.value

    def close(self) -> None:
        self._stop.set()
        self._t.join(2.0)
        self.conn.close()


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait(cond, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def test_a_pymavlink_gcs_on_gcs_out_sees_the_patrol(fleet_factory, tmp_path):
    port = _free_udp_port()
    gcs = GcsListener(port)
    try:
        f = fleet_factory(
            mission=quiet_mission(tmp_path, 300.0), sitl_args=("--gcs-out", f"127.0.0.1:{port}")
        )
        group = next(a for a in f.companions[0].proc.args if a.startswith("239.255."))
        f.wait_sim_time(30.0)
        names = {"pp_phs_err", "pp_xtrk", "pp_mode", "pp_members"}
        assert _wait(lambda: {(s, n) for s in range(1, 7) for n in names} <= set(gcs.values), 180)
        common = ["--insecure", "--group", group, "--listen-s", "1"]
        # a loaded machine (two cores shared by every test) can take seconds to start one
        out = companion_cli(
            "alert", "--at", "-900,0", "--alert-id", "op-out", *common, timeout_s=180
        )
        assert out.returncode == 0, out.stderr
        inside = companion_cli(
            "alert", "--at", "-450,0", "--alert-id", "op-in", *common, timeout_s=180
        )
        assert inside.returncode == 0, inside.stderr

        def tasked():
            return [t for t in gcs.texts if "alert op-in at -450,0 -> UAV" in t[2]]

        assert _wait(tasked, 180), gcs.texts
        refused = [t for t in gcs.texts if "refused op-out" in t[2]]
        assert refused == [(1, WARNING, "PP 1: refused op-out at -900,0: fence")], gcs.texts
        ((prosecutor, severity, text),) = tasked()
        assert (
            severity == NOTICE
            and text == f"PP {prosecutor}: alert op-in at -450,0 -> UAV {prosecutor}"
        )
        assert _wait(lambda: gcs.values.get((prosecutor, "pp_mode"), 0) >= 1, 120)
        t_end = last_truth_time(f.out / "truth.csv")
    finally:
        gcs.close()
    # every companion refused the out-of-fence alert; none flew it
    evs = companion_events(f.out)
    assert {
        e["sysid"] for e in evs if e["event"] == "alert_refused" and e["alert_id"] == "op-out"
    } == set(range(1, 7))
    assert not [
        e for e in evs if e.get("alert_id") == "op-out" and e["event"] in ("plan", "alert_tasked")
    ]
    assert t_end > 30.0
