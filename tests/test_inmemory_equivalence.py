"""The in-memory engine against a lockstepped UDP fleet on the same mission and seed.

``companion fleet`` (simulator and companions as processes over loopback UDP, lockstep)
flies the fast test mission; then ``companion.sim.inmemory`` flies it with each companion
started as the fleet's was: half a second before the autopilot HEARTBEAT (1 Hz, on whole
simulated seconds) that preceded its vehicle's ``guided_resumed`` (its first setpoint, a
few steps after that heartbeat). Before that, in both,
the vehicles fly uncommanded (GUIDED timeout at 3 s, then a loiter) while the fleet sets
up. That loiter can change the order of the six along the loop: which sysid takes which
place in the formation depends on take-over instants a tenth of a second apart (in one CI
run UAVs 1 and 2 had swapped places in the UDP run and not in memory), and so does where
the whole formation is along the loop when the decoy appears: in another CI run (UDP
take-over at 7.04-7.06 s, in memory 7.02 s) the decoy was first seen 14 s later over UDP
(194.15 s, by UAV 2) than in memory (180.15 s, by UAV 3), one splay interval (17.1 s) being
the most it can differ. Which UAV sees it first and when is therefore not compared. The
decoy is compared by place: prosecuted by the UAV at the same place behind its detector
along the loop, cleared in both, with its response against its plan and the run metrics
within the tolerances below (the two differ by their scheduling and the exact
take-over instants, so they are compared on outcomes and statistics, not bytes). The
take-over leaves the six up to 80 m off the loop and a few steps' difference in it gives
different transients (whole-run cross-track medians 3.9 and 1.7 m in one CI run), so the
cross-track is compared once both are back in patrol, after the decoy's prosecution.
Since the answer follows the decoy's track (issue 21), a decoy that one run's detector saw for
a whole pass and the other's for a second or two (the formation sits elsewhere along the loop
when it appears) is answered differently: a well-known still intruder is cleared at once, an
uncertain one is searched first (up to 2 T/N) and its prosecutor may then hand back its state
on the loop, the formation reshuffling. The runs are then not the same episode: the figures
after it are printed, and only the formation before the decoy and the outcome are compared.
The same when its prosecutor, searched in both, handed back its state on the loop (not in
its slot): the formation then re-splays along the loop by airspeed (a formed formation does
not fly off the loop to re-splay), which takes minutes and goes as the hand-back instant
and place put it (settled cross-track p95 1.9 m over UDP and 5.8 m in memory in one run;
before, the acquisition law took the same re-splay 49 m off the loop in memory).
The fleet's run is also checked as a user's run: its files, logs and summary.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.report.metrics import loop_geometry
from companion.report.rundata import load_run
from companion.sim.inmemory import Engine, EngineConfig

pytestmark = [pytest.mark.integration, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[1]
FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"
DURATION_S = 380.0  # the decoy appears at 180 s; its prosecutor is back by about 230 s
SETTLED_S = (240.0, DURATION_S)  # s: the window of the settled cross-track comparison
BEFORE_S = (120.0, 178.0)  # s: the formation alone, converged, before the decoy
TOLERANCES = {  # metric -> largest |UDP - in memory|
    "mean_pass_interval_s": 0.5,  # s, of about 17 s
    "settled_cross_track_median_m": 1.0,  # m
    "settled_cross_track_p95_m": 3.0,  # m
}


def settled_cross_track_m(folder: Path) -> tuple[float, float]:
    """Median and p95 (m) of every UAV's true distance from the loop over ``SETTLED_S``."""
    run = load_run(folder)
    _, loop = loop_geometry(run.mission.patrol)
    d = []
    for tr in run.tracks.values():
        sel = (tr.t_s >= SETTLED_S[0]) & (tr.t_s <= SETTLED_S[1])
        d.append(loop.distance_m(tr.pos_m[sel]))
    allx = np.concatenate(d)
    return float(np.median(allx)), float(np.percentile(allx, 95))


def before_decoy_m(folder: Path) -> tuple[float, float]:
    """Median and p95 (m) of every UAV's true distance from the loop over ``BEFORE_S``."""
    run = load_run(folder)
    _, loop = loop_geometry(run.mission.patrol)
    d = []
    for tr in run.tracks.values():
        sel = (tr.t_s >= BEFORE_S[0]) & (tr.t_s <= BEFORE_S[1])
        d.append(loop.distance_m(tr.pos_m[sel]))
    allx = np.concatenate(d)
    return float(np.median(allx)), float(np.percentile(allx, 95))


def searched_decoy(folder: Path) -> bool:
    """Whether the decoy's prosecutor searched for it (its track was uncertain)."""
    lines = (folder / "events.jsonl").read_text().splitlines()
    return any(json.loads(x)["event"] == "search_started" for x in lines)


def handed_back_in_slot(folder: Path) -> bool:
    """Whether every prosecutor that rejoined was back in its slot when it handed back."""
    lines = (folder / "events.jsonl").read_text().splitlines()
    ends = [json.loads(x) for x in lines if json.loads(x)["event"] == "rejoined"]
    return all(ev.get("in_slot", False) for ev in ends)


def take_over_times(events: Path) -> dict[int, float]:
    """Simulated time (s) of each vehicle's first setpoint: its first ``guided_resumed``,
    or, where its companion was already commanding when the autopilot's GUIDED time-out
    came due (no time-out, so nothing resumed), the companion's first command
    (``guided_targets``), sent in the same step as its first setpoint. On an idle machine
    the UDP companions' first command came at 3.02 s, the time-out's instant: the UDP
    autopilots timed out at 3.02 and resumed at 3.04, the in-memory ones never timed out."""
    resumed: dict[int, float] = {}
    first: dict[int, float] = {}
    for line in events.read_text().splitlines():
        ev = json.loads(line)
        if ev["event"] == "guided_resumed" and ev.get("source") == "sim":
            resumed.setdefault(int(ev["sysid"]), float(ev["t_s"]))
        elif ev["event"] == "guided_targets" and ev.get("source") == "companion":
            first.setdefault(int(ev["sysid"]), float(ev["t_s"]))
    return {**first, **resumed}


def decoy(metrics: dict) -> tuple[int, int, str]:
    """(detector, first prosecutor, final outcome) of the decoy's alert."""
    rows = metrics["alerts"]
    return rows[0]["detector_sysid"], rows[0]["prosecutor_sysid"], rows[-1]["outcome"]


def prosecutor_place(folder: Path, metrics: dict) -> int:
    """Where the decoy's first prosecutor was when it was detected: 1 for the UAV next
    behind the detector along the loop, 2 for the one behind that, and so on (from the
    truth log's positions at the detection, read as the loop's time-phases)."""
    from tests.fleet_harness import true_phases_at

    row = metrics["alerts"][0]
    phase = true_phases_at(folder, row["detected_t_s"])
    det = row["detector_sysid"]
    behind = {s: (phase[det] - p) % (2 * math.pi) for s, p in phase.items() if s != det}
    return 1 + sorted(behind, key=behind.get).index(row["prosecutor_sysid"])


def fleet_run_is_complete(out: Path, stdout: str) -> None:
    """What ``companion fleet`` leaves behind: no process, every file of the report, the
    truth log's columns, the merged events in time order, the decoy answered (not found)
    by a UAV other than its detector, tlogs pymavlink reads, a summary on stdout."""
    from pymavlink import mavutil

    from tests.fleet_harness import leftovers

    assert leftovers(str(out)) == []
    for name in ("truth.csv", "events.jsonl", "metrics.json", "mission.yaml"):
        assert (out / name).is_file(), name
    for name in ("map.png", "coverage.png", "errors.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    header = (out / "truth.csv").read_text().splitlines()[0]
    assert header == (
        "t_s,sysid,north_m,east_m,alt_m,heading_deg,course_deg,groundspeed_m_s,turn_rate_deg_s,"
        "mode,wind_north_m_s,wind_east_m_s"
    )
    events = [json.loads(x) for x in (out / "events.jsonl").read_text().splitlines()]
    times = [e["t_s"] for e in events]
    assert times == sorted(times) and times[0] >= 0 and times[-1] <= DURATION_S + 10
    assert {e.get("source") for e in events} == {"sim", "companion"}  # both merged
    m = json.loads((out / "metrics.json").read_text())
    # the decoy not found: "cleared", or "lost" when its detection was too short for the
    # sensor to cover its region (companion/agent/alerts/prosecution.py; UDP runs differ)
    decoy = [a for a in m["alerts"] if a["outcome"] in ("cleared", "lost")]
    assert len(decoy) == 1 and decoy[0]["prosecutor_sysid"] != decoy[0]["detector_sysid"]
    assert decoy[0]["planned_time_s"] > 0
    log = mavutil.mavlink_connection(str(out / "uav1" / "autopilot.tlog"))
    assert log.recv_match(type="HEARTBEAT") is not None
    log.close()
    assert "wrote" in stdout and "alert" in stdout


def test_in_memory_and_lockstep_udp_agree(tmp_path):
    udp, mem = tmp_path / "udp", tmp_path / "mem"
    p = subprocess.run(
        [sys.executable, "-m", "companion", "fleet", str(FAST), "--duration", f"{DURATION_S:g}",
         "--out", str(udp), "--no-progress"],
        cwd=REPO, capture_output=True, text=True, timeout=1800,
    )  # fmt: skip
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    fleet_run_is_complete(udp, p.stdout)
    starts = take_over_times(udp / "events.jsonl")
    assert len(starts) == 6, starts
    at = {s: math.floor(t - 1e-3) - 0.5 for s, t in starts.items()}
    cfg = EngineConfig(FAST, mem, start_s=at)
    with Engine(cfg) as e:
        e.run(DURATION_S)
        e.close()
    from companion.report.summary import write_report

    m_udp = json.loads((udp / "metrics.json").read_text())
    m_mem = write_report(mem, plots=False)
    for m, folder in ((m_udp, udp), (m_mem, mem)):
        med, p95 = settled_cross_track_m(folder)
        m["settled_cross_track_median_m"], m["settled_cross_track_p95_m"] = med, p95
    mem_starts = take_over_times(mem / "events.jsonl")
    sim_events = [json.loads(ln) for ln in (udp / "sim_events.jsonl").read_text().splitlines()]
    left_behind = [e for e in sim_events if e["event"] == "lockstep_wait_timeout"]
    figures = {
        "lockstep_wait_timeouts": len(left_behind),
        "take_over_s": {s: (starts[s], mem_starts.get(s)) for s in sorted(starts)},
        "decoy (detector, prosecutor, outcome)": (decoy(m_udp), decoy(m_mem)),
        "decoy prosecutor's place": (prosecutor_place(udp, m_udp), prosecutor_place(mem, m_mem)),
        "alerts": (m_udp["alerts"], m_mem["alerts"]),
        **{
            k: (m_udp[k], m_mem[k])
            for k in (*TOLERANCES, "cross_track_median_m", "max_pass_interval_s")
        },
    }
    print("equivalence (UDP lockstep, in memory):", json.dumps(figures))
    # a lockstepped run that went on without a companion is not the same run (see the bound
    # in docs/sitl.md); say so rather than compare it
    assert not left_behind, ("the UDP fleet left a companion behind", left_behind)
    assert all(abs(starts[s] - mem_starts[s]) < 0.3 for s in starts), figures
    for m in (m_udp, m_mem):
        det, pros, outcome = decoy(m)
        # not found: "cleared" where its prediction's region was covered, "lost" where the
        # detection was short enough that it was not (companion/agent/alerts/prosecution.py)
        assert outcome in ("cleared", "lost") and pros != det, figures
    assert figures["decoy prosecutor's place"][0] == figures["decoy prosecutor's place"][1]
    # the plan depends on the exact instant of detection (0.6 s apart gave 16.6 and 18.8 s in
    # CI), so the response is compared as flown against its plan
    q_udp, q_mem = (m["alerts"][0]["response_over_plan"] for m in (m_udp, m_mem))
    assert abs(q_udp - q_mem) <= 0.05, figures  # of about 0.9
    before = [before_decoy_m(folder) for folder in (udp, mem)]
    print("before the decoy (UDP, in memory): cross-track median, p95 m:", before)
    assert abs(before[0][0] - before[1][0]) <= 1.0 and abs(before[0][1] - before[1][1]) <= 3.0
    searched = [searched_decoy(folder) for folder in (udp, mem)]
    if searched[0] != searched[1]:
        print("the decoy was searched in one run only:", searched, "(not the same episode)")
        return
    in_slot = [handed_back_in_slot(folder) for folder in (udp, mem)]
    if not all(in_slot):
        print("a prosecutor handed back on the loop, out of its slot:", in_slot, "(a re-splay)")
        return
    for key, tol in TOLERANCES.items():
        u, m = figures[key]
        assert abs(u - m) <= tol, (key, figures)
