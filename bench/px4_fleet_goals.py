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

The splay of docs/design.md §8 reads each UAV's phase from its ground course, and PX4's reported
velocity (GLOBAL_POSITION_INT) is 1.4-1.6 deg off the course of its own positions at p95:
on the ellipse's flat sides that is metres of phase. So it also prints the splay of where
the aircraft are along the loop (each one's nearest loop point, sampled each second, away
windows left out) and that course noise, per UAV.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.core.measures import splay_error_deg
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


def along_splay_deg(run, t0_s: float, t1_s: float) -> np.ndarray:
    """Splay error (deg, docs/design.md §8's pairs) of the UAVs' time-phases (in ``run``'s
    mission wind) of their nearest loop points, each whole second from ``t0_s`` to ``t1_s``
    (s) that no UAV spends away on an alert."""
    patrol = run.mission.patrol
    times = np.arange(np.ceil(t0_s), t1_s + 1e-9, 1.0)
    for away in run.away_windows():
        times = times[(times < away.t0_s) | (times > away.t1_s)]
    phases = []
    for tr in run.tracks.values():
        idx = np.minimum(np.searchsorted(tr.t_s, times), len(tr.t_s) - 1)
        phases.append([patrol.phase_of_point(complex(z)) for z in tr.pos_m[idx]])
    ph = np.asarray(phases)
    return np.array([splay_error_deg(ph[:, j]) for j in range(times.size)])


def course_noise_deg(run, t0_s: float, t1_s: float) -> list[tuple[int, tuple[float, float]]]:
    """Per sysid: the reported ground course less the course between its successive
    positions (deg), median and p95 of its size, from ``t0_s`` to ``t1_s`` (s)."""
    out = []
    for sysid, tr in sorted(run.tracks.items()):
        dp, dt = np.diff(tr.pos_m), np.diff(tr.t_s)
        keep = (dt > 0) & (tr.t_s[1:] >= t0_s) & (tr.t_s[1:] <= t1_s)
        d = np.degrees(np.angle(np.exp(1j * (tr.course_rad[1:][keep] - np.angle(dp[keep])))))
        out.append((sysid, (float(np.median(d)), float(np.percentile(np.abs(d), 95)))))
    return out


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
    if window.any():
        along = along_splay_deg(run_true, m["window_start_s"], m["window_end_s"])
        print(
            f"  splay of where they are along the loop (nearest loop points, each second): "
            f"median {np.median(along):.2f} deg, p95 {np.percentile(along, 95):.2f} deg, max "
            f"{along.max():.2f} deg over {along.size} s"
        )
        for sysid, (med, p95) in course_noise_deg(run, m["window_start_s"], m["window_end_s"]):
            print(
                f"  UAV {sysid}: reported course - course of its positions: median {med:+.2f} "
                f"deg, p95 of its size {p95:.2f} deg"
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
