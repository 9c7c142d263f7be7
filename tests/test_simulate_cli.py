"""``companion simulate`` as a user runs it: a real process, its files and its summary.

The engine is the in-memory one (the simulator's vehicles and the real companions,
:mod:`companion.sim.inmemory`): the truth log is the simulator's, from t = 0.1 s, and its mode
column is the autopilot's mode.
"""

import csv
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from companion.core.measures import convergence_time_s, splay_error_deg

ROOT = Path(__file__).resolve().parents[1]
COLUMNS = (
    "t_s,sysid,north_m,east_m,alt_m,heading_deg,course_deg,groundspeed_m_s,turn_rate_deg_s,mode,"
    "wind_north_m_s,wind_east_m_s"
)


def test_simulate_writes_truth_and_prints_measures(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "companion",
            "simulate",
            str(ROOT / "missions/ellipse_6uav.yaml"),
            "--duration",
            "60",
            "--out",
            str(out),
            "--seed",
            "3",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    # first, what it is sure to see: 2 r_s N / T = 100 m x 6 / 102.49 s (docs/design.md §3)
    assert proc.stdout.startswith(
        "simulate: crossings sure to be seen: up to 5.85 m/s with 6 UAVs on the loop"
    )
    assert "splay error" in proc.stdout and "centre error" in proc.stdout
    assert "convergence time" in proc.stdout and "simulated in" in proc.stdout
    lines = (out / "truth.csv").read_text().splitlines()
    assert lines[0] == COLUMNS
    rows = list(csv.DictReader(lines))
    per_vehicle = Counter(int(r["sysid"]) for r in rows)
    assert sorted(per_vehicle) == [1, 2, 3, 4, 5, 6]
    assert min(per_vehicle.values()) >= 10 * 60  # at least 10 samples per simulated second
    first = [r for r in rows if r["t_s"] == "0.100"]
    assert len(first) == 6 and all(abs(float(r["east_m"])) < 1.0 for r in first)
    assert {r["mode"] for r in rows} == {"GUIDED"}  # the companions steered all along
    # course and ground speed are consistent with the heading, the wind (5 m/s from the
    # south) and an airspeed within the phase hold's 2 m/s of the mission's 20 m/s
    r = rows[-1]
    ground = float(r["groundspeed_m_s"]) * np.exp(1j * np.radians(float(r["course_deg"])))
    air = ground - 5.0
    assert abs(abs(air) - 20.0) <= 2.0 + 0.01
    heading_error = np.angle(air * np.exp(-1j * np.radians(float(r["heading_deg"]))))
    assert abs(np.degrees(heading_error)) < 0.01
    assert (out / "events.jsonl").exists() and (out / "metrics.json").exists()


def test_truth_log_alone_reproduces_the_printed_splay_error(simulated_run):
    """The truth log carries enough to recompute the formation measure independently."""
    out = simulated_run
    rows = list(csv.DictReader((out / "truth.csv").read_text().splitlines()))
    last_t = rows[-1]["t_s"]
    last = [r for r in rows if r["t_s"] == last_t]
    # time-phase from the loop: recompute from positions by the nearest point's phase
    from companion.mission import load_mission

    patrol = load_mission(ROOT / "missions/ellipse_6uav.yaml").patrol
    phases = [
        patrol.nearest(complex(float(r["north_m"]), float(r["east_m"]))).phase_rad for r in last
    ]
    assert splay_error_deg(phases) < 2.0
    assert convergence_time_s([0.0, 1.0], [3.0, 1.0], [1.0, 1.0]) == 1.0


def test_paper_mission_claims_hold_in_memory(simulated_run):
    """The paper's mission (missions/ellipse_6uav.yaml, the README demo) with the real stack
    in memory: converged before the decoy (604 s); the decoy at north 230, east -200 is
    prosecuted by exactly the next UAV in sequence, which every companion tasked, arriving
    within 5 % of its plan; it is cleared and the prosecutor rejoins in its slot; the others
    stay within 2 m of the loop and their course-based centre error does not rise. The same
    checks over loopback UDP are ``tests/test_companion_fleet.py::test_paper_mission``
    (extended tier)."""
    import json

    from tests.fleet_harness import PAPER, episode, truth_measures

    m = truth_measures(simulated_run)
    events = [json.loads(x) for x in (simulated_run / "events.jsonl").read_text().splitlines()]
    events = [e for e in events if e.get("source") == "companion"]
    t_alert = min(e["t_s"] for e in events if e["event"] == "alert_new")
    ep = episode(m, events, PAPER, complex(230, -200))
    print("paper in memory:", t_alert, m.convergence_time_s(t_alert), ep)
    assert m.convergence_time_s(t_alert) is not None and t_alert >= 600.0
    assert ep["prosecutors"] == {ep["prosecutor"]} and ep["prosecutor"] == ep["expected"]
    assert set(ep["tasked_by"].values()) == {ep["prosecutor"]} and len(ep["tasked_by"]) == 6
    assert abs(ep["arrive_s"] - ep["planned_s"]) <= 0.05 * ep["planned_s"]
    assert ep["outcome"] == "cleared"
    assert ep["rejoined"] is not None and ep["rejoined"]["in_slot"]
    assert ep["others_max_offset_m"] < 2.0
    assert ep["others_max_centre_m"] <= ep["others_max_centre_before_m"] + 0.5
