"""Benchmark of ``companion.planner.plan_path`` (run as ``python bench/planner.py``).

1000 seeded random cases: airspeed 20 m/s, wind 0-15 m/s from any direction, turn rate
10-30 deg/s, goal up to 2 km away, random start heading and final ground course. Prints the
median and p99 milliseconds per plan, plans per second, and how often and by how much the
full planner beats the paper's analytic subset (``families="paper"``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.core.wind import Wind
from companion.planner import Aircraft, Goal, Plan, Pose, plan_path


def make_cases(n: int, seed: int) -> list[dict]:
    """Seeded random planning cases (the arguments of ``plan_path``)."""
    rng = np.random.default_rng(seed)
    cases = []
    for _ in range(n):
        start = Pose(0j, rng.uniform(-math.pi, math.pi))
        goal_m = complex(rng.uniform(1, 2000) * np.exp(1j * rng.uniform(0, 2 * math.pi)))
        aircraft = Aircraft(20.0, math.radians(rng.uniform(10, 30)))
        wind = Wind.from_meteo(rng.uniform(0, 15), rng.uniform(0, 360))
        goal = Goal(goal_m, course_rad=rng.uniform(-math.pi, math.pi))
        cases.append((start, goal, aircraft, wind))
    return cases


def main() -> int:
    """Run the benchmark and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()
    cases = make_cases(args.cases, args.seed)
    for case in cases[:20]:  # warm-up (imports, caches)
        plan_path(*case)
    times_s, full, paper = [], [], []
    for case in cases:
        t0 = time.perf_counter()
        result = plan_path(*case)
        times_s.append(time.perf_counter() - t0)
        full.append(result)
        paper.append(plan_path(*case, families="paper"))
    ms = np.array(times_s) * 1e3
    print(f"cases: {len(cases)} (seed {args.seed})")
    print(f"full planner: median {np.median(ms):.3f} ms, p99 {np.percentile(ms, 99):.3f} ms, "
          f"{1e3 / np.mean(ms):.0f} plans/s")  # fmt: skip
    ok = [(f, p) for f, p in zip(full, paper, strict=True) if isinstance(f, Plan)]
    gain = np.array([p.time_s - f.time_s for f, p in ok])
    pct = np.array([100.0 * (p.time_s - f.time_s) / p.time_s for f, p in ok])
    better = gain > 1e-6
    print(f"full beats paper subset in {better.sum()} of {len(ok)} cases "
          f"({100.0 * better.mean():.1f} %)")  # fmt: skip
    if better.any():
        print(f"  by median {np.median(gain[better]):.2f} s ({np.median(pct[better]):.1f} %), "
              f"max {gain[better].max():.2f} s ({pct[better].max():.1f} %)")  # fmt: skip
    families: dict[str, int] = {}
    for f, _ in ok:
        families[f.family] = families.get(f.family, 0) + 1
    print("families:", ", ".join(f"{k} {v}" for k, v in sorted(families.items())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
