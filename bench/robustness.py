"""Robustness bench: the disturbance matrix, end to end, through the real companions.

Run from the repository root::

    python bench/robustness.py [--mission missions/ellipse_6uav.yaml] [--scenario NAME ...]
        [--speedup 10] [--duration S] [--jobs 1] [--out DIR] [--markdown] [--smoke]

Each scenario is one ``companion fleet`` run (``sitl-model``, the perimeter uploaded, one
``companion run`` per UAV over MAVLink and the signed group) in which the simulator's world
differs from the mission the companions are told (``--sim-param``), and sometimes the
setpoint profile too. One row per scenario, from the run's ``metrics.json`` (the model-free
measures of docs/design.md §8, defined in ``docs/robustness.md``): cross-track median / p95 /
max, coverage revisit, longest unseen (s and T/N), fraction of time within bounds, splay
error over the window (diagnostic), the worst alert response over its plan, and whether
exactly one UAV answered each alert. A scenario that fails prints its failure as its row;
the others go on. Raw run folders stay under ``--out``; ``results.json`` there holds the rows.

Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import json
import math
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from companion.campaign.scenarios import BY_NAME, SCENARIOS, Scenario
from companion.mission import load_mission

ELLIPSE = ROOT / "missions" / "ellipse_6uav.yaml"
SMOKE = ("gusts", 120.0, 10.0)  # scenario, simulated s, speed-up


@dataclass
class Row:
    """One scenario's outcome: its metrics, or why there are none."""

    scenario: str
    folder: str
    sim_params: dict[str, float]
    profile: str
    wall_s: float = 0.0
    error: str | None = None
    metrics: dict = field(default_factory=dict)

    def figures(self) -> dict:
        """The row's figures (None where not measured)."""
        m = self.metrics
        ratios = [a.get("response_over_plan") for a in m.get("alerts", [])]
        ratios = [r for r in ratios if r is not None]
        raised = m.get("alerts_raised")
        return {
            "xt_median_m": m.get("cross_track_median_m"),
            "xt_p95_m": m.get("cross_track_p95_m"),
            "xt_max_m": m.get("cross_track_max_m"),
            "coverage_revisit": m.get("coverage_revisit_ratio"),
            "coverage_revisit_excl_alerts": m.get("coverage_revisit_ratio_excl_alerts"),
            "longest_unseen_s": m.get("longest_unseen_s"),
            "longest_unseen_ratio": m.get("longest_unseen_ratio"),
            "reference_ideal_revisit_s": m.get("reference_ideal_revisit_s"),
            "within_bounds": m.get("fraction_within_bounds"),
            "within_bounds_excl_alerts": m.get("fraction_within_bounds_excl_alerts"),
            "settle_time_s": m.get("settle_time_s"),
            "settled": m.get("settled"),
            "window_s": None
            if m.get("window_start_s") is None
            else [m["window_start_s"], m["window_end_s"]],
            "splay_deg": m.get("window_splay_error_median_deg"),
            "response_over_plan_max": max(ratios) if ratios else None,
            "alerts_raised": raised,
            "one_uav_per_alert": None
            if not raised
            else not m.get("alerts_not_answered_by_one", []),
        }


def fleet_command(
    mission: Path,
    out: Path,
    sc: Scenario,
    params: dict,
    speedup: float,
    duration: float,
    engine: str = "udp",
) -> list[str]:
    """The command line of one scenario: ``companion fleet`` (engine "udp": processes over
    MAVLink on loopback) or ``companion simulate`` (engine "memory": the same companion code
    and simulator in one process, lockstepped, MAVLink and the group as bytes in memory)."""
    if engine == "memory":
        cmd = [
            sys.executable, "-m", "companion", "simulate", str(mission), "--out", str(out),
            "--duration", f"{duration:g}", "--profile", sc.profile,
        ]  # fmt: skip
        for name, value in params.items():
            cmd += ["--param", f"{name}={value:g}"]
        return cmd
    cmd = [
        sys.executable,
        "-m",
        "companion",
        "fleet",
        str(mission),
        "--out",
        str(out),
        "--speedup",
        f"{speedup:g}",
        "--duration",
        f"{duration:g}",
        "--profile",
        sc.profile,
        "--no-progress",
    ]
    for name, value in params.items():
        cmd += ["--sim-param", f"{name}={value:g}"]
    return cmd


class Runner:
    """Runs scenarios as child processes; on SIGINT/SIGTERM stops them (each fleet then
    stops its own processes and writes its report)."""

    def __init__(self) -> None:
        """No child yet."""
        self.children: dict[int, subprocess.Popen] = {}
        self.lock = threading.Lock()
        self.stopping = False

    def stop(self, *_: object) -> None:
        """Forward SIGTERM to every running fleet."""
        self.stopping = True
        with self.lock:
            for p in self.children.values():
                with contextlib.suppress(ProcessLookupError):
                    p.send_signal(signal.SIGTERM)

    def run(self, cmd: list[str], log: Path, timeout_s: float) -> tuple[int | None, float]:
        """Run ``cmd`` with its output in ``log``; returns (exit status or None, wall s)."""
        t0 = time.perf_counter()
        with open(log, "w") as fh:
            p = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT)
            with self.lock:
                self.children[p.pid] = p
            try:
                rc = p.wait(timeout_s)
            except subprocess.TimeoutExpired:
                p.send_signal(signal.SIGTERM)  # the fleet stops its processes, writes a report
                try:
                    p.wait(60)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
                rc = None
            finally:
                with self.lock:
                    self.children.pop(p.pid, None)
        return rc, time.perf_counter() - t0


def run_scenario(
    runner: Runner,
    mission: Path,
    out: Path,
    sc: Scenario,
    speedup: float,
    duration: float,
    timeout_s: float,
    engine: str = "udp",
) -> Row:
    """One scenario end to end (stopped after ``timeout_s`` wall s); a failure becomes the
    row's ``error``."""
    m = load_mission(mission)
    params = sc.params(m.wind.speed_m_s, m.wind.from_deg, duration)
    folder = out / m.name / sc.name
    row = Row(sc.name, str(folder), dict(params), sc.profile)
    if runner.stopping:
        row.error = "not run (interrupted)"
        return row
    folder.mkdir(parents=True, exist_ok=True)
    cmd = fleet_command(mission, folder, sc, params, speedup, duration, engine)
    (folder / "bench_command.txt").write_text(shlex.join(cmd) + "\n")
    rc, row.wall_s = runner.run(cmd, folder / "bench.log", timeout_s)
    metrics = folder / "metrics.json"
    if metrics.is_file():
        with contextlib.suppress(json.JSONDecodeError):
            row.metrics = json.loads(metrics.read_text())
    if rc != 0 or not row.metrics:
        tail = (folder / "bench.log").read_text(errors="replace").strip().splitlines()[-1:]
        why = "timed out" if rc is None else f"exit status {rc}"
        row.error = f"{why}: {tail[0][:150] if tail else 'no output'} (see {folder}/bench.log)"
    return row


def _f(v: object, digits: int, pct: bool = False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return f"{100 * v:.{digits}f} %" if pct else f"{v:.{digits}f}"


COLUMNS = (
    "scenario",
    "cross-track med / p95 / max (m)",
    "coverage revisit (excl. alerts)",
    "longest unseen s (T/N)",
    "within bounds",
    "splay (deg, diag.)",
    "response / plan",
    "one UAV per alert",
)


def cells(row: Row) -> list[str]:
    """The table cells of a row (a failed run: its error in the second cell)."""
    if row.error and not row.metrics:
        return [row.scenario, f"FAILED: {row.error}"] + [""] * (len(COLUMNS) - 2)
    f = row.figures()
    one = (
        "n/a (no alert)"
        if f["one_uav_per_alert"] is None
        else "yes"
        if f["one_uav_per_alert"]
        else "NO"
    )
    return [
        row.scenario + (" (!)" if row.error else ""),
        f"{_f(f['xt_median_m'], 1)} / {_f(f['xt_p95_m'], 1)} / {_f(f['xt_max_m'], 1)}",
        f"{_f(f['coverage_revisit'], 2)} ({_f(f['coverage_revisit_excl_alerts'], 2)})",
        f"{_f(f['longest_unseen_s'], 1)} ({_f(f['longest_unseen_ratio'], 2)})",
        _f(f["within_bounds"], 1, pct=True) + ("" if f["settled"] else " (unsettled)"),
        _f(f["splay_deg"], 2),
        _f(f["response_over_plan_max"], 2),
        one,
    ]


def table(rows: list[Row], markdown: bool) -> str:
    """The rows as a fixed-width or Markdown table."""
    body = [cells(r) for r in rows]
    if markdown:
        lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
        lines += ["| " + " | ".join(c.replace("|", "/") for c in b) + " |" for b in body]
        return "\n".join(lines)
    widths = [max(len(c[i]) for c in [list(COLUMNS), *body]) for i in range(len(COLUMNS))]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join(fmt.format(*c).rstrip() for c in [list(COLUMNS), *body])


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mission", type=Path, default=ELLIPSE, help="mission YAML (default ellipse)")
    p.add_argument(
        "--scenario",
        action="append",
        choices=[s.name for s in SCENARIOS],
        help="a scenario to run (repeatable; default all)",
    )
    p.add_argument("--speedup", type=float, default=10.0, help="fleet --speedup (default 10)")
    p.add_argument(
        "--engine",
        choices=("udp", "memory"),
        default="udp",
        help="udp: companion fleet (processes over loopback MAVLink, lockstepped); memory: "
        "companion simulate (the same code in one process; --speedup does not apply)",
    )
    p.add_argument("--duration", type=float, help="simulated s (default: the mission's)")
    p.add_argument("--jobs", type=int, default=1, help="fleets at once (default 1: 2 cores)")
    p.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        help="wall seconds before a scenario is stopped (default 300 + 2 x duration: a "
        "lockstepped fleet on a loaded 2-core host may run slower than real time)",
    )
    p.add_argument("--out", type=Path, help="raw run folders (default runs/robustness-TIME)")
    p.add_argument("--markdown", action="store_true", help="print the table in Markdown")
    p.add_argument(
        "--retabulate",
        type=Path,
        metavar="DIR",
        help="run nothing: recompute the metrics of an earlier bench's --out DIR and print "
        "its table",
    )
    p.add_argument(
        "--smoke",
        action="store_true",
        help=f"one short scenario ({SMOKE[0]}, {SMOKE[1]:g} s at {SMOKE[2]:g}x) for a test",
    )
    a = p.parse_args(argv)
    if a.jobs < 1:
        p.error("--jobs must be >= 1")
    if a.smoke:
        a.scenario, a.duration, a.speedup = [SMOKE[0]], SMOKE[1], SMOKE[2]
    return a


def retabulate(folder: Path, markdown: bool) -> int:
    """Recompute every row's metrics of an earlier bench (``folder/results.json``) from its
    run folder (as ``companion report DIR --no-plots``) and print the table again."""
    from companion.report.summary import write_report

    saved = json.loads((folder / "results.json").read_text())
    rows = []
    for r in saved["rows"]:
        row = Row(r["scenario"], r["folder"], r["sim_params"], r["profile"], r["wall_s"])
        row.error = r["error"]
        try:
            row.metrics = write_report(Path(r["folder"]), plots=False)
        except Exception as exc:  # a folder without a usable truth log: keep the row
            row.error = row.error or f"no report ({exc})"
        rows.append(row)
    print(
        f"recomputed from {folder}: mission {saved['mission']}, {saved['duration_s']:g} s at "
        f"most {saved['speedup']:g}x, run {saved['date_utc']} UTC, commit {saved['commit']}"
    )
    print(table(rows, markdown))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the chosen scenarios and print the table; 0 if every scenario ran."""
    a = parse_args(argv)
    if a.retabulate is not None:
        return retabulate(a.retabulate, a.markdown)
    mission = load_mission(a.mission)
    duration = a.duration if a.duration is not None else mission.duration_s
    out = a.out or ROOT / "runs" / f"robustness-{time.strftime('%Y%m%d-%H%M%S')}"
    out.mkdir(parents=True, exist_ok=True)
    chosen = [BY_NAME[n] for n in (a.scenario or [s.name for s in SCENARIOS])]
    timeout_s = a.timeout if a.timeout is not None else 300.0 + 2.0 * duration
    started = dt.datetime.now(dt.UTC)
    commit = subprocess.run(
        ["git", "describe", "--always", "--dirty"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip() or os.environ.get("BENCH_COMMIT", "")
    patrol = mission.patrol
    print(f"command: {shlex.join([Path(sys.argv[0]).name, *(argv or sys.argv[1:])])}")
    print(
        f"date: {started:%Y-%m-%d %H:%M} UTC; commit {commit or 'unknown'}; "
        f"{os.cpu_count()} cores; jobs {a.jobs}; engine {a.engine}"
    )
    print(
        f"mission {mission.name}: {mission.vehicles.count} UAVs, wind {mission.wind.speed_m_s:g} "
        f"m/s from {mission.wind.from_deg:g} deg, T {patrol.period_s:.1f} s, T/N "
        f"{patrol.period_s / mission.vehicles.count:.2f} s; {duration:g} simulated s per "
        f"scenario at most {a.speedup:g}x; runs in {out}",
        flush=True,
    )
    runner = Runner()
    old = {s: signal.signal(s, runner.stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with ThreadPoolExecutor(a.jobs) as pool:
            futures = [
                pool.submit(
                    run_scenario,
                    runner,
                    a.mission,
                    out,
                    sc,
                    a.speedup,
                    duration,
                    timeout_s,
                    a.engine,
                )
                for sc in chosen
            ]
            rows = []
            for fut in futures:
                row = fut.result()
                rows.append(row)
                status = row.error or "ok"
                print(f"  {row.scenario}: {status} ({row.wall_s:.0f} s wall)", flush=True)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    (out / "results.json").write_text(
        json.dumps(
            {
                "mission": mission.name,
                "duration_s": duration,
                "speedup": a.speedup,
                "date_utc": f"{started:%Y-%m-%d %H:%M}",
                "commit": commit,
                "rows": [
                    {
                        "scenario": r.scenario,
                        "profile": r.profile,
                        "sim_params": r.sim_params,
                        "folder": r.folder,
                        "wall_s": round(r.wall_s, 1),
                        "error": r.error,
                        **r.figures(),
                    }
                    for r in rows
                ],
            },
            indent=2,
        )
        + "\n"
    )
    print()
    print(table(rows, a.markdown))
    print(
        "\nwithin bounds: every patrolling UAV within 10 m of the loop and no loop point unseen "
        "longer than 1.5 T/N, over the window (from one loop period after settling; "
        "'unsettled': the second half of the run); response / plan: the worst alert, time to "
        "the site under the prosecutor's sensor (truth) over the plan's time to the site"
    )
    return 0 if all(r.error is None for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
