"""The companion's PX4 link, at home (no sockets, no PX4): its modes and masks, the OFFBOARD
entry (pre-stream, back-off, giving up), the clock, the two offboard profiles, the link's
telemetry requests, and the runner taking a PX4 over against hand-written fakes.

The same against real PX4 SITL: ``tests/test_px4.py``."""

from __future__ import annotations

import cmath
import io
import itertools
import math
import socket

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.attitude_target import px4_offboard_axes
from companion.link import px4
from companion.link.clock import VehicleClock
from companion.link.config import LinkConfig
from companion.link.connection import MAX_REQUEST_TRIES, AutopilotLink
from companion.link.modes import Authority
from companion.link.offboard import PX4_ACCEL_SIGN, EnergyHold, OffboardSetpoints
from companion.link.setpoints import (
    MASK_ATTITUDE_THRUST,
    MASK_BANK,
    MASK_TURN_RATE,
    describe,
)
from companion.link.supervision import default_profile
from companion.mission import load_mission
from companion.mission.model import Origin
from companion.process.config import RunConfig, telemetry_rates_hz
from companion.process.event_log import EventLog
from companion.process.runner import Runner
from sitl_model.testing import REPO
from tests.test_companion_link import FakeGroup, FakeLink, gpi_fields, wire

AUTO_LOITER = (4 << 16) | (3 << 24)
ORIGIN = Origin(39.8, -84.0, 250.0)


# ---- modes and masks ------------------------------------------------------------------------
def test_px4_modes_are_main_and_sub_bytes_of_custom_mode():
    assert px4.mode_name(AUTO_LOITER) == "AUTO.LOITER" and AUTO_LOITER == 50593792
    assert px4.mode_name(px4.OFFBOARD_CUSTOM_MODE) == "OFFBOARD"
    assert px4.OFFBOARD_CUSTOM_MODE == 393216
    assert px4.is_offboard(393216) and not px4.is_offboard(AUTO_LOITER)
    assert not px4.is_offboard(15)  # ArduPlane's GUIDED means nothing to PX4
    assert px4.mode_name((4 << 16) | (5 << 24)) == "AUTO.RTL"


def test_authority_on_px4_commands_in_offboard_only():
    a = Authority()
    assert a.heartbeat(AUTO_LOITER, 12).after == "waiting" and a.mode == "AUTO.LOITER"
    assert a.heartbeat(15, 12) is None  # mode 15 is not GUIDED on PX4
    assert a.heartbeat(px4.OFFBOARD_CUSTOM_MODE, 12).after == "commanding"
    tr = a.heartbeat((4 << 16) | (5 << 24), 12)  # the failsafe's RTL
    assert (tr.after, tr.mode) == ("overridden", "AUTO.RTL")


@pytest.mark.parametrize(
    ("mask", "valid", "thrust"),
    [
        (MASK_TURN_RATE, False, False),  # 0xC3: OFFBOARD refused (measured)
        (MASK_BANK, False, False),  # 0xFE: refused the same way
        (MASK_ATTITUDE_THRUST, True, True),  # 0x07: the attitude profile
        (0x7E, True, False),  # attitude; `thrust` ignored (bit 6), thrust_body[0] instead
        (0x80, True, True),  # all three body rates
        (0x47, True, False),  # attitude, THROTTLE_IGNORE: thrust 0 on PX4, not "kept"
    ],
)
def test_px4_reading_of_the_attitude_masks(mask, valid, thrust):
    axes = px4_offboard_axes(mask)
    assert axes["valid"] == valid
    if valid:
        assert axes["thrust"] == thrust


def test_default_profile_by_autopilot():
    assert default_profile(3) == "bank"
    assert default_profile(12) == "attitude"
    assert default_profile(0) == "turn-rate"


def test_telemetry_for_px4_asks_no_wind_and_no_heartbeat_rate():
    rates = telemetry_rates_hz(10.0, 12)
    assert "WIND" not in rates and "HEARTBEAT" not in rates  # PX4 answers FAILED to both
    assert rates["WIND_COV"] == 1.0 and rates["VFR_HUD"] == 10.0
    assert telemetry_rates_hz(10.0) == telemetry_rates_hz(10.0, 3)  # ArduPilot unchanged
    assert "WIND" in telemetry_rates_hz(10.0)


# ---- entering OFFBOARD ----------------------------------------------------------------------
def stream(entry: px4.OffboardEntry, t0: float, t1: float, dt: float = 0.1) -> list[float]:
    """Stream setpoints from t0 to t1 (s); the times a request was due."""
    asked = []
    for k in range(round((t1 - t0) / dt) + 1):
        t = round(t0 + k * dt, 6)
        entry.streamed(t)
        entry.poll(t)
        if entry.due(t):
            asked.append(t)
    return asked


def test_offboard_is_asked_for_only_after_a_second_of_stream():
    e = px4.OffboardEntry()
    assert not e.due(0.0)  # nothing streamed
    assert stream(e, 0.0, 0.95) == []
    assert stream(e, 1.0, 1.05) == [1.0]
    assert e.state == "requested" and e.tries == 1
    e.heartbeat(True)
    assert e.state == "entered" and e.done


def until_due(entry: px4.OffboardEntry, t0: float, dt: float = 0.1) -> float:
    """Stream from t0 (s) until a request is due; its time."""
    for k in range(1000):
        t = round(t0 + k * dt, 6)
        entry.streamed(t)
        if entry.due(t):
            return t
    raise AssertionError("never due")


def test_a_refusal_backs_off_and_five_give_up():
    e = px4.OffboardEntry()
    asked = [until_due(e, 0.0)]
    assert asked == [1.0]
    for _ in range(4):
        e.answer(asked[-1] + 0.05, mav.MAV_RESULT_TEMPORARILY_REJECTED)
        assert e.state == "backoff"
        asked.append(until_due(e, asked[-1] + 0.1))
    gaps = [round(b - a, 1) for a, b in itertools.pairwise(asked)]
    assert gaps == [2.1, 4.1, 8.1, 16.1]  # the back-off (plus the 0.1 s stream step)
    e.answer(asked[-1] + 0.05, mav.MAV_RESULT_TEMPORARILY_REJECTED)
    assert e.state == "gave_up" and e.tries == 5 and len(e.refusals) == 5
    assert stream(e, 100.0, 200.0) == []  # never asked again


def test_no_answer_counts_as_a_refusal_and_a_pause_restarts_the_prestream():
    e = px4.OffboardEntry()
    stream(e, 0.0, 1.0)
    stream(e, 1.1, 4.1)  # accepted or not, no OFFBOARD heartbeat within 3 s
    assert e.refusals == [-1] and e.state == "backoff"
    e.streamed(10.0)  # a 6 s pause: below 2 Hz
    assert e.state == "idle" or e.state == "streaming"
    assert not e.due(10.5)  # the pre-stream starts over
    assert stream(e, 10.1, 11.1) == [11.0]


def test_an_illegal_entry_event_raises():
    e = px4.OffboardEntry()
    with pytest.raises(ValueError):
        e._step("refused")


# ---- clock ----------------------------------------------------------------------------------
def test_px4_clock_is_its_own_boot_time_anchored_once():
    c = VehicleClock(anchor_once=True)
    c.on_system_time(1_000_000_000_000_000, 10_000)
    # SITL at 3x: the host's unix time advances 1 s while time_boot_ms advances 3 s
    c.on_system_time(1_000_000_001_000_000, 13_000)
    assert c.to_vehicle_s(13_000) == pytest.approx(1_000_000_003.0)
    free = VehicleClock()
    free.on_system_time(1_000_000_000_000_000, 10_000)
    free.on_system_time(1_000_000_001_000_000, 13_000)
    assert free.to_vehicle_s(13_000) == pytest.approx(1_000_000_001.0)  # ArduPlane's way


# ---- the offboard profiles ------------------------------------------------------------------
def test_energy_hold_starts_bumpless_and_pushes_the_right_way():
    h = EnergyHold()
    h.track(0.0, 0.05, 0.6)
    pitch, thrust = h.update(0.1, 0.0, 0.0, 0.0, 0.0, 0.05, 0.6)
    assert (pitch, thrust) == pytest.approx((0.05, 0.6))
    pitch, thrust = h.update(0.2, 10.0, 0.0, 2.0, 0.0, 0.05, 0.6)  # low and slow
    assert pitch > 0.05 and thrust > 0.6
    pitch, thrust = h.update(0.3, -10.0, 0.0, -2.0, 0.0, 0.05, 0.6)  # high and fast
    assert pitch < 0.05 and thrust < 0.6
    for k in range(1000):  # a limit is not wound into
        h.update(0.4 + 0.1 * k, 1000.0, 0.0, 100.0, 0.0, 0.0, 0.0)
    assert h.pitch_i_rad < math.radians(16) and h.thrust_i <= 1.0


def test_attitude_profile_encodes_roll_pitch_thrust_with_mask_0x07():
    o = OffboardSetpoints(ORIGIN)
    o.data.on_attitude(0.1, 0.02, 1.0)
    o.data.on_vfr_hud(20.0, 60.0)
    o.data.on_position(350_000, 0)
    o.target_alt_amsl_m, o.target_airspeed_m_s = 350.0, 20.0
    msg = wire(o.attitude(0.0, math.radians(20.0), 1234, 6))
    assert msg.type_mask == MASK_ATTITUDE_THRUST and msg.time_boot_ms == 1234
    d = describe(msg)
    assert d["kind"] == "attitude"
    assert d["roll_rad"] == pytest.approx(math.radians(20.0), abs=1e-6)
    assert d["thrust"] == pytest.approx(0.6, abs=1e-6)  # on target: its own throttle


@pytest.mark.parametrize("u", [0.0, 0.1, -0.2])
def test_path_profile_sends_the_arcs_look_ahead_point(u):
    o = OffboardSetpoints(ORIGIN, lookahead_s=1.0)
    o.target_alt_amsl_m = 350.0
    msg = wire(o.path(u, 100 + 50j, 0.0, 20.0, 0j, 1000, 6))
    d = describe(msg)
    assert msg.type_mask == 0xC00 and msg.coordinate_frame == mav.MAV_FRAME_GLOBAL_INT
    assert d["alt_amsl_m"] == pytest.approx(350.0)
    # the particle's arc: heading north, turning u for 1 s at 20 m/s
    ahead = 100 + 50j + 20.0 * (cmath.exp(1j * u) - 1) / (1j * u) if u else 120 + 50j
    import pymap3d

    lat, lon, _ = pymap3d.ned2geodetic(ahead.real, ahead.imag, 0.0, 39.8, -84.0, 250.0)
    assert d["lat_deg"] == pytest.approx(lat, abs=2e-7)
    assert d["lon_deg"] == pytest.approx(lon, abs=2e-7)
    vel = complex(d["vn_m_s"], d["ve_m_s"])
    assert vel == pytest.approx(20.0 * cmath.exp(1j * u), abs=1e-4)
    acc = complex(d["an_m_s2"], d["ae_m_s2"])
    # PX4 turns against the acceleration's normal part (measured): sent negated
    assert acc == pytest.approx(PX4_ACCEL_SIGN * 1j * u * vel, abs=1e-4)


# ---- the link's telemetry requests ----------------------------------------------------------
class _FakeMav:
    def __init__(self) -> None:
        self.sent: list = []
        self.srcSystem = 1
        self.robust_parsing = False

    def send(self, msg) -> None:
        self.sent.append(msg)


class _FakeConn:
    def __init__(self) -> None:
        self.mav = _FakeMav()
        self.inbox: list = []

    def recv_msg(self):
        return self.inbox.pop(0) if self.inbox else None

    def close(self) -> None:
        pass


def test_link_asks_by_autopilot_type_and_gives_a_failed_request_up():
    now = [0.0]
    conn = _FakeConn()
    warnings: list[str] = []
    link = AutopilotLink(
        "fake",
        rates_hz=lambda ap: telemetry_rates_hz(10.0, ap),
        clock=lambda: now[0],
        warn=warnings.append,
        opener=lambda *_: conn,
    )
    conn.inbox.append(wire(mav.MAVLink_heartbeat_message(1, 12, 129, AUTO_LOITER, 4, 3), 6, 1))
    link.receive()
    assert link.autopilot == 12 and set(link.rates_hz) == set(telemetry_rates_hz(10.0, 12))

    def intervals():
        return [
            int(m.param1)
            for m in conn.mav.sent
            if m.get_type() == "COMMAND_LONG" and m.command == mav.MAV_CMD_SET_MESSAGE_INTERVAL
        ]

    assert len(intervals()) == 6
    ok = mav.MAVLink_command_ack_message(mav.MAV_CMD_SET_MESSAGE_INTERVAL, 0)
    conn.inbox += [wire(ok, 6, 1) for _ in range(5)]  # all but the last (WIND_COV) accepted
    link.receive()
    for _ in range(20):  # 40 s
        now[0] += 2.0
        conn.inbox.append(wire(mav.MAVLink_heartbeat_message(1, 12, 129, AUTO_LOITER, 4, 3), 6, 1))
        link.receive()
        link.tick()
    wind_cov = mav.MAVLINK_MSG_ID_WIND_COV
    assert intervals().count(wind_cov) == MAX_REQUEST_TRIES  # then given up, not every 2 s
    assert len(warnings) == 1 and "WIND_COV" in warnings[0]


# ---- the runner taking a PX4 over ----------------------------------------------------------
class Px4FakeLink(FakeLink):
    """The FakeLink, as a PX4 (system 6)."""

    autopilot = 12

    def __init__(self) -> None:
        super().__init__()
        self.sysid = 6

    def is_autopilot(self, m) -> bool:
        return m.get_srcSystem() == 6 and m.get_srcComponent() == 1


def px4_runner(profile: str = "auto"):
    mission = load_mission(REPO / "tests" / "data" / "ellipse_1uav.yaml")
    link, group = Px4FakeLink(), FakeGroup()
    group._r, group._w = socket.socketpair()
    config = RunConfig(mission=mission, link=LinkConfig(profile=profile), take_control=True)
    events = EventLog(None)
    logged: list[dict] = []
    events.write = logged.append
    runner = Runner(config, link, lambda sysid: group, events, status_out=io.StringIO())
    return runner, link, group, logged


def px4_hb(mode: int):
    return wire(mav.MAVLink_heartbeat_message(1, 12, 1 | 128, mode, 4, 3), 6, 1)


def flying(runner) -> None:
    """SYSTEM_TIME, in the air, at cruise airspeed."""
    runner.on_messages([wire(mav.MAVLink_system_time_message(1_767_225_600_000_000, 50_000), 6, 1)])
    in_air = mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_IN_AIR)
    runner.on_messages([wire(in_air, 6, 1)])
    runner.on_messages([wire(mav.MAVLink_vfr_hud_message(20.0, 20.0, 0, 62, 350.0, 0.0), 6, 1)])
    runner.on_messages([wire(mav.MAVLink_attitude_message(50_000, 0.3, 0.02, 0.0, 0, 0, 0), 6, 1)])


def position(runner, k: int) -> None:
    lat, lon, alt, vx, vy = gpi_fields(2.0 * k, -200.0, 20 + 0j)
    m = mav.MAVLink_global_position_int_message(
        50_000 + 100 * k, lat, lon, alt, 100_000, vx, vy, 0, 0
    )
    runner.on_messages([wire(m, 6, 1)])


def modes_asked(link) -> list[tuple]:
    return [
        (m.param1, m.param2)
        for m in link.sent
        if m.get_type() == "COMMAND_LONG" and m.command == mav.MAV_CMD_DO_SET_MODE
    ]


def test_runner_prestreams_then_asks_offboard_and_never_mode_15():
    runner, link, group, _ = px4_runner()
    runner.on_messages([px4_hb(AUTO_LOITER)])
    assert runner.px4 and runner.profile == "attitude"
    flying(runner)
    position(runner, 0)
    runner.take_control()
    assert not link.commands  # no COMMAND_LONG 176/15 as ArduPlane's GUIDED
    for k in range(1, 9):
        position(runner, k)
    sps = [m for m in link.sent if m.get_type() == "SET_ATTITUDE_TARGET"]
    assert len(sps) == 8 and all(m.type_mask == MASK_ATTITUDE_THRUST for m in sps)
    assert modes_asked(link) == []  # 0.8 s of stream: not yet
    for k in range(9, 12):
        position(runner, k)
    assert modes_asked(link) == [(1.0, 6.0)]
    # PX4 refuses: said once, retried after the back-off, not every second
    nack = mav.MAVLink_command_ack_message(176, mav.MAV_RESULT_TEMPORARILY_REJECTED)
    runner.on_messages([wire(nack, 6, 1)])
    for k in range(12, 40):  # 2.8 s more
        position(runner, k)
    assert modes_asked(link) == [(1.0, 6.0)] * 2
    assert sum("OFFBOARD refused" in t for t in link.texts) == 1
    runner.on_messages([px4_hb(px4.OFFBOARD_CUSTOM_MODE)])
    assert runner.authority.commanding
    assert any("in command (OFFBOARD)" in t for t in link.texts)
    n = len(link.sent)
    position(runner, 40)
    new = link.sent[n:]
    assert [m.get_type() for m in new].count("SET_ATTITUDE_TARGET") == 1
    assert not [m for m in new if m.get_type() == "COMMAND_INT"]  # no GUIDED_CHANGE_*
    assert runner.counters.prestream == 39 and runner.counters.setpoints == 1
    group.close()


def test_runner_reports_an_ardupilot_profile_on_px4_and_never_streams_it():
    runner, link, group, _ = px4_runner(profile="bank")
    runner.on_messages([px4_hb(AUTO_LOITER)])
    assert "profile_unsupported" in runner.health()
    flying(runner)
    for k in range(30):
        position(runner, k)
        runner.take_control()
    assert not [m for m in link.sent if m.get_type() == "SET_ATTITUDE_TARGET"]
    assert modes_asked(link) == [] and not link.commands
    group.close()


def test_px4_offboard_loss_action_is_set_at_take_over_and_a_silence_failsafe_taken_back():
    """Taking PX4 over, the companion sets its offboard-loss action (COM_OBL_RC_ACT 5, Hold;
    NAV_LOITER_RAD the loiter radius) while it pre-streams; a stall sends PX4 to AUTO.LOITER:
    said at once, and with consent the companion pre-streams again and asks OFFBOARD back
    once its positions have come steadily for the health window."""
    clock = {"now": 500.0}
    mission = load_mission(REPO / "tests" / "data" / "ellipse_1uav.yaml")
    link, group = Px4FakeLink(), FakeGroup()
    group._r, group._w = socket.socketpair()
    config = RunConfig(
        mission=mission,
        link=LinkConfig(profile="auto"),
        take_control=True,
        retake_after_failsafe=True,
    )
    logged: list[dict] = []
    events = EventLog(None)
    events.write = logged.append
    runner = Runner(
        config, link, lambda sysid: group, events, status_out=io.StringIO(),
        wall=lambda: clock["now"],
    )  # fmt: skip
    runner.on_messages([px4_hb(AUTO_LOITER)])
    flying(runner)

    def fly(ks) -> None:
        for k in ks:
            clock["now"] += 0.1
            position(runner, k)
            runner.tick()

    fly(range(0, 12))
    sets = {m.param_id: m for m in link.sent if m.get_type() == "PARAM_SET"}
    assert set(sets) == {"COM_OBL_RC_ACT", "NAV_LOITER_RAD"}
    assert sets["COM_OBL_RC_ACT"].param_type == mav.MAV_PARAM_TYPE_INT32
    assert sets["NAV_LOITER_RAD"].param_value == 64.0  # the turn radius at 18 deg/s, 20 m/s
    for name in sets:  # PX4 reads them back
        m = sets[name]
        pv = mav.MAVLink_param_value_message(name.encode(), m.param_value, m.param_type, 900, 1)
        runner.on_messages([wire(pv, 6, 1)])
    said = [e for e in logged if e["event"] == "take_over_params"]
    assert said == [said[0]] and said[0]["params"] == "COM_OBL_RC_ACT=5 NAV_LOITER_RAD=64"
    assert said[0]["refused"] == ""
    assert modes_asked(link) == [(1.0, 6.0)]
    runner.on_messages([px4_hb(px4.OFFBOARD_CUSTOM_MODE)])
    fly(range(12, 30))
    assert runner.authority.commanding
    clock["now"] += 4.0  # stalled 4 s at 1x; PX4 held after COM_OF_LOSS_T
    fly(range(70, 72))  # the stream again ...
    runner.on_messages([px4_hb(AUTO_LOITER)])  # ... and PX4's 1 Hz heartbeat says Hold
    over = [e for e in logged if e["event"] == "override"]
    assert [(e["cause"], e["autopilot_mode"]) for e in over] == [("own_silence", "AUTO.LOITER")]
    fly(range(72, 95))  # 2.3 s: not healthy for 3 s yet
    assert modes_asked(link) == [(1.0, 6.0)]
    fly(range(95, 120))
    after = logged[logged.index(over[0]) :]
    steps = [e.get("action", e["event"]) for e in after if e["event"] in ("retake", "take_control")]
    assert steps == ["retake", "offboard_prestream", "offboard"]
    assert modes_asked(link) == [(1.0, 6.0)] * 2  # pre-streamed, then OFFBOARD asked again
    runner.on_messages([px4_hb(px4.OFFBOARD_CUSTOM_MODE)])
    assert runner.authority.commanding and any(e["event"] == "resumed" for e in logged)
    group.close()
