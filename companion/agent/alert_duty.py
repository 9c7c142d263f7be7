"""The Agent's alert duty (pure): what one companion does about intruders, as methods of
:class:`companion.agent.agent.Agent` kept apart from the formation and the step.

Its own sightings (contacts, alerts raised, tracks shared, the alert book), the prosecution
it flies (:mod:`companion.agent.alerts.prosecution`) and the tracking
(:mod:`companion.agent.alerts.tracker`). A mixin: every attribute it uses is set in
``Agent.__init__``; nothing here holds state of its own.
"""

from __future__ import annotations

from companion.agent.alerts.book import REPEAT_WINDOW_S
from companion.agent.alerts.contacts import TRACK_UPDATE_S, Contact
from companion.agent.alerts.lifecycle import OPEN, AlertStatus
from companion.agent.alerts.prosecution import Prosecution, keeps_it
from companion.agent.alerts.record import AlertRecord
from companion.agent.alerts.tracker import Tracker
from companion.agent.away import Away
from companion.agent.events import (
    Rejoined,
    Sighted,
    TrackerEnded,
)
from companion.agent.modes import ModeEvent, OwnMode
from companion.group.messages import Alert, Track
from companion.guidance.virtual import VirtualParticle

SEARCH_REVISITS = 2.0  # a search lasts at most this many T/N


class AlertDuty:
    """Sightings, alerts, prosecution and tracking: the Agent's methods for intruders."""

    # ---- alerts ---------------------------------------------------------------------------
    def _handle_detections(self, t_s: float, pos_m: complex) -> None:
        """Every sighting since the last update, in every mode: the contact it belongs to
        refines its alert's track or raises a new alert; the alert this UAV flies to or
        tracks, seen, ends the prosecution or keeps the track fresh."""
        detections, self._detections = self._detections, []
        seen: Contact | None = None
        for site, t_seen in detections:
            contact = self._contacts.find(t_seen, site)
            if contact is None:
                # an alert another contact under the sensor holds is that intruder's
                one = Track(t_seen, site)  # one sighting: its own error
                twin = self.book.twin(site, t_seen, one, self._contacts.live_alerts(t_seen))
                prior = twin.track if twin is not None and twin.status in OPEN else None
                contact = self._contacts.open(t_seen, site, prior)
                if twin is not None:
                    contact.alert_id = twin.alert.alert_id
                else:
                    self._raise_alert(contact, t_s)
            else:
                self._contacts.see(contact, t_seen, site)
            rec = self.alerts.get(contact.alert_id) if contact.alert_id else None
            if rec is not None and rec.status in OPEN:
                rec.update_track(contact.track())
            if self.away is not None and contact.alert_id == self.away.alert_id:
                seen = contact
        for contact in self._contacts.items:
            if contact.unsent() and t_s - contact.sent_t_s >= TRACK_UPDATE_S:
                self._send_track(contact, t_s)
        for contact in self._contacts.expire(t_s):
            if contact.unsent():
                self._send_track(contact, t_s)
            self._log_pass(contact, t_s)
        if seen is not None and self._mode.prosecuting:
            self._seen(t_s, seen)

    def _raise_alert(self, contact: Contact, t_s: float) -> None:
        """A new alert for ``contact``: its first sighting's track."""
        track = contact.track()
        self._seq += 1
        alert_id = f"{self.sysid}-{self._seq}"
        alert = Alert(alert_id, track.pos_m, self.sysid, track.t_s, "new", track=track)
        contact.alert_id = alert_id
        contact.sent_t_s, contact.sent_sightings = t_s, len(contact.fit)
        self._apply_alert(alert, t_s, own=True)
        self._outbox.append(alert)

    def _log_pass(self, contact: Contact, t_s: float) -> None:
        """A ``sighted`` event for a contact that has left the footprint."""
        if contact.alert_id is None:
            return
        track = contact.track()
        self._log(
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
        )

    def _send_track(self, contact: Contact, t_s: float) -> None:
        """Share ``contact``'s track as an update of its alert (if that is still open)."""
        contact.sent_t_s, contact.sent_sightings = t_s, len(contact.fit)
        rec = self.alerts.get(contact.alert_id) if contact.alert_id else None
        if rec is None or rec.status not in OPEN:
            return
        track = contact.track()
        update = Alert(
            rec.alert.alert_id, track.pos_m, self.sysid, track.t_s, "update", track=track
        )
        self._outbox.append(update)

    def _apply_alert(self, alert: Alert, t_s: float, own: bool) -> None:
        renamed = self.book.apply(alert, t_s, own)
        if renamed is not None:
            self._contacts.rename(*renamed)
            if self.away is not None and self.away.alert_id == renamed[0]:
                self.away.alert_id = renamed[1]  # an earlier report of the site we fly to

    def _repeat_alerts(self, t_s: float) -> None:
        """Re-send the alerts this UAV reported, confirmed or cleared, against packet loss."""
        for rec in self.alerts.values():
            a = rec.alert
            if a.detector_sysid != self.sysid or a.state in ("bid", "update"):
                continue
            if t_s - a.t_s > REPEAT_WINDOW_S or t_s - rec.rebroadcast_s < self.alert_repeat_s:
                continue
            rec.rebroadcast_s = t_s
            if a not in self._outbox:
                self._outbox.append(a)

    # ---- prosecution (companion/agent/alerts/prosecution.py) ---------------------------
    def _start_prosecution(self, t_s, rec: AlertRecord, pos_m, heading_rad, phase) -> None:
        vp = VirtualParticle(phase, t_s, self.patrol.period_s)
        self.away = Away(rec.alert.alert_id, rec.alert.site_m, vp)
        self._note_on_loop(t_s, pos_m)
        self._prosecution = Prosecution(
            self.away,
            sysid=self.sysid,
            max_u=self.max_u,
            sensor_m=self.sensor_m,
            replan_s=self.replan_s,
            hold_s=self.hold_s,
            # bounded by the formation's revisit too: a search longer than a couple of T/N
            # costs the perimeter more than it can find
            search_max_s=min(
                self.search_max_s,
                SEARCH_REVISITS * self.patrol.period_s / self.mission.vehicles.count,
            ),
        )
        self._on(ModeEvent.TASKED, t_s)
        self._log_all(self._prosecution.start(self.patrol, t_s, pos_m, heading_rad, _track_of(rec)))

    def _prosecute(
        self, t_s: float, pos_m: complex, heading_rad: float, centre: complex, phase: float
    ) -> float | None:
        """The intercept's or the search's turn rate (rad/s), or None once it ended here;
        while the site is checked from the loop, the patrol's command."""
        pros = self._prosecution
        rec = self.alerts.get(pros.alert_id)
        if rec is None or rec.status is AlertStatus.DONE:
            # cleared by someone else while we fly to it (the operator's cancel, detector
            # 255, or another UAV that checked the site): nothing left to do there
            by = rec.alert.detector_sysid if rec is not None else 0
            self._log_all(pros.cancel(t_s, by))
            self._on(ModeEvent.ENDED, t_s)
            return None
        others = [s for s, a in self._heard.prosecuting() if a == pros.alert_id]
        keeper = keeps_it(self.sysid, others)
        if keeper is not None:  # two UAVs on one alert: the other keeps it, this one rejoins
            self._log_all(pros.yield_to(t_s, keeper))
            rec.seen_under_way(keeper)
            self._on(ModeEvent.ENDED, t_s)
            return None
        self._note_on_loop(t_s, pos_m)
        searching = self._mode is OwnMode.SEARCHING
        loop_u = 0.0
        if self.away.check_phase_rad is not None:
            loop_u = self._patrol_command(t_s, pos_m, heading_rad, centre, phase)
        u, events, began = pros.step(
            self.patrol, t_s, pos_m, heading_rad, _track_of(rec), rec.alert.t_s, searching,
            loop_u,
        )  # fmt: skip
        self._log_all(events)
        if began:
            self._on(ModeEvent.PATH_FLOWN, t_s)
        if u is None:  # flown (and searched) and not seen: clear
            self._end_prosecution(t_s, None)
        return u

    def _note_on_loop(self, t_s: float, pos_m: complex) -> None:
        """While it prosecutes, where its sensor last reached the loop before it first flew
        out of reach of it: the end of the stretch it swept, which it flies back to if that
        is quicker for the perimeter (:mod:`companion.agent.rejoin`). A later pass near the
        loop elsewhere (a search) does not move it: the stretch after it is still unseen."""
        away = self.away
        if away.off_loop:
            return
        phase, off_m = self.patrol.phase_and_offset_of_point(pos_m)
        if off_m <= self.sensor_m:
            away.left_loop_t_s, away.left_loop_phase_rad = t_s, phase
        else:
            away.off_loop = True

    def _seen(self, t_s: float, contact: Contact) -> None:
        """This UAV's sensor sees the intruder it flies to: track it or hand it on."""
        self._end_prosecution(t_s, contact.track())

    def _end_prosecution(self, t_s: float, seen: Track | None) -> None:
        """The prosecution ends at ``t_s`` (s): ``seen`` (the track of the sighting) under
        policy "track" makes this UAV the tracker, under "chain" a confirmation; not seen,
        the alert is cleared, or lost where the sensor could not cover the prediction's
        region (:meth:`Prosecution.not_found`). Then the rejoin (or the tracking) starts."""
        pros = self._prosecution
        rec = self.alerts.get(pros.alert_id)
        alert_t = rec.alert.t_s if rec else None
        if seen is not None and self.on_confirm == "track":
            self._log_all(pros.end(t_s, seen.pos_m, alert_t, "tracking"))
            if rec is not None and rec.status is not AlertStatus.TRACKED:
                rec.tracked_by(self.sysid)
            self._tracker = Tracker(
                self.away,
                t_s,
                max_u=self.max_u,
                replan_s=self.replan_s,
                hold_s=self.hold_s,
                fence=self.mission.fence.fence if self.mission.fence is not None else None,
                lost_s=self.track_lost_s,
            )
            self.away.plan = None
            self.away.left_loop_t_s = None  # the formation re-splays without it
            self._prosecution = None
            self._on(ModeEvent.TRACKER, t_s)
            return
        if seen is not None:
            outcome = "confirmed"
        else:
            outcome = pros.not_found(t_s)
        self._log_all(pros.end(t_s, None if seen is None else seen.pos_m, alert_t, outcome))
        if seen is not None:
            alert = Alert(pros.alert_id, seen.pos_m, self.sysid, seen.t_s, "confirmed", track=seen)
        else:
            site = rec.predict(t_s) if rec is not None else pros.site_m
            # says what was looked at, so receivers finish only the other alerts expected there
            alert = Alert(pros.alert_id, site, self.sysid, t_s, outcome, track=checked(rec, t_s))
        self._on(ModeEvent.ENDED, t_s)
        self._apply_alert(alert, t_s, own=True)
        if rec is not None:
            rec.rebroadcast_s = t_s
        self._outbox.append(alert)
        if self.rejoin == "direct":
            self._log(
                Rejoined(
                    t_s=t_s, sysid=self.sysid, alert_id=pros.alert_id, in_slot=False, rejoin_s=0.0
                )
            )
            self._on(ModeEvent.HANDED_BACK, t_s)

    # ---- tracking (companion/agent/alerts/tracker.py) -----------------------------------
    def _track(self, t_s: float, pos_m: complex, heading_rad: float) -> float | None:
        """The tracker's turn rate (rad/s), or None once it stopped here (rejoining)."""
        tracker = self._tracker
        rec = self.alerts.get(self.away.alert_id)
        done = rec is None or rec.status is AlertStatus.DONE
        track = _track_of(rec) if rec is not None else None
        why = "released" if track is None else tracker.why_stop(self.patrol, t_s, track, done)
        if why is None:
            return tracker.step(self.patrol, t_s, pos_m, heading_rad, track)
        self._log(
            TrackerEnded(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=self.away.alert_id,
                reason=why,
                tracked_s=round(t_s - tracker.t0_s, 3),
            )
        )
        if why != "released":
            lost = Alert(self.away.alert_id, track.predict(t_s), self.sysid, t_s, "lost")
            self._apply_alert(lost, t_s, own=True)
            if rec is not None:
                rec.rebroadcast_s = t_s
            self._outbox.append(lost)
        # its new slot is where it joins the loop: the formation, splayed as N - 1 without
        # it, makes room for it as soon as it shares a virtual particle again
        here = float(self.patrol.phase_of_point(pos_m))
        self.away.virtual = VirtualParticle(here, t_s, self.patrol.period_s)
        self._on(ModeEvent.TRACK_ENDED, t_s)
        return None


def _track_of(rec: AlertRecord) -> Track:
    """The track to fly for ``rec``: its newest, or its site as a still intruder with no
    uncertainty (an operator's alert)."""
    if rec.track is not None:
        return rec.track
    return Track(rec.alert.t_s, rec.alert.site_m, 0j, 0.0, 0.0, 0)


def checked(rec: AlertRecord | None, t_s: float) -> Track | None:
    """What a "cleared" or "lost" message says was looked for at ``t_s`` (s): ``rec``'s sensor track
    predicted to then (its position, velocity and their sigmas), so a receiver finishes only
    the other alerts expected within that prediction's gate; None for a point (no sensor
    track). Stamped ``t_s``, so no receiver refuses it as old."""
    if rec is None or rec.track is None or rec.track.sightings <= 0:
        return None
    tr = rec.track
    return Track(t_s, tr.predict(t_s), tr.vel_m_s, tr.sigma_m(t_s), tr.vel_sigma_m_s, tr.sightings)
