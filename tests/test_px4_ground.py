"""The companion's own take-off and landing on PX4 (companion/link/px4_ground.py), the
command authority it keeps meanwhile (companion/link/modes.py). What ``companion fleet
--autopilot px4`` makes of a mission's spares and used batteries: tests/test_px4_sitl.py."""

from __future__ import annotations

from companion.link.modes import Authority
from companion.link.px4 import MAV_AUTOPILOT_PX4, OFFBOARD_CUSTOM_MODE
from companion.link.px4_ground import (
    AUTO_LAND,
    AUTO_LOITER,
    AUTO_TAKEOFF,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_SET_MODE,
    MAV_CMD_NAV_LAND,
    Px4GroundSequence,
    parked_setpoint,
)

OFFBOARD = OFFBOARD_CUSTOM_MODE
AUTO_RTL = (4 << 16) | (5 << 24)
SET_TAKEOFF = (MAV_CMD_DO_SET_MODE, 1, 4, 2)
ARM = (MAV_CMD_COMPONENT_ARM_DISARM, 1)
SET_OFFBOARD = (MAV_CMD_DO_SET_MODE, 1, 6)


def test_a_px4_takeoff_is_auto_takeoff_and_arm_then_offboard_once_it_flies() -> None:
    g = Px4GroundSequence()
    g.heartbeat(OFFBOARD, armed=False)  # a spare parked on the ground
    assert g.parked and not g.in_progress
    assert g.takeoff(100.0) == [SET_TAKEOFF, ARM] and g.in_progress and not g.parked
    assert g.step(100.5, flying=False) == []  # not again within a second
    g.heartbeat(AUTO_TAKEOFF, armed=False)  # the arming was refused
    assert g.step(101.0, flying=False) == [ARM]  # only what is still missing
    assert not g.heartbeat(AUTO_TAKEOFF, armed=True) and g.phase == "climbing"
    assert g.in_progress and g.step(102.0, flying=False) == []  # climbing: no setpoints
    g.heartbeat(AUTO_LOITER, armed=True)  # PX4 loiters by itself at MIS_TAKEOFF_ALT
    assert g.step(130.0, flying=True) == [] and not g.in_progress  # setpoints stream now
    assert g.step(130.5, flying=True) == []  # OFFBOARD only after ENTRY_STREAM_S of them
    assert g.step(131.0, flying=True) == [SET_OFFBOARD]
    assert g.step(131.5, flying=True) == []
    assert g.step(132.0, flying=True) == [SET_OFFBOARD]  # not shown yet: asked again
    assert g.heartbeat(OFFBOARD, armed=True)  # over: the companion's holds take over
    assert g.phase == "idle" and not g.in_progress and g.own_modes() == frozenset()
    assert not g.parked  # armed: the Agent's setpoints, not the parked one


def test_a_px4_landing_is_auto_land_then_offboard_parked_on_the_ground() -> None:
    g = Px4GroundSequence()
    g.heartbeat(OFFBOARD, armed=True)
    assert g.land() == [(MAV_CMD_NAV_LAND,)] and g.own_modes() == {AUTO_LAND, AUTO_LOITER}
    assert not g.in_progress  # the Duty holds its setpoints while it lands
    g.heartbeat(AUTO_LAND, armed=True)  # circling down
    assert g.step(500.0, flying=True) == [] and g.phase == "landing" and not g.parked
    g.heartbeat(AUTO_LOITER, armed=False)  # "Disarmed by landing": PX4 holds on the ground
    assert g.phase == "parking" and g.parked
    assert g.step(590.0, flying=False) == []  # the parked setpoint streams first
    assert g.step(591.0, flying=False) == [SET_OFFBOARD]
    assert g.step(591.5, flying=False) == []
    g.heartbeat(OFFBOARD, armed=False)
    assert g.phase == "idle" and g.parked and g.own_modes() == frozenset()
    assert g.takeoff(900.0) == [SET_TAKEOFF, ARM]  # and it can go again


def test_authority_on_px4_keeps_command_through_its_own_auto_modes_only() -> None:
    a, g = Authority(), Px4GroundSequence()
    assert a.heartbeat(OFFBOARD, MAV_AUTOPILOT_PX4).after == "commanding"
    g.takeoff(0.0)
    a.own_modes = g.own_modes()
    assert a.heartbeat(AUTO_TAKEOFF, MAV_AUTOPILOT_PX4) is None and a.commanding
    assert a.heartbeat(AUTO_LOITER, MAV_AUTOPILOT_PX4) is None and a.commanding
    assert a.heartbeat(AUTO_RTL, MAV_AUTOPILOT_PX4).after == "overridden"  # a failsafe's
    assert a.heartbeat(AUTO_TAKEOFF, MAV_AUTOPILOT_PX4) is None and not a.commanding
    b = Authority()  # without the companion's own sequence AUTO.LOITER is PX4's Hold
    b.heartbeat(OFFBOARD, MAV_AUTOPILOT_PX4)
    assert b.heartbeat(AUTO_LOITER, MAV_AUTOPILOT_PX4).after == "overridden"
    c = Authority()
    c.own_modes = frozenset({AUTO_LOITER})
    assert c.heartbeat(AUTO_LOITER, MAV_AUTOPILOT_PX4).after == "waiting"  # never gives it


def test_the_parked_setpoint_is_level_with_thrust_zero() -> None:
    m = parked_setpoint(123_456, 10)
    assert m.target_system == 10 and m.type_mask == 0x07 and m.time_boot_ms == 123_456
    assert list(m.q) == [1.0, 0.0, 0.0, 0.0] and m.thrust == 0.0
