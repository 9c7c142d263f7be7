"""Lockstep benchmark: the same fleet run idle and beside busy loops, lockstepped and free.

Run from the repository root: ``python bench/lockstep.py [--mission M] [--hogs 2]
[--modes lockstep,free]``.

For each mode (``companion fleet`` lockstepped, and ``--free-run`` at its 20x default) the
mission is flown twice: with nothing added, and with ``--hogs`` CPU-bound processes
(``python -c 'while True: pass'``, started before and killed by pid after). Printed per run:
wall time, the simulator's achieved real-time factor and lockstep counters, and the metrics
from ``metrics.json`` (convergence, steady splay and centre errors, revisit ratio, first
alert's planned time, response and rejoin). Then, per mode, the loaded run's differences
from the idle one against the tolerances below. Machine load (1-minute load average) is
printed with each run: "idle" means no hogs of ours, not an idle machine.

Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOL = {  # metric -> the idle/loaded difference within which a mode counts as load-proof
    "convergence_time_s": 30.0,
    "steady_splay_error_deg": 0.3,
    "steady_centre_error_m": 0.5,
    "revisit_ratio": 0.01,
    "response_s": 0.5,
    "rejoin_s": 1.0,
}


def hogs(n: int) -> list[subprocess.Popen]:
    """Start ``n`` busy loops (one core each while the scheduler lets them)."""
    return [
        subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)
        for _ in range(n)
    ]


def stop(procs: list[subprocess.Popen]) -> None:
    """Kill the processes we started, by pid, and reap them."""
    for p in procs:
        p.kill()
        p.wait()


def sim_status(out: Path) -> dict[str, str]:
    """The simulator's last status line as ``name -> value``."""
    lines = [ln for ln in (out / "sitl.log").read_text().splitlines() if ln.startswith("sitl t=")]
    return dict(p.split("=", 1) for p in lines[-1].split()[1:] if "=" in p) if lines else {}


def run(mission: Path, out: Path, lockstep: bool, n_hogs: int) -> dict:
    """One ``companion fleet`` run; its figures."""
    args = [sys.executable, "-m", "companion", "fleet", str(mission), "--out", str(out)]
    args += ["--no-progress"] + ([] if lockstep else ["--free-run"])
    busy = hogs(n_hogs)
    load0 = os.getloadavg()[0]
    try:
        t0 = time.perf_counter()
        proc = subprocess.run(args, capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - t0
    finally:
        stop(busy)
    if proc.returncode != 0:
        print(proc.stdout[-1500:], proc.stderr[-1500:])
    m = json.loads((out / "metrics.json").read_text())
    alert = (m.get("alerts") or [{}])[0]
    st = sim_status(out)
    return {
        "wall_s": wall,
        "load": max(load0, os.getloadavg()[0]),
        "rtf": st.get("rtf"),
        "timeouts": st.get("lockstep_timeouts", "-"),
        "convergence_time_s": m.get("convergence_time_s"),
        "steady_splay_error_deg": m.get("steady_splay_error_deg"),
        "steady_centre_error_m": m.get("steady_centre_error_m"),
        "revisit_ratio": m.get("revisit_ratio"),
        "planned_s": alert.get("planned_time_s"),
        "response_s": alert.get("response_time_s"),
        "rejoin_s": alert.get("rejoin_time_s"),
    }


def _f(v: object, digits: int) -> str:
    return "n/a" if v is None else (f"{v:.{digits}f}" if isinstance(v, float) else str(v))


def main() -> None:
    """Parse the flags, fly every run, print the table and the idle/loaded differences."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mission", type=Path, default=ROOT / "missions" / "ellipse_6uav.yaml")
    p.add_argument("--hogs", type=int, default=2, help="busy loops beside the loaded runs")
    p.add_argument("--modes", default="lockstep,free", help="lockstep, free or both")
    a = p.parse_args()
    print(f"lockstep bench: {a.mission.name}, {os.cpu_count()} CPUs, {a.hogs} hogs when loaded")
    head = "mode      load_run  load1  wall_s    rtf  t/o  conv_s  splay  centre  revisit"
    print(head + "  plan_s  resp_s  rejoin_s")
    results: dict[tuple[str, int], dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in a.modes.split(","):
            for n in (0, a.hogs):
                out = Path(tmp) / f"{mode}-{n}"
                r = results[(mode, n)] = run(a.mission, out, mode == "lockstep", n)
                print(
                    f"{mode:9s} {'loaded' if n else 'idle':8s} {r['load']:5.1f} "
                    f"{r['wall_s']:7.1f} {r['rtf'] or '-':>6s} {r['timeouts']:>4s} "
                    f"{_f(r['convergence_time_s'], 1):>7s} "
                    f"{_f(r['steady_splay_error_deg'], 3):>6s} "
                    f"{_f(r['steady_centre_error_m'], 2):>7s} {_f(r['revisit_ratio'], 3):>8s} "
                    f"{_f(r['planned_s'], 1):>7s} {_f(r['response_s'], 1):>7s} "
                    f"{_f(r['rejoin_s'], 1):>9s}",
                    flush=True,
                )
    for mode in a.modes.split(","):
        idle, loaded = results[(mode, 0)], results[(mode, a.hogs)]
        diffs = []
        for k, tol in TOL.items():
            x, y = idle.get(k), loaded.get(k)
            if x is None or y is None:
                diffs.append(f"{k} {'n/a' if x is None else 'ok'}/{'n/a' if y is None else 'ok'}")
            else:
                diffs.append(f"{k} {abs(y - x):.3g}{' (over)' if abs(y - x) > tol else ''}")
        print(f"{mode}: loaded - idle: " + ", ".join(diffs))


if __name__ == "__main__":
    main()
