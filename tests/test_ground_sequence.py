"""The companion's own take-off and landing, ArduPlane's way (companion/link/ground.py), the
command authority it keeps meanwhile (companion/link/modes.py), and our simulator answering
the same commands as ArduPlane's fixed wing (sitl_model/link.py)."""

from __future__ import annotations

from companion.link.ground import (
    AUTO,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_LAND_START,
    MAV_CMD_DO_SET_MISSION_CURRENT,
    MAV_CMD_DO_SET_MODE,
    TAKEOFF,
    GroundSequence,
)
from companion.link.modes import GUIDED, Authority
from sitl_model.autopilot import Mode
from sitl_model.codec import Decoder, Encoder, dialect
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import Params
from sitl_model.sim import Simulation, VehicleSetup

LOITER, RTL = 12, 11
SET_TAKEOFF = (MAV_CMD_DO_SET_MODE, 1, TAKEOFF)
ARM = (MAV_CMD_COMPONENT_ARM_DISARM, 1)
SET_GUIDED = (MAV_CMD_DO_SET_MODE, 1, GUIDED)


def test_a_takeoff_is_takeoff_mode_then_arm_retried_then_guided_once_it_flies() -> None:
    g = GroundSequence()
    g.heartbeat(GUIDED, armed=False)  # a spare waiting on the ground
    assert g.takeoff(100.0) == [SET_TAKEOFF, ARM] and g.in_progress
    assert g.step(100.5, flying=False) == []  # not again within a second
    g.heartbeat(TAKEOFF, armed=False)  # the arming was refused (a just-booted gyro check)
    assert g.step(101.0, flying=False) == [ARM]  # only what is still missing
    assert not g.heartbeat(TAKEOFF, armed=True) and g.phase == "climbing"
    assert g.step(102.0, flying=False) == []  # climbing: GUIDED waits for the altitude
    assert g.step(110.0, flying=True) == [SET_GUIDED]
    assert g.step(110.5, flying=True) == []
    assert g.step(111.0, flying=True) == [SET_GUIDED]  # not shown yet: asked again
    assert g.heartbeat(GUIDED, armed=True)  # over: the companion takes over its targets
    assert g.phase == "idle" and not g.in_progress and g.own_modes() == frozenset()


def test_a_landing_is_the_landing_sequence_then_guided_on_the_runway() -> None:
    g = GroundSequence()
    g.heartbeat(GUIDED, armed=True)
    assert g.land() == [(MAV_CMD_DO_LAND_START,)] and g.own_modes() == {AUTO}
    assert not g.in_progress  # no take-off: the Duty holds its setpoints while it lands
    g.heartbeat(AUTO, armed=True)  # on the approach
    assert g.step(500.0, flying=True) == [] and g.phase == "landing"
    g.heartbeat(AUTO, armed=False)  # disarmed on the runway, still in AUTO
    assert g.phase == "parking" and g.own_modes() == {AUTO}
    assert g.step(520.0, flying=False) == [SET_GUIDED]  # waits as a spare, in GUIDED
    assert g.step(520.5, flying=False) == []
    assert g.step(521.0, flying=False) == [SET_GUIDED]
    g.heartbeat(GUIDED, armed=False)
    assert g.phase == "idle" and g.own_modes() == frozenset()  # AUTO is a pilot's again
    # ArduPlane refuses to arm "In landing sequence" until the mission's current item moves
    assert g.takeoff(900.0) == [(MAV_CMD_DO_SET_MISSION_CURRENT, 1), SET_TAKEOFF, ARM]
    g.heartbeat(TAKEOFF, armed=True)
    assert g.step(901.0, flying=False) == []  # no second leave-the-sequence, no re-arm
    g.heartbeat(GUIDED, armed=True)
    assert g.takeoff(2000.0) == [SET_TAKEOFF]  # not landed by the sequence since: no leave


def test_our_simulators_landing_is_parked_at_once() -> None:
    g = GroundSequence()  # our simulator lands at once and stays in GUIDED
    g.land()
    g.heartbeat(GUIDED, armed=False)
    assert g.phase == "idle" and g.step(10.0, flying=False) == []


def test_authority_keeps_command_through_its_own_modes_only() -> None:
    a, g = Authority(), GroundSequence()
    a.heartbeat(GUIDED)
    g.takeoff(0.0)
    a.own_modes = g.own_modes()
    assert a.heartbeat(TAKEOFF) is None and a.commanding  # its own take-off: still in command
    assert a.heartbeat(LOITER).after == "overridden"  # a pilot's mode is still a pilot's
    assert a.heartbeat(TAKEOFF) is None and not a.commanding  # and never gives command back
    b = Authority()
    b.own_modes = frozenset({TAKEOFF})
    assert b.heartbeat(TAKEOFF).after == "waiting" and not b.commanding  # never took it
    c = Authority()
    c.heartbeat(GUIDED)
    assert c.heartbeat(RTL).after == "overridden"  # no sequence: every other mode overrides


def _link(sim: Simulation, index: int):
    from sitl_model.link import VehicleLink
    from sitl_model.telemetry import Telemetry

    return VehicleLink(sim, index, Telemetry(sim), MissionProtocol())


def _command(link, sysid: int, command: int, *params: float) -> int:
    p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
    msg = dialect.MAVLink_command_long_message(sysid, 1, command, 0, *p)
    decoded = Decoder().decode(Encoder(255, 190).pack(msg))[0][0]
    out = link.handle(decoded, "gcs", 0.0)
    return int(out[0][0].result)


def test_the_simulator_answers_arduplanes_ground_commands() -> None:
    setups = [
        VehicleSetup(1, 0.0, 0.0, 0.0, 100.0),
        VehicleSetup(10, 0.0, 300.0, 180.0, 130.0, True),  # a spare on the ground
    ]
    sim = Simulation(setups, Params({}), LocalFrame(*DEFAULT_ORIGIN))
    link = _link(sim, 1)
    accepted, unsupported = 0, 3
    # a fixed wing has no take-off or landing command (ArduPlane: a quadplane's)
    assert _command(link, 10, 22, 0, 0, 0, 0, 0, 0, 130) == unsupported
    assert _command(link, 10, 21) == unsupported
    assert sim.grounded[1]
    assert _command(link, 10, MAV_CMD_COMPONENT_ARM_DISARM, 1) == accepted  # armed in GUIDED:
    assert sim.grounded[1]  # it does not fly (as ArduPlane)
    assert _command(link, 10, MAV_CMD_COMPONENT_ARM_DISARM, 0) == accepted
    assert _command(link, 10, *SET_TAKEOFF[:1], 1, TAKEOFF) == accepted
    assert _command(link, 10, MAV_CMD_COMPONENT_ARM_DISARM, 1) == accepted  # armed in TAKEOFF
    ap = sim.autopilots[1]
    assert not sim.grounded[1] and ap.armed and sim.alt_m[1] == 130.0 and ap.mode is Mode.TAKEOFF
    for _ in range(250):  # TAKEOFF loiters where it climbed out until GUIDED
        sim.step()
    assert abs(sim.state.pos_m[1] - 300j) < 2.5 * ap.params["WP_LOITER_RAD"]
    assert _command(link, 10, MAV_CMD_DO_LAND_START) == accepted  # lands at once, no approach
    assert sim.grounded[1] and not ap.armed
