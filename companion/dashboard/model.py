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
* reliefs (a mission with a battery and spares; docs/energy.md): the batteries, the spares,
  the reliefs under way, the fleet's plan as the members compute it and its late warnings
  (:class:`companion.dashboard.reliefs.ReliefView`);
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

from companion.agent.relief.schedule import Plan
from companion.core.measures import splay_error_deg
from companion.core.wind import TWO_PI
from companion.dashboard.geometry import Geometry
from companion.dashboard.reliefs import SPARE_STATIONS, ReliefView, finite
from companion.group.messages import OUT_OF_FORMATION, Alert, MemberState, Mode, Track
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


@dataclass
class _Vehicle:
    state: MemberState
    rx_s: float  # wall time of the last state (s)
    pos_m: complex | None
    source: str
    lost: bool = False
    trail: deque = field(default_factory=lambda: deque(maxlen=TRAIL_MAX))  # (t_s, pos)


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
        self.reliefs = ReliefView(mission, self._event)  # the reliefs' part of the page

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
            self.reliefs.role_change(st.sysid, v.state.energy, st.energy)
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
            "warnings": [w for _, w in sorted(self.reliefs.warnings.items())],
            "gauges": self._gauges(),
            "events": list(self.events)[-events:] if events > 0 else [],
        }

    def _reliefs(self, now_s: float) -> tuple[dict[str, Any], Plan | None]:
        """The reliefs' picture at wall time ``now_s`` (s) and the plan (None: off)."""
        t = self.vehicle_time_at(now_s) if self.t_s is not None else None
        heard = [(s, v.state.energy, v.state.pos_m) for s, v in sorted(self.vehicles.items())
                 if not v.lost and v.state.energy is not None]  # fmt: skip
        return self.reliefs.picture(t, heard, self._patrol)

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
            out["energy"] = self.reliefs.of_vehicle(s, e, self.vehicle_time_at(now_s), p)
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
            out["crossing_sure_plan_m_s"] = finite(plan.sure_m_s, 2)
            if members and out["away"] < len(members):
                now = self.mission.crossing_guarantee(out["away"], vehicles=len(members))
                out["crossing_sure_m_s"] = finite(now.sure_m_s, 2)
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


def phase_deg_wrapped(phase_rad: float) -> float:
    """A phase in degrees within [0, 360)."""
    return math.degrees(phase_rad % TWO_PI)
