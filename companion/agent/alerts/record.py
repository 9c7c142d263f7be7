"""One distinct alert as a companion keeps it (mutable; its status changes only through its
methods, along the table of :mod:`companion.agent.alerts.lifecycle`).

Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from companion.agent.alerts.lifecycle import TAKEN, AlertStatus, transition
from companion.group.messages import Alert


@dataclass
class AlertRecord:
    """One distinct alert (duplicates are merged into it, never given a record of their own).

    Its :attr:`status` changes only through the methods below, each one transition of
    :data:`companion.agent.alerts.lifecycle.ALERT_TRANSITIONS` (an illegal one raises).
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
