"""Metrics of a run (docs/design.md §8), computed from the truth log and the events.

The headline measures are model-free (:mod:`companion.report.coverage`): cross-track,
coverage revisit, longest unseen and the fraction of time within bounds, from the true
positions and the loop's geometry only. The formation measures (splay, centre, their
convergence time) are diagnostics; they use what the companions share: a UAV away on an
alert counts as its virtual particle (centre c0, phase advancing at 2 pi / T from its phase
when tasked). Revisit gaps are measured over the converged part of the run with every UAV
on the loop.
"""

from __future__ import annotations

import itertools
from typing import TypeVar

import numpy as np

from companion.agent.events import (
    SITE_EVENTS,
    AgentEvent,
    AlertNew,
    LoopFlyable,
    LoopInfeasible,
    PlanMade,
    ProsecutionEnd,
    Rejoined,
    SiteCovered,
)
from companion.core.measures import (
    CENTRE_TOL_M,
    SPLAY_TOL_DEG,
    convergence_time_s,
    splay_errors_deg,
)
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, Wind
from companion.report.coverage import (
    POINT_SPACING_M,
    POLYLINE_SPACING_M,
    UNSEEN_BOUND_RATIO,
    XT_BOUND_M,
    PatrolMeasures,
    Polyline,
    loop_points,
    patrol_measures,
)
from companion.report.rundata import RunData

REVISIT_POINTS = 120


def formation_series(run: RunData) -> dict[str, np.ndarray]:
    """Per common sample time: ``t_s``, ``splay_deg``, ``centre_m`` of the shared states."""
    patrol = run.mission.patrol
    t = run.times_s
    sysids = sorted(run.tracks)
    n = len(sysids)
    centres = np.empty((n, t.size), dtype=complex)
    phases = np.empty((n, t.size))
    for k, s in enumerate(sysids):
        tr = run.tracks[s]
        idx = np.searchsorted(tr.t_s, t)
        c, psi = patrol.centre_and_phase_from_course(tr.pos_m[idx], tr.course_rad[idx])
        centres[k], phases[k] = c, psi
    for away in run.away_windows():
        k = sysids.index(away.sysid)
        inside = (t >= away.t0_s) & (t < away.t1_s)
        if not inside.any():
            continue
        # the last sample at or before tasking: a sample taken once the prosecutor has begun
        # to turn would give its phase a large error on a nearly straight edge
        j0 = max(int(np.searchsorted(t, away.t0_s, side="right")) - 1, 0)
        psi0 = phases[k, j0]
        phases[k, inside] = (psi0 + TWO_PI * (t[inside] - t[j0]) / patrol.period_s) % TWO_PI
        centres[k, inside] = patrol.centre_m
    splay = splay_errors_deg(phases)
    centre = np.max(np.abs(centres - patrol.centre_m), axis=0) if n else np.zeros(t.size)
    return {"t_s": t, "splay_deg": splay, "centre_m": centre}


def revisit_gaps(run: RunData, t_from_s: float, t_to_s: float | None = None) -> np.ndarray:
    """Intervals between successive sensor passes (s) over points spaced along the loop.

    Only gaps that lie wholly within ``[t_from_s, t_to_s]`` (simulated s; no end if None)
    and outside every alert episode count.
    """
    patrol = run.mission.patrol
    r_s = run.mission.sensor.footprint_radius_m
    t = run.times_s
    pts = patrol.point_at_phase(np.arange(REVISIT_POINTS) * TWO_PI / REVISIT_POINTS)
    covered = np.zeros((REVISIT_POINTS, t.size), dtype=bool)
    for tr in run.tracks.values():
        pos = tr.pos_m[np.searchsorted(tr.t_s, t)]
        for j0 in range(0, t.size, 5000):
            block = pos[j0 : j0 + 5000]
            covered[:, j0 : j0 + 5000] |= np.abs(pts[:, None] - block[None, :]) <= r_s
    valid = t >= t_from_s
    if t_to_s is not None:
        valid &= t <= t_to_s
    for away in run.away_windows():
        valid &= ~((t >= away.t0_s) & (t <= away.t1_s))
    gaps = []
    for row in covered:
        starts = np.flatnonzero(row[1:] & ~row[:-1]) + 1
        for a, b in itertools.pairwise(starts):
            if valid[a : b + 1].all():
                gaps.append(t[b] - t[a])
    return np.array(gaps)


def loop_geometry(patrol) -> tuple[np.ndarray, Polyline]:
    """Coverage points every ~10 m along the loop (complex m) and its cross-track polyline."""
    points = loop_points(patrol.point_at_phase, patrol.length_m, POINT_SPACING_M)
    dense = loop_points(patrol.point_at_phase, patrol.length_m, POLYLINE_SPACING_M)
    return points, Polyline.of(dense)


def truth_arrays(run: RunData) -> tuple[np.ndarray, list[int], np.ndarray, np.ndarray]:
    """Common times (s), sysids, true positions (A, S complex m), away masks (A, S)."""
    t = run.times_s
    sysids = sorted(run.tracks)
    pos = np.empty((len(sysids), t.size), dtype=complex)
    away = np.zeros((len(sysids), t.size), dtype=bool)
    for k, s in enumerate(sysids):
        tr = run.tracks[s]
        pos[k] = tr.pos_m[np.searchsorted(tr.t_s, t)]
    for a in run.away_windows() + run.off_station_windows():  # a relief's is not an alert's
        if a.sysid in sysids:
            away[sysids.index(a.sysid)] |= (t >= a.t0_s) & (t <= a.t1_s)
    return t, sysids, pos, away


def reference_patrol(run: RunData) -> tuple[Patrol, str]:
    """The loop timed in the world's wind, for the ideal revisit T/N, and how it was chosen.

    The wind is the mean true wind of the truth log over the second half of the run (where
    the measuring window usually lies); the mission's wind if the log has none or if that
    mean is not slower than the airspeed.
    """
    patrol = run.mission.patrol
    tracks = [tr for tr in run.tracks.values() if tr.t_s.size]
    if not tracks or any(tr.wind_m_s is None for tr in tracks):
        return patrol, "mission wind (the truth log has no wind)"
    half = 0.5 * (min(tr.t_s[0] for tr in tracks) + max(tr.t_s[-1] for tr in tracks))
    winds = np.concatenate([tr.wind_m_s[tr.t_s >= half] for tr in tracks])
    winds = winds[np.isfinite(winds)]
    if not winds.size:
        return patrol, "mission wind (the truth log has no wind)"
    w = complex(np.mean(winds))
    try:
        ref = Patrol.build(
            patrol.shape_world, patrol.airspeed_m_s, Wind.from_vector(w), patrol.clockwise
        )
    except ValueError:
        return patrol, "mission wind (the true mean wind is not slower than the airspeed)"
    return ref, "true wind: mean of the truth log's wind over the second half of the run"


def model_free_measures(run: RunData, reference: Patrol | None = None) -> PatrolMeasures:
    """Cross-track, coverage revisit, longest unseen, time within bounds (coverage module).

    ``reference``: the loop timed in the wind that sets T/N (default: the mission's).
    """
    patrol = run.mission.patrol
    ref = reference or patrol
    t, _, pos, away = truth_arrays(run)
    points, polyline = loop_geometry(patrol)
    return patrol_measures(
        t,
        pos,
        away,
        points,
        polyline,
        run.mission.sensor.footprint_radius_m,
        ref.period_s / run.mission.vehicles.count,
        ref.period_s,
        [(a.t0_s, a.t1_s) for a in run.away_windows()],
    )


def _truth_cover_s(run: RunData, sysid: int, site_m: complex, t0_s: float, t1_s: float):
    """First time in [t0_s, t1_s] the UAV's true position is within its sensor radius of the
    site (s), or None."""
    tr = run.tracks.get(sysid)
    if tr is None:
        return None
    r_s = run.mission.sensor.footprint_radius_m
    inside = (tr.t_s >= t0_s) & (tr.t_s <= t1_s) & (np.abs(tr.pos_m - site_m) <= r_s)
    hit = np.flatnonzero(inside)
    return float(tr.t_s[hit[0]]) if hit.size else None


def alert_answers(run: RunData) -> dict:
    """Whether each alert was answered by exactly one UAV at a time.

    An alert counts as answered by one when it has at least one prosecution and no two of
    its prosecutions (tasking to back in the slot) overlap in time. Every alert a detector
    raised (its own ``alert_new``) is checked.
    """
    raised = {e.alert_id for e in run.agent_events if isinstance(e, AlertNew) and e.own}
    by_alert: dict[str, list] = {}
    for a in run.away_windows():
        by_alert.setdefault(a.alert_id, []).append(a)
        raised.add(a.alert_id)
    bad = []
    for alert_id in sorted(raised):
        ws = sorted(by_alert.get(alert_id, []), key=lambda a: a.t0_s)
        overlap = any(b.t0_s < a.t1_s for a, b in itertools.pairwise(ws))
        if not ws or overlap:
            bad.append(alert_id)
    return {
        "alerts_raised": len(raised),
        "alerts_answered_by_one": len(raised) - len(bad),
        "alerts_not_answered_by_one": bad,
    }


def alert_records(run: RunData) -> list[dict]:
    """One record per prosecution: detection, tasking, plan, response, outcome, rejoin."""
    ev = run.agent_events
    detected: dict[str, AlertNew] = {}
    for e in ev:
        if isinstance(e, AlertNew) and e.own:
            detected.setdefault(e.alert_id, e)
    out = []
    for away in run.away_windows():
        mine = [
            e
            for e in ev
            if e.sysid == away.sysid
            and _alert_id(e) == away.alert_id
            and away.t0_s <= e.t_s <= away.t1_s
        ]
        plan, covered = _first(mine, PlanMade), _first(mine, SiteCovered)
        end, rejoined = _first(mine, ProsecutionEnd), _first(mine, Rejoined)
        origin = detected.get(away.alert_id)
        # a hand-off starts from the confirmation that tasked this UAV
        confirm = [
            e
            for e in ev
            if isinstance(e, ProsecutionEnd)
            and e.alert_id == away.alert_id
            and e.outcome == "confirmed"
            and e.t_s <= away.t0_s
        ]
        t_alert = confirm[-1].t_s if confirm else (origin.t_s if origin else away.t0_s)
        sites = [
            e
            for e in ev
            if isinstance(e, SITE_EVENTS)
            and e.alert_id == away.alert_id
            and e.t_s <= away.t0_s + 1.0
        ]
        t_cover = None
        if sites:
            site = complex(sites[-1].north_m, sites[-1].east_m)
            t_cover = _truth_cover_s(run, away.sysid, site, away.t0_s, away.t1_s)
        planned = plan.planned_time_s if plan else None
        out.append(
            {
                "alert_id": away.alert_id,
                "detected_t_s": origin.t_s if origin else None,
                "detector_sysid": origin.sysid if origin else None,
                "tasked_t_s": away.t0_s,
                "prosecutor_sysid": away.sysid,
                "planned_time_s": planned,
                "response_time_s": round(covered.t_s - t_alert, 3) if covered else None,
                "outcome": end.outcome if end else None,
                "rejoin_time_s": round(rejoined.t_s - end.t_s, 3) if rejoined and end else None,
                "truth_cover_from_tasking_s": None
                if t_cover is None
                else round(t_cover - away.t0_s, 3),
                "response_over_plan": None
                if t_cover is None or not planned
                else round((t_cover - away.t0_s) / planned, 4),
            }
        )
    return out


E = TypeVar("E", bound=AgentEvent)


def _first(events: list[AgentEvent], kind: type[E]) -> E | None:
    """The first of ``events`` of type ``kind``, or None."""
    return next((e for e in events if isinstance(e, kind)), None)


def _alert_id(ev: AgentEvent) -> str | None:
    """The alert an event is about, None for the kinds about no alert (wind, members)."""
    return getattr(ev, "alert_id", None)


def compute_metrics(run: RunData) -> dict:
    """The ``metrics.json`` content of a run."""
    patrol = run.mission.patrol
    n = run.mission.vehicles.count
    ideal = patrol.period_s / n
    series = formation_series(run)
    conv = convergence_time_s(series["t_s"], series["splay_deg"], series["centre_m"])
    metrics: dict = {
        "mission": run.mission.name,
        "vehicles": n,
        "duration_s": float(series["t_s"][-1]) if series["t_s"].size else 0.0,
        "loop_length_m": round(patrol.length_m, 3),
        "loop_period_s": round(patrol.period_s, 3),
        "ideal_revisit_s": round(ideal, 3),
        "convergence_time_s": None if conv is None else round(conv, 3),
        "convergence_rule": f"splay < {SPLAY_TOL_DEG} deg and centre < {CENTRE_TOL_M} m hold",
        "steady_rule": "median from one loop period after convergence to the end",
        "steady_splay_error_deg": None,
        "steady_centre_error_m": None,
        "max_revisit_gap_s": None,
        "mean_revisit_gap_s": None,
        "revisit_ratio": None,
    }
    if conv is not None:
        steady = series["t_s"] >= conv + patrol.period_s
        if steady.any():
            splay = float(np.median(series["splay_deg"][steady]))
            centre = float(np.median(series["centre_m"][steady]))
            metrics["steady_splay_error_deg"] = round(splay, 4)
            metrics["steady_centre_error_m"] = round(centre, 4)
        gaps = revisit_gaps(run, conv)
        if gaps.size:
            metrics["max_revisit_gap_s"] = round(float(gaps.max()), 3)
            metrics["mean_revisit_gap_s"] = round(float(gaps.mean()), 3)
            metrics["revisit_ratio"] = round(float(gaps.max()) / ideal, 4)
    metrics["final_splay_error_deg"] = round(float(series["splay_deg"][-1]), 4)
    metrics["final_centre_error_m"] = round(float(series["centre_m"][-1]), 4)
    ref, ref_rule = reference_patrol(run)
    pm = model_free_measures(run, ref)
    metrics |= {
        "reference_rule": ref_rule,
        "reference_wind_speed_m_s": round(ref.wind.speed_m_s, 3),
        "reference_wind_from_deg": round(float(np.degrees(ref.wind.towards_rad) + 180) % 360, 2),
        "reference_loop_period_s": round(ref.period_s, 3),
        "reference_ideal_revisit_s": round(ref.period_s / n, 3),
    }
    metrics |= model_free_metrics(pm, ideal)
    win = series["t_s"] >= pm.window_start_s
    for key, name in (
        ("splay_deg", "window_splay_error_median_deg"),
        ("centre_m", "window_centre_error_median_m"),
    ):
        metrics[name] = round(float(np.median(series[key][win])), 4) if win.any() else None
    metrics["alerts"] = alert_records(run)
    metrics |= alert_answers(run)
    metrics["loop_infeasible_s"] = round(loop_infeasible_s(run, metrics["duration_s"]), 1)
    return metrics


def loop_infeasible_s(run: RunData, end_s: float) -> float:
    """Time (s) the fleet's agreed wind made the loop need more turn rate than the aircraft
    have, as the lowest-sysid companion said it (``loop_infeasible`` .. ``loop_flyable``),
    up to ``end_s`` (s)."""
    said = [e for e in run.agent_events if isinstance(e, (LoopInfeasible, LoopFlyable))]
    if not said:
        return 0.0
    first = min(int(e.sysid) for e in said)
    total, since = 0.0, None
    for e in (e for e in said if e.sysid == first):  # agent_events are in time order
        if isinstance(e, LoopInfeasible) and since is None:
            since = float(e.t_s)
        elif isinstance(e, LoopFlyable) and since is not None:
            total += float(e.t_s) - since
            since = None
    if since is not None:
        total += max(0.0, end_s - since)
    return total


def model_free_metrics(pm: PatrolMeasures, ideal_revisit_s: float) -> dict:
    """The ``metrics.json`` keys of the model-free measures (units or ``ratio`` in names).

    Their ratios are in units of the reference T/N (:func:`reference_patrol`);
    ``ideal_revisit_s`` is the mission's T/N (s), for ``coverage_revisit_ratio_mission_wind``.
    """

    def r(v: float | None, nd: int) -> float | None:
        return None if v is None else round(float(v), nd)

    return {
        "window_rule": "from one loop period after the settle time to the end if that "
        "leaves a loop period, else the second half of the run (settled: false)",
        "settle_rule": f"first stretch within bounds (alert episodes excused) lasting one "
        f"loop period; bounds: every patrolling UAV's cross-track <= {XT_BOUND_M:g} m and "
        f"no loop point unseen longer than {UNSEEN_BOUND_RATIO:g} T/N",
        "settle_time_s": r(pm.settle_time_s, 3),
        "settled": pm.settled,
        "window_start_s": r(pm.window_start_s, 3),
        "window_end_s": r(pm.window_end_s, 3),
        "cross_track_median_m": r(pm.cross_track_median_m, 3),
        "cross_track_p95_m": r(pm.cross_track_p95_m, 3),
        "cross_track_max_m": r(pm.cross_track_max_m, 3),
        "coverage_points": pm.coverage_points,
        "coverage_spacing_m": POINT_SPACING_M,
        "max_pass_interval_s": r(pm.max_pass_interval_s, 3),
        "max_pass_interval_excl_alerts_s": r(pm.max_pass_interval_excl_alerts_s, 3),
        "mean_pass_interval_s": r(pm.mean_pass_interval_s, 3),
        "coverage_revisit_ratio": r(pm.coverage_revisit_ratio, 4),
        "coverage_revisit_ratio_excl_alerts": r(pm.coverage_revisit_ratio_excl_alerts, 4),
        "coverage_revisit_ratio_mission_wind": None
        if pm.max_pass_interval_s is None
        else round(pm.max_pass_interval_s / ideal_revisit_s, 4),
        "longest_unseen_s": r(pm.longest_unseen_s, 3),
        "longest_unseen_ratio": r(pm.longest_unseen_ratio, 4),
        "longest_unseen_excl_alerts_s": r(pm.longest_unseen_excl_alerts_s, 3),
        "longest_unseen_excl_alerts_ratio": r(pm.longest_unseen_excl_alerts_ratio, 4),
        "points_never_seen_in_window": pm.points_never_seen_in_window,
        "fraction_within_bounds": r(pm.fraction_within_bounds, 4),
        "fraction_within_bounds_excl_alerts": r(pm.fraction_within_bounds_excl_alerts, 4),
    }
