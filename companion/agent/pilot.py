"""What one UAV flies, by its own mode (pure): a component of
:class:`companion.agent.agent.Agent`.

A :class:`Pilot` holds the own mode and that mode's record (:class:`~companion.agent.away.OwnState`)
and flies the mode's handler, picked from a table keyed by :class:`~companion.agent.modes.OwnMode`:

================= ===========================================================================
mode              handler
================= ===========================================================================
patrol            the time-splay law and the phase-holding airspeed (:mod:`~.splay`)
prosecuting       the intercept (:class:`~companion.agent.alerts.prosecution.Prosecution`)
searching         the search of the track's uncertainty (the same)
tracking          the passes over its intruder (:class:`~companion.agent.alerts.tracker.Tracker`)
rejoin_to_loop    back onto the loop, then along it (:func:`~companion.agent.rejoin.rejoin_step`)
rejoin_along_loop the slot recovered along the loop by the airspeed (the same)
================= ===========================================================================

A handler that ends its mode changes it (the table, :data:`~companion.agent.modes.MODE_TABLE`)
and returns None: the next mode's handler flies the same step, so the UAV that ends a
prosecution flies the first step of its tracking or its rejoin at once, and one handed back
flies the splay. Every transition is made by :meth:`Pilot._change` with the entered mode's
record, made from what carries over (:mod:`companion.agent.away`).

The prosecution's end (docs/design.md §5): seen, under ``on_confirm="track"`` the prosecutor
stays over its intruder, under "chain" (the paper's) it confirms and the next UAV takes the
alert; not seen, the alert is cleared, or lost where the sensor could not cover the
prediction's region. A search lasts at most ``SEARCH_REVISITS`` ideal revisit times T/N.
Every method returns its events, in order, for the caller to log. Times are vehicle seconds,
positions complex north + i east metres, angles radians.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar, NamedTuple, Protocol

from companion.agent.alerts.contacts import Contact
from companion.agent.alerts.lifecycle import AlertStatus
from companion.agent.alerts.prosecution import Prosecution, keeps_it
from companion.agent.alerts.record import AlertRecord
from companion.agent.alerts.tracker import Tracker
from companion.agent.away import (
    AwayRecord,
    OwnState,
    Prosecuting,
    Rejoining,
    Searching,
    Tracking,
)
from companion.agent.config import AgentConfig
from companion.agent.events import AgentEvent, Rejoined, TrackerEnded
from companion.agent.fix import Fix
from companion.agent.modes import ModeEvent, OwnMode
from companion.agent.neighbours import Neighbours
from companion.agent.rejoin import (
    TRACKING_WINDOW_PERIODS,
    RejoinContext,
    TrackingAccuracy,
    rejoin_airspeed,
    rejoin_step,
)
from companion.agent.splay import Splay
from companion.group.messages import Alert, Mode, Track
from companion.guidance.virtual import VirtualParticle
from companion.mission import Mission

SEARCH_REVISITS = 2.0  # a search lasts at most this many T/N
Events = list[AgentEvent]


class Alerts(Protocol):
    """What the pilot may call on the alerts it knows
    (:class:`companion.agent.alert_duty.AlertDuty`): read a record, publish its answer."""

    def get(self, alert_id: str) -> AlertRecord | None:
        """The record of ``alert_id``, None if it is not kept."""
        ...

    def publish(
        self, alert: Alert, t_s: float, rec: AlertRecord | None
    ) -> tuple[tuple[str, str] | None, list[AgentEvent]]:
        """Send its own answer ``alert`` on ``rec`` at ``t_s`` (s): the renaming it made
        (old id, new id) or None, and the events."""
        ...


class Flight(NamedTuple):
    """What a handler flies: the turn rate (rad/s) and the airspeed (m/s)."""

    turn_rate_rad_s: float
    airspeed_m_s: float


class Pilot:
    """The own mode, its record and its handlers.

    Args:
        sysid: this UAV's system id.
        mission: the mission (vehicles, sensor, fence, loop).
        config: the companion's options.
        alerts: the alerts it knows (records read, its answers published).
        heard: the members heard (who else prosecutes its alert, the formation's size).
        splay: the patrol's steering (flown on patrol and while checking a site from the
            loop).
    """

    def __init__(
        self,
        sysid: int,
        mission: Mission,
        config: AgentConfig,
        alerts: Alerts,
        heard: Neighbours,
        splay: Splay,
    ) -> None:
        """On patrol."""
        self.sysid = int(sysid)
        self.config = config
        self.members = mission.vehicles.count
        self.sensor_m = mission.sensor.footprint_radius_m
        self.alerts = alerts
        self.heard = heard
        self.splay = splay
        self.state = OwnState()  # changed only by _change (companion.agent.away)
        max_u = mission.vehicles.max_turn_rate_rad_s
        fence = mission.fence.fence if mission.fence is not None else None
        self.prosecution = Prosecution(
            sysid=self.sysid,
            max_u=max_u,
            sensor_m=self.sensor_m,
            replan_s=config.replan_s,
            hold_s=config.hold_s,
            fence=fence,
        )
        self.tracker = Tracker(
            max_u=max_u,
            replan_s=config.replan_s,
            hold_s=config.hold_s,
            fence=fence,
            lost_s=config.track_lost_s,
        )
        # its own centre error on patrol: the rejoin's slot tolerance follows it
        self.tracking = TrackingAccuracy(TRACKING_WINDOW_PERIODS * mission.patrol.period_s)

    @property
    def away(self) -> AwayRecord | None:
        """The record of the mode it is in (:mod:`companion.agent.away`), None on patrol."""
        return self.state.record

    def observe(self, fix: Fix) -> None:
        """A new fix: on patrol, its centre error measures how well it tracks the loop."""
        if self.state.mode is OwnMode.PATROL:
            self.tracking.add(fix.t_s, abs(fix.centre_m - fix.patrol.centre_m))

    def rename(self, old_id: str, new_id: str) -> None:
        """An earlier report of the same site replaced alert ``old_id`` by ``new_id``: the
        alert it is away for follows."""
        away = self.state.record
        if away is not None and away.alert_id == old_id:
            away.alert_id = new_id

    def sharing(self, fix: Fix) -> tuple[complex, float, Mode, str]:
        """What it shares at ``fix``: centre (m), time-phase (rad), mode and alert id. Its real
        state on patrol and while tracking (out of the formation); its virtual particle, at
        the loop's centre, while it prosecutes or rejoins."""
        away = self.state.record
        if away is None:
            return fix.centre_m, fix.phase_rad, Mode.PATROL, ""
        if isinstance(away, Tracking):
            return fix.centre_m, fix.phase_rad, Mode.TRACKING, away.alert_id
        mode = self.state.mode.shared
        return fix.patrol.centre_m, away.virtual.phase(fix.t_s), mode, away.alert_id

    # ---- transitions ----------------------------------------------------------------------
    def start(self, fix: Fix, rec: AlertRecord) -> Events:
        """This UAV tasked itself with ``rec`` at ``fix``: prosecuting, its first plan."""
        patrol = fix.patrol
        away = Prosecuting(
            rec.alert.alert_id,
            rec.alert.site_m,
            VirtualParticle(fix.phase_rad, fix.t_s, patrol.period_s),
            # bounded by the formation's revisit too: a search longer than a couple of T/N
            # costs the perimeter more than it can find
            search_max_s=min(
                self.config.search_max_s, SEARCH_REVISITS * patrol.period_s / self.members
            ),
        )
        away.left.note(fix, self.sensor_m)
        self._change(ModeEvent.TASKED, away)
        return self.prosecution.start(away, fix, track_of(rec))

    def seen(self, fix: Fix, contact: Contact) -> Events:
        """Its sensor sees the intruder of the alert it is away for (``contact``: its own
        sightings of it): while prosecuting, the prosecution ends seen, on the contact's
        track; else nothing."""
        events: Events = []
        if self.state.mode.prosecuting:
            self._end(fix, contact.track(), events)
        return events

    def _change(self, event: ModeEvent, away: AwayRecord | None) -> None:
        """The one place the own mode changes: by ``event`` along the table, to the entered
        mode's record ``away`` (:meth:`companion.agent.away.OwnState.change`)."""
        self.state.change(event, away)

    # ---- the step -------------------------------------------------------------------------
    def fly(self, fix: Fix) -> tuple[Flight, Events]:
        """The mode's handler at ``fix``, and the next mode's while a handler ends its mode:
        what to fly and the events."""
        events: Events = []
        handlers, state = self._HANDLERS, self.state
        for _ in range(len(handlers)):  # a handler flies, or moves the mode on towards patrol
            flight = handlers[state.mode](self, fix, events)
            if flight is not None:
                return flight, events
        raise RuntimeError(f"no handler flew in mode {state.mode.value!r}")

    def _patrol(self, fix: Fix, events: Events) -> Flight:
        """On patrol (or just handed back): the splay."""
        return Flight(self.splay.command(fix), self.splay.airspeed(fix))

    def _prosecute(self, fix: Fix, events: Events) -> Flight | None:
        """The intercept's turn rate; while the site is checked from the loop, the splay's.
        None once the prosecution ended here."""
        away = self.state.record
        assert isinstance(away, Prosecuting)
        rec = self._still_ours(fix, away, events)
        if rec is None:
            return None
        away.left.note(fix, self.sensor_m)
        loop_u = self.splay.command(fix) if away.check_phase_rad is not None else 0.0
        u, more, search = self.prosecution.step(away, fix, track_of(rec), rec.alert.t_s, loop_u)
        events += more
        if search is not None:  # the path flown and the intruder not seen: search for it
            searching = Searching.begin(away, search)
            self._change(ModeEvent.PATH_FLOWN, searching)
            u = self.prosecution.search_step(searching, fix)
        if u is None:  # flown (and searched) and not seen: clear
            self._end(fix, None, events)
            return None
        return Flight(u, fix.patrol.airspeed_m_s)

    def _search(self, fix: Fix, events: Events) -> Flight | None:
        """The search's turn rate, or None once the prosecution ended here."""
        away = self.state.record
        assert isinstance(away, Searching)
        rec = self._still_ours(fix, away, events)
        if rec is None:
            return None
        away.left.note(fix, self.sensor_m)
        u, more = self.prosecution.search(away, fix, track_of(rec), rec.alert.t_s)
        events += more
        if u is None:  # searched and not seen: clear
            self._end(fix, None, events)
            return None
        return Flight(u, fix.patrol.airspeed_m_s)

    def _still_ours(
        self, fix: Fix, away: Prosecuting | Searching, events: Events
    ) -> AlertRecord | None:
        """The record of the alert it prosecutes, or None once the prosecution ended: the
        alert cleared by someone else (the operator's cancel, detector 255, or another UAV
        that checked the site), or another UAV on it that keeps it (this one rejoins)."""
        rec = self.alerts.get(away.alert_id)
        if rec is None or rec.status is AlertStatus.DONE:
            by = rec.alert.detector_sysid if rec is not None else 0
            events += self.prosecution.cancel(away, fix.t_s, by)
            self._change(ModeEvent.ENDED, Rejoining.after(away, fix.t_s))
            return None
        others = [s for s, a in self.heard.prosecuting() if a == away.alert_id]
        keeper = keeps_it(self.sysid, others)
        if keeper is not None:
            events += self.prosecution.yield_to(away, fix.t_s, keeper)
            rec.seen_under_way(keeper)
            self._change(ModeEvent.ENDED, Rejoining.after(away, fix.t_s))
            return None
        return rec

    def _end(self, fix: Fix, seen: Track | None, events: Events) -> None:
        """The prosecution ends at ``fix``: ``seen`` (the track of the sighting) under
        policy "track" makes this UAV the tracker, under "chain" a confirmation; not seen,
        the alert is cleared, or lost where the sensor could not cover the prediction's
        region (:meth:`Prosecution.not_found`). Then the rejoin (or the tracking) starts."""
        away = self.state.record
        assert isinstance(away, Prosecuting | Searching)
        t_s, pros = fix.t_s, self.prosecution
        rec = self.alerts.get(away.alert_id)
        alert_t = rec.alert.t_s if rec else None
        if seen is not None and self.config.on_confirm == "track":
            events += pros.end(away, t_s, seen.pos_m, alert_t, "tracking")
            if rec is not None and rec.status is not AlertStatus.TRACKED:
                rec.tracked_by(self.sysid)
            self._change(ModeEvent.TRACKER, Tracking.begin(away, t_s))
            return
        outcome = "confirmed" if seen is not None else pros.not_found(away, t_s)
        events += pros.end(away, t_s, None if seen is None else seen.pos_m, alert_t, outcome)
        if seen is not None:
            alert = Alert(away.alert_id, seen.pos_m, self.sysid, seen.t_s, "confirmed", track=seen)
        else:
            site = rec.predict(t_s) if rec is not None else away.site_m
            # says what was looked at, so receivers finish only the other alerts expected there
            alert = Alert(away.alert_id, site, self.sysid, t_s, outcome, track=checked(rec, t_s))
        rejoining = Rejoining.after(away, t_s)
        self._change(ModeEvent.ENDED, rejoining)
        self._publish(alert, t_s, rec, events)
        if self.config.rejoin == "direct":
            events.append(
                Rejoined(
                    t_s=t_s,
                    sysid=self.sysid,
                    alert_id=rejoining.alert_id,
                    in_slot=False,
                    rejoin_s=0.0,
                )
            )
            self._change(ModeEvent.HANDED_BACK, None)

    def _track(self, fix: Fix, events: Events) -> Flight | None:
        """The tracker's turn rate, or None once it stopped here (rejoining)."""
        away = self.state.record
        assert isinstance(away, Tracking)
        t_s = fix.t_s
        rec = self.alerts.get(away.alert_id)
        done = rec is None or rec.status is AlertStatus.DONE
        track = track_of(rec) if rec is not None else None
        why = "released"  # without a track
        if track is not None:
            stop = self.tracker.why_stop(fix, track, done)
            if stop is None:
                return Flight(self.tracker.step(away, fix, track), fix.patrol.airspeed_m_s)
            why = stop
        events.append(
            TrackerEnded(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=away.alert_id,
                reason=why,
                tracked_s=round(t_s - away.t0_s, 3),
            )
        )
        if track is not None and why != "released":  # released: there is no track
            lost = Alert(away.alert_id, track.predict(t_s), self.sysid, t_s, "lost")
            self._publish(lost, t_s, rec, events)
        # its new slot is where it joins the loop: the formation, splayed as N - 1 without
        # it, makes room for it as soon as it shares a virtual particle again
        here = float(fix.loop_phase_rad)
        rejoining = Rejoining.after_tracking(away, here, t_s, fix.patrol.period_s)
        self._change(ModeEvent.TRACK_ENDED, rejoining)
        return None

    def _rejoin(self, fix: Fix, events: Events) -> Flight | None:
        """The rejoin's turn rate and airspeed, or None once the real state is handed back."""
        away = self.state.record
        assert isinstance(away, Rejoining)
        patrol = fix.patrol
        ctx = RejoinContext(
            patrol,
            self.splay.gains,
            self.splay.max_u,
            self.sensor_m,
            self.config.replan_s,
            tracking_p95_m=self.tracking.p95_m(),
            hold_s=self.config.hold_s,
            sysid=self.sysid,
            revisit_s=patrol.period_s / (1 + self.heard.in_formation()),
        )
        u, more, changes = rejoin_step(ctx, away, fix)
        events += more
        for change in changes:
            self._change(change, away.on_loop() if change is ModeEvent.ON_LOOP else None)
        if u is None:
            return None
        airspeed = patrol.airspeed_m_s
        along = self.state.record
        if isinstance(along, Rejoining) and along.to_loop is None:
            airspeed = rejoin_airspeed(ctx, fix, along.virtual.phase(fix.t_s))
        return Flight(u, airspeed)

    def _publish(self, alert: Alert, t_s: float, rec: AlertRecord | None, events: Events) -> None:
        """Send its own answer ``alert`` on ``rec`` at ``t_s`` (s); a renaming it makes
        follows the alert it is away for."""
        renamed, more = self.alerts.publish(alert, t_s, rec)
        events += more
        if renamed is not None:
            self.rename(*renamed)

    _HANDLERS: ClassVar[dict[OwnMode, Callable[[Pilot, Fix, Events], Flight | None]]] = {
        OwnMode.PATROL: _patrol,
        OwnMode.PROSECUTING: _prosecute,
        OwnMode.SEARCHING: _search,
        OwnMode.TRACKING: _track,
        OwnMode.REJOIN_TO_LOOP: _rejoin,
        OwnMode.REJOIN_ALONG_LOOP: _rejoin,
    }


def track_of(rec: AlertRecord) -> Track:
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
    return rec.track.at(t_s)
