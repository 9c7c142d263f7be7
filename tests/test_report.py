"""Run reports: metrics against hand-built runs with known answers, and the plots."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from companion.commands.main import main
from companion.contracts.simulator import TRUTH_COLUMNS
from companion.report.metrics import compute_metrics
from companion.report.rundata import load_run

ROOT = Path(__file__).resolve().parents[1]
CIRCLE_MISSION = """\
version: 1
name: circle_4uav
origin: {lat_deg: 39.8, lon_deg: -84.0, alt_m: 200}
perimeter:
  ellipse: {semi_major_m: 300, semi_minor_m: 300}
wind: {speed_m_s: 0, from_deg: 0}
vehicles:
  count: 4
  airspeed_m_s: 20
  max_turn_rate_deg_s: 18
  initial: {line: {from: {north_m: 0, east_m: 0}, to: {north_m: 10, east_m: 0}, heading_deg: 0}}
sensor: {footprint_radius_m: 40}
"""
R, S0, N = 300.0, 20.0, 4
T = 2 * math.pi * R / S0


def write_ideal_run(folder: Path, lag_s: float = 0.0, duration_s: float = 600.0) -> None:
    """Four UAVs in perfect splay on a 300 m circle (calm air); UAV 4 lags by ``lag_s``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "mission.yaml").write_text(CIRCLE_MISSION)
    with open(folder / "truth.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(TRUTH_COLUMNS)
        for t in np.arange(0.0, duration_s + 1e-9, 0.1):
            for k in range(N):
                lag = lag_s if k == 3 else 0.0
                gamma = 2 * math.pi * ((t - lag) / T - k / N)  # clockwise, course increasing
                pos = R * np.exp(1j * (gamma - math.pi / 2))
                w.writerow(
                    [
                        round(t, 3),
                        k + 1,
                        pos.real,
                        pos.imag,
                        100.0,
                        math.degrees(gamma) % 360,
                        math.degrees(gamma) % 360,
                        S0,
                        math.degrees(S0 / R),
                        "GUIDED",
                    ]
                )
    (folder / "events.jsonl").write_text("")


def test_ideal_splay_has_revisit_ratio_one(tmp_path):
    write_ideal_run(tmp_path / "ideal")
    m = compute_metrics(load_run(tmp_path / "ideal"))
    assert m["loop_period_s"] == pytest.approx(T, abs=1e-3)
    assert m["ideal_revisit_s"] == pytest.approx(T / N, abs=1e-3)
    assert m["convergence_time_s"] == 0.0
    assert m["steady_splay_error_deg"] < 0.01 and m["steady_centre_error_m"] < 0.01
    assert m["mean_revisit_gap_s"] == pytest.approx(T / N, abs=0.11)
    assert m["revisit_ratio"] == pytest.approx(1.0, abs=0.11 / (T / N))


def test_a_lagging_uav_opens_a_known_gap(tmp_path):
    lag = 6.0  # UAV 4 six seconds late: the gap before it grows by 6 s, the next shrinks
    write_ideal_run(tmp_path / "lag", lag_s=lag)
    m = compute_metrics(load_run(tmp_path / "lag"))
    assert m["convergence_time_s"] is None  # 6 s of 94 s is 23 deg of splay error
    write_ideal_run(tmp_path / "lag2", lag_s=0.3)  # 1.15 deg: converged, small gap
    m2 = compute_metrics(load_run(tmp_path / "lag2"))
    assert m2["max_revisit_gap_s"] == pytest.approx(T / N + 0.3, abs=0.11)
    assert m2["steady_splay_error_deg"] == pytest.approx(360 * 0.3 / T, abs=0.01)


def test_report_of_a_simulated_run(simulated_run):
    m = json.loads((simulated_run / "metrics.json").read_text())
    for key in (
        "loop_period_s",
        "ideal_revisit_s",
        "convergence_time_s",
        "steady_splay_error_deg",
        "steady_centre_error_m",
        "max_revisit_gap_s",
        "mean_revisit_gap_s",
        "revisit_ratio",
        "alerts",
    ):
        assert key in m
    # the real stack in memory (companion simulate): judged by the model-free measures; the
    # course-based splay/centre diagnostics of an ideal particle fleet are not reached by
    # flown tracks in the time (tests/test_steering.py checks the law itself)
    assert m["settled"] and m["settle_time_s"] < 6 * m["loop_period_s"]
    assert m["coverage_revisit_ratio"] < 1.3
    assert m["alerts_raised"] == m["alerts_answered_by_one"] == 1
    (alert,) = m["alerts"]
    assert alert["outcome"] == "cleared" and alert["prosecutor_sysid"] != alert["detector_sysid"]
    assert 14 < alert["response_time_s"] < 20 and alert["planned_time_s"] > 0
    # each intruder judged from the truth: the decoy under the prosecutor's sensor, no false
    # clear, its episode's longest unseen within 1.5 T/N (the paper's case)
    (decoy,) = m["intruder_episodes"]
    assert decoy["kind"] == "decoy" and decoy["false_clears"] == decoy["lost_near"] == 0
    (pros,) = decoy["prosecutions"]
    assert pros["sysid"] == alert["prosecutor_sysid"] and pros["cover_over_plan"] <= 1.2
    assert decoy["episode"]["longest_unseen_ratio"] <= 1.5
    for name in ("map.png", "coverage.png", "errors.png"):
        data = (simulated_run / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_report_command_recomputes_the_same_metrics(simulated_run, capsys):
    before = (simulated_run / "metrics.json").read_text()
    (simulated_run / "metrics.json").unlink()
    assert main(["report", str(simulated_run), "--no-plots"]) == 0
    assert (simulated_run / "metrics.json").read_text() == before
    out = capsys.readouterr().out
    assert "revisit gap" in out
    assert "intruder paper-alert (decoy): covered after" in out and "false clears 0" in out


def test_report_of_a_folder_that_is_not_a_run(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "not a run folder" in capsys.readouterr().err
