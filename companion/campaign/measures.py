"""One run's measures as one flat table row: plain dicts in, a dict of scalars out.

From the run's ``metrics.json`` (:func:`companion.report.metrics.compute_metrics`) every
scalar that is model-free: everything but the text (rules, the mission's name), the lists
(alerts, per prosecution) and the formation diagnostics of :data:`DIAGNOSTICS` (splay,
centre and their convergence, which use what the companions share; ``docs/robustness.md``).
A key that is also a column saying what was run (``duration_s``) is kept as ``metrics_KEY``.

From its alert episodes (:func:`companion.report.episodes.episode_measures`, one record per
intruder) a per-run summary, the worst of each measure over the intruders (None: nothing to
measure, e.g. no intruder detected): see :data:`ALERT_COLUMNS`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

DIAGNOSTICS = frozenset(
    {
        "convergence_time_s",
        "steady_splay_error_deg",
        "steady_centre_error_m",
        "max_revisit_gap_s",
        "mean_revisit_gap_s",
        "revisit_ratio",
        "final_splay_error_deg",
        "final_centre_error_m",
        "window_splay_error_median_deg",
        "window_centre_error_median_m",
    }
)
"""``metrics.json`` keys left out of a row: the formation diagnostics (model-based)."""

ALERT_COLUMNS: dict[str, str] = {
    "intruders": "intruders in the mission's scenario",
    "intruders_detected": "intruders some sensor covered",
    "intruders_alerted": "intruders an alert was raised for",
    "detect_max_s": "longest time from appearing to first sensor coverage (s)",
    "first_alert_max_s": "longest time from appearing to the first alert (s)",
    "prosecutions": "prosecutions flown (tasking to rejoin)",
    "cover_over_plan_max": "worst tasking-to-sensor-over-the-intruder time / its plan",
    "response_over_plan_max": "worst alert response / plan (metrics.json alerts)",
    "under_track_min": "least share of an intruder's time inside the fence under track",
    "longest_unwatched_max_s": "longest an intruder inside the fence went unwatched (s)",
    "false_clears": "alerts cleared while the intruder sat under the UAV",
    "episode_unseen_max_ratio": "worst longest-unseen over an alert episode (T/N)",
    "back_on_loop_max_ratio": "longest from a prosecution's end to back on the loop (T/N)",
    "excursion_max_m": "largest distance of a prosecutor from the loop (m)",
}

Scalar = bool | int | float | str | None


def metric_columns(metrics: dict, taken: Iterable[str] = ()) -> dict[str, Scalar]:
    """The model-free scalars of a ``metrics.json`` dict (units in their names); a key in
    ``taken`` (the run's own columns) becomes ``metrics_KEY``."""
    taken = set(taken)
    out: dict[str, Scalar] = {}
    for key, value in metrics.items():
        if key in DIAGNOSTICS or isinstance(value, str | list | dict):
            continue
        out[f"metrics_{key}" if key in taken else key] = value
    return out


def alert_columns(episodes: list[dict], alerts: list[dict]) -> dict[str, Scalar]:
    """The per-run summary of the episodes (one dict per intruder) and of ``metrics.json``'s
    ``alerts`` (one dict per prosecution); keys and meanings in :data:`ALERT_COLUMNS`."""
    pros = [p for e in episodes for p in e["prosecutions"]]
    eps = [e["episode"] for e in episodes if e.get("episode")]
    return {
        "intruders": len(episodes),
        "intruders_detected": sum(e["detect_s"] is not None for e in episodes),
        "intruders_alerted": sum(e["alert_s"] is not None for e in episodes),
        "detect_max_s": _max(e["detect_s"] for e in episodes),
        "first_alert_max_s": _max(e["alert_s"] for e in episodes),
        "prosecutions": len(pros),
        "cover_over_plan_max": _max(p["cover_over_plan"] for p in pros),
        "response_over_plan_max": _max(a.get("response_over_plan") for a in alerts),
        "under_track_min": _min(e["under_track_fraction"] for e in episodes),
        "longest_unwatched_max_s": _max(e["longest_unwatched_s"] for e in episodes),
        "false_clears": sum(int(e["false_clears"]) for e in episodes),
        "episode_unseen_max_ratio": _max(x["longest_unseen_ratio"] for x in eps),
        "back_on_loop_max_ratio": _max(p["back_on_loop_ratio"] for p in pros),
        "excursion_max_m": _max(p["max_excursion_m"] for p in pros),
    }


def run_columns(metrics: dict, episodes: list[dict], taken: Iterable[str]) -> dict[str, Scalar]:
    """A run's measures: :func:`metric_columns` then :func:`alert_columns`."""
    return metric_columns(metrics, taken) | alert_columns(episodes, metrics.get("alerts", []))


def _finite(values: Iterable[float | None]) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(v)]


def _max(values: Iterable[float | None]) -> float | None:
    vals = _finite(values)
    return max(vals) if vals else None


def _min(values: Iterable[float | None]) -> float | None:
    vals = _finite(values)
    return min(vals) if vals else None
