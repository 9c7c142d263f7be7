"""The events an :class:`~companion.agent.agent.Agent` logs, as typed records (pure).

One frozen dataclass per event kind the Agent and its seams emit
(:mod:`companion.agent.alerts.book`,
:mod:`companion.agent.wind.follow`, :mod:`companion.agent.alerts.prosecution`,
:mod:`companion.agent.rejoin`). Every
event carries the vehicle time ``t_s`` (s, rounded to the millisecond as logged) and the
``sysid`` of the UAV that logged it; the class attribute :attr:`AgentEvent.name` is the
``event`` string written to ``events.jsonl``. Field names carry their units as everywhere
else (``planned_time_s``, ``north_m``, ``wind_from_deg``); the values are stored as logged
(rounded where they are made), so :meth:`AgentEvent.to_record` gives exactly the dict
written today (same keys in the same order, same values) and :func:`parse_event` reads it
back: ``parse_event(ev.to_record()) == ev``.

A field whose default is None is optional: it is left out of the record when None (e.g.
``rejoined`` without ``tol_m`` when the UAV hands back at once, ``rejoin: direct``).

Only the Agent's events are typed here. The Runner's own events (``start``, ``link_up``,
``authority``, ``guided_targets`` ...) and the simulator's (``detection``, ``mode_change``,
``intruder_appeared`` ...) stay dicts for now: :func:`parse_event` returns None for a kind it
does not know. A record of a known kind with a field missing or one it does not expect is
refused with :class:`EventRecordError` (a ``ValueError``). The key ``source`` that
:func:`companion.sim.fleet.merge_events` adds to the merged log is not part of an event and
is ignored.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, fields
from typing import Any, ClassVar, TypeVar, dataclass_transform

IGNORED_KEYS = frozenset({"source"})
"""Keys of a logged record that are not an event's fields (added by the merged log)."""


class EventRecordError(ValueError):
    """A record of a known event kind that does not carry that kind's fields."""


@dataclass(frozen=True, kw_only=True)
class AgentEvent:
    """What every Agent event carries: the vehicle time ``t_s`` (s, rounded to 1 ms, as
    logged) and the logging UAV's ``sysid``; subclasses add their fields and ``name``."""

    name: ClassVar[str] = ""
    t_s: float
    sysid: int

    def __post_init__(self) -> None:
        """Round the time to the millisecond, as the log always has (idempotent)."""
        object.__setattr__(self, "t_s", round(float(self.t_s), 3))

    def to_record(self) -> dict[str, Any]:
        """The JSON-ready dict logged to ``events.jsonl``: ``t_s``, ``event``, ``sysid``,
        then the fields in declaration order (optional ones left out when None)."""
        rec: dict[str, Any] = {"t_s": self.t_s, "event": self.name, "sysid": self.sysid}
        for f in fields(self)[2:]:
            value = getattr(self, f.name)
            if value is None and f.default is None:
                continue
            rec[f.name] = value
        return rec


E = TypeVar("E", bound=AgentEvent)

EVENT_TYPES: dict[str, type[AgentEvent]] = {}
"""Every typed event kind, by its ``event`` name."""


def _register(cls: type[E]) -> type[E]:
    """Add ``cls`` to :data:`EVENT_TYPES` (a name used twice raises)."""
    if not cls.name or cls.name in EVENT_TYPES:
        raise ValueError(f"event name {cls.name!r} of {cls.__name__} is empty or taken")
    EVENT_TYPES[cls.name] = cls
    return cls


@dataclass_transform(frozen_default=True, kw_only_default=True)
def _event(cls: type[E]) -> type[E]:
    """An event kind: a frozen keyword-only dataclass, added to :data:`EVENT_TYPES` (declared a
    dataclass transform, so a type checker knows each kind's fields)."""
    return _register(dataclass(frozen=True, kw_only=True)(cls))


# ---- formation (companion/agent/agent.py, companion/agent/neighbours.py) -------------------------
@_event
class MemberJoined(AgentEvent):
    """A member is heard again, or for the first time; ``members`` counts this UAV too."""

    name: ClassVar[str] = "member_joined"
    member_sysid: int
    members: int


@_event
class MemberLost(AgentEvent):
    """A member fell silent for ``member_timeout_s`` and left the formation."""

    name: ClassVar[str] = "member_lost"
    member_sysid: int
    members: int


# ---- alerts (companion/agent/alerts/book.py, companion/agent/agent.py) ---------------------------
@_event
class AlertNew(AgentEvent):
    """A new alert opened: the site (m, north and east of the origin, to 1 cm); ``own``:
    raised by this UAV's sensor."""

    name: ClassVar[str] = "alert_new"
    alert_id: str
    detector_sysid: int
    north_m: float
    east_m: float
    own: bool


@_event
class AlertReceived(AgentEvent):
    """An alert first heard in a later state (confirmed): opened as :class:`AlertNew`."""

    name: ClassVar[str] = "alert_received"
    alert_id: str
    detector_sysid: int
    north_m: float
    east_m: float
    own: bool


@_event
class AlertConfirmed(AgentEvent):
    """The intruder was seen again by ``detector_sysid``: the next UAV takes the alert."""

    name: ClassVar[str] = "alert_confirmed"
    alert_id: str
    detector_sysid: int


@_event
class AlertCleared(AgentEvent):
    """The alert's site was checked and found empty by ``detector_sysid``; ``via``: the id
    of the cleared alert of the same site that answered this one too."""

    name: ClassVar[str] = "alert_cleared"
    alert_id: str
    detector_sysid: int
    via: str | None = None


@_event
class AlertMerged(AgentEvent):
    """Another report of an open (or just cleared) site, merged ``into`` that alert;
    ``distance_m``: between the two sites (m, to 0.1 m)."""

    name: ClassVar[str] = "alert_merged"
    alert_id: str
    into: str
    distance_m: float


@_event
class AlertOverflow(AgentEvent):
    """An alert dropped: ``max_open`` alerts were open already."""

    name: ClassVar[str] = "alert_overflow"
    alert_id: str
    max_open: int


@_event
class AlertCounts(AgentEvent):
    """The alert book's totals (:data:`companion.agent.alerts.book.ALERT_COUNTERS`)."""

    name: ClassVar[str] = "alert_counts"
    received: int
    distinct: int
    repeats: int
    merged: int
    overflow: int
    suppressed: int
    bad_track: int = 0


@_event
class AlertRequeued(AgentEvent):
    """An alert back in the queue (its prosecutor never left, or was lost: ``reason``)."""

    name: ClassVar[str] = "alert_requeued"
    alert_id: str
    reason: str | None = None


@_event
class AlertTasked(AgentEvent):
    """``prosecutor_sysid`` is tasked to the alert under ``policy`` ("next", "fastest")."""

    name: ClassVar[str] = "alert_tasked"
    alert_id: str
    prosecutor_sysid: int
    policy: str


@_event
class AlertRefused(AgentEvent):
    """No UAV is tasked: the geofence rules the site out (``reason`` "fence"), or the
    message's track may not be flown (``reason`` "track": NaN, a speed no intruder has, too
    old; the site is None where it is not a number). ``detail`` says how."""

    name: ClassVar[str] = "alert_refused"
    alert_id: str
    reason: str
    detail: str
    north_m: float | None
    east_m: float | None


@_event
class AlertLost(AgentEvent):
    """``detector_sysid`` lost the intruder: its tracker (not seen for the track time-out, or
    out of the fence), or its prosecutor (not found where predicted, and the prediction's
    region not covered by the sensor); ``via``: the id of the lost alert of the same
    intruder that answered this one too."""

    name: ClassVar[str] = "alert_lost"
    alert_id: str
    detector_sysid: int
    via: str | None = None


SITE_EVENTS = (AlertNew, AlertReceived, AlertRefused)
"""The alert events that carry the site (``north_m``, ``east_m``)."""


@_event
class Sighted(AgentEvent):
    """This UAV's sensor passed over the intruder of ``alert_id``: the pass's first and last
    sighting times (s), how many it made, and the track after it (where, m; speed, m/s;
    1-sigma position error per axis, m)."""

    name: ClassVar[str] = "sighted"
    alert_id: str
    first_t_s: float
    sightings: int
    north_m: float
    east_m: float
    speed_m_s: float
    sigma_m: float


# ---- prosecution (companion/agent/alerts/prosecution.py) -----------------------------------------
@_event
class PlanMade(AgentEvent):
    """The first path to the site: its time (s, to 1 ms) and family; family "loop": the
    site is checked from the loop, and ``quickest_time_s`` (s) is the minimum-time path's."""

    name: ClassVar[str] = "plan"
    alert_id: str
    planned_time_s: float
    path_type: str
    quickest_time_s: float | None = None


@_event
class PlanFailed(AgentEvent):
    """No path to the site (the planner's ``reason``)."""

    name: ClassVar[str] = "plan_failed"
    alert_id: str
    reason: str


@_event
class Replan(AgentEvent):
    """A re-planned path replaced the one in force: its time (s) and family."""

    name: ClassVar[str] = "replan"
    alert_id: str
    planned_time_s: float
    path_type: str


@_event
class SiteCovered(AgentEvent):
    """The sensor reached the site: ``response_time_s`` from the alert (s), against the first
    plan's ``planned_time_s`` (s)."""

    name: ClassVar[str] = "site_covered"
    alert_id: str
    response_time_s: float
    planned_time_s: float


@_event
class SearchStarted(AgentEvent):
    """The intercept found nothing where the track predicted it: a search of its uncertainty
    (``sigma_m``, m, 1-sigma per axis now) for at most ``max_s`` (s)."""

    name: ClassVar[str] = "search_started"
    alert_id: str
    sigma_m: float
    max_s: float


@_event
class ProsecutionEnd(AgentEvent):
    """The flight to the intruder ended: ``outcome`` "confirmed" (seen, handed on),
    "tracking" (seen, this UAV stays over it), "cleared" (not found where the sensor looked;
    with the ``response_time_s`` from the alert, s), "lost" (not found, its prediction's
    region not covered by the sensor), "cancelled" (cleared ``by_sysid`` first) or
    "yielded" (``by_sysid`` prosecutes it too and keeps it);
    ``searched_s`` (s) and ``search_end`` ("covered", "outpaced", "time") when it searched;
    ``search_end`` "outpaced_at_start" and no ``searched_s`` when a search was needed but
    could never have caught up with the region, so none was flown; "left_fence" when the
    intercept would have met a moving intruder beyond the fence (or within a turn of its
    edge), so none was flown."""

    name: ClassVar[str] = "prosecution_end"
    alert_id: str
    outcome: str
    by_sysid: int | None = None
    planned_time_s: float
    response_time_s: float | None = None
    searched_s: float | None = None
    search_end: str | None = None


# ---- tracking (companion/agent/alerts/tracker.py) -------------------------------------------
@_event
class TrackerEnded(AgentEvent):
    """This UAV stopped tracking after ``tracked_s`` (s): ``reason`` "lost" (not seen for
    the time-out), "left_fence" (the intruder too near the fence's edge or out of it) or
    "released" (the operator, or the alert cleared)."""

    name: ClassVar[str] = "tracker_ended"
    alert_id: str
    reason: str
    tracked_s: float


# ---- rejoin (companion/agent/rejoin.py, companion/agent/agent.py) --------------------------------
@_event
class RejoinPath(AgentEvent):
    """The path back onto the loop: its time (s) and family; ``resume_after_s`` when it
    flies back to where it left the loop, that long (s) after it left (else ahead)."""

    name: ClassVar[str] = "rejoin_path"
    alert_id: str
    planned_time_s: float
    path_type: str
    resume_after_s: float | None = None


@_event
class OnLoop(AgentEvent):
    """Back on the loop ``after_s`` (s) from the start of the rejoin; its slot is recovered
    along the loop from here."""

    name: ClassVar[str] = "on_loop"
    alert_id: str
    after_s: float


@_event
class Rejoined(AgentEvent):
    """The real state handed back after ``rejoin_s`` (s): ``in_slot`` or late; ``tol_m``:
    the centre tolerance (m), None when handed back at once (``rejoin: direct``)."""

    name: ClassVar[str] = "rejoined"
    alert_id: str
    in_slot: bool
    rejoin_s: float
    tol_m: float | None = None


# ---- the fleet's wind (companion/agent/wind/follow.py) -------------------------------------------
@_event
class WindProposed(AgentEvent):
    """This UAV proposed wind record ``seq``, in force from ``t_eff_s`` (s); the wind's
    speed (m/s) and the direction it blows FROM (deg)."""

    name: ClassVar[str] = "wind_proposed"
    seq: int
    t_eff_s: float
    wind_speed_m_s: float
    wind_from_deg: float


@_event
class WindAgreed(AgentEvent):
    """The record in force changed: the loop re-timed to ``period_s`` (s) in that wind."""

    name: ClassVar[str] = "wind_agreed"
    seq: int
    proposer: int
    period_s: float
    wind_speed_m_s: float
    wind_from_deg: float


@_event
class LoopInfeasible(AgentEvent):
    """The loop, in the wind in force, needs ``need_deg_s`` of turn rate, more than the
    aircraft's ``limit_deg_s`` (deg/s, to 0.1)."""

    name: ClassVar[str] = "loop_infeasible"
    need_deg_s: float
    limit_deg_s: float
    wind_speed_m_s: float
    wind_from_deg: float


@_event
class LoopFlyable(AgentEvent):
    """The loop is flyable again in the wind in force (fields as :class:`LoopInfeasible`)."""

    name: ClassVar[str] = "loop_flyable"
    need_deg_s: float
    limit_deg_s: float
    wind_speed_m_s: float
    wind_from_deg: float


def parse_event(record: dict[str, Any]) -> AgentEvent | None:
    """The typed event of a logged record, or None for a kind not typed here (the Runner's
    and the simulator's events).

    Raises:
        EventRecordError: a known kind with a field missing or an unexpected key.
    """
    name = record.get("event")
    cls = EVENT_TYPES.get(name) if isinstance(name, str) else None
    if cls is None:
        return None
    known = fields(cls)
    given = set(record) - {"event"} - IGNORED_KEYS
    names = {f.name for f in known}
    missing = [
        f.name
        for f in known
        if f.name not in given and f.default is MISSING and f.default_factory is MISSING
    ]
    unexpected = sorted(given - names)
    if missing or unexpected:
        raise EventRecordError(
            f"{cls.name} event at t_s={record.get('t_s')!r}: "
            + "; ".join(
                part
                for part in (
                    f"missing {', '.join(missing)}" if missing else "",
                    f"unexpected {', '.join(unexpected)}" if unexpected else "",
                )
                if part
            )
        )
    return cls(**{k: record[k] for k in given})
