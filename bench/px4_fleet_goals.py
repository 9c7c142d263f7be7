"""Issue 23's goals for a ``companion fleet --autopilot px4`` run folder, docs/px4.md.

    companion fleet missions/ellipse_6uav.yaml --autopilot px4 --out runs/px4-6
    python bench/px4_fleet_goals.py runs/px4-6

Reads the run's ``metrics.json`` (the report), ``truth.csv`` (when the take-off began: the
first AUTO.TAKEOFF row) and the formation series of the report, and prints against the goals:
cross-track p95 (m), coverage revisit (worst pass interval / (T/N), alert episodes excused),
splay (deg) after convergence; the alert's answer (by how many UAVs, response / plan); and
convergence from the take-off in loop periods, by the report's settle rule (every patrolling
UAV within 10 m of the loop, no loop point unseen too long, for a loop period) and by its
strict rule (splay < 2 deg and centre < 5 m hold). PX4's SIH has no wind: still air.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.mission.model import WindSpec
from companion.report.metrics import formation_series
from companion.report.rundata import load_run


def takeoff_s(folder: Path) -> float | None:
    """Vehicle time (s) of the first AUTO.TAKEOFF row of the truth log, or None."""
    with open(folder / "truth.csv") as fh:
        for row in csv.DictReader(fh):
            if row["mode"] == "AUTO.TAKEOFF":
                return float(row["t_s"])
    return None


def main(argv: list[str] | None = None) -> int:
    """Print the goals' figures for one run folder."""
    folder = Path((argv or sys.argv[1:])[0])
    m = json.loads((folder / "metrics.json").read_text())
    run = load_run(folder)
    period = m.get("reference_loop_period_s") or m["loop_period_s"]  # in the true (still) air
    t0 = takeoff_s(folder)
    # the report's formation series uses the mission's wind; the splay and centre here use
    # the true wind the truth log carries (PX4's SIH: still air), as the coverage does
    true_wind = WindSpec(m["reference_wind_speed_m_s"], m["reference_wind_from_deg"], 0.0)
    run_true = dataclasses.replace(run, mission=dataclasses.replace(run.mission, wind=true_wind))
    series = formation_series(run_true)
    t, splay, centre = series["t_s"], series["splay_deg"], series["centre_m"]
    mission_series = formation_series(run)
    window = (t >= m["window_start_s"]) & (t <= m["window_end_s"])

    def periods(x: float | None) -> str:
        return "n/a" if x is None or t0 is None else f"{(x - t0) / period:.2f} T"

    print(
        f"run {folder}: {m['mission']}, {m['vehicles']} UAVs, {m['duration_s']:g} s, T {period} s"
    )
    print(
        f"  take-off at {t0} s; settled (report's rule) at {m['settle_time_s']} s = "
        f"{periods(m['settle_time_s'])} after take-off; strict convergence "
        f"{m['convergence_time_s']} s = {periods(m['convergence_time_s'])} (goal <= 8 T)"
    )
    print(f"  window {m['window_start_s']}-{m['window_end_s']} s (settled: {m['settled']})")
    print(
        f"  cross-track median {m['cross_track_median_m']} m, p95 {m['cross_track_p95_m']} m, "
        f"max {m['cross_track_max_m']} m (goal p95 <= 10)"
    )
    print(
        f"  coverage revisit {m['coverage_revisit_ratio_excl_alerts']} alert episodes excused, "
        f"{m['coverage_revisit_ratio']} with them (goal <= 1.15)"
    )
    if window.any():
        print(
            f"  splay in the window: median {np.median(splay[window]):.2f} deg, p95 "
            f"{np.percentile(splay[window], 95):.2f} deg, max {splay[window].max():.2f} deg; "
            f"centre error median {np.median(centre[window]):.1f} m (goal splay < 2), in the "
            f"true wind ({true_wind.speed_m_s:g} m/s); in the mission's wind "
            f"({run.mission.wind.speed_m_s:g} m/s, the report's): splay median "
            f"{np.median(mission_series['splay_deg'][window]):.2f} deg"
        )
    print(
        f"  alerts raised {m['alerts_raised']}, answered by exactly one UAV "
        f"{m['alerts_answered_by_one']}"
    )
    for a in m["alerts"]:
        print(
            f"  alert {a['alert_id']}: UAV {a['prosecutor_sysid']} planned "
            f"{a['planned_time_s']} s, response {a['response_time_s']} s, response / plan "
            f"{a.get('response_over_plan')} (goal within 10 %), {a['outcome']}"
        )
    for key in ("clock_skew_s", "achieved_speedup", "paused_wall_s", "handover"):
        if key in m:
            print(f"  {key}: {m[key]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
