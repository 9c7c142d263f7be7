"""The alerts one companion knows, raises and shares (pure): a component of
:class:`companion.agent.agent.Agent`, with its own state.

* its own sightings (:mod:`companion.agent.alerts.contacts`): every sighting, in every mode,
  refines the track of the alert its contact holds, or raises a new alert carrying its track;
  a contact's track is shared as "update" at most every ``TRACK_UPDATE_S`` and at the end of
  the pass, and a ``sighted`` event logged when the pass ends;
* the alert book (:mod:`companion.agent.alerts.book`): every alert message heard or sent;
* the outbox: the alert messages to send with the next update (its own alerts, their
  updates, the prosecution's answers, bids, and the re-sends against packet loss every
  ``alert_repeat_s`` for ``REPEAT_WINDOW_S``).

What the others may call: :meth:`~AlertDuty.get` (a record), :meth:`~AlertDuty.receive`,
:meth:`~AlertDuty.detect`, :meth:`~AlertDuty.sightings`, :meth:`~AlertDuty.publish`,
:meth:`~AlertDuty.send`, :meth:`~AlertDuty.repeat`, :meth:`~AlertDuty.prune`,
:meth:`~AlertDuty.counts_due` and :meth:`~AlertDuty.take_outbox`. It returns its events, in
order, for the caller to log; an alert renamed (an earlier report of the same site replaced
it) is returned too, for the UAV's own record.
Times are vehicle seconds, positions complex north + i east metres.
"""

from __future__ import annotations

from dataclasses import dataclass

from companion.agent.alerts.book import REPEAT_WINDOW_S, AlertBook
from companion.agent.alerts.contacts import TRACK_UPDATE_S, Contact, Contacts
from companion.agent.alerts.lifecycle import OPEN
from companion.agent.alerts.record import AlertRecord
from companion.agent.config import AgentConfig
from companion.agent.events import AgentEvent, Sighted
from companion.group.messages import Alert, Track

Events = list[AgentEvent]
Renamed = tuple[str, str] | None  # (old id, new id): an earlier report replaced the record


@dataclass(frozen=True)
class Sightings:
    """What one batch of its own sightings did (:meth:`AlertDuty.sightings`).

    Attributes:
        events: the events, in order (alerts raised, passes ended).
        renamed: the alerts renamed, in order (old id, new id).
        seen: the contact of the alert this UAV is away for, if the batch saw it.
    """

    events: tuple[AgentEvent, ...]
    renamed: tuple[tuple[str, str], ...]
    seen: Contact | None


NO_SIGHTINGS = Sightings((), (), None)


class AlertDuty:
    """One companion's alerts: its contacts, the book, the next alert id, the outbox.

    Args:
        sysid: this UAV's system id (its alerts' ids are ``"<sysid>-<n>"``).
        sensor_m: the sensor footprint radius (m).
        config: the companion's options (``alert_repeat_s``, ``max_open_alerts``,
            ``merge_hold_s``).
    """

    def __init__(self, sysid: int, sensor_m: float, config: AgentConfig) -> None:
        """No alert known, no sighting yet."""
        self.sysid = int(sysid)
        self.repeat_s = config.alert_repeat_s
        self.book = AlertBook(
            sensor_m,
            sysid=self.sysid,
            max_open=config.max_open_alerts,
            merge_hold_s=config.merge_hold_s,
        )
        self._contacts = Contacts(2.0 * sensor_m)  # its own sightings, by intruder
        self._seq = 0
        self._detections: list[tuple[complex, float]] = []
        self._outbox: list[Alert] = []

    @property
    def records(self) -> dict[str, AlertRecord]:
        """The open and recently finished alerts, by id."""
        return self.book.records

    @property
    def counts(self) -> dict[str, int]:
        """The book's counts (:data:`companion.agent.alerts.book.ALERT_COUNTERS`)."""
        return self.book.counts

    def get(self, alert_id: str) -> AlertRecord | None:
        """The record of ``alert_id``, None if it is not (or no longer) kept."""
        return self.book.records.get(alert_id)

    # ---- in -------------------------------------------------------------------------------
    def receive(self, alert: Alert, t_s: float) -> tuple[Renamed, Events]:
        """An alert message from the group, received at ``t_s`` (s): the renaming it made,
        and the events."""
        return self._apply(alert, t_s, own=False)

    def detect(self, site_m: complex, t_s: float) -> None:
        """The own sensor covers an intruder at ``site_m`` (m) at ``t_s`` (s): kept for the
        next :meth:`sightings`."""
        self._detections.append((complex(site_m), float(t_s)))

    def sightings(self, t_s: float, own_id: str | None) -> Sightings:
        """Every sighting since the last call, at ``t_s`` (s): the contact it belongs to
        refines its alert's track or raises a new alert; ``own_id``: the alert this UAV is
        away for (None on patrol), whose contact seen is returned."""
        if not self._detections and not self._contacts.items:
            return NO_SIGHTINGS  # the usual step: nothing seen, no contact open
        detections, self._detections = self._detections, []
        events: Events = []
        renames: list[tuple[str, str]] = []
        seen: Contact | None = None
        for site, t_seen in detections:
            contact = self._contacts.find(t_seen, site)
            if contact is None:
                # an alert another contact under the sensor holds is that intruder's
                one = Track(t_seen, site)  # one sighting: its own error
                live = self._contacts.live_alerts(t_seen)
                twin = self.book.twin(site, t_seen, one, live)
                prior = twin.track if twin is not None and twin.status in OPEN else None
                if twin is None and own_id is not None and own_id not in live:
                    # the intruder it is away for, off its prediction (turned): its own fit
                    twin = self.book.sought(own_id, site, t_seen)
                contact = self._contacts.open(t_seen, site, prior)
                if twin is not None:
                    contact.alert_id = twin.alert.alert_id
                elif (renamed := self._raise_alert(contact, t_s, events)) is not None:
                    renames.append(renamed)
                    own_id = renamed[1] if own_id == renamed[0] else own_id
            else:
                self._contacts.see(contact, t_seen, site)
            rec = self.get(contact.alert_id) if contact.alert_id else None
            if rec is not None and rec.status in OPEN:
                rec.update_track(contact.track())
            if own_id is not None and contact.alert_id == own_id:
                seen = contact
        for contact in self._contacts.items:
            if contact.unsent() and t_s - contact.sent_t_s >= TRACK_UPDATE_S:
                self._send_track(contact, t_s)
        for contact in self._contacts.expire(t_s):
            if contact.unsent():
                self._send_track(contact, t_s)
            events += self._passed(contact, t_s)
        return Sightings(tuple(events), tuple(renames), seen)

    # ---- out ------------------------------------------------------------------------------
    def publish(self, alert: Alert, t_s: float, rec: AlertRecord | None) -> tuple[Renamed, Events]:
        """Send this UAV's own answer ``alert`` at ``t_s`` (s) (confirmed, cleared, lost) on
        the record ``rec`` it answers (its re-sends count from now): taken into the book and
        queued. Returns the renaming it made, and the events."""
        out = self._apply(alert, t_s, own=True)
        if rec is not None:
            rec.rebroadcast_s = t_s
        self._outbox.append(alert)
        return out

    def send(self, alerts: tuple[Alert, ...]) -> None:
        """Queue alert messages (bids) for the group."""
        self._outbox.extend(alerts)

    def repeat(self, t_s: float) -> None:
        """Re-send the alerts this UAV reported, confirmed or cleared, against packet loss."""
        for rec in self.book.records.values():
            a = rec.alert
            if a.detector_sysid != self.sysid or a.state in ("bid", "update"):
                continue
            if t_s - a.t_s > REPEAT_WINDOW_S or t_s - rec.rebroadcast_s < self.repeat_s:
                continue
            rec.rebroadcast_s = t_s
            if a not in self._outbox:
                self._outbox.append(a)

    def prune(self, t_s: float, keep_id: str | None) -> None:
        """Forget the finished alerts no longer needed at ``t_s`` (s), but ``keep_id`` (the
        one this UAV is away for): :meth:`AlertBook.prune`."""
        self.book.prune(t_s, keep_id=keep_id)

    def counts_due(self, t_s: float) -> Events:
        """The ``alert_counts`` event when due at ``t_s`` (s): :meth:`AlertBook.counts_due`."""
        return self.book.counts_due(t_s)

    def take_outbox(self) -> tuple[Alert, ...]:
        """The alert messages queued since the last call, in order."""
        out, self._outbox = tuple(self._outbox), []
        return out

    # ---- inside ---------------------------------------------------------------------------
    def _apply(self, alert: Alert, t_s: float, own: bool) -> tuple[Renamed, Events]:
        renamed, events = self.book.apply(alert, t_s, own)
        if renamed is not None:
            self._contacts.rename(*renamed)
        return renamed, events

    def _raise_alert(self, contact: Contact, t_s: float, events: Events) -> Renamed:
        """A new alert for ``contact``: its first sighting's track (its events into
        ``events``; the renaming it made returned)."""
        track = contact.track()
        self._seq += 1
        alert_id = f"{self.sysid}-{self._seq}"
        alert = Alert(alert_id, track.pos_m, self.sysid, track.t_s, "new", track=track)
        contact.alert_id = alert_id
        contact.sent_t_s, contact.sent_sightings = t_s, len(contact.fit)
        renamed, more = self._apply(alert, t_s, own=True)
        events += more
        self._outbox.append(alert)
        return renamed

    def _passed(self, contact: Contact, t_s: float) -> Events:
        """A ``sighted`` event for a contact that has left the footprint."""
        if contact.alert_id is None:
            return []
        track = contact.track()
        return [
            Sighted(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=contact.alert_id,
                first_t_s=round(contact.first_t_s, 3),
                sightings=len(contact.fit),
                north_m=round(track.pos_m.real, 2),
                east_m=round(track.pos_m.imag, 2),
                speed_m_s=round(abs(track.vel_m_s), 2),
                sigma_m=round(track.pos_sigma_m, 2),
            )
        ]

    def _send_track(self, contact: Contact, t_s: float) -> None:
        """Share ``contact``'s track as an update of its alert (if that is still open)."""
        contact.sent_t_s, contact.sent_sightings = t_s, len(contact.fit)
        rec = self.get(contact.alert_id) if contact.alert_id else None
        if rec is None or rec.status not in OPEN:
            return
        track = contact.track()
        update = Alert(
            rec.alert.alert_id, track.pos_m, self.sysid, track.t_s, "update", track=track
        )
        self._outbox.append(update)
