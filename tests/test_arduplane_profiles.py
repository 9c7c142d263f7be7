"""ArduPlane's reading of the companion's setpoints, at home: the mask semantics of
SET_ATTITUDE_TARGET (from ArduPlane's source, docs/arduplane.md), the simulator flying them
as ArduPlane does, and the speed / altitude commands of GUIDED (all in process, no sockets)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.link.setpoints import (
    MASK_BANK,
    MASK_TURN_RATE,
    arduplane_forced_axes,
    bank_setpoint,
    describe,
    turn_rate_setpoint,
)
from sitl_model.autopilot import Mode
from sitl_model.codec import dialect as d
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.link import VehicleLink
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import Params
from sitl_model.sim import DT_S, Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

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
    hb = link.tm.heartbeat(0)
    assert hb.autopilot == d.MAV_AUTOPILOT_GENERIC  # it does not claim to be ArduPilot
    _sim2, (link2,) = make_link(1)
    assert link2.tm.heartbeat(0).autopilot == d.MAV_AUTOPILOT_ARDUPILOTMEGA


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
