"""Fleet benchmark: the ellipse scenario at several speed-ups, and the largest fleet at 1x.

Run from the repository root: ``python bench/fleet.py [--speedups 10,20,40] [--sizes 12,24,48]
[--lockstep] [--group-budget B_PER_S]``.

1. The paper's ellipse scenario (15 simulated minutes, 6 UAVs, every process: simulator,
   uploads, six companions) at each speed-up: wall time, real-time factor, and the metrics
   that must not depend on it (convergence time, steady errors, revisit ratio, alert
   response). The highest speed-up whose metrics stay within the tolerances of the
   slowest run's is reported.
2. Fleets of N UAVs on a circle sized for a 150 m spacing, 60 simulated seconds at 1x
   (free-running, or ``--lockstep``; ``--group-budget`` as ``companion fleet``'s): the
   lowest per-companion setpoint rate (setpoints per simulated second, counted in each
   companion's tlog after the first 20 s). The control rate holds while it stays >= 10
   (9.95: one setpoint short in 40 s is the edge of the count).

Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[1]
SIM_EPOCH_UNIX_S = 1_767_225_600
TOL = {  # metric -> allowed difference from the reference run
    "convergence_time_s": 30.0,
    "steady_splay_error_deg": 1.0,
    "steady_centre_error_m": 3.0,
    "revisit_ratio": 0.05,
}


def run_fleet(
    mission: Path,
    out: Path,
    speedup: float,
    duration: float | None = None,
    lockstep: bool = False,
    extra: tuple[str, ...] = (),
) -> float:
    """One ``companion fleet`` run (free-running unless ``lockstep``, with ``extra``
    arguments); returns its wall time (s)."""
    args = [
        sys.executable,
        "-m",
        "companion",
        "fleet",
        str(mission),
        "--speedup",
        f"{speedup:g}",
        "--out",
        str(out),
        "--no-progress",
        *([] if lockstep else ["--free-run"]),  # free: the speed-up under test is the pace
        *extra,
    ]
    if duration is not None:
        args += ["--duration", f"{duration:g}"]
    t0 = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(proc.stdout[-1500:], proc.stderr[-1500:])
        raise SystemExit(f"fleet run failed at {speedup}x")
    return wall


def speedup_table(speedups: list[float], tmp: Path) -> None:
    mission = ROOT / "missions" / "ellipse_6uav.yaml"
    rows = []
    for x in speedups:
        out = tmp / f"ellipse_{x:g}x"
        wall = run_fleet(mission, out, x)
        m = json.loads((out / "metrics.json").read_text())
        resp = [a["response_time_s"] for a in m["alerts"] if a["response_time_s"] is not None]
        rows.append((x, wall, m, resp[0] if resp else None))
    ref = rows[0][2]
    print("ellipse_6uav, 900 simulated s, 6 UAVs, all processes")
    print(
        f"{'speedup':>8} {'wall_s':>7} {'rtf':>6} {'conv_s':>7} {'splay':>6} {'centre':>7} "
        f"{'revisit':>8} {'resp_s':>7}  metrics kept"
    )
    best = None
    for x, wall, m, resp in rows:
        kept = all(
            m.get(k) is not None and ref.get(k) is not None and abs(m[k] - ref[k]) <= tol
            for k, tol in TOL.items()
        )
        if kept:
            best = x
        print(
            f"{x:>8g} {wall:>7.1f} {m['duration_s'] / wall:>6.1f} "
            f"{_f(m['convergence_time_s'], 7, 1)} {_f(m['steady_splay_error_deg'], 6, 2)} "
            f"{_f(m['steady_centre_error_m'], 7, 2)} {_f(m['revisit_ratio'], 8, 3)} "
            f"{_f(resp, 7, 1)}  {'yes' if kept else 'no'}"
        )
    print(f"highest speed-up that keeps the metrics (tolerances {TOL}): {best}")


def _f(v: float | None, width: int, digits: int) -> str:
    return f"{'n/a':>{width}}" if v is None else f"{v:>{width}.{digits}f}"


def circle_mission(n: int, path: Path) -> None:
    radius = max(300.0, n * 150.0 / (2 * math.pi))
    ids = ", ".join(str(i + 1) for i in range(n))
    poses = "\n".join(
        f"      - {{north_m: {radius * math.cos(2 * math.pi * k / n):.1f}, "
        f"east_m: {-radius * math.sin(2 * math.pi * k / n):.1f}, "
        f"heading_deg: {(math.degrees(-2 * math.pi * k / n) + 90) % 360:.1f}}}"
        for k in range(n)
    )
    path.write_text(f"""version: 1
name: circle_{n}uav
origin: {{lat_deg: 39.8, lon_deg: -84.0, alt_m: 250}}
perimeter:
  ellipse: {{semi_major_m: {radius:.1f}, semi_minor_m: {radius:.1f}}}
wind: {{speed_m_s: 5, from_deg: 180}}
vehicles:
  count: {n}
  sysids: [{ids}]
  airspeed_m_s: 20
  max_turn_rate_deg_s: 18
  altitude_m: 100
  altitude_step_m: 5
  initial:
    poses:
{poses}
sensor: {{footprint_radius_m: 50}}
scenario: {{duration_s: 60}}
""")


def setpoint_rate(tlog: Path, after_s: float) -> float:
    """Setpoints per simulated second the companion sent, after ``after_s`` (s)."""
    log = mavutil.mavlink_connection(str(tlog))
    times = []
    while True:
        m = log.recv_match(type=["SET_ATTITUDE_TARGET", "COMMAND_INT"])
        if m is None:
            break
        t = m._timestamp - SIM_EPOCH_UNIX_S
        if t >= after_s:
            times.append(t)
    if len(times) < 2:
        return 0.0
    return (len(times) - 1) / (times[-1] - times[0])


def size_table(sizes: list[int], tmp: Path, lockstep: bool, budget: float | None) -> None:
    how = "lockstepped" if lockstep else "free-running"
    extra = ("--group-budget", f"{budget:g}") if budget else ()
    print(
        f"\nfleets at 1x, {how}"
        + (f", group budget {budget:g} B/s" if budget else "")
        + ", 60 simulated s on a circle (150 m spacing)"
    )
    print(f"{'N':>4} {'wall_s':>7} {'min setpoints/s':>16} {'median':>7}  control rate held")
    largest = None
    for n in sizes:
        mission = tmp / f"circle_{n}.yaml"
        circle_mission(n, mission)
        out = tmp / f"circle_{n}"
        wall = run_fleet(mission, out, 1.0, lockstep=lockstep, extra=extra)
        rates = sorted(
            setpoint_rate(out / f"uav{s}" / "autopilot.tlog", 20.0) for s in range(1, n + 1)
        )
        held = rates[0] >= 10.0 - 0.05  # one setpoint short over 40 s is the count's edge
        if held:
            largest = n
        print(
            f"{n:>4} {wall:>7.1f} {rates[0]:>16.2f} {rates[len(rates) // 2]:>7.2f}  "
            f"{'yes' if held else 'no'}"
        )
    print(f"largest fleet holding every companion's control rate at 1x: {largest}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--speedups", default="10,20,40")
    p.add_argument("--sizes", default="12,24,48")
    p.add_argument("--lockstep", action="store_true", help="the size table lockstepped")
    p.add_argument("--group-budget", type=float, default=None, help="B/s, for the size table")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        if a.speedups:
            speedup_table([float(x) for x in a.speedups.split(",")], tmp)
        if a.sizes:
            size_table([int(x) for x in a.sizes.split(",")], tmp, a.lockstep, a.group_budget)


if __name__ == "__main__":
    main()
