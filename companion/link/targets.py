"""The GUIDED airspeed and altitude targets of one vehicle (the Runner's, over its link).

Sent at every take-over and repeated every ``TARGETS_PERIOD_S``: the airspeed in force and
the vehicle's mission altitude (MAV_CMD_GUIDED_CHANGE_SPEED / _ALTITUDE, or
MAV_CMD_DO_CHANGE_SPEED where the first is unsupported). Between repeats the agent's airspeed
(the phase held by airspeed) is sent once it moves ``SPEED_STEP_M_S``, at most every
``SPEED_MIN_INTERVAL_S``. An autopilot that refuses an airspeed (ArduPlane: outside
AIRSPEED_MIN..MAX) makes the vehicle hold the mission's from then on, said once. Times are
vehicle seconds, passed in. Nothing is sent from here: every call returns what to send
and log (:class:`TargetsOut`), in order, for the caller to pass on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from companion.link.events import AirspeedDenied, GuidedTargetsSent, LinkEvent, TargetUnsupported
from companion.link.outbox import MAV_SEVERITY_WARNING, LinkOut, Statustext
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


class Addressed(Protocol):
    """What the targets read of the link: the autopilot's system id (None: not heard yet)."""

    @property
    def sysid(self) -> int | None:
        """The autopilot's MAVLink system id."""
        ...


@dataclass(frozen=True)
class TargetsOut:
    """What one call asks for, in order: messages to the autopilot (built messages and
    :class:`~companion.link.outbox.Statustext`) and events, with the airspeed it sent.

    Attributes:
        out: the messages and events, in the order they arose.
        airspeed_m_s: the airspeed sent to the autopilot (m/s), or None: the airspeed
            monitor and the bank conversion follow it.
        denied: the call was a refusal of an airspeed, and the vehicle now holds the
            mission's (the caller fixes its agent's airspeed).
    """

    out: tuple[LinkOut | LinkEvent, ...] = ()
    airspeed_m_s: float | None = None
    denied: bool = False


NOTHING = TargetsOut()


class GuidedTargets:
    """One vehicle's GUIDED airspeed and altitude targets.

    Args:
        link: what is read of the autopilot link (its ``sysid``).
        mission_airspeed_m_s: the mission's airspeed (m/s).
        alt_amsl_m: this vehicle's mission altitude above mean sea level (m), when asked.
    """

    def __init__(
        self, link: Addressed, mission_airspeed_m_s: float, alt_amsl_m: Callable[[], float]
    ) -> None:
        """Nothing sent yet; the mission's airspeed in force."""
        self.link = link
        self.mission_airspeed_m_s = mission_airspeed_m_s
        self.alt_amsl_m = alt_amsl_m
        self.speed_m_s = mission_airspeed_m_s  # the airspeed target in force (m/s)
        self.free = True  # False once the autopilot refused an airspeed
        self._speed_t_s: float | None = None  # vehicle time it was last sent
        self._sent_t_s: float | None = None  # vehicle time the targets were last sent
        self._unsupported: set[int] = set()

    def take_over(self, now_s: float | None) -> TargetsOut:
        """At every take-over: the mission's airspeed and altitude."""
        self.speed_m_s = self.mission_airspeed_m_s
        return self.send(now_s)

    def send(self, now_s: float | None) -> TargetsOut:
        """The airspeed in force and the altitude, now (vehicle s; None: with the first
        control step)."""
        sysid = self.link.sysid
        if sysid is None or now_s is None:
            self._sent_t_s = None
            return NOTHING
        alt_amsl = self.alt_amsl_m()
        out: list[LinkOut | LinkEvent] = [self._speed(self.speed_m_s, now_s, sysid)]
        if MAV_CMD_GUIDED_CHANGE_ALTITUDE not in self._unsupported:
            out.append(change_altitude_command(alt_amsl, sysid))
        out.append(
            GuidedTargetsSent(
                t_s=now_s,
                sysid=sysid,
                airspeed_m_s=self.speed_m_s,
                alt_amsl_m=round(alt_amsl, 2),
            )
        )
        self._sent_t_s = now_s
        return TargetsOut(tuple(out), self.speed_m_s)

    def repeat_if_due(self, t_s: float, now_s: float | None) -> TargetsOut:
        """Before each setpoint at ``t_s`` (vehicle s): the targets again if due."""
        if self._sent_t_s is None or t_s - self._sent_t_s >= TARGETS_PERIOD_S:
            return self.send(now_s)
        return NOTHING

    def command_speed(self, airspeed_m_s: float, t_s: float) -> TargetsOut:
        """The agent's airspeed (m/s) at ``t_s`` (vehicle s), paced as the module says."""
        sysid = self.link.sysid
        if sysid is None or not self.free or abs(airspeed_m_s - self.speed_m_s) < SPEED_STEP_M_S:
            return NOTHING
        if self._speed_t_s is not None and t_s - self._speed_t_s < SPEED_MIN_INTERVAL_S:
            return NOTHING
        msg = self._speed(round(airspeed_m_s, 2), t_s, sysid)
        return TargetsOut((msg,), self.speed_m_s)

    def on_ack(
        self, command: int, result: int, commanding: bool, now_s: float | None
    ) -> TargetsOut:
        """A COMMAND_ACK (MAV_CMD ``command``, MAV_RESULT ``result``) at vehicle time
        ``now_s`` (s); ``denied`` when it refused an airspeed and the vehicle now holds the
        mission's (the caller fixes its agent's airspeed)."""
        sysid = self.link.sysid
        if sysid is None:  # not from our autopilot
            return NOTHING
        speed_cmds = (MAV_CMD_GUIDED_CHANGE_SPEED, MAV_CMD_DO_CHANGE_SPEED)
        if result == MAV_RESULT_DENIED and command in speed_cmds:
            return self._denied(commanding, now_s, sysid)
        targets = (MAV_CMD_GUIDED_CHANGE_SPEED, MAV_CMD_GUIDED_CHANGE_ALTITUDE)
        new = command in targets and command not in self._unsupported
        if not (result == MAV_RESULT_UNSUPPORTED and new):
            return NOTHING
        self._unsupported.add(command)
        out: list[LinkOut | LinkEvent] = [
            TargetUnsupported(t_s=now_s, sysid=sysid, command=command)
        ]
        if command == MAV_CMD_GUIDED_CHANGE_SPEED:  # the older command instead
            out.append(do_change_speed_command(self.speed_m_s, sysid))
        return TargetsOut(tuple(out))

    def _denied(self, commanding: bool, now_s: float | None, sysid: int) -> TargetsOut:
        """The autopilot refused an airspeed: hold the mission's from now on, said once
        (event, STATUSTEXT)."""
        v = self.mission_airspeed_m_s
        if not self.free or not commanding or self.speed_m_s == v:
            return NOTHING  # a refusal outside GUIDED, or of the mission's own airspeed
        self.free = False
        out: list[LinkOut | LinkEvent] = [
            AirspeedDenied(
                t_s=now_s, sysid=sysid, airspeed_m_s=self.speed_m_s, mission_airspeed_m_s=v
            ),
            Statustext(
                f"companion {sysid}: airspeed {self.speed_m_s:.1f} m/s refused; "
                f"holding {v:.1f}, phase kept by steering only",
                MAV_SEVERITY_WARNING,
            ),
        ]
        if now_s is None:
            return TargetsOut(tuple(out), denied=True)
        out.append(self._speed(v, now_s, sysid))
        return TargetsOut(tuple(out), v, denied=True)

    def _speed(self, airspeed_m_s: float, t_s: float, sysid: int) -> LinkOut:
        """The airspeed command (m/s) to autopilot ``sysid`` at vehicle time ``t_s`` (s), now
        the one in force."""
        if MAV_CMD_GUIDED_CHANGE_SPEED not in self._unsupported:
            msg = change_speed_command(airspeed_m_s, sysid)
        else:
            msg = do_change_speed_command(airspeed_m_s, sysid)
        self.speed_m_s, self._speed_t_s = airspeed_m_s, t_s
        return msg
