"""What the live patrol page shows, from the group's messages alone (pure: no I/O, no clock).

A :class:`FleetView` is fed every accepted :class:`~companion.group.messages.MemberState` and
:class:`~companion.group.messages.Alert` with the **wall time of receipt** (s, any monotonic
clock),
and :meth:`FleetView.snapshot` gives the JSON-ready picture at a wall time:

* vehicles: position (local metres from the mission origin), short trail, mode (patrol,
  prosecuting, rejoining, or lost = silent for ``member_timeout_s`` wall seconds), loop
  centre, time-phase, cross-track (distance from the loop);
* alerts: site, state (new, confirmed, cleared, lost), detector, prosecutor (the member that
  is or last was prosecuting it: derived from the members' states, mode prosecuting or
  searching with the alert's id), its tracker (mode tracking), every UAV that answered it,
  and its newest track (position and velocity at the track's time, sigma, age, and where it
  predicts the intruder now);
* stations: where each aircraft is as the formation counts it (:func:`station_of`): in the
  formation (patrol, prosecuting, searching, rejoining: the members the companions splay
  with, :data:`companion.group.messages.OUT_OF_FORMATION`), tracking (on station, out of the
  formation), a spare waiting (on the ground or holding), climbing out to relieve a member,
  going home, or lost;
* gauges over the formation only (spares, aircraft climbing out or going home and trackers
  are counted apart): splay error, the ideal revisit ``T/N``, the largest cross-track and
  centre error, and coverage (the longest time any loop point went unseen by a patrolling
  UAV's sensor disc over the last loop period, from the positions seen here); and the
  fastest crossing of the sensor band the patrol is sure to see
  (:mod:`companion.core.guarantee`): as planned (the mission's N, none away,
  ``crossing_sure_plan_m_s``) and now (the formation's members, those away among them,
  ``crossing_sure_m_s``; None: any speed, or no member);
* reliefs (a mission with a battery and spares; docs/energy.md): each member's battery (%),
  relief role and time to leave (on station) or to ready (a spare), the spares and their
  state, the reliefs under way, and the fleet's plan computed here exactly as the members
  compute it (:mod:`companion.agent.relief.roster`, :mod:`companion.agent.relief.schedule`)
  from the same shared states: who relieves whom, when it launches, when it holds the slot,
  and which reliefs will be late: one standing warning per member whose relief is predicted
  late, updated in place as the prediction changes (``warnings``), logged ``relief_late``
  once when it is first raised (before it is late) until that member leaves the station. A
  state under a sysid the mission does not list is shown as refused and never planned with;
* a bounded event log.

Positions. ``PATROL_STATE`` carries the loop centre ``c`` and the time-phase ``psi``, not the
position, until the real position is added to it (``MemberState.pos_m``). Without it a patrol
member's position is its loop point ``c + rho(gamma(psi))``, i.e. ``point_at_phase(psi) +
(c - c0)`` (exact for a UAV on its loop around its centre), and a member away (prosecuting
or rejoining) shares its *virtual particle*, so what is drawn is its slot on the loop, not
the aircraft; ``position_source`` says which. When a state carries ``pos_m`` it is used.

Times: ``t_s`` is vehicle time (the members' clocks, SYSTEM_TIME); silence and the order of
events are judged by receipt wall time, as the companions do (docs/design.md §7).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from companion.agent.relief.roster import Roster, plan_from
from companion.agent.relief.schedule import NoLaunchWatch, Plan
from companion.core.measures import splay_error_deg
from companion.core.wind import TWO_PI
from companion.dashboard.geometry import Geometry
from companion.group.messages import OUT_OF_FORMATION, Alert, Energy, MemberState, Mode, Track
from companion.mission import Mission

__all__ = ["MODES", "STATIONS", "FleetView", "Geometry", "station_of"]

MODES = (*Mode, "lost")  # what the page shows: the group's modes, and a member gone silent
PROSECUTING = (Mode.PROSECUTING, Mode.SEARCHING)  # flying to an alert
TRAIL_S = 20.0  # vehicle seconds of trail kept per UAV
TRAIL_STEP_S = 0.5  # at most one trail point per this many vehicle seconds
TRAIL_MAX = 200  # points per trail, whatever the clocks do
EVENTS_MAX = 500  # events kept
ALERTS_MAX = 200  # alerts kept (the oldest finished ones are forgotten first)
COVERAGE_POINTS = 360  # loop points watched for coverage
CROSS_TRACK_POINTS = 4096  # loop polyline used for cross-track distances
STATIONS = ("formation", "tracking", "spare", "climbing_out", "going_home", "lost")
SPARE_STATIONS = {  # a member out of the formation for the reliefs, by its relief role
    "spare": "spare",  # waiting on the ground or holding
    "unavailable": "spare",  # a spare that could not take off (still on its base)
    "relieving": "climbing_out",  # launched, flying in to a member's slot
    "home": "going_home",  # relieved, flying home to land
    "on_station": "spare",  # not yet flying its slot (a state between two roles)
}
RELIEF_EVENTS = {  # (old role, new role) -> (event kind, text after "UAV <sysid> ")
    ("spare", "relieving"): ("relief_launched", "launched to relieve UAV {m}"),
    ("relieving", "on_station"): ("relief_in_slot", "in UAV {m}'s slot: on station"),
    ("relieving", "spare"): ("relief_stood_down", "stood down: another spare relieves UAV {m}"),
    ("relieving", "home"): ("relief_stood_down", "turned back: another spare relieves UAV {m}"),
    ("relieving", "unavailable"): ("relief_no_takeoff", "did not take off: unavailable"),
    ("on_station", "home"): ("relieved", "left the loop for home"),
    ("home", "spare"): ("relief_landed", "landed: a spare again"),
}


@dataclass
class _Vehicle:
    state: MemberState
    rx_s: float  # wall time of the last state (s)
    pos_m: complex | None
    source: str
    lost: bool = False
    trail: deque = field(default_factory=lambda: deque(maxlen=TRAIL_MAX))  # (t_s, pos)
    refused: str | None = None  # why its relief state is never planned with, or None


@dataclass
class _Alert:
    alert_id: str
    site_m: complex
    state: str
    detector_sysid: int
    first_t_s: float
    t_s: float
    rx_s: float
    prosecutor: int | None = None
    active: bool = False  # the prosecutor is flying to it now
    responders: list[int] = field(default_factory=list)
    track: Track | None = None  # the newest track heard
    tracker: int | None = None  # the member staying over it now
    searching: bool = False  # its prosecutor searches for it


PATH_AHEAD_S = 30.0  # the live page draws a track's path estimate this far ahead (s)
PATH_STEP_S = 5.0  # ... one point every this many seconds


def _path_estimate(track: Track, now_s: float) -> list[list[float]]:
    """A track's path estimate for the live page: ``[north_m, east_m, sigma_m]`` from
    ``now_s`` (s) to ``PATH_AHEAD_S`` ahead every ``PATH_STEP_S``, along its model
    (:meth:`Track.predict`, a turn's arc) with its 1-sigma uncertainty then (m): the page
    draws the line and a band of three sigma round it."""
    out = []
    steps = round(PATH_AHEAD_S / PATH_STEP_S)
    for k in range(steps + 1):
        t = now_s + k * PATH_STEP_S
        p = track.predict(t)
        out.append([round(p.real, 1), round(p.imag, 1), round(track.sigma_m(t), 1)])
    return out


def station_of(st: MemberState, lost: bool = False) -> str:
    """Where a member is as the formation counts it (one of :data:`STATIONS`): ``formation``
    (patrol, prosecuting, searching, rejoining: the members the companions splay with,
    :meth:`companion.agent.neighbours.Neighbours.in_formation`), ``tracking`` (over an
    intruder: on station, out of the formation), ``spare`` (mode spare, waiting),
    ``climbing_out`` (mode spare, relieving a member), ``going_home`` (mode spare, relieved)
    or ``lost`` (silent)."""
    if lost:
        return "lost"
    if st.mode not in OUT_OF_FORMATION:
        return "formation"
    if st.mode is Mode.TRACKING:
        return "tracking"
    return SPARE_STATIONS.get(st.energy.role, "spare") if st.energy is not None else "spare"


class FleetView:
    """The page's model of the patrol, built from the group's messages (see module doc).

    Args:
        mission: the mission (loop, sensor, origin), or None: then only positions carried
            by the states (``pos_m``) can be drawn and the loop gauges are absent.
        member_timeout_s: wall seconds of silence after which a member is shown lost.
    """

    def __init__(self, mission: Mission | None, member_timeout_s: float = 3.0) -> None:
        """An empty view."""
        if not (math.isfinite(member_timeout_s) and member_timeout_s > 0):
            raise ValueError(f"member_timeout_s must be > 0 s, got {member_timeout_s!r}")
        self.mission = mission
        self.member_timeout_s = float(member_timeout_s)
        self.vehicles: dict[int, _Vehicle] = {}
        self.alerts: dict[str, _Alert] = {}
        self.events: deque[dict[str, Any]] = deque(maxlen=EVENTS_MAX)
        self._seq = 0
        self.t_s: float | None = None  # newest vehicle time heard (s)
        self._newest_rx_s: float | None = None
        self._patrol = mission.patrol if mission is not None else None
        if self._patrol is not None:
            p = self._patrol
            self._c0 = complex(p.centre_m)
            self._loop_pts = np.asarray(p.sample_by_time(CROSS_TRACK_POINTS), dtype=complex)
            self._cov_pts = np.asarray(p.sample_by_time(COVERAGE_POINTS), dtype=complex)
            self._last_seen = np.full(COVERAGE_POINTS, np.nan)  # vehicle s
            self._sensor_m = float(mission.sensor.footprint_radius_m)
        self._cov_t0: float | None = None
        self._gaps: deque[tuple[float, float]] = deque(maxlen=20_000)  # (t_s, unseen s)
        v = mission.vehicles if mission is not None else None
        on = v is not None and v.battery is not None and bool(v.spares)
        self._roster = Roster(mission) if on else None  # None: no reliefs in this mission
        self._watch = NoLaunchWatch()
        self._late_said: set[int] = set()  # members whose late relief was logged this stint
        self.warnings: dict[int, dict[str, Any]] = {}  # member -> its standing late warning
        self.relief_refused = 0  # relief states refused (not in the mission), counted

    # ---- input ----------------------------------------------------------------------------
    def feed(self, msg: MemberState | Alert, rx_s: float) -> None:
        """One accepted group message, received at wall time ``rx_s`` (s)."""
        if isinstance(msg, MemberState):
            self._on_state(msg, rx_s)
        elif isinstance(msg, Alert):
            self._on_alert(msg, rx_s)

    def note(self, kind: str, text: str, **fields: Any) -> None:
        """Log an event of the dashboard itself (e.g. an operator action)."""
        self._event(kind, text, **fields)

    def vehicle_time_at(self, now_s: float) -> float:
        """Best guess of the members' vehicle time (s) at wall time ``now_s``: the newest
        state's time plus the wall time since it arrived; 0 ("unknown") before any state."""
        if self.t_s is None or self._newest_rx_s is None:
            return 0.0
        return self.t_s + max(0.0, now_s - self._newest_rx_s)

    def _on_state(self, st: MemberState, rx_s: float) -> None:
        pos, source = self._position(st)
        if self.t_s is None or st.t_s >= self.t_s:
            self.t_s, self._newest_rx_s = st.t_s, rx_s
        v = self.vehicles.get(st.sysid)
        mode = st.mode
        if v is None:
            v = _Vehicle(st, rx_s, pos, source)
            self.vehicles[st.sysid] = v
            self._event("member_joined", f"UAV {st.sysid} joined ({mode})", sysid=st.sysid)
        else:
            if v.lost:
                self._event("member_back", f"UAV {st.sysid} heard again", sysid=st.sysid)
            self._mode_change(v.state, st)
            self._role_change(v.state.energy, st)
            v.state, v.rx_s, v.pos_m, v.source = st, rx_s, pos, source
        v.lost = False
        if pos is not None:
            if v.trail and st.t_s < v.trail[-1][0]:
                v.trail.clear()  # the vehicle's clock went back (a new run)
            if not v.trail or st.t_s - v.trail[-1][0] >= TRAIL_STEP_S:
                v.trail.append((st.t_s, pos))
            while v.trail and v.trail[0][0] < st.t_s - TRAIL_S:
                v.trail.popleft()
            if st.mode is Mode.PATROL or source == "reported":
                self._cover(pos, st.t_s)
        self._track_prosecution(st)

    def _position(self, st: MemberState) -> tuple[complex | None, str]:
        reported = getattr(st, "pos_m", None)
        if reported is not None:
            return complex(reported), "reported"
        if self._patrol is None:
            return None, "unknown"
        rho = complex(self._patrol.point_at_phase(st.phase_rad)) - self._c0
        source = "loop point" if st.mode is Mode.PATROL else "virtual particle"
        return complex(st.centre_m) + rho, source

    def _mode_change(self, old: MemberState, new: MemberState) -> None:
        if old.mode == new.mode and old.alert_id == new.alert_id:
            return
        s = new.sysid
        if new.mode is Mode.REJOINING:
            self._event(
                "rejoining", f"UAV {s} flying back into its slot", sysid=s, alert_id=new.alert_id
            )
        elif new.mode is Mode.PATROL:
            self._event("back_on_patrol", f"UAV {s} back on patrol", sysid=s)

    def _role_change(self, old: Energy | None, new: MemberState) -> None:
        e = new.energy
        if old is None or e is None or old.role == e.role:
            return
        got = RELIEF_EVENTS.get((old.role, e.role))
        if got is None:
            return
        member = e.relief_sysid or old.relief_sysid
        kind, text = got
        self._event(kind, f"UAV {new.sysid} " + text.format(m=member), sysid=new.sysid,
                    member_sysid=member)  # fmt: skip

    def _track_prosecution(self, st: MemberState) -> None:
        rec = self.alerts.get(st.alert_id) if st.alert_id else None
        if st.mode is Mode.TRACKING and rec is not None and rec.tracker != st.sysid:
            rec.tracker, rec.active = st.sysid, False
            self._event(
                "tracking",
                f"alert {rec.alert_id}: UAV {st.sysid} tracking",
                sysid=st.sysid,
                alert_id=rec.alert_id,
            )
        for other in self.alerts.values():  # a member no longer tracking what it was
            if other.tracker == st.sysid and (
                st.mode is not Mode.TRACKING or st.alert_id != other.alert_id
            ):
                other.tracker = None
        if st.mode in PROSECUTING and rec is not None:
            if st.sysid not in rec.responders:
                rec.responders.append(st.sysid)
                self._event(
                    "tasked",
                    f"alert {rec.alert_id}: UAV {st.sysid} prosecuting",
                    sysid=st.sysid,
                    alert_id=rec.alert_id,
                )
            rec.prosecutor, rec.active = st.sysid, True
        for other in self.alerts.values():  # a member no longer prosecuting what it was
            gone = st.mode not in PROSECUTING or st.alert_id != other.alert_id
            if other.active and other.prosecutor == st.sysid and gone:
                other.active = False
            if other.prosecutor == st.sysid:
                other.searching = st.mode is Mode.SEARCHING and not gone

    def _on_alert(self, a: Alert, rx_s: float) -> None:
        if a.state == "bid":
            return
        rec = self.alerts.get(a.alert_id)
        if a.state == "update":  # a newer track: no event, the map shows it
            newer = rec is not None and a.track is not None
            if newer and (rec.track is None or a.track.t_s > rec.track.t_s):
                rec.track = a.track
            return
        who = "the operator" if a.detector_sysid == 255 else f"UAV {a.detector_sysid}"
        where = f"({a.site_m.real:.0f}, {a.site_m.imag:.0f}) m"
        if rec is None:
            rec = _Alert(a.alert_id, a.site_m, a.state, a.detector_sysid, a.t_s, a.t_s, rx_s)
            rec.track = a.track
            self.alerts[a.alert_id] = rec
            self._forget_old_alerts()
            self._event(
                f"alert_{a.state}",
                f"alert {a.alert_id} {a.state} by {who} at {where}",
                alert_id=a.alert_id,
                sysid=a.detector_sysid,
            )
            return
        if rec.state in ("cleared", "lost"):
            return  # news about an alert already finished
        if a.state == rec.state and (a.state == "new" or a.t_s <= rec.t_s):
            return  # a repeat (a later confirmation is news: the intruder seen again)
        if a.state == "new" and rec.state == "confirmed":
            return  # a late repeat of the first report
        rec.state, rec.site_m, rec.t_s, rec.rx_s = a.state, a.site_m, a.t_s, rx_s
        rec.detector_sysid = a.detector_sysid
        if a.track is not None and (rec.track is None or a.track.t_s > rec.track.t_s):
            rec.track = a.track
        if a.state in ("cleared", "lost"):
            rec.active, rec.tracker, rec.searching = False, None, False
        self._event(
            f"alert_{a.state}",
            f"alert {a.alert_id} {a.state} by {who} at {where}",
            alert_id=a.alert_id,
            sysid=a.detector_sysid,
        )

    def _forget_old_alerts(self) -> None:
        while len(self.alerts) > ALERTS_MAX:
            done = [r for r in self.alerts.values() if r.state in ("cleared", "lost")]
            victim = min(done or self.alerts.values(), key=lambda r: r.rx_s)
            del self.alerts[victim.alert_id]

    def _cover(self, pos: complex, t_s: float) -> None:
        if self._patrol is None:
            return
        if self._cov_t0 is None:
            self._cov_t0 = t_s
        seen = np.abs(self._cov_pts - pos) <= self._sensor_m
        last = self._last_seen
        last[seen] = np.where(np.isnan(last[seen]), t_s, np.fmax(last[seen], t_s))

    def _event(self, kind: str, text: str, **fields: Any) -> None:
        self._seq += 1
        ev = {"seq": self._seq, "t_s": self.t_s, "kind": kind, "text": text}
        ev.update(fields)
        self.events.append(ev)

    # ---- output ---------------------------------------------------------------------------
    def snapshot(self, now_s: float, events: int = 60) -> dict[str, Any]:
        """The JSON-ready picture at wall time ``now_s`` (s), with the last ``events`` events.

        Also marks members silent for longer than the timeout as lost (and logs it).
        """
        for s, v in self.vehicles.items():
            if not v.lost and now_s - v.rx_s > self.member_timeout_s:
                v.lost = True
                for rec in self.alerts.values():
                    if rec.active and rec.prosecutor == s:
                        rec.active = False
                self._event("member_lost", f"UAV {s} lost (silent)", sysid=s)
        reliefs, p = self._reliefs(now_s)
        vehicles = [self._vehicle_json(s, v, now_s, p) for s, v in sorted(self.vehicles.items())]
        alerts = [self._alert_json(r) for r in sorted(self.alerts.values(), key=lambda r: r.rx_s)]
        return {
            "t_s": self.t_s,
            "vehicles": vehicles,
            "alerts": alerts,
            "reliefs": reliefs,
            "warnings": [self.warnings[m] for m in sorted(self.warnings)],
            "gauges": self._gauges(),
            "events": list(self.events)[-events:] if events > 0 else [],
        }

    def _reliefs(self, now_s: float) -> tuple[dict[str, Any], Plan | None]:
        """The reliefs' picture at wall time ``now_s`` (s) and the plan (None: off)."""
        roster, patrol = self._roster, self._patrol
        out: dict[str, Any] = {"enabled": roster is not None, "plan": [], "spares": [],
                               "under_way": [], "refused": [],
                               "refused_count": self.relief_refused}  # fmt: skip
        if roster is None or patrol is None or self.t_s is None:
            return out, None
        t = self.vehicle_time_at(now_s)
        heard = [(s, v.state.energy, v.state.pos_m) for s, v in sorted(self.vehicles.items())
                 if not v.lost and v.state.energy is not None]  # fmt: skip
        got = roster.inputs(t, heard, patrol)
        refused = {r.sysid: r for r in got.refused}
        for s, v in self.vehicles.items():
            why = refused.get(s)
            if why is not None and v.refused is None:
                self.relief_refused += 1
                self._event("relief_refused", f"UAV {s} refused as {why.role}: not in the "
                            "mission", sysid=s, reason=why.reason)  # fmt: skip
            v.refused = why.reason if why is not None else None
        p, _ = plan_from(t, got, patrol, self._watch)
        for r in p.reliefs:
            out["plan"].append(_relief_json(r, t))
        self._warn_late(p, t, {s for s, e, _ in heard if e.role == "on_station"})
        for s, e, _ in heard:
            if s in refused:
                out["refused"].append({"sysid": s, "role": e.role, "reason": refused[s].reason})
            elif e.role in ("spare", "unavailable", "home", "relieving"):
                out["spares"].append(_energy_json(s, e, t) | {"booked_for": _booked(p, s)})
            if s not in refused and e.role == "relieving" and e.relief_sysid:
                out["under_way"].append({"spare_sysid": s, "member_sysid": e.relief_sysid})
        out["refused_count"] = self.relief_refused
        return out, p

    def _warn_late(self, p: Plan, t_s: float, on_station: set[int]) -> None:
        """One standing warning per member whose relief the plan ``p`` predicts late, updated
        in place at vehicle time ``t_s`` (s); logged once when first raised while the member
        is in ``on_station`` (the members that share that role now)."""
        late = {r.member: r for r in p.reliefs if r.late and not r.under_way}
        for m in [m for m in self.warnings if m not in late]:
            del self.warnings[m]
        self._late_said &= on_station  # a member that left the station may warn again
        for m, r in late.items():
            how = "no spare" if r.spare is None else f"{r.late_s:.0f} s late by UAV {r.spare}"
            text = f"UAV {m}: relief {how}"
            w = self.warnings.get(m)
            if w is None:
                w = self.warnings[m] = {"kind": "relief_late", "member_sysid": m,
                                        "since_t_s": t_s}  # fmt: skip
            w.update(spare_sysid=r.spare, late_s=_finite(r.late_s, 1),
                     leave_in_s=round(r.leave_t_s - t_s, 1), t_s=t_s, text=text)  # fmt: skip
            if m not in self._late_said:
                self._late_said.add(m)
                self._event("relief_late", text, sysid=m, spare_sysid=r.spare or 0,
                            late_s=_finite(r.late_s, 1))  # fmt: skip

    def _vehicle_json(
        self, s: int, v: _Vehicle, now_s: float, p: Plan | None = None
    ) -> dict[str, Any]:
        st = v.state
        mode = "lost" if v.lost else st.mode
        out: dict[str, Any] = {
            "sysid": s,
            "north_m": None if v.pos_m is None else round(v.pos_m.real, 2),
            "east_m": None if v.pos_m is None else round(v.pos_m.imag, 2),
            "mode": mode,
            "station": station_of(st, v.lost),
            "alert_id": st.alert_id,
            "position_source": v.source,
            "t_s": st.t_s,
            "age_s": round(max(0.0, now_s - v.rx_s), 2),
            "centre_north_m": round(st.centre_m.real, 2),
            "centre_east_m": round(st.centre_m.imag, 2),
            "phase_deg": round(phase_deg_wrapped(st.phase_rad), 2),
            "cross_track_m": None,
            "trail": [[round(p.real, 1), round(p.imag, 1)] for _, p in v.trail],
        }
        if v.pos_m is not None and self._patrol is not None:
            out["cross_track_m"] = round(float(np.min(np.abs(self._loop_pts - v.pos_m))), 2)
        e = st.energy
        out["energy"] = None
        if e is not None:
            t = self.vehicle_time_at(now_s)
            out["energy"] = _energy_json(s, e, t) | {"refused": v.refused}
            mine = p.of_member(s) if p is not None and e.role == "on_station" else None
            out["energy"]["relief"] = None if mine is None else _relief_json(mine, t)
        return out

    def _alert_json(self, r: _Alert) -> dict[str, Any]:
        track = None
        if r.track is not None:
            now = self.t_s if self.t_s is not None else r.track.t_s
            pred = r.track.predict(max(now, r.track.t_s))
            track = {
                "t_s": r.track.t_s,
                "north_m": round(r.track.pos_m.real, 2),
                "east_m": round(r.track.pos_m.imag, 2),
                "vel_north_m_s": round(r.track.vel_m_s.real, 2),
                "vel_east_m_s": round(r.track.vel_m_s.imag, 2),
                "speed_m_s": round(abs(r.track.vel_m_s), 2),
                "sigma_m": round(r.track.sigma_m(max(now, r.track.t_s)), 1),
                "age_s": round(max(0.0, now - r.track.t_s), 1),
                "predicted_north_m": round(pred.real, 2),
                "predicted_east_m": round(pred.imag, 2),
                "sightings": r.track.sightings,
                "model": r.track.model,
                "model_p": round(r.track.model_p, 2),
                "turn_deg_s": round(math.degrees(r.track.turn_rad_s), 1),
                "manoeuvre_m_s2": round(r.track.manoeuvre_m_s2, 2),
                "path": _path_estimate(r.track, max(now, r.track.t_s)),
            }
        return {
            "alert_id": r.alert_id,
            "north_m": round(r.site_m.real, 2),
            "east_m": round(r.site_m.imag, 2),
            "state": r.state,
            "prosecutor_sysid": r.prosecutor,
            "prosecuting": r.active,
            "responders": list(r.responders),
            "tracker_sysid": r.tracker,
            "searching": r.searching,
            "track": track,
            "detector_sysid": r.detector_sysid,
            "operator": r.detector_sysid == 255 or r.alert_id.startswith("255-"),
            "t_s": r.first_t_s,
        }

    def _gauges(self) -> dict[str, Any]:
        """The gauges over the formation (see the module doc), and how many aircraft are at
        each station."""
        by: dict[str, list[_Vehicle]] = {k: [] for k in STATIONS}
        for v in self.vehicles.values():
            by[station_of(v.state, v.lost)].append(v)
        members = by["formation"]
        out: dict[str, Any] = {
            "members": len(members),
            "away": sum(1 for v in members if v.state.mode is not Mode.PATROL),
            "on_station": len(members) + len(by["tracking"]),
            "tracking": len(by["tracking"]),
            "spares": len(by["spare"]),
            "climbing_out": len(by["climbing_out"]),
            "going_home": len(by["going_home"]),
            "lost": len(by["lost"]),
            "splay_deg": None,
            "cross_track_max_m": None,
            "centre_error_max_m": None,
            "coverage_max_unseen_s": None,
            "coverage_window_s": None,
            "coverage_ideal_s": None,
            "coverage_unseen_now_fraction": None,
            "crossing_sure_plan_m_s": None,
            "crossing_sure_m_s": None,
        }
        if self.mission is not None:
            plan = self.mission.crossing_guarantee()
            out["crossing_sure_plan_m_s"] = _finite(plan.sure_m_s, 2)
            if members and out["away"] < len(members):
                now = self.mission.crossing_guarantee(out["away"], vehicles=len(members))
                out["crossing_sure_m_s"] = _finite(now.sure_m_s, 2)
        p = self._patrol
        if p is None or self.t_s is None:
            return out
        t = self.t_s
        out["coverage_window_s"] = round(p.period_s, 1)
        if members:
            phases = [v.state.phase_at(t, p.period_s) for v in members]
            out["splay_deg"] = round(splay_error_deg(phases), 3)
            out["coverage_ideal_s"] = round(p.period_s / len(members), 2)
        on_patrol = [v for v in members if v.state.mode is Mode.PATROL]
        xt = [  # the UAVs on patrol: a prosecutor leaves the loop on purpose
            float(np.min(np.abs(self._loop_pts - v.pos_m)))
            for v in on_patrol
            if v.pos_m is not None
        ]
        if xt:
            out["cross_track_max_m"] = round(max(xt), 2)
        if on_patrol:
            ce = max(abs(v.state.centre_m - self._c0) for v in on_patrol)
            out["centre_error_max_m"] = round(ce, 2)
        if self._cov_t0 is not None:
            last = np.where(np.isnan(self._last_seen), self._cov_t0, self._last_seen)
            unseen = np.maximum(0.0, t - last)
            out["coverage_unseen_now_fraction"] = round(
                float(np.mean(unseen > 2.0 * self._sensor_m / p.airspeed_m_s)), 3
            )
            if self._gaps and t < self._gaps[-1][0]:
                self._gaps.clear()  # the clock went back: a new run
            if not self._gaps or t > self._gaps[-1][0]:
                self._gaps.append((t, float(np.max(unseen))))
            while self._gaps and self._gaps[0][0] < t - p.period_s:
                self._gaps.popleft()
            out["coverage_max_unseen_s"] = round(max(g for _, g in self._gaps), 2)
        return out


def _finite(x: float, digits: int) -> float | None:
    """``x`` rounded, None if it is not finite (JSON has no inf)."""
    return round(x, digits) if math.isfinite(x) else None


def _energy_json(sysid: int, e: Energy, t_s: float) -> dict[str, Any]:
    """What a member shares about its battery and the reliefs, with the time left until
    its role's time (on station: until it must leave; a spare: until it is ready) at
    vehicle time ``t_s`` (s)."""
    until = None if e.t_s is None else round(e.t_s - t_s, 1)
    return {
        "sysid": sysid,
        "role": e.role,
        "battery_pct": _pct(e.battery_pct),
        "leave_in_s": until if e.role == "on_station" else None,
        "ready_in_s": max(0.0, until) if e.role == "spare" and until is not None else None,
        "relief_sysid": e.relief_sysid or None,
    }


def _pct(pct: float | None) -> float | None:
    """A shared battery charge (%) as shown: None when unknown or out of 0-100 %."""
    if pct is None or not 0.0 <= pct <= 100.0:
        return None
    return round(pct, 1)


def _relief_json(r: Any, t_s: float) -> dict[str, Any]:
    """One relief of the plan, times from vehicle time ``t_s`` (s); None: never (no spare)
    or already (under way)."""
    return {
        "member_sysid": r.member,
        "spare_sysid": r.spare,
        "under_way": r.under_way,
        "leave_in_s": round(r.leave_t_s - t_s, 1),
        "launch_in_s": None if r.under_way else _finite(r.launch_t_s - t_s, 1),
        "in_slot_in_s": None if r.under_way else _finite(r.on_station_t_s - t_s, 1),
        "late": r.late,
        "late_s": _finite(r.late_s, 1),
    }


def _booked(p: Plan, sysid: int) -> int | None:
    r = p.of_spare(sysid)
    return None if r is None else r.member


def phase_deg_wrapped(phase_rad: float) -> float:
    """A phase in degrees within [0, 360)."""
    return math.degrees(phase_rad % TWO_PI)
