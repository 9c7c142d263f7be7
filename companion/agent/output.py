"""What one :meth:`companion.agent.agent.Agent.update` returns (frozen)."""

from __future__ import annotations

from dataclasses import dataclass

from companion.agent.events import AgentEvent
from companion.group.messages import Alert, MemberState, Mode

Event = dict[str, object]  # an event as logged (AgentEvent.to_record)


@dataclass(frozen=True)
class AgentOutput:
    """What one ``update`` produces.

    Attributes:
        turn_rate_rad_s: turn-rate command (rad/s, positive right, within the limit).
        airspeed_m_s: airspeed to fly (m/s): the mission's, or on patrol within
            ``Gains.speed_authority_m_s`` of it to hold the time-phase.
        broadcast: the state to share with the group.
        alerts_out: alerts to send to the group.
        typed_events: the events to log, typed (:mod:`companion.agent.events`).
        mode: patrol, prosecuting or rejoining (:class:`companion.group.messages.Mode`).
        hold: send the autopilot no setpoint (on the ground, :mod:`companion.agent.relief`).
        command: ``takeoff`` or ``land`` for the autopilot (the reliefs), or None.
    """

    turn_rate_rad_s: float
    airspeed_m_s: float
    broadcast: MemberState
    alerts_out: tuple[Alert, ...]
    typed_events: tuple[AgentEvent, ...]
    mode: Mode
    hold: bool = False
    command: str | None = None

    @property
    def events(self) -> tuple[Event, ...]:
        """The events as logged: one dict each (``t_s``, ``event``, ``sysid``, ``alert_id``
        ...), :meth:`companion.agent.events.AgentEvent.to_record`."""
        return tuple(ev.to_record() for ev in self.typed_events)
