"""What the companion asks its autopilot link to send, as plain data (pure).

A part of the companion that wants something sent returns it instead of sending it: a built
MAVLink message (a setpoint, a PARAM_REQUEST_READ ...), a :class:`Statustext` or a
:class:`CommandLong`. The process's one sender (:class:`companion.process.sender.Sender`)
hands them, in order, to :class:`companion.link.connection.AutopilotLink` (``send``,
``statustext``, ``command_long``), the one place bytes cross the link.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

MAV_SEVERITY_WARNING = 4
MAV_SEVERITY_NOTICE = 5


@dataclass(frozen=True, slots=True)
class Statustext:
    """A STATUSTEXT to the autopilot and ground stations (MAV_SEVERITY ``severity``)."""

    text: str
    severity: int = MAV_SEVERITY_NOTICE


@dataclass(frozen=True, slots=True)
class CommandLong:
    """A COMMAND_LONG (MAV_CMD ``command``) to the autopilot, ``params`` padded with zeros."""

    command: int
    params: tuple[float, ...] = ()

    @classmethod
    def of(cls, command: int, *params: float) -> CommandLong:
        """``CommandLong(command, params)`` from a command tuple as
        :mod:`companion.link.ground` writes them."""
        return cls(command, tuple(params))


LinkOut = Any
"""A built pymavlink message, a :class:`Statustext` or a :class:`CommandLong`."""
