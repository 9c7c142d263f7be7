"""In-process fleet simulation: particles + the companion's guidance, no MAVLink.

Every vehicle is the ``sitl_model`` particle; every companion's decisions come from the same
pure modules the real companion uses, exchanging states through a perfect in-memory group.
Used by ``companion simulate`` to tune gains and check a mission before flying. Time is
simulated seconds from 0; the clock is this object's own counter, never the wall clock.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from companion.alerts import Alert, next_in_sequence, plan_to_site, remaining_s, turn_rate_at
from companion.core.formation import track_command
from companion.core.measures import centre_error_m, convergence_time_s, splay_error_deg
from companion.core.steering import (
    phase_gains_m2_s,
    reference_centre,
    splay_gradient,
    steering_turn_rate,
)
from companion.core.virtual import VirtualParticle, phase_gap_rad
from companion.core.wind import TWO_PI
from companion.mission import Mission
from companion.planner import NoPath, Plan
from sitl_model.particle import ParticleParams, ParticleState, step

TRUTH_COLUMNS = (
    "t_s",
    "sysid",
    "north_m",
    "east_m",
    "alt_m",
    "heading_deg",
    "course_deg",
    "groundspeed_m_s",
    "turn_rate_deg_s",
    "mode",
)

TruthRow = tuple[float, int, float, float, float, float, float, float, float, str]
Event = dict[str, object]


@dataclass
class Series:
    """Formation measures sampled over the run (one entry per sample time)."""

    t_s: list[float] = field(default_factory=list)
    splay_deg: list[float] = field(default_factory=list)
    centre_m: list[float] = field(default_factory=list)

    def convergence_time_s(self) -> float | None:
        """First time after which splay < 2 deg and centre < 5 m hold (s), or None."""
        return convergence_time_s(self.t_s, self.splay_deg, self.centre_m)


class FleetSimulation:
    """N particles steered by the companion guidance, stepped at a fixed ``dt_s``.

    Args:
        mission: the mission (loop, wind, vehicles, gains, sensor, scenario).
        seed: seed of the one random generator (gusts).
        dt_s: control and physics step (s); the physics is exact for the held turn rate.
    """

    def __init__(self, mission: Mission, seed: int = 0, dt_s: float = 0.1) -> None:
        """Place the vehicles at the mission's initial poses at t = 0."""
        self.mission = mission
        self.patrol = mission.patrol
        self.dt_s = float(dt_s)
        self.rng = np.random.default_rng(seed)
        v = mission.vehicles
        self.sysids = np.array(v.sysids)
        self.alt_m = np.array(v.altitudes_m)
        self.params = ParticleParams(
            v.airspeed_m_s, v.max_turn_rate_rad_s, gust_std_m_s=mission.wind.gust_std_m_s
        )
        self.wind_m_s = mission.wind.wind().vector
        self.state = ParticleState.at(
            [p.north_m for p in v.initial],
            [p.east_m for p in v.initial],
            np.radians([p.heading_deg for p in v.initial]),
        )
        self.step_index = 0
        self.modes = ["patrol"] * v.count
        self.series = Series()
        self.events: list[Event] = []
        self._controller = FleetController(mission)

    @property
    def t_s(self) -> float:
        """Simulated time (s)."""
        return self.step_index * self.dt_s

    def run(
        self,
        duration_s: float,
        on_truth: Callable[[list[TruthRow]], None] | None = None,
        on_event: Callable[[Event], None] | None = None,
    ) -> Series:
        """Fly until ``duration_s`` (s); sample every step; return the measures."""
        steps = round(duration_s / self.dt_s)
        for _ in range(steps + 1):
            t = self.t_s
            u, modes, events = self._controller.commands(t, self.state, self.modes)
            self.modes = modes
            for ev in events:
                self.events.append(ev)
                if on_event is not None:
                    on_event(ev)
            self._sample(t, u, on_truth)
            if self.step_index >= steps:
                break
            self.state = step(self.state, u, self.params, self.wind_m_s, self.dt_s, self.rng)
            self.step_index += 1
        return self.series

    def _sample(
        self, t: float, u: np.ndarray, on_truth: Callable[[list[TruthRow]], None] | None
    ) -> None:
        st = self.state
        centres, phases = self._controller.shared_centres_phases(t, st, self.modes)
        self.series.t_s.append(t)
        self.series.splay_deg.append(splay_error_deg(phases))
        self.series.centre_m.append(centre_error_m(centres, self.patrol.centre_m))
        if on_truth is None:
            return
        vel = self.params.airspeed_m_s * np.exp(1j * st.heading_rad) + self.wind_m_s + st.gust_m_s
        u_ach = np.clip(u, -self.params.max_turn_rate_rad_s, self.params.max_turn_rate_rad_s)
        rows = list(
            zip(
                [round(t, 3)] * len(self.sysids),
                self.sysids.tolist(),
                np.round(st.pos_m.real, 3).tolist(),
                np.round(st.pos_m.imag, 3).tolist(),
                self.alt_m.tolist(),
                np.round(np.degrees(st.heading_rad) % 360.0, 3).tolist(),
                np.round(np.degrees(np.angle(vel)) % 360.0, 3).tolist(),
                np.round(np.abs(vel), 3).tolist(),
                np.round(np.degrees(u_ach), 4).tolist(),
                self.modes,
                strict=True,
            )
        )
        on_truth(rows)


@dataclass
class _Away:
    """A UAV away from the formation: prosecuting an alert, then flying back into its slot."""

    alert: Alert
    virtual: VirtualParticle
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    planned_time_s: float = 0.0
    rejoining: bool = False
    covered: bool = False  # the prosecutor's sensor has covered the site


class FleetController:
    """Every companion's decisions, with a perfect in-memory group.

    Patrolling members run the time-splay law on the shared states; a prosecutor shares its
    virtual particle, flies the minimum-time plan (re-planned every ``replan_s``), ends on
    re-detection (confirm and hand off) or at the path's end (clear), then flies into its
    virtual particle's slot with the tracking law before handing back its real state.
    """

    def __init__(self, mission: Mission, replan_s: float = 1.0) -> None:
        """Bind the mission's loop, gains, limits, sensor and scenario."""
        self.mission = mission
        self.patrol = mission.patrol
        self.gains = mission.gains
        self.max_u = mission.vehicles.max_turn_rate_rad_s
        self.sysids = list(mission.vehicles.sysids)
        self.k_m = phase_gains_m2_s(self.patrol, self.gains, len(self.sysids))
        self.sensor_m = mission.sensor.footprint_radius_m
        self.replan_s = replan_s
        self.away: dict[int, _Away] = {}
        self.alerts: dict[str, Alert] = {}
        self.active_sites: dict[str, complex] = {}  # alert_id -> site, until cleared
        self.first_seen: dict[str, float] = {}  # intruder id -> time first detected
        self.appeared: set[str] = set()
        self._pending: list[tuple[Alert, float]] = []  # alerts waiting for a prosecutor
        self._seq = 0

    # ---- shared state ---------------------------------------------------------------------
    def shared_centres_phases(
        self, t_s: float, state: ParticleState, modes: list[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Centres (m) and phases (rad) the members share at ``t_s`` (virtual when away)."""
        c, psi = self.patrol.centre_and_phase(state.pos_m, state.heading_rad)
        c, psi = np.array(c, dtype=complex), np.array(psi, dtype=float)
        for k, sysid in enumerate(self.sysids):
            if sysid in self.away:
                c[k] = self.patrol.centre_m
                psi[k] = self.away[sysid].virtual.phase(t_s)
        return c, psi

    # ---- one control step -----------------------------------------------------------------
    def commands(
        self, t_s: float, state: ParticleState, modes: list[str]
    ) -> tuple[np.ndarray, list[str], list[Event]]:
        """Turn-rate commands (rad/s), the new modes and the events at ``t_s``."""
        events: list[Event] = []
        c, psi = self.shared_centres_phases(t_s, state, modes)
        self._sense(t_s, state, psi, events)
        pending, self._pending = self._pending, []
        for alert, reporter_phase in pending:
            self._task(t_s, alert, reporter_phase, state, events)
        c, psi = self.shared_centres_phases(t_s, state, modes)
        grad = splay_gradient(psi, psi, self.k_m)
        c_ref = reference_centre(self.patrol, self.gains, c)
        u = np.array(
            steering_turn_rate(
                self.patrol, self.gains, state.pos_m, state.heading_rad, grad, c_ref, self.max_u
            ),
            dtype=float,
        )
        new_modes = ["patrol"] * len(self.sysids)
        for k, sysid in enumerate(self.sysids):
            away = self.away.get(sysid)
            if away is None:
                continue
            pos, heading = complex(state.pos_m[k]), float(state.heading_rad[k])
            if not away.rejoining:
                u[k] = self._prosecute(t_s, sysid, away, pos, heading, events)
            if away.rejoining:
                u[k] = self._rejoin(t_s, sysid, away, pos, heading, events)
            new_modes[k] = self._mode(sysid)
        return u, new_modes, events

    def _mode(self, sysid: int) -> str:
        away = self.away.get(sysid)
        if away is None:
            return "patrol"
        return "rejoining" if away.rejoining else "prosecuting"

    # ---- sensing and tasking --------------------------------------------------------------
    def _sense(self, t_s: float, state: ParticleState, psi: np.ndarray, events: list[Event]):
        for intruder in self.mission.intruders:
            if intruder.id not in self.appeared and t_s >= intruder.appear_t_s:
                self.appeared.add(intruder.id)
                events.append(
                    _ev(
                        t_s,
                        "intruder_appeared",
                        None,
                        intruder=intruder.id,
                        north_m=intruder.north_m,
                        east_m=intruder.east_m,
                    )
                )
            if not intruder.present(t_s, self.first_seen.get(intruder.id)):
                continue
            where = intruder.position_m(t_s)
            seen_by = np.flatnonzero(np.abs(state.pos_m - where) <= self.sensor_m)
            for k in seen_by:
                sysid = self.sysids[k]
                self.first_seen.setdefault(intruder.id, t_s)
                away = self.away.get(sysid)
                if away is not None and not away.rejoining:
                    if abs(away.alert.site_m - where) <= 2 * self.sensor_m:
                        self._end_prosecution(t_s, sysid, away, True, where, psi, events)
                    continue
                if away is not None:
                    continue
                if any(abs(s - where) <= 2 * self.sensor_m for s in self.active_sites.values()):
                    continue  # the same site: merged into the alert already under way
                self._seq += 1
                alert = Alert(f"{sysid}-{self._seq}", where, sysid, t_s, "new")
                self.alerts[alert.alert_id] = alert
                self.active_sites[alert.alert_id] = where
                events.append(
                    _ev(
                        t_s,
                        "alert_new",
                        sysid,
                        alert_id=alert.alert_id,
                        north_m=where.real,
                        east_m=where.imag,
                        intruder=intruder.id,
                    )
                )
                self._pending.append((alert, float(psi[k])))

    def _task(
        self,
        t_s: float,
        alert: Alert,
        reporter_phase: float,
        state: ParticleState,
        events: list[Event],
    ) -> None:
        _, psi = self.patrol.centre_and_phase(state.pos_m, state.heading_rad)
        phases = {
            s: float(psi[k])
            for k, s in enumerate(self.sysids)
            if s not in self.away and s != alert.detector_sysid
        }
        chosen = next_in_sequence(reporter_phase, phases)
        if chosen is None:
            events.append(
                _ev(
                    t_s,
                    "alert_unassigned",
                    alert.detector_sysid,
                    alert_id=alert.alert_id,
                    reason="no free UAV",
                )
            )
            return
        k = self.sysids.index(chosen)
        vp = VirtualParticle(phases[chosen], t_s, self.patrol.period_s)
        away = _Away(alert=alert, virtual=vp)
        self.away[chosen] = away
        events.append(
            _ev(
                t_s,
                "alert_tasked",
                chosen,
                alert_id=alert.alert_id,
                detector_sysid=alert.detector_sysid,
            )
        )
        self._replan(
            t_s,
            chosen,
            away,
            complex(state.pos_m[k]),
            float(state.heading_rad[k]),
            events,
            first=True,
        )

    # ---- prosecution ----------------------------------------------------------------------
    def _replan(self, t_s, sysid, away: _Away, pos, heading, events, first=False) -> None:
        plan = plan_to_site(self.patrol, pos, heading, away.alert.site_m, self.max_u)
        away.last_plan_s = t_s
        if isinstance(plan, NoPath):
            if first:
                events.append(
                    _ev(t_s, "plan_failed", sysid, alert_id=away.alert.alert_id, reason=plan.reason)
                )
            return
        away.plan, away.plan_t0_s = plan, t_s
        if first:
            away.planned_time_s = plan.time_s
            events.append(
                _ev(
                    t_s,
                    "plan",
                    sysid,
                    alert_id=away.alert.alert_id,
                    planned_time_s=round(plan.time_s, 3),
                    path_type=plan.family,
                )
            )

    def _prosecute(self, t_s, sysid, away: _Away, pos, heading, events) -> float:
        if not away.covered and abs(pos - away.alert.site_m) <= self.sensor_m:
            away.covered = True
            events.append(
                _ev(
                    t_s,
                    "site_covered",
                    sysid,
                    alert_id=away.alert.alert_id,
                    response_time_s=round(t_s - away.alert.t_s, 3),
                    planned_time_s=round(away.planned_time_s, 3),
                )
            )
        due = away.plan is None or t_s - away.last_plan_s >= self.replan_s - 1e-9
        if due and (
            away.plan is None or remaining_s(away.plan, t_s - away.plan_t0_s) > self.replan_s
        ):
            self._replan(t_s, sysid, away, pos, heading, events)
        if away.plan is None or remaining_s(away.plan, t_s - away.plan_t0_s) <= 1e-9:
            self._end_prosecution(t_s, sysid, away, False, None, None, events)
            return 0.0
        return turn_rate_at(away.plan, t_s - away.plan_t0_s)

    def _end_prosecution(self, t_s, sysid, away: _Away, seen: bool, where, psi, events) -> None:
        alert = away.alert
        away.rejoining = True
        events.append(
            _ev(
                t_s,
                "prosecution_end",
                sysid,
                alert_id=alert.alert_id,
                outcome="confirmed" if seen else "cleared",
                planned_time_s=round(away.planned_time_s, 3),
                response_time_s=round(t_s - alert.t_s, 3),
            )
        )
        if not seen:
            self.active_sites.pop(alert.alert_id, None)
            events.append(_ev(t_s, "alert_cleared", sysid, alert_id=alert.alert_id))
            return
        confirmed = Alert(alert.alert_id, where, sysid, t_s, "confirmed")
        self.alerts[alert.alert_id] = confirmed
        self.active_sites[alert.alert_id] = where
        events.append(
            _ev(
                t_s,
                "alert_confirmed",
                sysid,
                alert_id=alert.alert_id,
                north_m=where.real,
                east_m=where.imag,
            )
        )
        # hand off: the next UAV behind the confirming UAV's slot (its virtual particle)
        self._pending.append((confirmed, away.virtual.phase(t_s)))

    # ---- rejoin ---------------------------------------------------------------------------
    def _rejoin(self, t_s, sysid, away: _Away, pos, heading, events) -> float:
        c, psi = self.patrol.centre_and_phase(pos, heading)
        target = away.virtual.phase(t_s)
        in_slot = abs(complex(c) - self.patrol.centre_m) < REJOIN_CENTRE_M and abs(
            phase_gap_rad(float(psi), target)
        ) < np.radians(REJOIN_PHASE_DEG)
        if in_slot:
            del self.away[sysid]
            events.append(_ev(t_s, "rejoined", sysid, alert_id=away.alert.alert_id))
        return track_command(self.patrol, self.gains, pos, heading, float(psi), target, self.max_u)


REJOIN_CENTRE_M = 3.0
REJOIN_PHASE_DEG = 1.0


def _ev(t_s: float, event: str, sysid: int | None, **fields: object) -> Event:
    out: Event = {"t_s": round(float(t_s), 3), "event": event}
    if sysid is not None:
        out["sysid"] = int(sysid)
    out.update(fields)
    return out


__all__ = ["TRUTH_COLUMNS", "TWO_PI", "FleetSimulation", "Series"]
