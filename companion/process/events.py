"""The companion process's own events, as typed records (pure).

One frozen dataclass per event kind the process logs next to its Agent's: the run's start
and stop, the link, command authority, taking control and PX4's OFFBOARD entry, the setpoint
profile, the group's schedule, the checks' issues. Each is a
:class:`~companion.link.events.LinkEvent`: the latest vehicle time ``t_s`` (s, rounded to
1 ms; None before the first position) and the autopilot's ``sysid``, then its fields;
:meth:`~companion.link.events.LinkEvent.to_record` gives exactly the dict written to
``events.jsonl`` (``t_s``, ``event``, ``sysid``, the fields in declaration order, an
optional field left out when None), and :func:`parse_process_event` reads it back.

The checks' issues (:class:`companion.link.supervision.Issue`) are logged under the issue's
own name (``profile_ignored``, ``airspeed_off`` ...) and ``<name>_cleared``:
:class:`IssueRaised` and :class:`IssueCleared` carry the name as a field.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from companion.link.events import (
    LINK_EVENT_TYPES,
    LinkEvent,
    link_event,
    parse_link_event,
)


# ---- the run ---------------------------------------------------------------------------------
@link_event
class Start(LinkEvent):
    """The companion starts: the setpoint profile and tasking policy asked for."""

    name: ClassVar[str] = "start"
    profile: str
    policy: str


@link_event
class Stop(LinkEvent):
    """The companion stops, after ``setpoints`` setpoints."""

    name: ClassVar[str] = "stop"
    setpoints: int


# ---- the link --------------------------------------------------------------------------------
@link_event
class LinkUp(LinkEvent):
    """The first autopilot heartbeat: the Agent starts for system ``autopilot_sysid``."""

    name: ClassVar[str] = "link_up"
    autopilot_sysid: int


@link_event
class LinkLost(LinkEvent):
    """No autopilot heartbeat for the link's time-out, or its serial device hung up:
    ``silent_s`` the companion's own wall seconds since the last heartbeat (the vehicle
    time ``t_s`` stands still while nothing is heard)."""

    name: ClassVar[str] = "link_lost"
    silent_s: float | None = None


@link_event
class LinkRestored(LinkEvent):
    """The autopilot is heard again after a loss (``reconnects`` so far): ``outage_s`` the
    companion's own wall seconds from the last heartbeat before the loss to the first after
    it."""

    name: ClassVar[str] = "link_restored"
    reconnects: int
    outage_s: float | None = None


@link_event
class StreamSlow(LinkEvent):
    """A stream the companion asked for arrives at ``received_hz`` (Hz, over the last
    window) of the ``asked_hz`` it asked (a ground station on the same link changed it): it
    is asked again (:mod:`companion.process.streams`). Said once per fight."""

    name: ClassVar[str] = "stream_slow"
    stream: str
    asked_hz: float
    received_hz: float


@link_event
class StreamRestored(LinkEvent):
    """The slowed ``stream`` is back at its rate (``received_hz`` over the last window),
    ``after_s`` vehicle seconds after it was found slow, after ``requests`` requests."""

    name: ClassVar[str] = "stream_restored"
    stream: str
    asked_hz: float
    received_hz: float
    after_s: float
    requests: int


@link_event
class StreamGivenUp(LinkEvent):
    """The slowed ``stream`` stayed slow through ``requests`` requests: not asked again until
    the link comes up anew."""

    name: ClassVar[str] = "stream_given_up"
    stream: str
    asked_hz: float
    received_hz: float
    requests: int


@link_event
class Armed(LinkEvent):
    """The autopilot armed (not said for the first heartbeat)."""

    name: ClassVar[str] = "armed"


@link_event
class Disarmed(LinkEvent):
    """The autopilot disarmed (not said for the first heartbeat)."""

    name: ClassVar[str] = "disarmed"


@link_event
class CommandRefused(LinkEvent):
    """A COMMAND_ACK neither ACCEPTED nor IN_PROGRESS (MAV_CMD, MAV_RESULT)."""

    name: ClassVar[str] = "command_refused"
    command: int
    result: int


# ---- command authority, taking control, PX4's OFFBOARD entry ---------------------------------
@link_event
class AuthorityChanged(LinkEvent):
    """A change of command authority (:mod:`companion.link.modes`) and the autopilot mode
    that caused it."""

    name: ClassVar[str] = "authority"
    before: str
    after: str
    autopilot_mode: str | None


@link_event
class Override(LinkEvent):
    """The aircraft left the companion's mode, or the link came back with it in another:
    ``cause`` ``pilot`` (the setpoints flowed: a pilot or a ground station) or
    ``own_silence`` (after ``silent_s`` vehicle s without a setpoint, or a lost link: the
    autopilot's failsafe), :mod:`companion.link.failsafe`."""

    name: ClassVar[str] = "override"
    autopilot_mode: str | None
    cause: str | None = None
    silent_s: float | None = None


@link_event
class Retaking(LinkEvent):
    """With the operator's consent, the companion asks for its mode back after a loss to its
    own silence (ask number ``attempt`` in the window), its link and steps healthy again."""

    name: ClassVar[str] = "retake"
    autopilot_mode: str | None
    attempt: int


@link_event
class RetakeGivenUp(LinkEvent):
    """The companion stops asking for its aircraft back (too many asks in the window)."""

    name: ClassVar[str] = "retake_given_up"
    attempts: int


@link_event
class TakeOverParams(LinkEvent):
    """Parameters the companion set at take-over, as the autopilot read them back
    (``params``: ``NAME=VALUE`` separated by spaces), and those never read back (``refused``:
    names separated by spaces, "" if none)."""

    name: ClassVar[str] = "take_over_params"
    params: str
    refused: str


@link_event
class Resumed(LinkEvent):
    """The companion's mode again after an override."""

    name: ClassVar[str] = "resumed"


@link_event
class TakeControlRefused(LinkEvent):
    """Why the aircraft is not taken over (said once per reason)."""

    name: ClassVar[str] = "take_control_refused"
    reason: str


@link_event
class TakeControl(LinkEvent):
    """Taking control: ``guided`` asked, ``offboard_prestream`` begun, or ``offboard``
    asked (its ``attempt``)."""

    name: ClassVar[str] = "take_control"
    action: str
    attempt: int | None = None


@link_event
class OffboardEntryStep(LinkEvent):
    """A change of PX4's OFFBOARD entry (:class:`companion.link.px4.OffboardEntry`)."""

    name: ClassVar[str] = "offboard_entry"
    before: str
    after: str
    tries: int


@link_event
class VehicleCommand(LinkEvent):
    """The Agent's ``takeoff`` or ``land`` passed to the autopilot."""

    name: ClassVar[str] = "vehicle_command"
    command: str


# ---- setpoints, the group, the checks ---------------------------------------------------------
@link_event
class ProfileChosen(LinkEvent):
    """The setpoint profile chosen from the first heartbeat's MAV_AUTOPILOT ``autopilot``."""

    name: ClassVar[str] = "profile"
    profile: str
    autopilot: int | None


@link_event
class GroupSchedule(LinkEvent):
    """The group budget's schedule for ``members``: the state rate (Hz, to 1e-4), the member
    time-out (s, to 1 ms) and the budget (bytes/s)."""

    name: ClassVar[str] = "group_schedule"
    members: int
    rate_hz: float
    member_timeout_s: float
    budget_bytes_s: float


@dataclass(frozen=True, kw_only=True)
class IssueRaised(LinkEvent):
    """A check raised issue ``issue`` (logged under that name) with its text."""

    issue: str
    text: str

    @property
    def event(self) -> str:
        """The issue's name."""
        return self.issue

    def to_record(self) -> dict[str, Any]:
        """``t_s``, ``event`` (the issue's name), ``sysid``, ``text``."""
        return {"t_s": self.t_s, "event": self.event, "sysid": self.sysid, "text": self.text}


@dataclass(frozen=True, kw_only=True)
class IssueCleared(IssueRaised):
    """A check cleared issue ``issue`` (logged as ``<issue>_cleared``) with its text."""

    @property
    def event(self) -> str:
        """``<issue>_cleared``."""
        return f"{self.issue}_cleared"


def parse_process_event(
    record: dict[str, Any], issues: frozenset[str] = frozenset()
) -> LinkEvent | None:
    """The typed event of a logged record, or None for a kind not typed here (the Agent's,
    the simulator's). ``issues``: the check names to read as :class:`IssueRaised` (and
    ``<name>_cleared`` as :class:`IssueCleared`).

    Raises:
        LinkEventRecordError: a known kind with a field missing or an unexpected key.
    """
    name = record.get("event", "")
    stamp = {"t_s": record.get("t_s"), "sysid": record.get("sysid")}
    if name in issues:
        return IssueRaised(**stamp, issue=name, text=record["text"])
    if name.endswith("_cleared") and name.removesuffix("_cleared") in issues:
        return IssueCleared(**stamp, issue=name.removesuffix("_cleared"), text=record["text"])
    return parse_link_event(record, LINK_EVENT_TYPES)
