"""The companion's own take-off and landing on PX4 (pure; docs/px4.md, "Reliefs on PX4").

PX4's fixed wing takes off and lands by itself in its AUTO modes: AUTO.TAKEOFF (a runway
take-off to MIS_TAKEOFF_ALT straight ahead, then AUTO.LOITER by itself) and AUTO.LAND
(MAV_CMD_NAV_LAND: a landing where it is; the land detector disarms it on the ground). The
companion's mode is OFFBOARD, which PX4 enters only while setpoints stream
(:mod:`companion.link.px4`). So, the counterpart of ArduPlane's
:class:`companion.link.ground.GroundSequence`, with the same interface (the control step
drives either):

* a spare waits on the ground **parked**: disarmed in OFFBOARD, the companion streaming a
  level attitude setpoint with thrust 0 (:func:`parked_setpoint`; nothing moves: PX4 does
  not arm by itself). From OFFBOARD on the ground PX4's AUTO.TAKEOFF climbs as it should
  (its TECS re-initialises after the pause; docs/px4.md, the take-off that works);
* ``takeoff``: DO_SET_MODE AUTO.TAKEOFF, then arm (both asked again every ``RETRY_S`` until
  it is armed in AUTO.TAKEOFF); ``climbing``: no setpoint until it flies at its altitude (the
  take-over checks), then the Agent's setpoints stream and DO_SET_MODE OFFBOARD is asked
  once they have for ``ENTRY_STREAM_S`` and again every ``RETRY_S`` until PX4 reports
  OFFBOARD: the take-off is over (the companion's airspeed and altitude holds take over);
* ``land``: MAV_CMD_NAV_LAND (AUTO.LAND where it is, within the relief's landing radius of
  its base) until it is disarmed, then ``parking``: the parked setpoint streams and
  OFFBOARD is asked again every ``RETRY_S`` until PX4 reports it: it waits as a spare, as
  the spares wait at the start.

While one of these is under way the AUTO modes it puts the aircraft in are the companion's own
(:attr:`companion.link.modes.Authority.own_modes`): its command authority holds. Any other
mode, and these outside the companion's own sequence, is a pilot's. Times vehicle s.
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.ground import Command, Phase
from companion.link.px4 import OFFBOARD_MAIN_MODE, is_offboard

AUTO_MAIN_MODE = 4
AUTO_TAKEOFF_SUB, AUTO_LOITER_SUB, AUTO_RTL_SUB, AUTO_LAND_SUB = 2, 3, 5, 6
AUTO_TAKEOFF = (AUTO_MAIN_MODE << 16) | (AUTO_TAKEOFF_SUB << 24)
AUTO_LOITER = (AUTO_MAIN_MODE << 16) | (AUTO_LOITER_SUB << 24)  # 50593792
AUTO_LAND = (AUTO_MAIN_MODE << 16) | (AUTO_LAND_SUB << 24)
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_NAV_LAND = 21
CUSTOM = 1  # MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
RETRY_S = 1.0  # vehicle s between requests of the same step
ENTRY_STREAM_S = 1.0  # vehicle s of setpoints before OFFBOARD is asked (PX4 refuses it before)
PARKED_TYPE_MASK = 0x07  # body rates ignored; attitude and thrust used


def parked_setpoint(time_boot_ms: int, sysid: int) -> mav.MAVLink_set_attitude_target_message:
    """SET_ATTITUDE_TARGET level with thrust 0 (a valid offboard setpoint that moves nothing):
    what keeps a parked aircraft (disarmed on the ground) in OFFBOARD."""
    return mav.MAVLink_set_attitude_target_message(
        int(time_boot_ms) & 0xFFFFFFFF, sysid, 1, PARKED_TYPE_MASK,
        [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0,
    )  # fmt: skip


@dataclass
class Px4GroundSequence:
    """Where the companion's own take-off or landing on PX4 is (see the module docstring).

    ``idle``: none; ``taking_off``: AUTO.TAKEOFF and arm asked for until it is armed in
    AUTO.TAKEOFF; ``climbing``: armed, PX4 climbing (then loitering) until it flies at its
    altitude, then setpoints stream and OFFBOARD is asked for until PX4 reports it;
    ``landing``: NAV_LAND sent, until it is disarmed; ``parking``: disarmed, the parked
    setpoint streams and OFFBOARD is asked for until PX4 reports it.
    """

    phase: Phase = "idle"
    _asked_s: float = -1e18
    _mode: int = -1
    _armed: bool = False
    _flying_since_s: float | None = None  # climbing: flies at its altitude since (vehicle s)
    _parked_since_s: float | None = None  # parking: the parked setpoint streams since

    def own_modes(self) -> frozenset[int]:
        """The custom modes that are the companion's own now (besides OFFBOARD)."""
        if self.phase in ("taking_off", "climbing"):  # PX4 loiters by itself once climbed
            return frozenset((AUTO_TAKEOFF, AUTO_LOITER))
        if self.phase in ("landing", "parking"):  # on the ground AUTO.LAND may end in a hold
            return frozenset((AUTO_LAND, AUTO_LOITER))
        return frozenset()

    @property
    def in_progress(self) -> bool:
        """Whether no setpoint of the Agent's should be sent (asking for the take-off, or
        climbing before it flies at its altitude)."""
        return self.phase == "taking_off" or (
            self.phase == "climbing" and self._flying_since_s is None
        )

    @property
    def parked(self) -> bool:
        """Disarmed on the ground, not taking off: the parked setpoint keeps OFFBOARD."""
        return not self._armed and self.phase in ("idle", "parking")

    def takeoff(self, t_s: float) -> list[Command]:
        """The commands that start a take-off from the ground at vehicle time ``t_s`` (s)."""
        self.phase, self._asked_s, self._flying_since_s = "taking_off", t_s, None
        return self._takeoff_commands()

    def land(self) -> list[Command]:
        """The command that starts a landing where the aircraft is (AUTO.LAND)."""
        self.phase, self._parked_since_s = "landing", None
        return [(MAV_CMD_NAV_LAND,)]

    def heartbeat(self, custom_mode: int, armed: bool) -> bool:
        """PX4's mode and armed flag; True when the take-off is over (OFFBOARD after the
        climb): the companion's holds then take over its airspeed and altitude."""
        self._mode, self._armed = int(custom_mode), bool(armed)
        offboard = is_offboard(self._mode)
        if self.phase == "taking_off" and self._mode == AUTO_TAKEOFF and self._armed:
            self.phase, self._asked_s = "climbing", -1e18
        elif self.phase == "climbing" and offboard and self._flying_since_s is not None:
            self.phase, self._flying_since_s = "idle", None
            return True
        if self.phase == "landing" and not self._armed:
            self.phase, self._asked_s = "parking", -1e18  # on the ground, disarmed
        if self.phase == "parking" and offboard:
            self.phase, self._parked_since_s = "idle", None
        return False

    def step(self, t_s: float, flying: bool) -> list[Command]:
        """At vehicle time ``t_s`` (s), with ``flying`` whether the aircraft flies at its
        altitude (the take-over checks): what to ask for again or next, at most every
        ``RETRY_S``."""
        if self.phase == "climbing" and flying and self._flying_since_s is None:
            self._flying_since_s = t_s  # the Agent's setpoints stream from now on
        if self.phase == "parking" and self._parked_since_s is None:
            self._parked_since_s = t_s  # the parked setpoint streams from now on
        if self.phase not in ("taking_off", "climbing", "parking"):
            return []
        if t_s - self._asked_s < RETRY_S:
            return []
        if self.phase == "taking_off":
            self._asked_s = t_s
            return self._takeoff_commands()
        since = self._flying_since_s if self.phase == "climbing" else self._parked_since_s
        if since is None or t_s - since < ENTRY_STREAM_S:
            return []
        self._asked_s = t_s  # setpoints have streamed: OFFBOARD
        return [(MAV_CMD_DO_SET_MODE, CUSTOM, OFFBOARD_MAIN_MODE)]

    def _takeoff_commands(self) -> list[Command]:
        out: list[Command] = []
        if self._mode != AUTO_TAKEOFF:
            out.append((MAV_CMD_DO_SET_MODE, CUSTOM, AUTO_MAIN_MODE, AUTO_TAKEOFF_SUB))
        if not self._armed:
            out.append((MAV_CMD_COMPONENT_ARM_DISARM, 1))
        return out
