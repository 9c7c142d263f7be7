"""The records an :class:`companion.agent.Agent` keeps, and what one update returns.

Mutable dataclasses (the agent's working state; an :class:`AlertRecord`'s status changes
only through its methods, along :mod:`companion.core.state_tables`) plus the frozen
:class:`AgentOutput`.
Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from companion.alerts import Alert
from companion.core.formation import MemberState
from companion.core.state_tables import TAKEN, AlertStatus, transition
from companion.core.virtual import VirtualParticle
from companion.events import AgentEvent
from companion.planner import Plan

Mode = Literal["patrol", "prosecuting", "rejoining"]
Event = dict[str, object]  # an event as logged (:meth:`companion.events.AgentEvent.to_record`)


@dataclass
class Neighbour:
    state: MemberState
    rx_t_s: float


@dataclass
class AlertRecord:
    """One distinct alert (duplicates are merged into it, never given a record of their own).

    Its :attr:`status` changes only through the methods below, each one transition of
    :data:`companion.core.state_tables.ALERT_TRANSITIONS` (an illegal one raises).
    ``done_t_s`` is the time (s) it was cleared (the message's, at most its receipt's);
    ``site_phase_rad`` caches the time-phase of the loop point nearest the site.
    """

    alert: Alert
    prosecutor: int | None = None
    bids: dict[int, float] = field(default_factory=dict)
    bid_deadline_s: float = 0.0
    rebroadcast_s: float = -1e9
    taken_t_s: float = 0.0
    excluded: set[int] = field(default_factory=set)
    done_t_s: float | None = None
    site_phase_rad: float | None = None
    t0_s: float = 0.0  # time of the first report (s): which of two reports of a site wins
    fence_checked: bool = False  # the geofence check has been made (Tasking._fence_refuses)
    _status: AlertStatus = field(default=AlertStatus.QUEUED, init=False)

    @property
    def status(self) -> AlertStatus:
        """Where the alert is: queued, bidding, tasked, under_way or done."""
        return self._status

    @property
    def taken(self) -> bool:
        """Whether a prosecutor was chosen (tasked or under way)."""
        return self._status in TAKEN

    @property
    def started(self) -> bool:
        """Whether its prosecutor is flying to it (under way)."""
        return self._status is AlertStatus.UNDER_WAY

    def _move(self, to: AlertStatus) -> None:
        self._status = transition(self._status, to)

    def open_bidding(self, deadline_s: float) -> None:
        """queued -> bidding: collect bids until ``deadline_s`` (s)."""
        self._move(AlertStatus.BIDDING)
        self.bids, self.bid_deadline_s = {}, deadline_s

    def task(self, prosecutor: int, t_s: float, started: bool) -> None:
        """queued or bidding -> tasked (``started``: under way) to ``prosecutor`` at ``t_s``
        (s); under way at once when this UAV takes it itself."""
        self._move(AlertStatus.UNDER_WAY if started else AlertStatus.TASKED)
        self.prosecutor, self.taken_t_s = prosecutor, t_s

    def seen_under_way(self, prosecutor: int) -> None:
        """``prosecutor`` is seen prosecuting it: under way (from any open status)."""
        if self._status is not AlertStatus.UNDER_WAY:
            self._move(AlertStatus.UNDER_WAY)
        self.prosecutor = prosecutor

    def requeue(self) -> None:
        """Back to the queue with no prosecutor (its tasking failed, or it was confirmed:
        the next UAV takes it); a queued alert stays queued."""
        if self._status is not AlertStatus.QUEUED:
            self._move(AlertStatus.QUEUED)
        self.prosecutor = None

    def finish(self, done_t_s: float) -> None:
        """An open alert is done (cleared or refused) at ``done_t_s`` (s)."""
        self._move(AlertStatus.DONE)
        self.done_t_s = done_t_s

    def inherit(self, other: AlertRecord) -> None:
        """Take over ``other``'s tasking (an earlier report of the same site replaces it; this
        record is new, hence queued). Bids were made for the other id: bid again."""
        if other.status in TAKEN:
            self._move(other.status)
        self.prosecutor = other.prosecutor
        self.taken_t_s, self.excluded, self.bids = other.taken_t_s, set(other.excluded), {}
        self.bid_deadline_s = other.bid_deadline_s


@dataclass
class Away:
    """A UAV's working state while away from the loop: prosecuting an alert, then flying
    back into its slot (whether it is still prosecuting or already rejoining is the Agent's
    own mode, :attr:`companion.agent.Agent.mode`, not a field here)."""

    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    planned_time_s: float = 0.0
    covered: bool = False
    rejoin_t0_s: float = 0.0
    merge: Plan | None = None  # the path that meets the slot on time
    merge_t0_s: float = 0.0
    meet_t_s: float = 0.0  # when the path meets the slot (s)
    merged: bool = False  # met the slot: the tracking law finishes the job
    wait: Plan | None = None  # back over the site while the slot comes round
    wait_t0_s: float = 0.0
    last_check_s: float = -1e9


@dataclass(frozen=True)
class AgentOutput:
    """What one ``update`` produces.

    Attributes:
        turn_rate_rad_s: turn-rate command (rad/s, positive right, within the limit).
        airspeed_m_s: airspeed to fly (m/s): the mission's, or on patrol within
            ``Gains.speed_authority_m_s`` of it to hold the time-phase.
        broadcast: the state to share with the group.
        alerts_out: alerts to send to the group.
        typed_events: the events to log, typed (:mod:`companion.events`).
        mode: "patrol", "prosecuting" or "rejoining".
    """

    turn_rate_rad_s: float
    airspeed_m_s: float
    broadcast: MemberState
    alerts_out: tuple[Alert, ...]
    typed_events: tuple[AgentEvent, ...]
    mode: Mode

    @property
    def events(self) -> tuple[Event, ...]:
        """The events as logged: one dict each (``t_s``, ``event``, ``sysid``, ``alert_id``
        ...), :meth:`companion.events.AgentEvent.to_record`."""
        return tuple(ev.to_record() for ev in self.typed_events)
