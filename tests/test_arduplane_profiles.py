"""ArduPlane's reading of the companion's setpoints, at home: the mask semantics of
SET_ATTITUDE_TARGET (from ArduPlane's source, docs/arduplane.md), the simulator flying them
as ArduPlane does, and the speed / altitude commands of GUIDED (all in process, no sockets)."""

from __future__ import annotations

import io
import math
import re
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.contracts.attitude_target import arduplane_forced_axes
from companion.contracts.errors import UserError
from companion.link import setpoints as setpoints_module
from companion.link.config import LinkConfig
from companion.link.setpoints import (
    MASK_BANK,
    MASK_TURN_RATE,
    bank_setpoint,
    describe,
    turn_rate_setpoint,
)
from companion.link.supervision import (
    AirspeedMonitor,
    ResponseMonitor,
    default_profile,
    not_flying_reason,
    take_over_min_alt_m,
)
from companion.mission import load_mission
from companion.process.config import RunConfig
from companion.process.event_log import EventLog
from companion.process.runner import Runner
from companion.sim.arduplane.sitl import find_binary
from sitl_model.autopilot import Mode
from sitl_model.codec import dialect as d
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.link import VehicleLink
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import Params
from sitl_model.sim import DT_S, Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

# real processes or sockets, wall clock; alone: real ArduPlane SITL, free-running
pytestmark = [pytest.mark.integration, pytest.mark.alone]

FRAME = LocalFrame(*DEFAULT_ORIGIN)


@pytest.mark.parametrize(
    ("mask", "roll", "pitch", "rudder", "throttle"),
    [
        (0xFE, True, False, False, False),  # the bank profile: roll alone
        (0x7E, True, True, True, False),  # "attitude used": pitch 0 and rudder 0 as well
        (0xC3, False, False, True, False),  # the turn-rate profile: only the rudder, to 0
        (0xFF, False, False, False, False),  # everything ignored
        (0x00, True, True, True, True),  # everything used
        (0xBC, True, True, False, True),  # roll + pitch + throttle (bits 0, 1, 6 clear)
    ],
)
def test_arduplane_forced_axes_follow_its_source(mask, roll, pitch, rudder, throttle):
    assert arduplane_forced_axes(mask) == {
        "roll": roll,
        "pitch": pitch,
        "rudder": rudder,
        "throttle": throttle,
    }


def test_bank_profile_forces_roll_only_on_arduplane_and_is_described_as_bank():
    assert MASK_BANK == 0xFE
    axes = arduplane_forced_axes(MASK_BANK)
    assert axes["roll"] and not (axes["pitch"] or axes["rudder"] or axes["throttle"])
    msg = bank_setpoint(math.radians(20.0), 1000, 1)
    assert describe(msg) == pytest.approx({"kind": "bank", "roll_rad": math.radians(20.0)})
    assert not arduplane_forced_axes(MASK_TURN_RATE)["roll"]


def make_link(n: int = 1, **overrides: float) -> tuple[Simulation, list[VehicleLink]]:
    setups = [VehicleSetup(i + 1, 0.0, 1000.0 * i, 0.0, 100.0) for i in range(n)]
    sim = Simulation(setups, Params(overrides), FRAME)
    tm = Telemetry(sim)
    links = [VehicleLink(sim, i, tm, MissionProtocol(home=sim.home_item())) for i in range(n)]
    return sim, links


def fly(sim: Simulation, link: VehicleLink, seconds: float, msg_fn, period_s: float = 0.2):
    """Step ``seconds`` sending ``msg_fn(t)`` every ``period_s``; heading change (rad)."""
    turned = 0.0
    every = max(1, round(period_s / DT_S))
    for k in range(round(seconds / DT_S)):
        if k % every == 0:
            link.handle(msg_fn(sim.t_s), "peer", 0.0)
        prev = float(sim.state.heading_rad[0])
        sim.step()
        turned += (float(sim.state.heading_rad[0]) - prev + math.pi) % (2 * math.pi) - math.pi
    return turned


def test_simulator_flies_the_bank_profile_and_keeps_its_airspeed():
    sim, (link,) = make_link(1, GUID_TIMEOUT=3.0)
    phi = math.radians(15.0)
    turned = fly(sim, link, 20.0, lambda t: bank_setpoint(phi, round(t * 1000), 1))
    expected = 9.80665 * math.tan(phi) / 20.0 * 20.0
    assert turned == pytest.approx(expected, rel=0.02)
    assert float(sim.airspeed_m_s[0]) == pytest.approx(20.0)
    assert not sim.autopilots[0].guided_loitering


def test_simulator_ignores_body_yaw_rate_like_arduplane_and_loiters():
    """0xC3 steers nothing on ArduPlane: the vehicle holds, then loiters on its own."""
    sim, (link,) = make_link(1, GUID_TIMEOUT=3.0)
    u = math.radians(-10.0)  # a left turn asked for
    turned = fly(sim, link, 30.0, lambda t: turn_rate_setpoint(u, round(t * 1000), 1))
    ap = sim.autopilots[0]
    assert ap.guided_loitering  # its own loiter (a right-hand circle), not the command
    assert turned > 0.0
    assert link.counters.refused == 0  # accepted silently, as ArduPlane does


def test_simulator_honours_body_yaw_rate_only_as_a_rate_autopilot():
    sim, (link,) = make_link(1, GUID_TIMEOUT=3.0, SIM_RATE_OK=1.0)
    u = math.radians(-10.0)
    turned = fly(sim, link, 10.0, lambda t: turn_rate_setpoint(u, round(t * 1000), 1))
    assert turned == pytest.approx(u * 10.0, rel=0.01)
    # the bank profile works the same, without ArduPlane's pitch forcing
    sim2, (link2,) = make_link(1, SIM_RATE_OK=1.0)
    fly(sim2, link2, 30.0, lambda t: bank_setpoint(0.2, round(t * 1000), 1))
    assert float(sim2.airspeed_m_s[0]) == pytest.approx(20.0)
    m = bank_setpoint(0.2, 0, 1)
    m.type_mask = 0x07  # the MAVLink spec's "attitude used": no decay in this mode
    fly(sim2, link2, 30.0, lambda t: m)
    assert float(sim2.airspeed_m_s[0]) == pytest.approx(20.0)


def test_pitch_forcing_mask_makes_the_simulated_airspeed_decay():
    """0x7E forces pitch 0 on ArduPlane: the airspeed decays (19.9 -> 11.4 m/s in 60 s
    measured); the simulator flies and reports it, 0xFE does not."""
    sim, (link, link2) = make_link(2)

    def msg(mask: int, sysid: int):
        def build(t: float):
            m = bank_setpoint(0.0, round(t * 1000), sysid)
            m.type_mask = mask
            return m

        return build

    every = round(0.2 / DT_S)
    speeds = {}
    for k in range(round(60.0 / DT_S)):
        if k % every == 0:
            link.handle(msg(0x7E, 1)(sim.t_s), "p", 0.0)
            link2.handle(msg(MASK_BANK, 2)(sim.t_s), "p", 0.0)
        sim.step()
        for t_mark in (10.0, 30.0, 60.0):
            if abs(sim.t_s - t_mark) < DT_S / 2:
                speeds[t_mark] = float(sim.airspeed_m_s[0])
    assert speeds[10.0] == pytest.approx(16.6, abs=0.8)
    assert speeds[30.0] == pytest.approx(13.4, abs=0.8)
    assert speeds[60.0] == pytest.approx(11.4, abs=0.8)
    assert float(sim.airspeed_m_s[1]) == pytest.approx(20.0)  # 0xFE: cruise kept
    hud = link.tm.vfr_hud(0)
    assert hud.airspeed == pytest.approx(float(sim.airspeed_m_s[0]))
    # the decayed vehicle really flies slower
    gs = np.abs(sim.ground_velocity_m_s)
    assert gs[0] < 0.7 * gs[1]


def command_int(cmd: int, p1=0.0, p2=0.0, p3=0.0, frame=0, z=0.0):
    return d.MAVLink_command_int_message(1, 1, frame, cmd, 0, 0, p1, p2, p3, 0.0, 0, 0, z)


def test_guided_change_speed_and_altitude_as_arduplane_takes_them():
    sim, (link,) = make_link(1)
    out = link.handle(command_int(d.MAV_CMD_GUIDED_CHANGE_SPEED, 0.0, 24.0), "p", 0.0)
    assert out[0][0].result == d.MAV_RESULT_ACCEPTED
    out = link.handle(command_int(d.MAV_CMD_GUIDED_CHANGE_SPEED, 0.0, 60.0), "p", 0.0)
    assert out[0][0].result == d.MAV_RESULT_DENIED  # outside the airframe's range
    z = FRAME.alt_m + 130.0  # AMSL
    out = link.handle(
        command_int(d.MAV_CMD_GUIDED_CHANGE_ALTITUDE, frame=d.MAV_FRAME_GLOBAL, z=z), "p", 0.0
    )
    assert out[0][0].result == d.MAV_RESULT_ACCEPTED
    for _ in range(round(20.0 / DT_S)):
        sim.step()
    assert float(sim.airspeed_m_s[0]) == pytest.approx(24.0, abs=0.05)
    assert float(sim.alt_m[0]) == pytest.approx(130.0, abs=1e-6)  # 30 m at 3 m/s
    # outside GUIDED both fail, as on ArduPlane
    sim.autopilots[0].set_mode(Mode.LOITER, sim.t_s, sim.obs(0))
    out = link.handle(command_int(d.MAV_CMD_GUIDED_CHANGE_SPEED, 0.0, 20.0), "p", 0.0)
    assert out[0][0].result != d.MAV_RESULT_ACCEPTED
    out = link.handle(
        command_int(d.MAV_CMD_GUIDED_CHANGE_ALTITUDE, frame=d.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=90),
        "p",
        0.0,
    )
    assert out[0][0].result == d.MAV_RESULT_FAILED


# ---- the companion against the simulator in process: supervision closes the loop ---------
REPO = Path(__file__).resolve().parents[1]


class SimBridge:
    """The runner's autopilot link, wired to one simulated vehicle (no sockets)."""

    url = "sim"
    tlog = None
    generation = 0
    traffic_bytes = (0, 0)  # (received, sent) bytes: ONBOARD_COMPUTER_STATUS

    def __init__(self, vlink: VehicleLink) -> None:
        self.v = vlink
        self.sysid = vlink.sysid
        self.autopilot: int | None = None
        self.rates_hz: dict[str, float] = {}  # nothing asked: no stream watched
        self.texts: list[str] = []
        self.counts = {"rx": 0}
        self.inbox: list = []
        self.sent: list = []

    def is_autopilot(self, m) -> bool:
        return m.get_srcComponent() == 1

    def send(self, msg) -> None:
        self.sent.append(msg)
        for out, _peer in self.v.handle(wire(msg, 255, 190), "companion", 0.0):
            self.inbox.append(out)

    def command_long(self, command: int, *params: float) -> None:
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.send(d.MAVLink_command_long_message(self.sysid, 1, command, 0, *p))

    def statustext(self, text: str, severity: int = 5) -> None:
        self.texts.append(text)

    def fileno(self):
        return None

    def tick(self) -> None:  # no link supervision: the link never drops
        return None

    def close(self) -> None:
        pass


class NullGroup:
    rx_bytes = tx_bytes = 0  # the group's traffic: ONBOARD_COMPUTER_STATUS

    def __init__(self) -> None:
        self.stats = {"accepted": 0, "sent": 0}
        self._r, self._w = socket.socketpair()

    def send_state(self, s) -> None:
        pass

    def send_alert(self, a) -> None:
        pass

    def receive(self, now_s=None):
        return []

    def fileno(self) -> int:
        return self._r.fileno()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._r.close()
        self._w.close()


def wire(msg, src_system: int, src_component: int):
    enc = d.MAVLink(None, srcSystem=src_system, srcComponent=src_component)
    out = d.MAVLink(None).parse_buffer(msg.pack(enc))
    assert out is not None and len(out) == 1
    return out[0]


def fly_companion(
    seconds: float,
    profile: str = "auto",
    start_mode: Mode = Mode.GUIDED,
    alt_m: float = 110.0,
    take_control: bool = False,
    **params: float,
):
    """One simulated vehicle (sysid 1, on the mission's loop) and its companion, stepped
    together: telemetry at the simulator's default rates, every message over the codec."""
    mission = load_mission(REPO / "tests" / "data" / "companion_ellipse_fast.yaml")
    pose = mission.vehicles.initial[0]
    setup = VehicleSetup(1, pose.north_m, pose.east_m, pose.heading_deg, alt_m)
    o = mission.origin
    sim = Simulation(
        [setup],
        Params({"SIM_AIRSPEED": mission.vehicles.airspeed_m_s, **params}),
        LocalFrame(o.lat_deg, o.lon_deg, o.alt_m),
        start_mode=start_mode,
    )
    tm = Telemetry(sim)
    vlink = VehicleLink(sim, 0, tm, MissionProtocol(home=sim.home_item()))
    link, group = SimBridge(vlink), NullGroup()
    config = RunConfig(mission=mission, link=LinkConfig(profile=profile), take_control=take_control)
    events: list[dict] = []
    log = EventLog(None)
    log.write = events.append
    runner = Runner(config, link, lambda sysid: group, log, status_out=io.StringIO())
    b = tm.builders
    every = {  # steps of 20 ms
        "HEARTBEAT": 50, "SYSTEM_TIME": 50, "EXTENDED_SYS_STATE": 50, "VFR_HUD": 25,
        "GLOBAL_POSITION_INT": 10,
    }  # fmt: skip
    try:
        for k in range(round(seconds / DT_S)):
            sim.step()
            for name, n in every.items():
                if k % n == 0:
                    msg = b[name](0)
                    if name == "HEARTBEAT":
                        link.autopilot = int(msg.autopilot)
                    link.inbox.append(msg)
            msgs, link.inbox = link.inbox, []
            for m in msgs:
                runner.on_messages([wire(m, 1, 1)])
            if k % 50 == 0:
                runner.take_control()
    finally:
        group.close()
    return sim, runner, link, events


def test_auto_profile_on_an_arduplane_like_autopilot_is_bank_and_healthy():
    sim, runner, _link, events = fly_companion(40.0)
    assert runner.profile == "bank"
    assert [e["profile"] for e in events if e["event"] == "profile"] == ["bank"]
    assert runner.health() == "ok"
    assert runner.shaper.gain == pytest.approx(1.0, abs=0.1)  # SIM_TR_EFF 1: flown as sent
    assert float(sim.airspeed_m_s[0]) == pytest.approx(20.0, abs=0.01)


def test_turn_rate_profile_on_a_rate_autopilot_is_followed():
    _sim, runner, _link, events = fly_companion(40.0, profile="turn-rate", SIM_RATE_OK=1.0)
    assert runner.profile == "turn-rate"
    assert runner.health() == "ok"
    assert not [e for e in events if e["event"] == "profile_ignored"]


def test_a_turn_rate_profile_arduplane_ignores_is_detected_not_silently_commanded():
    """The defect of the issue: on ArduPlane the body yaw rate steers nothing and the
    aircraft flies its own loiter. Now reported: event, STATUSTEXT, status-line field."""
    _sim, runner, link, events = fly_companion(40.0, profile="turn-rate")
    assert runner.authority.commanding
    raised = [e for e in events if e["event"] == "profile_ignored"]
    assert raised, [e["event"] for e in events]
    t0 = next(e["t_s"] for e in events if e["t_s"] is not None)
    assert raised[0]["t_s"] - t0 < 25.0  # a 10 s window once commanding
    assert any("turn not followed" in t for t in link.texts)
    assert "profile_ignored" in runner.health()


def test_a_pitch_forcing_mask_shows_as_airspeed_far_from_the_missions(monkeypatch):
    """The old bank mask 0x7E (ArduPlane forces pitch 0): the airspeed decays and is
    reported once more than 15 % off for 10 s; with 0xFE nothing is reported."""
    monkeypatch.setattr(setpoints_module, "MASK_BANK", 0x7E)
    sim, runner, link, events = fly_companion(40.0, profile="bank")
    assert float(sim.airspeed_m_s[0]) < 15.0
    off = [e for e in events if e["event"] == "airspeed_off"]
    assert len(off) == 1
    assert any("airspeed" in t and "mission 20.0" in t for t in link.texts)
    assert "airspeed_off" in runner.health()


def test_take_over_sends_the_missions_airspeed_and_altitude_and_they_are_held():
    """Started during a climb-out at 60 m (mission 100 m for sysid 1): taken over once high
    enough, then the mission's altitude and airspeed are GUIDED targets."""
    sim, runner, link, events = fly_companion(
        30.0, start_mode=Mode.LOITER, alt_m=60.0, take_control=True, SIM_AIRSPEED=20.0
    )
    assert runner.authority.commanding
    first = next(e for e in events if e["event"].startswith("take_control"))
    assert first["event"] == "take_control"  # 60 m is above half the mission's 100 m
    cmds = [m.command for m in link.sent if m.get_type() == "COMMAND_INT"]
    assert 43000 in cmds and 43001 in cmds
    assert sim.autopilots[0].alt_target_m == pytest.approx(100.0)
    assert float(sim.alt_m[0]) == pytest.approx(100.0)  # climbed at 3 m/s and holds it


def test_a_climbing_out_aircraft_is_not_taken_over():
    sim, runner, link, events = fly_companion(
        6.0, start_mode=Mode.LOITER, alt_m=30.0, take_control=True
    )
    assert sim.autopilots[0].mode is Mode.LOITER  # never switched
    assert not runner.authority.was_commanding
    refused = [e["reason"] for e in events if e["event"] == "take_control_refused"]
    assert refused == ["30 m above home, below 50 m"]  # once, not every retry
    assert any("not flying: 30 m above home" in t for t in link.texts)
    assert runner.health() == "not_flying"


# ---- the pure monitors ---------------------------------------------------------------------
def test_take_over_altitude_floor():
    assert take_over_min_alt_m(100.0) == 50.0
    assert take_over_min_alt_m(30.0) == 20.0
    assert take_over_min_alt_m(15.0) == 15.0
    assert not_flying_reason(True, 2, 80.0, 19.0, 100.0, 20.0) is None
    assert not_flying_reason(True, None, 80.0, None, 100.0, 20.0) is None  # nothing streamed
    assert not_flying_reason(True, 3, 80.0, 19.0, 100.0, 20.0) == "landed state TAKEOFF"
    assert not_flying_reason(None, 2, 80.0, 19.0, 100.0, 20.0) == "disarmed"


def test_airspeed_monitor_needs_the_deviation_to_last():
    m = AirspeedMonitor(20.0, tol_frac=0.15, hold_s=10.0)
    assert m.update(0.0, 16.0) is None  # 20 % off, just started
    assert m.update(9.9, 16.0) is None
    assert m.update(10.0, 16.0).active
    assert m.update(11.0, 16.0) is None  # reported once
    assert m.update(12.0, 19.0) is None
    assert m.update(21.9, 19.0) is None
    iss = m.update(22.0, 19.0)
    assert iss is not None and not iss.active
    m2 = AirspeedMonitor(20.0)
    assert all(m2.update(t, 17.5) is None for t in range(100))  # 12.5 % off: tolerated


def test_response_monitor_tells_followed_from_ignored_and_grounded():
    r = ResponseMonitor(window_s=10.0)
    for k in range(100):  # followed, with a lag-like error
        x = 0.1 * math.sin(0.3 * k * 0.2)
        assert r.update(0.2 * k, x, 0.95 * x + 0.005, 1.0, 20.0) == []
    got = []
    for k in range(100, 200):  # ignored: a steady 0.2 rad/s loiter whatever is asked
        x = 0.1 * math.sin(0.3 * k * 0.2)
        got += r.update(0.2 * k, x, 0.2, 1.0, 20.0)
    assert [(i.name, i.active) for i in got] == [("profile_ignored", True)]
    got = []
    for k in range(200, 300):
        got += r.update(0.2 * k, 0.05, 0.05, 1.0, 0.0)  # sat on the ground
    assert ("not_responding", True) in [(i.name, i.active) for i in got]


def test_response_monitor_says_nothing_of_commands_held_at_the_limit():
    # acquiring the splay, the law asks the full 0.314 rad/s and the autopilot's roll limit
    # gives 0.2: that is the aircraft's limit, not an ignored profile
    limit = math.radians(18.0)
    r = ResponseMonitor(window_s=10.0, max_turn_rate_rad_s=limit)
    got = []
    for k in range(200):
        got += r.update(0.2 * k, limit / 0.7, 0.2, 0.7, 20.0)
    assert got == []
    # a gain not yet learnt (30 % off) is not an ignored profile
    r = ResponseMonitor(window_s=10.0, max_turn_rate_rad_s=limit)
    got = []
    for k in range(200):
        got += r.update(0.2 * k, 0.15 / 0.7, 0.7 * 0.15 / 0.7 * 1.3, 0.7, 20.0)
    assert got == []
    # a steady miss below the limit is reported
    got = []
    for k in range(200, 400):
        got += r.update(0.2 * k, 0.15 / 0.7, -0.02, 0.7, 20.0)
    assert [(i.name, i.active) for i in got] == [("profile_ignored", True)]


def test_response_monitor_says_nothing_of_a_lagging_aircraft_swung_between_its_limits():
    """Acquiring the splay (or flying a minimum-time path), the law swings its command from
    one turn-rate limit to the other; an aircraft that rolls with a 0.5 s first-order lag
    (integrated in 10 ms steps, sampled every 0.1 s) follows. Only the crossings are below
    the limit, and there the lag alone reads up to the whole limit off: judged against the
    unlagged command on those samples alone, three ArduPlanes raised 5-6 false
    ``profile_ignored`` per run (10.5 to 3.5 deg/s "off"). The lagged expectation and the
    judged-fraction rule say nothing; a steady miss below the limit is still reported."""
    limit = math.radians(18.0)
    r = ResponseMonitor(window_s=10.0, max_turn_rate_rad_s=limit)
    got, y = [], 0.0
    for k in range(1200):  # 120 s: 3 s at +limit, 3 s at -limit, 0.4 s ramps between
        t = 0.1 * k
        u = (t % 6.0) / 0.4 if (t % 6.0) < 3.0 else (3.0 - t % 6.0) / 0.4
        x = limit * max(-1.0, min(1.0, 2.0 * u - 1.0 if (t % 6.0) < 3.0 else 1.0 + 2.0 * u))
        for _ in range(10):
            y += (x - y) * (1.0 - math.exp(-0.01 / 0.5))
        got += r.update(t, x, y, 1.0, 20.0)
    assert got == []
    for k in range(1200, 1600):  # then a steady command below the limit, not flown
        got += r.update(0.1 * k, 0.5 * limit, 0.0, 1.0, 20.0)
    assert [(i.name, i.active) for i in got] == [("profile_ignored", True)]


def test_keepalive_resends_the_setpoint_when_telemetry_stalls():
    """ArduPlane drops an attitude override 3 s after the last message: with no new
    position (so no control step), the setpoint in force goes again every 0.25 s of wall."""
    wall = [0.0]
    mission = load_mission(REPO / "tests" / "data" / "companion_ellipse_fast.yaml")
    sim, (vlink,) = make_link(1)
    link, group = SimBridge(vlink), NullGroup()
    runner = Runner(
        RunConfig(mission=mission, link=LinkConfig(profile="bank")),
        link,
        lambda sysid: group,
        EventLog(None),
        status_out=io.StringIO(),
        wall=lambda: wall[0],
    )
    try:
        runner.on_messages([wire(vlink.tm.heartbeat(0), 1, 1)])
        setpoint = bank_setpoint(0.2, 0, 1)  # a control step's setpoint, sent and in force
        link.send(setpoint)
        runner.channel.in_force(setpoint, wall[0])

        def setpoints() -> int:  # what else goes (ONBOARD_COMPUTER_STATUS at 1 Hz) not counted
            return sum(m.get_type() == "SET_ATTITUDE_TARGET" for m in link.sent)

        n = setpoints()
        for _ in range(12):  # 3 s of wall without telemetry
            wall[0] += 0.25
            runner.tick()
        assert setpoints() == n + 12
        assert runner.counters.keepalives == 12
        assert sim.autopilots[0]._last_setpoint_t == 0.0  # the simulator took each one
    finally:
        group.close()


# ---- one short check on real ArduPlane SITL (where the binary is) ---------------------------
def _arduplane() -> Path | None:
    """The binary as ``companion fleet --autopilot arduplane`` finds it ($ARDUPLANE_SITL,
    which tests/conftest.py points at ../shared beside the clone), or None."""
    try:
        return find_binary(None)
    except UserError:
        return None


ARDUPLANE = _arduplane()


def free_instance() -> int:
    """An ArduPlane ``-I`` whose TCP ports 5760-5763 + 10 I are free."""
    for i in range(7, 40):
        try:
            for port in range(5760 + 10 * i, 5764 + 10 * i):
                with socket.socket() as s:
                    s.bind(("127.0.0.1", port))
        except OSError:
            continue
        return i
    pytest.skip("no free ArduPlane port range")


# extended: CI's three-ArduPlane fleet (tests/test_arduplane.py) checks the same of each aircraft
@pytest.mark.extended
@pytest.mark.slow
@pytest.mark.skipif(ARDUPLANE is None, reason="no ArduPlane SITL binary ($ARDUPLANE_SITL)")
def test_bank_profile_on_real_arduplane_holds_speed_and_height(tmp_path):
    """The default profile for ArduPilot, on the real firmware: airspeed and altitude held,
    the turn-rate gain identified near ArduPlane's 0.70, nothing reported."""
    bench = subprocess.Popen(
        [sys.executable, str(REPO / "bench" / "arduplane_profiles.py"), "--profiles", "bank",
         "--speedup", "5", "--seconds", "150", "--binary", str(ARDUPLANE),
         "--instance", str(free_instance()), "--out", str(tmp_path)],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        out, _ = bench.communicate(timeout=600)
    finally:
        if bench.poll() is None:  # SIGTERM: the bench stops the instance it started
            bench.terminate()
            bench.communicate(timeout=30)
    assert bench.returncode == 0
    print(out)
    line = next(ln for ln in out.splitlines() if ln.startswith("bank"))
    nums = [float(x) for x in re.findall(r"[-+]?\d+\.\d+", line)]
    airspeed, _p5, _alt_med, alt_max, xtrack_med, _p95, gain = nums[:7]
    assert airspeed == pytest.approx(20.0, abs=1.0)
    assert alt_max < 3.0
    # one aircraft converging from wherever TAKEOFF left it: 1.2 m median after 180 s in
    # one run, 13-26 m over this shorter window on a loaded machine; the ignored turn-rate
    # profile gave 69 m (its own loiter)
    assert xtrack_med < 50.0
    assert 0.5 < gain < 0.9
    assert line.endswith("health ok")


def test_default_profile_by_autopilot_type():
    assert default_profile(d.MAV_AUTOPILOT_ARDUPILOTMEGA) == "bank"
    assert default_profile(d.MAV_AUTOPILOT_PX4) == "attitude"  # PX4 refuses 0xC3: docs/px4.md
    assert default_profile(None) == "turn-rate"
