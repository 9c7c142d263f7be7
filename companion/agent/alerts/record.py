"""One distinct alert as a companion keeps it (mutable; its status changes only through its
methods, along the table of :mod:`companion.agent.alerts.lifecycle`).

Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from companion.agent.alerts.fusion import fuse
from companion.agent.alerts.lifecycle import TAKEN, AlertEvent, AlertStatus, next_status
from companion.group.messages import Alert, Track


@dataclass
class AlertRecord:
    """One distinct alert (duplicates are merged into it, never given a record of their own).

    Its :attr:`status` changes only through the methods below, each one event of
    :data:`companion.agent.alerts.lifecycle.ALERT_TABLE` (an illegal one raises).
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
    track: Track | None = None  # the newest track known, from any member's message
    _status: AlertStatus = field(default=AlertStatus.QUEUED, init=False)

    def __post_init__(self) -> None:
        """The first report's track, if it has one."""
        if self.track is None:
            self.track = self.alert.track

    def predict(self, t_s: float) -> complex:
        """Where the intruder is expected at ``t_s`` (s; complex m): its track's prediction,
        or the reported site when it has no track."""
        return self.track.predict(t_s) if self.track is not None else self.alert.site_m

    def sigma_m(self, t_s: float) -> float:
        """The prediction's 1-sigma error per axis at ``t_s`` (m); 0 without a track."""
        return self.track.sigma_m(t_s) if self.track is not None else 0.0

    def update_track(self, track: Track | None) -> bool:
        """Take in ``track`` if it is newer than the one held (True if taken): fused with
        the one held by covariance intersection (:func:`~companion.agent.alerts.fusion.fuse`:
        a sighting both hold is not counted twice), or kept as it is when the held one is a
        point or disagrees with it."""
        if track is None or (self.track is not None and track.t_s <= self.track.t_s):
            return False
        self.track = track if self.track is None else fuse(self.track, track)
        return True

    @property
    def status(self) -> AlertStatus:
        """Where the alert is: queued, bidding, tasked, under_way, tracked or done."""
        return self._status

    @property
    def finished_t_s(self) -> float:
        """When a done alert was cleared, lost or refused (s: ``done_t_s``).

        Raises:
            ValueError: it is not done: the caller's bug.
        """
        if self.done_t_s is None:
            raise ValueError(f"alert {self.alert.alert_id} ({self._status}) is not done")
        return self.done_t_s

    @property
    def tasked_to(self) -> int:
        """The sysid of its prosecutor, for an alert that has one (tasked, under way or
        tracked).

        Raises:
            ValueError: it has none (queued, bidding or done): the caller's bug.
        """
        if self.prosecutor is None:
            raise ValueError(f"alert {self.alert.alert_id} ({self._status}) has no prosecutor")
        return self.prosecutor

    @property
    def taken(self) -> bool:
        """Whether a prosecutor was chosen (tasked or under way)."""
        return self._status in TAKEN

    @property
    def started(self) -> bool:
        """Whether its prosecutor is flying to it (under way)."""
        return self._status is AlertStatus.UNDER_WAY

    def _on(self, event: AlertEvent) -> None:
        """Move along :data:`~companion.agent.alerts.lifecycle.ALERT_TABLE` (an illegal
        event raises :class:`~companion.agent.machine.IllegalTransitionError`)."""
        self._status = next_status(self._status, event)

    def open_bidding(self, deadline_s: float) -> None:
        """``auction_opened``: collect bids until ``deadline_s`` (s)."""
        self._on(AlertEvent.AUCTION_OPENED)
        self.bids, self.bid_deadline_s = {}, deadline_s

    def task(self, prosecutor: int, t_s: float, started: bool) -> None:
        """``tasked`` to ``prosecutor`` at ``t_s`` (s); ``tasked_self`` (``started``: under
        way at once) when this UAV takes it itself."""
        self._on(AlertEvent.TASKED_SELF if started else AlertEvent.TASKED)
        self.prosecutor, self.taken_t_s = prosecutor, t_s

    def seen_under_way(self, prosecutor: int) -> None:
        """``seen_under_way``: ``prosecutor`` is seen prosecuting it."""
        self._on(AlertEvent.SEEN_UNDER_WAY)
        self.prosecutor = prosecutor

    def tracked_by(self, tracker: int) -> None:
        """``tracking_seen``: ``tracker`` is seen staying over the intruder."""
        self._on(AlertEvent.TRACKING_SEEN)
        self.prosecutor = tracker

    def requeue(self, why: AlertEvent) -> None:
        """Back to the queue with no prosecutor: ``why`` is ``confirmed`` (the next UAV takes
        it), ``task_lapsed`` or ``prosecutor_lost``."""
        self._on(why)
        self.prosecutor = None

    def finish(self, done_t_s: float, why: AlertEvent = AlertEvent.CLEARED) -> None:
        """Done at ``done_t_s`` (s): ``why`` is ``cleared``, ``lost`` or ``refused``."""
        self._on(why)
        self.done_t_s = done_t_s

    def inherit(self, other: AlertRecord) -> None:
        """Take over ``other``'s tasking (an earlier report of the same site replaces it; this
        record is new, hence queued). Bids were made for the other id: bid again."""
        if other.status is AlertStatus.TASKED:
            self._on(AlertEvent.TAKEN_OVER_TASKED)
        elif other.status is AlertStatus.UNDER_WAY:
            self._on(AlertEvent.TAKEN_OVER_AWAY)
        elif other.status is AlertStatus.TRACKED:
            self._on(AlertEvent.TRACKING_SEEN)
        self.update_track(other.track)
        self.prosecutor = other.prosecutor
        self.taken_t_s, self.excluded, self.bids = other.taken_t_s, set(other.excluded), {}
        self.bid_deadline_s = other.bid_deadline_s
