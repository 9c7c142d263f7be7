"""Unit tests of the companion's link pieces: setpoint encoders, gain shaping, vehicle clock,
state estimation, the authority state machine, and the runner's pilot-override logic
against hand-written fakes (no sockets)."""

from __future__ import annotations

import io
import math

import numpy as np
import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.core.wind import Wind, course_from_heading, heading_from_course
from companion.group.messages import Mode
from companion.link.clock import VehicleClock
from companion.link.config import LinkConfig
from companion.link.estimate import Estimator
from companion.link.modes import GUIDED, Authority
from companion.link.setpoints import (
    G_M_S2,
    MASK_BANK,
    bank_angle_rad,
    bank_setpoint,
    describe,
    heading_setpoint,
    quaternion_roll_rad,
    roll_quaternion,
    turn_rate_setpoint,
)
from companion.link.shaping import Shaper
from companion.mission import load_mission
from companion.mission.model import Origin
from companion.process.config import RunConfig
from companion.process.event_log import EventLog
from companion.process.runner import Runner
from sitl_model.testing import REPO

ORIGIN = Origin(39.8, -84.0, 250.0)
WIND = Wind.from_meteo(5.0, 180.0)
LOITER = 12
RTL = 11


def wire(msg, src_system: int = 1, src_component: int = 1):
    """Pack ``msg`` as MAVLink 2 from (system, component) and parse it back."""
    enc = mav.MAVLink(None, srcSystem=src_system, srcComponent=src_component)
    data = msg.pack(enc)
    dec = mav.MAVLink(None)
    out = dec.parse_buffer(data)
    assert out is not None and len(out) == 1
    return out[0]


# ---- setpoints ---------------------------------------------------------------------------
@pytest.mark.parametrize("u", [-0.3, -0.05, 0.0, 0.1, 0.31])
def test_turn_rate_setpoint_round_trip(u):
    m = wire(turn_rate_setpoint(u, 123456, 3))
    assert m.get_type() == "SET_ATTITUDE_TARGET"
    assert m.target_system == 3 and m.target_component == 1
    assert m.type_mask & mav.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
    assert not m.type_mask & mav.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE
    assert m.time_boot_ms == 123456
    assert describe(m) == pytest.approx({"kind": "turn-rate", "turn_rate_rad_s": u}, abs=1e-6)


@pytest.mark.parametrize("u", [-0.3, -0.1, 0.0, 0.05, 0.2])
def test_bank_setpoint_is_atan_v_u_over_g_and_roll_only(u):
    v = 20.0
    phi = bank_angle_rad(u, v)
    assert phi == pytest.approx(math.atan(v * u / G_M_S2))
    m = wire(bank_setpoint(phi, 1000, 2))
    assert m.type_mask == MASK_BANK
    w, x, y, z = m.q
    assert y == 0.0 and z == 0.0  # no pitch, no yaw
    assert w * w + x * x == pytest.approx(1.0, abs=1e-6)
    assert quaternion_roll_rad(m.q) == pytest.approx(phi, abs=1e-6)
    assert describe(m)["roll_rad"] == pytest.approx(phi, abs=1e-6)
    # ArduPlane reads the inverted mask 0x01: the roll of q only (0x81, "attitude used",
    # would force pitch and rudder too: see tests/test_arduplane_profiles.py)
    assert (m.type_mask ^ 0xFF) & 0b10000111 == 0b00000001


def test_bank_angle_is_clipped():
    assert bank_angle_rad(10.0, 20.0) == pytest.approx(math.radians(60.0))
    assert roll_quaternion(0.0) == (1.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("course_deg", [0.0, 45.0, 359.5, -90.0])
def test_heading_setpoint_round_trip(course_deg):
    m = wire(heading_setpoint(math.radians(course_deg), 6.3, 4))
    assert m.get_type() == "COMMAND_INT"
    assert m.command == mav.MAV_CMD_GUIDED_CHANGE_HEADING == 43002
    assert m.param1 == 0  # course over ground
    assert m.param2 == pytest.approx(course_deg % 360.0, abs=1e-4)
    assert m.param3 == pytest.approx(6.3)  # > 0: ArduPlane barely turns with 0
    assert m.target_system == 4 and m.target_component == 1
    assert describe(m)["course_rad"] == pytest.approx(math.radians(course_deg % 360.0), abs=1e-6)


def test_heading_setpoint_refuses_zero_acceleration():
    with pytest.raises(ValueError):
        heading_setpoint(0.0, 0.0, 1)


# ---- shaping: closing the loop on the achieved turn rate ---------------------------------
def fly_shaper(shaper: Shaper, plant, steps: int = 600, dt: float = 0.1) -> list[float]:
    """Command a varying turn rate through ``shaper`` into ``plant(msg) -> achieved u``."""
    achieved = None
    errors = []
    rng = np.random.default_rng(1)
    course = 0.0
    for k in range(steps):
        t = k * dt
        shaper.observe(t, achieved)
        u_cmd = 0.15 * math.sin(0.05 * t) + 0.02 * rng.standard_normal()
        msg = wire(shaper.setpoint(t, u_cmd, course, int(t * 1000), 1))
        achieved = plant(msg, course)
        errors.append(achieved - u_cmd)
        course += achieved * dt
    return errors


def test_bank_profile_learns_the_turn_efficiency():
    v, eff = 20.0, 0.75

    def plant(msg, course):
        return eff * G_M_S2 * math.tan(quaternion_roll_rad(msg.q)) / v

    shaper = Shaper("bank", v, math.radians(18.0))
    errors = fly_shaper(shaper, plant)
    assert shaper.gain == pytest.approx(eff, abs=0.02)
    assert np.max(np.abs(errors[-100:])) < 0.004  # rad/s: the loop is closed
    open_loop = Shaper("bank", v, math.radians(18.0), adapt=False)
    errors_open = fly_shaper(open_loop, plant)
    assert np.max(np.abs(errors_open[-100:])) > 0.02


@pytest.mark.parametrize("lag_s", [0.0, 0.5])
def test_bank_gain_is_not_biased_by_a_lagging_autopilot_and_gusty_commands(lag_s):
    """ArduPlane answers a bank with a roll lag; commands that vary fast (gusts) must not drag
    the identified gain to its floor (it did: 0.40 against a true 0.70)."""
    v, eff = 20.0, 0.7
    state = {"u": 0.0}

    def plant(msg, course):
        target = eff * G_M_S2 * math.tan(quaternion_roll_rad(msg.q)) / v
        a = 1.0 if lag_s == 0 else 1.0 - math.exp(-0.1 / lag_s)
        state["u"] += a * (target - state["u"])
        return state["u"]

    shaper = Shaper("bank", v, math.radians(18.0))
    achieved, rng, course = None, np.random.default_rng(5), 0.0
    for k in range(1500):
        t = k * 0.1
        shaper.observe(t, achieved)
        u_cmd = 0.1 * math.sin(0.05 * t) + 0.04 * rng.standard_normal()
        achieved = plant(wire(shaper.setpoint(t, u_cmd, course, int(t * 1000), 1)), course)
        course += achieved * 0.1
    assert shaper.gain == pytest.approx(eff, abs=0.06)


def test_heading_profile_flies_a_rate_through_the_acceleration_limit():
    v, kp, eff = 20.0, 0.5, 0.8  # a course hold, and an autopilot that turns short of param3

    def plant(msg, course):
        lead = math.remainder(math.radians(msg.param2) - course, 2 * math.pi)
        assert abs(abs(lead) - math.pi / 2) < 1e-3  # always 90 deg ahead on the turn side
        cap = eff * msg.param3 / v
        return max(-cap, min(cap, kp * lead))

    shaper = Shaper("heading", v, math.radians(18.0))
    errors = fly_shaper(shaper, plant)
    assert shaper.gain == pytest.approx(eff, abs=0.03)
    assert np.max(np.abs(errors[-100:])) < 0.01


def test_turn_rate_profile_is_flown_as_is():
    shaper = Shaper("turn-rate", 20.0, 0.3)
    errors = fly_shaper(shaper, lambda msg, course: 0.5 * msg.body_yaw_rate, steps=100)
    assert shaper.gain == 1.0  # no adaptation: rate-controlled autopilots fly it exactly
    assert max(abs(e) for e in errors) > 0.01


# ---- vehicle clock -----------------------------------------------------------------------
def test_vehicle_clock_from_system_time_and_reboot():
    c = VehicleClock()
    assert c.to_vehicle_s(1000) is None
    c.on_system_time(0, 500)  # no GPS time yet: ignored
    assert not c.valid
    c.on_system_time(1_767_225_600_000_000 + 2_000_000, 2000)
    assert c.to_vehicle_s(2500) == pytest.approx(1_767_225_602.5)
    assert c.boot_ms_at(1_767_225_603.0) == 3000
    # a small step back (a reordered message) is not a reboot
    assert c.to_vehicle_s(100) == pytest.approx(1_767_225_600.1)
    c2 = VehicleClock()
    c2.on_system_time(1_767_225_700_000_000, 100_000)
    assert c2.to_vehicle_s(10) is None  # rebooted: unknown until the next SYSTEM_TIME
    c2.on_system_time(1_767_225_800_000_000, 20)
    assert c2.to_vehicle_s(1020) == pytest.approx(1_767_225_801.0)


# ---- state estimate ----------------------------------------------------------------------
def gpi_fields(north_m: float, east_m: float, vel: complex) -> tuple[int, int, int, int, int]:
    lat, lon, alt = pymap3d.ned2geodetic(
        north_m, east_m, -100.0, ORIGIN.lat_deg, ORIGIN.lon_deg, 250
    )
    return (
        round(lat * 1e7),
        round(lon * 1e7),
        round(alt * 1e3),
        round(vel.real * 100),
        round(vel.imag * 100),
    )


def test_estimate_position_course_heading_and_turn_rate():
    est = Estimator(ORIGIN, 20.0, WIND)
    u = 0.1  # air turn rate (rad/s)
    heading0 = 0.3
    samples = []
    pos = complex(120.0, -80.0)
    for k in range(3):
        th = heading0 + u * 0.1 * k
        vel = 20.0 * np.exp(1j * th) + WIND.vector
        lat, lon, alt, vx, vy = gpi_fields(pos.real, pos.imag, vel)
        samples.append(
            est.from_global_position(1000.0 + 0.1 * k, 100 * k, lat, lon, alt, vx, vy, 0)
        )
        pos += vel * 0.1
    s0, s2 = samples[0], samples[2]
    assert s0.pos_m == pytest.approx(complex(120.0, -80.0), abs=0.02)
    assert s0.alt_m == pytest.approx(100.0, abs=0.01)
    assert s0.course_rad == pytest.approx(
        float(course_from_heading(20.0, heading0, WIND)), abs=1e-3
    )
    assert s0.heading_rad == pytest.approx(heading0, abs=1e-3)
    assert s0.turn_rate_rad_s is None
    assert s2.turn_rate_rad_s == pytest.approx(u, abs=0.01)
    # a stale (reordered) message is ignored
    lat, lon, alt, vx, vy = gpi_fields(0, 0, 20 + 0j)
    assert est.from_global_position(1000.05, 50, lat, lon, alt, vx, vy, 0) is None


def test_estimate_slow_vehicle_uses_the_heading_field():
    est = Estimator(ORIGIN, 20.0, WIND)
    lat, lon, alt, _, _ = gpi_fields(0, 0, 0j)
    s = est.from_global_position(5.0, 10, lat, lon, alt, 0, 0, 9000)
    assert s.heading_rad == pytest.approx(math.radians(90.0), abs=1e-6)
    assert float(heading_from_course(20.0, s.course_rad, WIND)) == pytest.approx(s.heading_rad)


# ---- authority state machine -------------------------------------------------------------
def test_authority_transitions():
    a = Authority()
    assert a.heartbeat(LOITER).after == "waiting"
    assert not a.commanding
    tr = a.heartbeat(GUIDED)
    assert (tr.before, tr.after, tr.mode) == ("waiting", "commanding", "GUIDED")
    assert a.heartbeat(GUIDED) is None
    tr = a.heartbeat(LOITER)
    assert (tr.after, tr.mode) == ("overridden", "LOITER") and not a.commanding
    assert a.heartbeat(GUIDED).after == "commanding"
    assert a.link_lost().after == "no_link"
    assert a.was_commanding


# ---- the runner's override logic against fakes --------------------------------------------
class FakeLink:
    """Records what the runner sends; the autopilot is system 2."""

    url = "fake"
    tlog = None
    generation = 0
    traffic_bytes = (0, 0)  # (received, sent) bytes: ONBOARD_COMPUTER_STATUS
    autopilot = 3  # MAV_AUTOPILOT_ARDUPILOTMEGA

    def __init__(self) -> None:
        self.sysid = 2
        self.rates_hz: dict[str, float] = {}  # nothing asked: no stream watched
        self.sent: list = []
        self.texts: list[str] = []
        self.commands: list[tuple] = []
        self.counts = {"rx": 0, "reconnects": 0}
        self.silent_s: float | None = None
        self.last_outage_s: float | None = None

    def is_autopilot(self, m) -> bool:
        return m.get_srcSystem() == 2 and m.get_srcComponent() == 1

    def send(self, msg) -> None:
        self.sent.append(msg)

    def statustext(self, text: str, severity: int = 5) -> None:
        self.texts.append(text)

    def command_long(self, command: int, *params: float) -> None:
        self.commands.append((command, *params))

    def fileno(self):
        return None

    def tick(self):
        """The link's supervision: "lost" once when the test says so."""
        lost, self.lose = getattr(self, "lose", False), False
        return "lost" if lost else None

    def close(self) -> None:
        pass


class FakeGroup:
    """Records states and alerts; receives nothing."""

    def __init__(self) -> None:
        self.states: list = []
        self.alerts: list = []
        self.stats = {"accepted": 0, "sent": 0}
        self.rx_bytes = self.tx_bytes = 0  # datagram bytes: ONBOARD_COMPUTER_STATUS

    def send_state(self, s) -> None:
        self.states.append(s)

    def send_alert(self, a) -> None:
        self.alerts.append(a)

    def receive(self, now_s=None):
        return []

    def fileno(self) -> int:
        return self._r.fileno()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._r.close()
        self._w.close()


def make_runner(take_control: bool = False, retake: bool = False, wall=None):
    import socket

    mission = load_mission(REPO / "tests" / "data" / "companion_ellipse_fast.yaml")
    link, group = FakeLink(), FakeGroup()
    group._r, group._w = socket.socketpair()
    config = RunConfig(
        mission=mission,
        link=LinkConfig(profile="bank"),
        take_control=take_control,
        retake_after_failsafe=retake,
    )
    events = EventLog(None)
    logged: list[dict] = []
    events.write = logged.append  # record the events
    clock = {"wall": wall} if wall is not None else {}
    runner = Runner(config, link, lambda sysid: group, events, status_out=io.StringIO(), **clock)
    return runner, link, group, logged


def hb(mode: int, armed: bool = True):
    base = 1 | (128 if armed else 0)
    return wire(mav.MAVLink_heartbeat_message(1, 3, base, mode, 4, 3), 2, 1)


def feed_position(runner, k: int, t0_boot_ms: int = 0) -> None:
    lat, lon, alt, vx, vy = gpi_fields(0.0 + 2.5 * k, -200.0, 20 + 5 + 0j)
    m = mav.MAVLink_global_position_int_message(
        t0_boot_ms + 100 * k, lat, lon, alt, 100_000, vx, vy, 0, 0
    )
    runner.on_messages([wire(m, 2, 1)])


def test_runner_stops_setpoints_at_once_on_override_and_resumes():
    runner, link, group, logged = make_runner()
    runner.on_messages([wire(mav.MAVLink_system_time_message(1_767_225_600_000_000, 0), 2, 1)])
    runner.on_messages([hb(GUIDED)])
    for k in range(1, 6):
        feed_position(runner, k)
    assert len(setpoints(link)) == 5  # one setpoint per state estimate
    # and at take-over the mission's airspeed and altitude as GUIDED targets, and the GUIDED
    # target a silent companion's aircraft would fly to: a point of the loop ahead
    assert [m.command for m in link.sent if m.get_type() == "COMMAND_INT"] == [43000, 43001, 192]
    assert group.states  # sharing its state
    assert all(st.mode is Mode.PATROL for st in group.states)
    runner.on_messages([hb(LOITER)])  # the pilot takes over
    n_sent, n_states = len(setpoints(link)), len(group.states)
    feed_position(runner, 6)
    assert len(group.states) == n_states + 1  # says so with the next position
    for k in range(7, 30):
        feed_position(runner, k)
    assert len(setpoints(link)) == n_sent  # not one more setpoint
    away = group.states[n_states:]  # out of the formation, at the state period (5 Hz)
    assert len(away) == 12 and all(st.mode is Mode.OVERRIDDEN for st in away)
    assert any("pilot took over (LOITER)" in t for t in link.texts)
    assert any(
        e["event"] == "override" and e["autopilot_mode"] == "LOITER" and e["cause"] == "pilot"
        for e in logged
    )
    runner.on_messages([hb(GUIDED)])
    feed_position(runner, 30)
    assert len(setpoints(link)) == n_sent + 1
    assert any(e["event"] == "resumed" for e in logged)
    assert not link.commands  # never took control back by itself
    group.close()


def setpoints(link) -> list:
    return [m for m in link.sent if m.get_type() == "SET_ATTITUDE_TARGET"]


def position_at(runner, k: int, rel_alt_m: float, speed_m_s: float = 20.0) -> None:
    lat, lon, alt, vx, vy = gpi_fields(2.5 * k, -200.0, complex(speed_m_s, 0.0))
    m = mav.MAVLink_global_position_int_message(
        100 * k, lat, lon, alt, round(rel_alt_m * 1000), vx, vy, 0, 0
    )
    runner.on_messages([wire(m, 2, 1)])


def test_runner_take_control_only_of_a_flying_aircraft_and_never_arms():
    runner, link, group, logged = make_runner(take_control=True)
    runner.on_messages([hb(LOITER, armed=False)])
    runner.take_control()
    assert not link.commands  # never arms
    assert any("not flying: disarmed" in t for t in link.texts)
    assert runner.health() == "not_flying"
    runner.on_messages([hb(LOITER, armed=True)])
    position_at(runner, 1, rel_alt_m=12.0)  # climbing out
    runner.take_control()
    assert not link.commands
    refused = [e["reason"] for e in logged if e["event"] == "take_control_refused"]
    assert refused[-1] == "12 m above home, below 55 m"
    on_ground = mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_ON_GROUND)
    runner.on_messages([wire(on_ground, 2, 1)])
    position_at(runner, 2, rel_alt_m=100.0)
    runner.take_control()
    assert not link.commands  # the autopilot says it is on the ground
    in_air = mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_IN_AIR)
    runner.on_messages([wire(in_air, 2, 1)])
    hud = mav.MAVLink_vfr_hud_message(9.0, 9.0, 0, 50, 350.0, 0.0)
    runner.on_messages([wire(hud, 2, 1)])
    runner.take_control()
    assert not link.commands  # too slow: not flying at cruise
    hud = mav.MAVLink_vfr_hud_message(19.5, 19.5, 0, 50, 350.0, 0.0)
    runner.on_messages([wire(hud, 2, 1)])
    runner.take_control()
    assert link.commands[-1] == (176, 1, GUIDED)
    runner.on_messages([hb(GUIDED)])
    runner.on_messages([hb(LOITER)])  # the pilot: never taken back
    n = len(link.commands)
    runner.take_control()
    assert len(link.commands) == n
    group.close()


# ---- a failsafe the fleet survives ---------------------------------------------------------------
class WallClock:
    """The companion's wall clock, moved by the test."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def flying(runner) -> None:
    """Vehicle time, and what says the aircraft flies (in the air, at cruise)."""
    runner.on_messages([wire(mav.MAVLink_system_time_message(1_767_225_600_000_000, 0), 2, 1)])
    in_air = mav.MAVLink_extended_sys_state_message(0, mav.MAV_LANDED_STATE_IN_AIR)
    hud = mav.MAVLink_vfr_hud_message(20.0, 20.0, 0, 50, 350.0, 0.0)
    runner.on_messages([wire(in_air, 2, 1), wire(hud, 2, 1)])


def fly(runner, clock: WallClock, ks: range) -> None:
    """Positions ``ks`` (0.1 s of vehicle time each) at 1x, a tick after each."""
    for k in ks:
        clock.now += 0.1
        feed_position(runner, k)
        runner.tick()


def set_modes(link) -> list[float]:
    return [c[2] for c in link.commands if c[0] == 176]  # DO_SET_MODE's custom mode


def test_a_failsafe_after_its_own_silence_is_said_at_once_and_taken_back_with_consent():
    """The companion stalls 2.5 s (vehicle time), the autopilot leaves GUIDED meanwhile: the
    cause is its own silence, said at once (event, STATUSTEXT, the group: out of the
    formation); with consent it asks for GUIDED back once its positions have come steadily
    for the health window, and commands again when GUIDED returns."""
    clock = WallClock()
    runner, link, group, logged = make_runner(retake=True, wall=clock)
    flying(runner)
    runner.on_messages([hb(GUIDED)])
    fly(runner, clock, range(1, 21))
    clock.now += 2.5  # stalled: nothing read, nothing sent
    feed_position(runner, 46)  # the backlog's newest position is steered from ...
    runner.on_messages([hb(RTL)])  # ... and the failsafe's mode is heard
    over = [e for e in logged if e["event"] == "override"]
    assert [(e["cause"], e["autopilot_mode"]) for e in over] == [("own_silence", "RTL")]
    assert over[0]["silent_s"] == pytest.approx(2.6, abs=0.05)
    assert any("RTL after 2.6 s silent, retaking when healthy" in t for t in link.texts)
    n_states = len(group.states)
    fly(runner, clock, range(47, 48))
    assert group.states[n_states].mode is Mode.OVERRIDDEN  # with the next position
    assert not set_modes(link)
    fly(runner, clock, range(48, 70))  # 2.2 s steady: not yet healthy for 3 s
    assert not set_modes(link)
    fly(runner, clock, range(70, 85))
    assert set_modes(link) == [GUIDED]
    assert [e["attempt"] for e in logged if e["event"] == "retake"] == [1]
    n = len(setpoints(link))
    runner.on_messages([hb(GUIDED)])
    fly(runner, clock, range(85, 90))
    assert len(setpoints(link)) == n + 5
    assert any(e["event"] == "resumed" for e in logged)
    assert group.states[-1].mode is Mode.PATROL
    group.close()


def test_a_pilots_mode_change_is_never_taken_back_even_with_consent():
    clock = WallClock()
    runner, link, group, logged = make_runner(retake=True, wall=clock)
    flying(runner)
    runner.on_messages([hb(GUIDED)])
    fly(runner, clock, range(1, 21))
    runner.on_messages([hb(LOITER)])  # the setpoints flowed: a pilot
    fly(runner, clock, range(21, 200))  # 18 s of healthy link and steps
    assert not set_modes(link)
    assert [e["cause"] for e in logged if e["event"] == "override"] == ["pilot"]
    assert group.states[-1].mode is Mode.OVERRIDDEN  # still out of the formation
    group.close()


def test_without_consent_a_failsafe_is_said_and_never_taken_back():
    clock = WallClock()
    runner, link, group, logged = make_runner(wall=clock)
    flying(runner)
    runner.on_messages([hb(GUIDED)])
    fly(runner, clock, range(1, 21))
    clock.now += 3.0
    feed_position(runner, 51)
    runner.on_messages([hb(RTL)])
    fly(runner, clock, range(52, 200))
    assert not set_modes(link)
    assert any("after 3.1 s silent, holding off" in t for t in link.texts)
    assert not [e for e in logged if e["event"] == "retake"]
    group.close()


def test_a_link_lost_while_commanding_and_back_in_another_mode_is_its_own_silence():
    clock = WallClock()
    runner, link, group, logged = make_runner(retake=True, wall=clock)
    flying(runner)
    runner.on_messages([hb(GUIDED)])
    fly(runner, clock, range(1, 21))
    link.lose, link.silent_s = True, 3.0
    runner.tick()
    assert [e["silent_s"] for e in logged if e["event"] == "link_lost"] == [3.0]
    clock.now += 20.0
    link.last_outage_s = 23.0
    runner.on_messages([hb(RTL)])
    assert [e["outage_s"] for e in logged if e["event"] == "link_restored"] == [23.0]
    over = [e for e in logged if e["event"] == "override"]
    assert [(e["cause"], e["silent_s"]) for e in over] == [("own_silence", 23.0)]
    fly(runner, clock, range(250, 290))
    assert set_modes(link) == [GUIDED]
    group.close()


# ---- a silent link: re-opened or not -------------------------------------------------------
class FakeConn:
    """What AutopilotLink uses of a pymavlink connection: heartbeats queued by the test."""

    def __init__(self) -> None:
        self.mav = mav.MAVLink(None, srcSystem=1, srcComponent=191)
        self.mav.send = lambda msg: None
        self.queue: list = []

    def recv_msg(self):
        return self.queue.pop(0) if self.queue else None

    def close(self) -> None:
        pass


@pytest.mark.parametrize(("url", "reopens"), [("udpout:127.0.0.1:14580", False),
                                              ("tcp:127.0.0.1:5762", True)])  # fmt: skip
def test_a_silent_udp_link_keeps_its_socket_and_a_tcp_link_is_reopened(url, reopens):
    """PX4 answers only the source port that first sent to it: a companion that re-opened
    its UDP socket after an outage was never heard again (a relay exited on the stale port)."""
    from companion.link.connection import AutopilotLink

    now = [0.0]
    opened: list[FakeConn] = []

    def opener(u, s, c):
        opened.append(FakeConn())
        return opened[-1]

    link = AutopilotLink(url, clock=lambda: now[0], opener=opener)
    opened[0].queue.append(hb(GUIDED))
    link.receive()
    assert link.up
    now[0] = 3.5
    assert link.tick() == "lost"
    for t in (7.0, 10.0, 13.0):
        now[0] = t
        link.tick()
    assert (len(opened) > 1) == reopens
