"""A run folder's report: ``metrics.json`` (and the plots) written, and the headline lines
printed by ``companion simulate``, ``companion fleet`` and ``companion report``."""

from __future__ import annotations

import json
from pathlib import Path

from companion.core.guarantee import describe
from companion.report.episodes import episode_measures, format_episode
from companion.report.metrics import compute_metrics, formation_series
from companion.report.rundata import load_run


def write_report(folder: Path, plots: bool = True) -> dict:
    """Compute and write the metrics (and plots) of ``folder``; returns the metrics."""
    data = load_run(folder)
    metrics = compute_metrics(data)
    # each intruder's answer, judged from the truth (companion/report/episodes.py)
    metrics["intruder_episodes"] = episode_measures(data)
    # the fastest crossing the patrol is sure to see, with 0, 1, 2 away (core/guarantee.py)
    metrics["crossing_guarantee"] = [g.as_dict() for g in data.mission.crossing_guarantees()]
    metrics |= _run_info(folder)
    (folder / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    if plots:
        # matplotlib only when plotting: its import is about a third of a second of every
        # `companion simulate` and `companion fleet` without --report
        from companion.report.plots import plot_coverage, plot_errors, plot_map

        plot_map(data, folder / "map.png")
        plot_coverage(data, folder / "coverage.png")
        plot_errors(data, formation_series(data), folder / "errors.png")
    return metrics


def _run_info(folder: Path) -> dict:
    """``run_info.json`` of a run on real firmware (truth source, time base, clocks) or {}."""
    path = folder / "run_info.json"
    try:
        info = json.loads(path.read_text()) if path.is_file() else {}
    except (OSError, json.JSONDecodeError):
        return {}
    return info if isinstance(info, dict) else {}


def headline(m: dict) -> list[str]:
    """The model-free headline of a metrics dict: cross-track, coverage revisit, longest
    unseen, fraction of time within bounds (older metrics without them: nothing)."""
    if "cross_track_p95_m" not in m:
        return []

    def f(v: object, fmt: str) -> str:
        return "n/a" if v is None else format(v, fmt)

    def pct(v: float | None) -> str:
        return "n/a" if v is None else f"{100 * v:.1f} %"

    window = f"from {f(m['window_start_s'], '.0f')} to {f(m['window_end_s'], '.0f')} s " + (
        f"(settled at {f(m['settle_time_s'], '.0f')} s)"
        if m["settled"]
        else "(never settled: second half of the run)"
    )
    return [
        f"cross-track median {f(m['cross_track_median_m'], '.2f')} m, p95 "
        f"{f(m['cross_track_p95_m'], '.2f')} m, max {f(m['cross_track_max_m'], '.2f')} m; "
        f"coverage revisit {f(m['coverage_revisit_ratio'], '.3f')}; longest unseen "
        f"{f(m['longest_unseen_s'], '.1f')} s ({f(m['longest_unseen_ratio'], '.2f')} T/N); "
        f"within bounds {pct(m['fraction_within_bounds'])} of the time",
        f"  excluding alert episodes: coverage revisit "
        f"{f(m['coverage_revisit_ratio_excl_alerts'], '.3f')}, longest unseen "
        f"{f(m['longest_unseen_excl_alerts_s'], '.1f')} s "
        f"({f(m['longest_unseen_excl_alerts_ratio'], '.2f')} T/N), within bounds "
        f"{pct(m['fraction_within_bounds_excl_alerts'])}; window {window}; T/N "
        f"{f(m.get('reference_ideal_revisit_s'), '.2f')} s in the "
        + (
            "mission's wind"
            if str(m.get("reference_rule", "")).startswith("mission")
            else f"true wind ({f(m.get('reference_wind_speed_m_s'), '.1f')} m/s from "
            f"{f(m.get('reference_wind_from_deg'), '.0f')} deg{_world_wind(m.get('world_wind'))})"
        ),
    ]


def _world_wind(ww: object) -> str:
    """Where a run on real firmware took its world's wind from (``run_info.json``), as a
    clause of the headline ("" for our own simulator, whose truth log has the wind)."""
    if not isinstance(ww, dict) or "source" not in ww:
        return ""
    try:
        said = f"{float(ww['mission_speed_m_s']):.1f} m/s from {float(ww['mission_from_deg']):.0f}"
    except (KeyError, TypeError, ValueError):
        return f": {ww['source']}"
    return f": {ww['source']}; the mission says {said} deg"


def summary(m: dict) -> str:
    """Headline figures of a metrics dict, a few lines of text."""

    def f(v: object, fmt: str) -> str:
        return "n/a" if v is None else format(v, fmt)

    lines = [
        *headline(m),
        f"loop period {f(m['loop_period_s'], '.2f')} s, ideal revisit "
        f"{f(m['ideal_revisit_s'], '.2f')} s",
        f"diagnostics: convergence time {f(m['convergence_time_s'], '.1f')} s, steady splay "
        f"error {f(m['steady_splay_error_deg'], '.3f')} deg, steady centre error "
        f"{f(m['steady_centre_error_m'], '.2f')} m",
        f"revisit gap max {f(m['max_revisit_gap_s'], '.2f')} s, mean "
        f"{f(m['mean_revisit_gap_s'], '.2f')} s, ratio {f(m['revisit_ratio'], '.3f')}",
    ]
    for a in m["alerts"]:
        lines.append(
            f"alert {a['alert_id']}: UAV {a['prosecutor_sysid']} planned "
            f"{f(a['planned_time_s'], '.1f')} s, response {f(a['response_time_s'], '.1f')} s, "
            f"{a['outcome']}, rejoined after {f(a['rejoin_time_s'], '.1f')} s"
            + (
                f"; response / plan {a['response_over_plan']:.2f}"
                if a.get("response_over_plan") is not None
                else ""
            )
        )
    if m.get("crossing_guarantee"):
        lines.append(describe(m["crossing_guarantee"]))
    end_s = m.get("duration_s")
    for rec in m.get("intruder_episodes") or []:
        if end_s is None or rec["appear_t_s"] < end_s:  # not one the run ended before
            lines.append("intruder " + format_episode(rec))
    if m.get("alerts_not_answered_by_one"):
        lines.append(
            "alerts not answered by exactly one UAV: " + ", ".join(m["alerts_not_answered_by_one"])
        )
    if m.get("truth_source"):
        lines.append(f"truth: {m['truth_source']}")
    sk = m.get("clock_skew_s")
    if sk:
        lines.append(
            f"clocks: instances apart by {f(sk.get('median'), '.3f')} s median, "
            f"{f(sk.get('max'), '.3f')} s max ({f(sk.get('first'), '.3f')} s at the start, "
            f"{f(sk.get('last'), '.3f')} s at the end, over {sk.get('over_vehicle_s')} s); "
            "speed-ups "
            + ", ".join(f"{k}: {v:.2f}x" for k, v in m.get("achieved_speedup", {}).items())
        )
    hold = {e.get("event"): e for e in m.get("handover") or []}
    if "handover_hold" in hold and "handover_release" in hold:
        rel = hold["handover_release"]
        lines.append(
            f"hand-over: clocks held from {hold['handover_hold']['t_s']:.1f} to "
            f"{rel['t_s']:.1f} s while the companions took control"
            + ("" if rel.get("all_guided") else " (released by the timeout, not all in GUIDED)")
        )
    return "\n".join(lines)
