"""The companion's own take-off and landing on ArduPlane (pure; docs/energy.md, "On real
ArduPlane").

ArduPlane's fixed wing has no take-off or landing command (MAV_CMD_NAV_TAKEOFF is a
quadplane's, ``GCS_MAVLink_Plane.cpp``): it takes off armed in TAKEOFF (13), climbs to
TKOFF_ALT and loiters there, and it lands by its mission's landing sequence
(MAV_CMD_DO_LAND_START: AUTO from the DO_LAND_START item nearest it). Our simulator
(:mod:`sitl_model.link`) answers the same commands, at once.

A relief's ``takeoff`` is: TAKEOFF, arm; once the aircraft flies at its altitude (the take-over
checks, :func:`companion.link.supervision.not_flying_reason`), GUIDED; and the companion takes
over its targets when GUIDED is back. A ``land`` is DO_LAND_START; once the aircraft is
disarmed on the runway, GUIDED again (it waits as a spare there, as spares wait at the
start). While one of these is in progress the mode it puts the aircraft in (TAKEOFF, AUTO) is
the companion's own: its command authority holds
(:attr:`companion.link.modes.Authority.own_modes`) and no setpoint is sent until GUIDED is
back. Any other mode, and these outside the companion's own sequence, is a pilot's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from companion.link.modes import GUIDED

TAKEOFF = 13  # ArduPlane custom modes
AUTO = 10
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_COMPONENT_ARM_DISARM = 400
MAV_CMD_DO_LAND_START = 189
MAV_CMD_DO_SET_MISSION_CURRENT = 224
FIRST_WAYPOINT = 1  # ArduPilot's item 0 is home
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
RETRY_S = 1.0  # vehicle s between requests of the same step

Command = tuple[int, ...]  # COMMAND_LONG: the command, then its parameters
Phase = Literal["idle", "taking_off", "climbing", "landing", "parking"]
GROUND_PHASES: tuple[Phase, ...] = ("taking_off", "climbing", "parking")  # asking for something


@dataclass
class GroundSequence:
    """Where the companion's own take-off or landing is (see the module docstring).

    ``idle``: none; ``taking_off``: TAKEOFF and arm asked for (again every ``RETRY_S``: a
    just-landed ArduPlane may refuse its first arming) until it is armed in TAKEOFF;
    ``climbing``: armed in TAKEOFF, GUIDED asked for once it flies at its altitude;
    ``landing``: DO_LAND_START sent, until it is disarmed (ArduPlane disarms on the runway);
    ``parking``: landed, GUIDED asked for (a spare waits on the ground in GUIDED, as at the
    start), so that from then on AUTO, like any other mode, is a pilot's again.
    """

    phase: Phase = "idle"
    _asked_s: float = -1e18
    _mode: int = -1
    _armed: bool = False
    _in_sequence: bool = False  # landed by DO_LAND_START: the mission is still in it

    def own_modes(self) -> frozenset[int]:
        """The custom modes that are the companion's own now (besides GUIDED)."""
        if self.phase == "taking_off":  # AUTO: asked to go while still parking
            return frozenset((TAKEOFF, AUTO))
        if self.phase == "climbing":
            return frozenset((TAKEOFF,))
        if self.phase in ("landing", "parking"):
            return frozenset((AUTO,))
        return frozenset()

    @property
    def in_progress(self) -> bool:
        """Whether a take-off is under way (no setpoints until GUIDED is back)."""
        return self.phase in ("taking_off", "climbing")

    def takeoff(self, t_s: float) -> list[Command]:
        """The commands that start a take-off from the ground at vehicle time ``t_s`` (s):
        TAKEOFF, then arm; after its own landing first the mission's first waypoint made
        current (ArduPlane refuses to arm "In landing sequence" until the mission leaves it)."""
        leave: list[Command] = []
        if self._in_sequence:
            leave, self._in_sequence = [(MAV_CMD_DO_SET_MISSION_CURRENT, FIRST_WAYPOINT)], False
        self.phase, self._asked_s, self._mode = "taking_off", t_s, -1
        return leave + self._takeoff_commands()

    def land(self) -> list[Command]:
        """The command that starts a landing: the landing sequence of the mission."""
        self.phase, self._in_sequence = "landing", True
        return [(MAV_CMD_DO_LAND_START,)]

    def heartbeat(self, custom_mode: int, armed: bool) -> bool:
        """The autopilot's mode and armed flag; True when the take-off is over (GUIDED after
        TAKEOFF): the companion then takes over its targets (airspeed, altitude)."""
        self._mode, self._armed = int(custom_mode), bool(armed)
        if self.phase == "taking_off" and self._mode == TAKEOFF and self._armed:
            self.phase, self._asked_s = "climbing", -1e18
        elif self.phase == "climbing" and self._mode == GUIDED:
            self.phase = "idle"
            return True
        if self.phase == "landing" and not self._armed:
            self.phase, self._asked_s = "parking", -1e18  # on the runway, disarmed
        if self.phase == "parking" and self._mode == GUIDED:
            self.phase = "idle"
        return False

    def step(self, t_s: float, flying: bool) -> list[Command]:
        """At vehicle time ``t_s`` (s), with ``flying`` whether the aircraft flies at its
        altitude (the take-over checks): what to ask for again or next, at most every
        ``RETRY_S``."""
        if self.phase not in GROUND_PHASES or t_s - self._asked_s < RETRY_S:
            return []
        if self.phase == "taking_off":
            self._asked_s = t_s
            return self._takeoff_commands()
        if self.phase == "climbing" and not flying:
            return []
        self._asked_s = t_s  # climbed, or parked on the runway: GUIDED
        return [(MAV_CMD_DO_SET_MODE, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)]

    def _takeoff_commands(self) -> list[Command]:
        out: list[Command] = []
        if self._mode != TAKEOFF:
            out.append((MAV_CMD_DO_SET_MODE, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, TAKEOFF))
        if not self._armed:
            out.append((MAV_CMD_COMPONENT_ARM_DISARM, 1))
        return out
