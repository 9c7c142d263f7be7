"""Where what the companion decided leaves the process: the one sender.

The components of a :class:`~companion.process.runner.Runner` send nothing and log nothing
themselves: each hook returns its :data:`Effects`, in order, and the Runner hands them to
:meth:`Sender.send`:

* a built MAVLink message, a :class:`~companion.link.outbox.Statustext` or a
  :class:`~companion.link.outbox.CommandLong` -> the autopilot link;
* a :class:`~companion.group.messages.MemberState` or an
  :class:`~companion.group.messages.Alert` -> the group;
* an event (:mod:`companion.process.events`, :mod:`companion.link.events`,
  :mod:`companion.agent.events`) -> ``events.jsonl``.

The order is kept across all three: a step's state reaches the group before its setpoint
reaches the autopilot (docs/sitl.md, "Lockstep"), and the events keep the order in which
they arose.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Protocol

from companion.agent.events import AgentEvent
from companion.group.messages import Alert, MemberState
from companion.link.events import LinkEvent
from companion.link.outbox import CommandLong, LinkOut, Statustext
from companion.process.event_log import EventLog

Effect = LinkOut | MemberState | Alert | LinkEvent | AgentEvent
"""One thing a hook asks for: a message to the autopilot or the group, or an event."""

Effects = Sequence[Effect]
"""What a hook asks for, in order."""

NOTHING: Effects = ()
"""No effect."""


class LinkOutput(Protocol):
    """What the sender calls on the autopilot link
    (:class:`companion.link.connection.AutopilotLink`)."""

    def send(self, msg: Any) -> None:
        """Send one built message."""

    def statustext(self, text: str, severity: int = ...) -> None:
        """Send a STATUSTEXT."""

    def command_long(self, command: int, *params: float) -> None:
        """Send a COMMAND_LONG."""


class GroupOutput(Protocol):
    """What the sender calls on the group (:class:`companion.group.transport.Group`)."""

    def send_state(self, state: MemberState) -> None:
        """Send this member's state."""

    def send_alert(self, alert: Alert) -> None:
        """Send an alert."""


class Sender:
    """Sends effects in order: to the link, the group (once there is one) and the event log.

    Args:
        link: the autopilot link.
        events: the event log.
    """

    def __init__(self, link: LinkOutput, events: EventLog) -> None:
        """No group yet (:attr:`group` is set once the Agent starts)."""
        self.link = link
        self.events = events
        self.group: GroupOutput | None = None

    def send(self, effects: Iterable[Effect]) -> None:
        """Every effect, in order. A message to the group before there is one is a bug."""
        for e in effects:
            if isinstance(e, LinkEvent | AgentEvent):
                self.events.write(e.to_record())
            elif isinstance(e, Statustext):
                self.link.statustext(e.text, e.severity)
            elif isinstance(e, CommandLong):
                self.link.command_long(e.command, *e.params)
            elif isinstance(e, MemberState):
                self._group().send_state(e)
            elif isinstance(e, Alert):
                self._group().send_alert(e)
            else:
                self.link.send(e)

    def _group(self) -> GroupOutput:
        if self.group is None:
            raise RuntimeError("a message to the group before the group was opened")
        return self.group
