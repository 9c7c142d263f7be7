"""In-memory engine benchmark: wall and CPU time of ``companion simulate``'s engine.

Flies each mission with :class:`companion.sim.inmemory.Engine` (the simulator's vehicles and the
real companion stack, lockstepped in one process) for its scenario duration (or
``--duration``) and prints, per mission: wall time, real-time factor, process CPU per
physics step (50 Hz) split into simulator and companions, companion CPU per control step
(10 Hz per UAV), the whole run's process CPU per control step, and with ``--profile`` the
top functions of a cProfile run.

Usage: ``PYTHONPATH=. python bench/inmemory.py [--mission M]... [--vehicles N]... [--duration S]
[--group-budget BYTES_PER_S] [--profile]``; ``--vehicles N`` flies N UAVs on a circle sized
for 150 m between them (``bench/fleet.py``'s circle mission; 60 simulated s unless
``--duration``); ``--group-budget``: every companion's ``--group-budget`` (docs/protocol.md,
"Bandwidth budget"). The real-time factor is printed on the wall clock and on the process's
CPU time (one thread: what an idle core gives).
Goals (issue 13): ellipse_6uav (900 s) in at most 10 s of wall time; wpafb_4uav (8000 s) in
at most 60 s; companion CPU per control step at most 0.3 ms; 100 UAVs faster than real time.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bench.fleet import circle_mission
from companion.mission import load_mission
from companion.sim.inmemory import Engine, EngineConfig

MISSIONS = (REPO / "missions" / "ellipse_6uav.yaml", REPO / "missions" / "wpafb_4uav.yaml")


def bench(
    path: Path, duration_s: float | None, profile: bool, top: int, budget: float | None = None
) -> None:
    """Fly one mission and print its figures (and profile); ``budget``: the group's
    bandwidth budget (bytes/s, None: none)."""
    mission = load_mission(path)
    duration = mission.duration_s if duration_s is None else duration_s
    engine = Engine(EngineConfig(path, group_budget_bytes_s=budget))
    prof = cProfile.Profile() if profile else None
    cpu0, wall0 = time.process_time(), time.perf_counter()
    if prof is not None:
        prof.enable()
    engine.run(duration)
    if prof is not None:
        prof.disable()
    wall = time.perf_counter() - wall0
    cpu = time.process_time() - cpu0
    engine.close()
    steps = engine.sim.steps
    setpoints = sum(r.counters.setpoints for r in engine.runners)
    print(
        f"{mission.name}: {mission.vehicles.count} UAVs, {duration:g} s simulated in "
        f"{wall:.1f} s wall, {cpu:.1f} s CPU ({duration / wall:.2f}x real time on the wall "
        f"clock, {duration / cpu:.2f}x on the CPU)"
        + ("" if budget is None else f", group budget {budget:g} bytes/s")
        + (" [under cProfile]" if profile else "")
    )
    print(
        f"  per physics step ({steps} of 20 ms): {1e3 * cpu / steps:.3f} ms CPU; time in the "
        f"simulator {1e3 * engine.time_sim_s / steps:.3f} ms, on the links' wires "
        f"{1e3 * engine.time_transport_s / steps:.3f} ms, in the companions "
        f"{1e3 * engine.time_companion_s / steps:.3f} ms"
    )
    print(
        f"  per companion control step ({setpoints} setpoints): "
        f"{1e3 * engine.time_companion_s / max(setpoints, 1):.3f} ms (everything a "
        "companion does, divided by its setpoints)"
    )
    print(
        f"  process CPU per companion control step: {1e3 * cpu / max(setpoints, 1):.3f} ms "
        "(process_time of the whole run, simulator included, divided by the setpoints)"
    )
    if prof is not None:
        s = io.StringIO()
        order = os.environ.get("PROFILE_SORT", "tottime")  # e.g. cumulative
        pstats.Stats(prof, stream=s).sort_stats(order).print_stats(top)
        print(s.getvalue())


def main() -> int:
    """Run the benchmark on the missions asked for (default: both)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mission", action="append", type=Path, help="mission YAML (repeatable)")
    ap.add_argument("--vehicles", action="append", type=int, help="N UAVs on a circle (repeatable)")
    ap.add_argument("--duration", type=float, help="simulated s (default: the mission's)")
    ap.add_argument("--profile", action="store_true", help="cProfile the run, print the top")
    ap.add_argument("--top", type=int, default=25, help="profile lines to print")
    ap.add_argument("--group-budget", type=float, help="the group's budget (bytes/s)")
    args = ap.parse_args()
    paths = list(args.mission or ([] if args.vehicles else MISSIONS))
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.vehicles or []:
            paths.append(Path(tmp) / f"circle_{n}uav.yaml")
            circle_mission(n, paths[-1])
        for path in paths:
            bench(path, args.duration, args.profile, args.top, args.group_budget)
    return 0


if __name__ == "__main__":
    sys.exit(main())
