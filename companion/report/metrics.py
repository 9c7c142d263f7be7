"""Metrics of a run (DESIGN section 8), computed from the truth log and the events.

The formation measures use what the companions share: a UAV away on an alert counts as its
virtual particle (centre c0, phase advancing at 2 pi / T from its phase when tasked).
Revisit gaps are measured over the converged part of the run with every UAV on the loop.
"""

from __future__ import annotations

import itertools

import numpy as np

from companion.core.measures import (
    CENTRE_TOL_M,
    SPLAY_TOL_DEG,
    convergence_time_s,
    splay_error_deg,
)
from companion.core.wind import TWO_PI
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
    splay = np.array([splay_error_deg(phases[:, j]) for j in range(t.size)])
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


def alert_records(run: RunData) -> list[dict]:
    """One record per prosecution: detection, tasking, plan, response, outcome, rejoin."""
    ev = sorted(run.events, key=lambda e: e.get("t_s", 0.0))
    detected = {}
    for e in ev:
        if e.get("event") == "alert_new" and e.get("own", True):
            detected.setdefault(e["alert_id"], e)
    out = []
    for away in run.away_windows():
        mine = [
            e
            for e in ev
            if e.get("sysid") == away.sysid
            and e.get("alert_id") == away.alert_id
            and away.t0_s <= e.get("t_s", 0.0) <= away.t1_s
        ]

        def first(name: str, mine: list[dict] = mine) -> dict | None:
            return next((e for e in mine if e.get("event") == name), None)

        plan, covered, end = first("plan"), first("site_covered"), first("prosecution_end")
        origin = detected.get(away.alert_id)
        # a hand-off starts from the confirmation that tasked this UAV
        confirm = [
            e
            for e in ev
            if e.get("event") == "prosecution_end"
            and e.get("alert_id") == away.alert_id
            and e.get("outcome") == "confirmed"
            and e.get("t_s", 0.0) <= away.t0_s
        ]
        t_alert = confirm[-1]["t_s"] if confirm else (origin["t_s"] if origin else away.t0_s)
        rejoined = first("rejoined")
        out.append(
            {
                "alert_id": away.alert_id,
                "detected_t_s": origin["t_s"] if origin else None,
                "detector_sysid": origin["sysid"] if origin else None,
                "tasked_t_s": away.t0_s,
                "prosecutor_sysid": away.sysid,
                "planned_time_s": plan["planned_time_s"] if plan else None,
                "response_time_s": round(covered["t_s"] - t_alert, 3) if covered else None,
                "outcome": end["outcome"] if end else None,
                "rejoin_time_s": round(rejoined["t_s"] - end["t_s"], 3)
                if rejoined and end
                else None,
            }
        )
    return out


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
    metrics["alerts"] = alert_records(run)
    return metrics
