"""The GUIDED airspeed and altitude targets of one vehicle (the Runner's, over its link).

Sent at every take-over and repeated every ``TARGETS_PERIOD_S``: the airspeed in force and
the vehicle's mission altitude (MAV_CMD_GUIDED_CHANGE_SPEED / _ALTITUDE, or
MAV_CMD_DO_CHANGE_SPEED where the first is unsupported). Between repeats the agent's airspeed
(the phase held by airspeed) is sent once it moves ``SPEED_STEP_M_S``, at most every
``SPEED_MIN_INTERVAL_S``. An autopilot that refuses an airspeed (ArduPlane: outside
AIRSPEED_MIN..MAX) makes the vehicle hold the mission's from then on, said once. Times are
vehicle seconds, passed in.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from companion.link.setpoints import (
    change_altitude_command,
    change_speed_command,
    do_change_speed_command,
)

TARGETS_PERIOD_S = 10.0  # vehicle s between repeats of the airspeed and altitude targets
SPEED_STEP_M_S = 0.1  # an airspeed asked for by the agent is sent once it moves this much
SPEED_MIN_INTERVAL_S = 1.0  # and at most this often (vehicle s)
MAV_CMD_GUIDED_CHANGE_SPEED = 43000
MAV_CMD_GUIDED_CHANGE_ALTITUDE = 43001
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_RESULT_DENIED = 2
MAV_RESULT_UNSUPPORTED = 3

Log = Callable[..., None]  # (event, **fields)


class GuidedTargets:
    """One vehicle's GUIDED airspeed and altitude targets.

    Args:
        link: the autopilot link (``send``, ``statustext``, ``sysid``).
        mission_airspeed_m_s: the mission's airspeed (m/s).
        alt_amsl_m: this vehicle's mission altitude above mean sea level (m), when asked.
        log: the companion's event log, ``log(event, **fields)``.
        on_airspeed: called with every airspeed sent (m/s): the monitors and the bank
            conversion follow it.
    """

    def __init__(
        self,
        link: Any,
        mission_airspeed_m_s: float,
        alt_amsl_m: Callable[[], float],
        log: Log,
        on_airspeed: Callable[[float], None],
    ) -> None:
        """Nothing sent yet; the mission's airspeed in force."""
        self.link = link
        self.mission_airspeed_m_s = mission_airspeed_m_s
        self.alt_amsl_m = alt_amsl_m
        self._log = log
        self._on_airspeed = on_airspeed
        self.speed_m_s = mission_airspeed_m_s  # the airspeed target in force (m/s)
        self.free = True  # False once the autopilot refused an airspeed
        self._speed_t_s: float | None = None  # vehicle time it was last sent
        self._sent_t_s: float | None = None  # vehicle time the targets were last sent
        self._unsupported: set[int] = set()

    def take_over(self, now_s: float | None) -> None:
        """At every take-over: the mission's airspeed and altitude."""
        self.speed_m_s = self.mission_airspeed_m_s
        self.send(now_s)

    def send(self, now_s: float | None) -> None:
        """The airspeed in force and the altitude, now (vehicle s; None: with the first
        control step)."""
        sysid = self.link.sysid
        if sysid is None or now_s is None:
            self._sent_t_s = None
            return
        alt_amsl = self.alt_amsl_m()
        self._send_speed(self.speed_m_s, now_s)
        if MAV_CMD_GUIDED_CHANGE_ALTITUDE not in self._unsupported:
            self.link.send(change_altitude_command(alt_amsl, sysid))
        self._log("guided_targets", airspeed_m_s=self.speed_m_s, alt_amsl_m=round(alt_amsl, 2))
        self._sent_t_s = now_s

    def repeat_if_due(self, t_s: float, now_s: float | None) -> None:
        """Before each setpoint at ``t_s`` (vehicle s): the targets again if due."""
        if self._sent_t_s is None or t_s - self._sent_t_s >= TARGETS_PERIOD_S:
            self.send(now_s)

    def command_speed(self, airspeed_m_s: float, t_s: float) -> None:
        """The agent's airspeed (m/s) at ``t_s`` (vehicle s), paced as the module says."""
        if not self.free or abs(airspeed_m_s - self.speed_m_s) < SPEED_STEP_M_S:
            return
        if self._speed_t_s is not None and t_s - self._speed_t_s < SPEED_MIN_INTERVAL_S:
            return
        self._send_speed(round(airspeed_m_s, 2), t_s)

    def on_ack(self, command: int, result: int, commanding: bool, now_s: float | None) -> bool:
        """A COMMAND_ACK; True when it refused an airspeed and the vehicle now holds the
        mission's (the caller fixes its agent's airspeed)."""
        speed_cmds = (MAV_CMD_GUIDED_CHANGE_SPEED, MAV_CMD_DO_CHANGE_SPEED)
        if result == MAV_RESULT_DENIED and command in speed_cmds:
            return self._denied(commanding, now_s)
        targets = (MAV_CMD_GUIDED_CHANGE_SPEED, MAV_CMD_GUIDED_CHANGE_ALTITUDE)
        new = command in targets and command not in self._unsupported
        if result == MAV_RESULT_UNSUPPORTED and new:
            self._unsupported.add(command)
            self._log("target_unsupported", command=command)
            if command == MAV_CMD_GUIDED_CHANGE_SPEED:  # the older command instead
                self.link.send(do_change_speed_command(self.speed_m_s, self.link.sysid))
        return False

    def _denied(self, commanding: bool, now_s: float | None) -> bool:
        """The autopilot refused an airspeed: hold the mission's from now on, said once
        (event, STATUSTEXT)."""
        v = self.mission_airspeed_m_s
        if not self.free or not commanding or self.speed_m_s == v:
            return False  # a refusal outside GUIDED, or of the mission's own airspeed
        self.free = False
        self._log("airspeed_denied", airspeed_m_s=self.speed_m_s, mission_airspeed_m_s=v)
        self.link.statustext(
            f"companion {self.link.sysid}: airspeed {self.speed_m_s:.1f} m/s refused; "
            f"holding {v:.1f}, phase kept by steering only",
            severity=4,
        )
        if now_s is not None:
            self._send_speed(v, now_s)
        return True

    def _send_speed(self, airspeed_m_s: float, t_s: float) -> None:
        if MAV_CMD_GUIDED_CHANGE_SPEED not in self._unsupported:
            self.link.send(change_speed_command(airspeed_m_s, self.link.sysid))
        else:
            self.link.send(do_change_speed_command(airspeed_m_s, self.link.sysid))
        self.speed_m_s, self._speed_t_s = airspeed_m_s, t_s
        self._on_airspeed(airspeed_m_s)
