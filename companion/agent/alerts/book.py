"""The alerts one companion knows (pure): distinct alerts, duplicates merged, bounded memory.

An :class:`AlertBook` is fed every alert message a companion hears or raises ("new", "confirmed",
"cleared", "bid") with the local vehicle time (s), and keeps one
:class:`~companion.agent.alerts.record.AlertRecord` per distinct alert. Who takes an alert is
decided elsewhere (:mod:`companion.agent.agent`); this module only decides what is the same alert
and what is kept. The rules are deterministic from the messages, so every companion keeps the same
open alerts whatever order they arrive in:

* An id seen again is the same alert: a repeat, counted, nothing else.
* A report within the gate of an open alert's prediction (:meth:`AlertBook.gate_m`: for two
  sensor tracks ``GATE_SIGMAS`` sigma of their difference, so two intruders a few tens of
  metres apart stay two alerts; ``2 r_s`` when either is a point without a track, or three
  sigma of the track when wider), or of one cleared no earlier than the report was made,
  is the same alert: merged (its id is remembered, so its repeats are repeats; it never
  gets a record, hence never a prosecutor); its track is kept if newer. A report made after
  a clear is news and opens an alert of its own. Of two open reports of one
  site the earlier (first report time, id) wins: a later-arriving earlier report replaces
  the record and takes over its tasking (:meth:`AlertBook.apply` returns the renaming).
* A "cleared" report of a site (a UAV flew over it and saw nothing), or a "lost" one (its
  prosecutor or tracker lost the intruder there), also finishes the other
  open alerts reported before it, whatever their id, that were expected under the sensor
  that checked: within the gate and within one footprint radius of the site checked.
* An "update" carries a newer track of an open alert; "lost" finishes it (its tracker lost
  it). A message whose track may not be flown (NaN, a speed no intruder has, older than
  ``TRACK_TIMEOUT_S``) is refused whole and counted (``bad_track``).
* At most ``max_open`` alerts are open (queued, bidding, tasked or under way); beyond that
  the one last in queue order, (time, id), is dropped, counted and logged as
  ``alert_overflow``.
* Finished alerts are kept while they are re-sent or hold their site (``merge_hold_s``),
  then only their id is remembered, among the last ``CLOSED_IDS_MAX`` ids.

So memory and the work per message or update are bounded (O(``max_open``)) whatever the group
sends. ``alert_merged`` and ``alert_overflow`` events are logged up to ``STORM_EVENTS_PER_S``
a second of vehicle time and the rest only counted (:attr:`AlertBook.counts`); an
``alert_counts`` event reports the totals at most every ``COUNTS_EVERY_S`` when merges,
overflows or suppressed events were counted. Every method that makes events returns them,
in order, for the caller to log.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from companion.agent.alerts.lifecycle import OPEN, WAITING, AlertEvent, AlertStatus
from companion.agent.alerts.record import AlertRecord
from companion.agent.alerts.search import ROAD_MIN_M_S, SEARCH_SIGMAS
from companion.agent.alerts.track import track_refusal
from companion.agent.events import (
    AgentEvent,
    AlertCleared,
    AlertConfirmed,
    AlertCounts,
    AlertLost,
    AlertMerged,
    AlertNew,
    AlertOverflow,
    AlertReceived,
    AlertRefused,
)
from companion.group.messages import SIGHTING_SIGMA_M, Alert, Track

MAX_OPEN_ALERTS = 64  # default cap on open (not done) alerts
MAX_GATE_SENSORS = 3.0  # a report is the same intruder at most this many footprint radii off
GATE_SIGMAS = 4.0  # two sensor tracks farther apart than this many sigma are two intruders
PASS_BIAS_M = SIGHTING_SIGMA_M  # per axis: one UAV's geolocation error common to a whole pass
TRACK_TIMEOUT_S = 120.0  # a track older than this on receipt is refused (s)
CLOSED_IDS_MAX = 4096  # ids of finished, merged or dropped alerts remembered (oldest forgotten)
REPEAT_WINDOW_S = 10.0  # a UAV re-sends the alerts it reported this long after their time (s)
STORM_EVENTS_PER_S = 10  # merge/overflow events logged per second of vehicle time, rest counted
COUNTS_EVERY_S = 10.0  # an ``alert_counts`` event at most this often (s)

ALERT_COUNTERS = (
    "received",
    "distinct",
    "repeats",
    "merged",
    "overflow",
    "suppressed",
    "bad_track",
)
"""What :attr:`AlertBook.counts` counts, over the alert messages heard or raised (bids aside):
``distinct`` opened a record, ``repeats`` carried an id already known, ``merged`` were other
reports of an open (or just cleared) site, ``overflow`` did not fit under the cap,
``suppressed`` merge/overflow events were counted but not logged one by one, and
``bad_track`` carried a track that may not be flown (``track_refusal``: NaN, a speed no
intruder has, too old), refused whole."""

Events = list[AgentEvent]  # the events a call made, in order, for the caller to log


class AlertBook:
    """One companion's alert records, the ids it has finished with, and its counts.

    Args:
        sensor_m: sensor footprint radius ``r_s`` (m); reports within ``2 r_s`` are one site.
        sysid: the owning UAV's system id (the events' ``sysid``).
        max_open: most alerts open at once; more are dropped (overflow).
        merge_hold_s: a finished alert is kept this long after it is done (s), to absorb the
            late reports made before it was cleared.
    """

    def __init__(
        self,
        sensor_m: float,
        *,
        sysid: int,
        max_open: int = MAX_OPEN_ALERTS,
        merge_hold_s: float = 10.0,
    ) -> None:
        """An empty book."""
        if max_open < 1:
            raise ValueError(f"max_open_alerts must be at least 1, got {max_open!r}")
        if not (np.isfinite(merge_hold_s) and merge_hold_s >= 0.0):
            raise ValueError(f"merge_hold_s must be >= 0 s, got {merge_hold_s!r}")
        self.merge_m = 2.0 * float(sensor_m)
        self.max_open = int(max_open)
        self.merge_hold_s = float(merge_hold_s)
        self.records: dict[str, AlertRecord] = {}  # open and recently finished
        self.counts: dict[str, int] = dict.fromkeys(ALERT_COUNTERS, 0)
        self.sysid = int(sysid)
        self._closed: dict[str, None] = {}  # ids finished with, oldest first
        self._counts_logged = dict(self.counts)
        self._counts_t_s = -np.inf
        self._storm_t0_s, self._storm_logged = -np.inf, 0

    # ---- queries ----------------------------------------------------------------------------
    def open_records(self) -> list[AlertRecord]:
        """The alerts not finished (queued, bidding, tasked or under way)."""
        return [r for r in self.records.values() if r.status in OPEN]

    @staticmethod
    def queue(open_: list[AlertRecord]) -> list[AlertRecord]:
        """The waiting alerts (queued or bidding) of ``open_`` in service order (time, id)."""
        waiting = [r for r in open_ if r.status in WAITING]
        return sorted(waiting, key=lambda r: (r.alert.t_s, r.alert.alert_id))

    def is_closed(self, alert_id: str) -> bool:
        """Whether ``alert_id`` was merged, dropped or finished and forgotten."""
        return alert_id in self._closed

    def twin(
        self,
        site: complex,
        t_s: float,
        track: Track | None = None,
        exclude: Collection[str] = (),
    ) -> AlertRecord | None:
        """The alert a report of ``site`` (m) made at ``t_s`` (s), with the report's sensor
        ``track`` if it has one, duplicates, if any: the earliest open one whose intruder is
        expected within its gate (:meth:`gate_m`) of the report, else one cleared there no
        earlier than the report (a report made before the check; one made after it is news:
        the intruder is there after all). The alerts in ``exclude`` are not candidates
        (another intruder under the sensor holds them)."""
        best, best_key = None, None
        for rec in self.records.values():
            if rec.alert.alert_id in exclude:
                continue
            done = rec.status is AlertStatus.DONE
            if done and (rec.done_t_s is None or t_s > rec.done_t_s):
                continue
            if abs(rec.predict(t_s) - site) > self.gate_m(rec, t_s, track):
                continue
            key = (done, rec.t0_s, rec.alert.alert_id)
            if best_key is None or key < best_key:
                best, best_key = rec, key
        return best

    def sought(self, alert_id: str, site: complex, t_s: float) -> AlertRecord | None:
        """The alert ``alert_id`` this UAV is away for (prosecuting, searching or tracking),
        when a sighting of ``site`` (m) at ``t_s`` (s) that no alert's gate holds
        (:meth:`twin`) is its intruder: the record is open, its track moving (at least
        ``ROAD_MIN_M_S``) and the sighting within its sought region, ``SEARCH_SIGMAS`` sigma
        of the prediction (the region its search covers) or ``MAX_GATE_SENSORS`` footprint
        radii, whichever is wider, or within where the intruder can have driven since its
        last sighting (:meth:`reachable_m`). Else None.

        A vehicle that turned at a junction just before a pass ended is predicted straight on
        (the filter has not yet seen the new heading): 19-34 m off, five sigma, 1-2 s later,
        and 164 m off a cv track 22 s old (1.7 sigma); the twin gate missed both, so the
        prosecutor that flew over it raised a new alert and searched on for the old one
        (generated missions 28 and 32, ``docs/alerts.md``). Another intruder that close to a
        moving one, not in any alert's gate, is far less likely than the same one turned."""
        rec = self.records.get(alert_id)
        if rec is None or rec.status not in OPEN or rec.track is None:
            return None
        if rec.track.sightings <= 0 or abs(rec.track.vel_m_s) < ROAD_MIN_M_S:
            return None
        reach = max(MAX_GATE_SENSORS * self.merge_m / 2.0, SEARCH_SIGMAS * rec.sigma_m(t_s))
        if abs(rec.predict(t_s) - complex(site)) <= reach:
            return rec
        near = abs(rec.track.pos_m - complex(site)) <= self.reachable_m(rec.track, t_s)
        return rec if near else None

    def reachable_m(self, track: Track, t_s: float) -> float:
        """How far (m) from ``track``'s last position its intruder can be at ``t_s`` (s),
        whatever it did since: its speed and ``SEARCH_SIGMAS`` sigma of it over the time
        since, ``SEARCH_SIGMAS`` sigma of the position, and a footprint radius for the
        sighting's own error (the road search's points lie within it).

        A vehicle that turns at a junction after its last sighting is off the straight
        prediction by up to ``2 |v| dt sin(turn / 2)``, while the filter's manoeuvre term
        grows as ``a dt^2 / 2`` with the small ``a`` of a straight track. Generated mission
        28 of ``--kinds paths-all --max-loop-km 25``: a 15 m/s vehicle turned 60 deg at a
        junction just after its last sighting; 17 s later its prosecutor flew over it 207 m
        off the prediction (the sought region 177 m) and 234 m from where it was last seen
        (reachable 318 m). It raised a new alert, searched on for the old one, and the new
        one was tasked 110 s later with a 714 s intercept (``docs/alerts.md``)."""
        age = max(0.0, t_s - track.t_s)
        speed = abs(track.vel_m_s) + SEARCH_SIGMAS * track.vel_sigma_m_s
        return speed * age + SEARCH_SIGMAS * track.pos_sigma_m + self.merge_m / 2.0

    def gate_m(self, rec: AlertRecord, t_s: float, track: Track | None = None) -> float:
        """How far (m) from ``rec``'s prediction at ``t_s`` (s) a report with sensor ``track``
        (None: a point) is the same intruder, at most ``MAX_GATE_SENSORS`` footprints.

        Both sensor tracks: ``GATE_SIGMAS`` sigma of the difference of the two positions (the
        record's prediction, the report's track and each one's ``PASS_BIAS_M``), so a walker
        passing a still intruder 30 m away is two alerts. Otherwise ``2 r_s``, or three sigma
        of the record's prediction when wider: a point (the operator's) says little about
        where the intruder is."""
        cap = MAX_GATE_SENSORS * self.merge_m / 2
        own = rec.track
        if own is not None and own.sightings > 0 and track is not None and track.sightings > 0:
            sigma = math.hypot(rec.sigma_m(t_s), track.sigma_m(t_s), PASS_BIAS_M, PASS_BIAS_M)
            return min(GATE_SIGMAS * sigma, cap)
        return min(max(self.merge_m, 3.0 * rec.sigma_m(t_s)), cap)

    # ---- messages ---------------------------------------------------------------------------
    def apply(self, alert: Alert, t_s: float, own: bool) -> tuple[tuple[str, str] | None, Events]:
        """Take in one alert message received (or raised, ``own``) at local time ``t_s`` (s).

        Returns:
            ``(old_id, new_id)`` when an earlier report replaced the record of the same site
            (a UAV away for ``old_id`` is now away for ``new_id``), else None; and the events.
        """
        events: Events = []
        return self._apply(alert, t_s, own, events), events

    def _apply(self, alert: Alert, t_s: float, own: bool, out: Events) -> tuple[str, str] | None:
        rec = self.records.get(alert.alert_id)
        if alert.state == "bid":
            if rec is not None and rec.status is AlertStatus.BIDDING:
                rec.bids[alert.detector_sysid] = float(alert.bid_s)
            return None
        self.counts["received"] += 1
        if alert.track is not None and not own:
            why = track_refusal(alert.track, t_s, TRACK_TIMEOUT_S)
            if why is not None:  # never flown: counted, and logged (storm-limited)
                self.counts["bad_track"] += 1
                site = alert.site_m
                north, east = (
                    round(x, 2) if math.isfinite(x) else None for x in (site.real, site.imag)
                )
                self._log_storm(
                    t_s,
                    AlertRefused(
                        t_s=t_s,
                        sysid=self.sysid,
                        alert_id=alert.alert_id,
                        reason="track",
                        detail=why,
                        north_m=north,
                        east_m=east,
                    ),
                    out,
                )
                return None
        if rec is None and alert.alert_id in self._closed:
            self.counts["repeats"] += 1
            return None
        if alert.state in ("cleared", "lost"):
            self._clear_twins(alert, t_s, out)
        if rec is None:
            return self._admit(alert, t_s, own, out)
        if alert.state == "update":
            if rec.status in OPEN and rec.update_track(alert.track):
                return None
            self.counts["repeats"] += 1
            return None
        if alert.state in ("cleared", "lost") and rec.status in OPEN:
            cleared = alert.state == "cleared"
            rec.finish(min(alert.t_s, t_s), AlertEvent.CLEARED if cleared else AlertEvent.LOST)
            rec.alert = alert
            kind = AlertCleared if cleared else AlertLost
            out.append(
                kind(
                    t_s=t_s,
                    sysid=self.sysid,
                    alert_id=alert.alert_id,
                    detector_sysid=alert.detector_sysid,
                )
            )
            return None
        if alert.state == "confirmed" and rec.status in OPEN and alert.t_s > rec.alert.t_s:
            rec.alert = alert
            rec.update_track(alert.track)
            rec.requeue(AlertEvent.CONFIRMED)  # seen again by its sender: the next UAV takes it
            rec.bids, rec.excluded = {}, set()
            out.append(
                AlertConfirmed(
                    t_s=t_s,
                    sysid=self.sysid,
                    alert_id=alert.alert_id,
                    detector_sysid=alert.detector_sysid,
                )
            )
        else:
            self.counts["repeats"] += 1
        return None

    def _admit(self, alert: Alert, t_s: float, own: bool, out: Events) -> tuple[str, str] | None:
        """A report with an id not known yet: a new alert, a duplicate, or an overflow."""
        if alert.state in ("cleared", "lost"):  # the alert itself was missed: it is done
            done = AlertRecord(alert, t0_s=alert.t_s)
            why = AlertEvent.CLEARED if alert.state == "cleared" else AlertEvent.LOST
            done.finish(min(alert.t_s, t_s), why)
            self.records[alert.alert_id] = done
            return None
        rec = AlertRecord(alert, t0_s=alert.t_s)
        twin = self.twin(alert.site_m, alert.t_s, alert.track)
        renamed = None
        if twin is not None:
            old = twin.alert.alert_id
            if twin.status is AlertStatus.DONE or (rec.t0_s, alert.alert_id) >= (twin.t0_s, old):
                self._merge(alert, twin, t_s, out)
                if twin.status is not AlertStatus.DONE:
                    twin.update_track(alert.track)  # another member's sighting of it
                return None
            rec.inherit(twin)  # the earlier report of an open site replaces the later one
            del self.records[old]
            self._merge(twin.alert, rec, t_s, out)
            renamed = (old, alert.alert_id)
        elif not self._make_room(alert, t_s, out):
            return None
        self.records[alert.alert_id] = rec
        self.counts["distinct"] += 1
        kind = AlertNew if alert.state == "new" else AlertReceived
        out.append(
            kind(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=alert.alert_id,
                detector_sysid=alert.detector_sysid,
                north_m=round(alert.site_m.real, 2),
                east_m=round(alert.site_m.imag, 2),
                own=own,
            )
        )
        if alert.state == "confirmed":  # seen again by its sender: the next UAV takes it
            rec.requeue(AlertEvent.CONFIRMED)
        return renamed

    def _clear_twins(self, cleared: Alert, t_s: float, out: Events) -> None:
        """A UAV checked ``cleared``'s site and found nothing ("cleared"), or lost its
        intruder there ("lost"): the other open alerts of that site reported before the
        check are answered too, the same way (a companion that missed the first report of a
        site holds a later one under another id; it must not send a second UAV).

        Only those expected under the sensor that checked: within the twin gate
        (:meth:`gate_m`) and within one footprint radius of the site checked. A still
        intruder well tracked 83 m from a decoy's site checked with a 52 m footprint was
        not looked at, yet the 2 r_s gate of a point without a track finished its alert
        (generated mission 124, ``docs/alerts.md``)."""
        sensor_m = self.merge_m / 2.0
        for rec in self.open_records():
            if rec.alert.alert_id == cleared.alert_id or rec.t0_s > cleared.t_s:
                continue
            off_m = abs(rec.predict(cleared.t_s) - cleared.site_m)
            if off_m <= min(sensor_m, self.gate_m(rec, cleared.t_s, cleared.track)):
                lost = cleared.state == "lost"
                rec.finish(min(cleared.t_s, t_s), AlertEvent.LOST if lost else AlertEvent.CLEARED)
                out.append(
                    (AlertLost if lost else AlertCleared)(
                        t_s=t_s,
                        sysid=self.sysid,
                        alert_id=rec.alert.alert_id,
                        detector_sysid=cleared.detector_sysid,
                        via=cleared.alert_id,
                    )
                )

    def _merge(self, alert: Alert, into: AlertRecord, t_s: float, out: Events) -> None:
        """``alert`` is another report of ``into``'s site: remember its id, count, log."""
        self._close(alert.alert_id)
        self.counts["merged"] += 1
        self._log_storm(
            t_s,
            AlertMerged(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=alert.alert_id,
                into=into.alert.alert_id,
                distance_m=round(abs(alert.site_m - into.alert.site_m), 1),
            ),
            out,
        )

    def _make_room(self, alert: Alert, t_s: float, out: Events) -> bool:
        """Whether ``alert`` may open (the queue's last alert is dropped if it comes first)."""
        open_ = self.open_records()
        if len(open_) < self.max_open:
            return True
        waiting = [r for r in open_ if r.status in WAITING]
        last = max(waiting, key=lambda r: (r.alert.t_s, r.alert.alert_id), default=None)
        if last is None or (alert.t_s, alert.alert_id) >= (last.alert.t_s, last.alert.alert_id):
            dropped = alert
        else:
            dropped = last.alert
            del self.records[dropped.alert_id]
        self._close(dropped.alert_id)
        self.counts["overflow"] += 1
        self._log_storm(
            t_s,
            AlertOverflow(
                t_s=t_s, sysid=self.sysid, alert_id=dropped.alert_id, max_open=self.max_open
            ),
            out,
        )
        return dropped is not alert

    def _close(self, alert_id: str) -> None:
        """Remember ``alert_id`` as finished with; forget the oldest such ids."""
        self._closed[alert_id] = None
        if len(self._closed) > CLOSED_IDS_MAX:
            del self._closed[next(iter(self._closed))]

    # ---- upkeep -----------------------------------------------------------------------------
    def prune(self, t_s: float, keep_id: str | None = None) -> None:
        """Forget finished alerts no longer re-sent nor holding their site (their ids stay
        known); at most ``max_open`` finished records are kept. ``keep_id`` is never pruned
        (the alert this UAV is flying back from)."""
        keep_s = max(self.merge_hold_s, REPEAT_WINDOW_S) + 1.0
        done = [r for r in self.records.values() if r.status is AlertStatus.DONE]
        done.sort(key=lambda r: (r.finished_t_s, r.alert.alert_id))
        extra = len(done) - self.max_open
        for k, rec in enumerate(done):
            if (k < extra or t_s - rec.finished_t_s > keep_s) and rec.alert.alert_id != keep_id:
                del self.records[rec.alert.alert_id]
                self._close(rec.alert.alert_id)

    def counts_due(self, t_s: float) -> Events:
        """An ``alert_counts`` event (the totals) when merges, overflows or suppressed events
        were counted since the last one, at most every ``COUNTS_EVERY_S`` (repeats alone are
        routine: every alert is re-sent against loss); else none."""
        if t_s - self._counts_t_s < COUNTS_EVERY_S:
            return []
        c = self.counts
        if any(c[k] != self._counts_logged[k] for k in ALERT_COUNTERS[3:]):
            self._counts_logged, self._counts_t_s = dict(c), t_s
            return [AlertCounts(t_s=t_s, sysid=self.sysid, **c)]
        return []

    def _log_storm(
        self, t_s: float, event: AlertMerged | AlertOverflow | AlertRefused, out: Events
    ) -> None:
        """Log a merge or overflow at ``t_s`` (s), at most ``STORM_EVENTS_PER_S`` a second;
        count the rest."""
        if t_s - self._storm_t0_s >= 1.0:
            self._storm_t0_s, self._storm_logged = t_s, 0
        if self._storm_logged < STORM_EVENTS_PER_S:
            self._storm_logged += 1
            out.append(event)
        else:
            self.counts["suppressed"] += 1
