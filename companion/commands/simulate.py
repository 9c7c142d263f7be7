"""``companion simulate``: the whole fleet in process (particles + guidance, no MAVLink).

Writes ``DIR/truth.csv`` (one row per vehicle per sample), ``DIR/events.jsonl`` and prints
the splay error, centre error and convergence time (DESIGN section 8).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import sys
import time
from pathlib import Path

from companion.errors import UserError
from companion.mission import load_mission
from companion.simulation import TRUTH_COLUMNS, FleetSimulation


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` sub-command."""
    p = sub.add_parser(
        "simulate",
        help="fly the whole fleet in process (no MAVLink) and write truth.csv",
        description="Fly the mission's fleet in process: particles in wind steered by the "
        "time-splay law. Writes DIR/truth.csv and DIR/events.jsonl; prints the splay error, "
        "centre error and convergence time.",
    )
    p.add_argument("mission", help="mission YAML file")
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds (default: the mission's scenario duration)",
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random generator (gusts)")
    p.add_argument(
        "--dt",
        type=float,
        default=0.05,
        metavar="S",
        help="control and physics step in simulated seconds (default 0.05)",
    )
    p.add_argument(
        "--sample-hz",
        type=float,
        default=10.0,
        metavar="HZ",
        help="truth.csv rows per vehicle per simulated second (default 10)",
    )
    p.add_argument(
        "--report",
        action="store_true",
        help="also write metrics.json and the plots (as 'companion report DIR')",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the simulation; returns the exit status."""
    mission = load_mission(args.mission)
    duration = mission.duration_s if args.duration is None else args.duration
    if not (math.isfinite(duration) and 0 < duration <= 7 * 24 * 3600):
        raise UserError(f"--duration must be > 0 and at most a week of seconds, got {duration}")
    if not (math.isfinite(args.dt) and 0.001 <= args.dt <= 1.0):
        raise UserError(f"--dt must be between 0.001 and 1 s, got {args.dt}")
    if not (math.isfinite(args.sample_hz) and 1.0 / args.dt >= args.sample_hz >= 10.0):
        raise UserError(
            f"--sample-hz must be from 10 to 1/dt = {1 / args.dt:g}, got {args.sample_hz}"
        )
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output folder {out}: {exc.strerror or exc}") from None
    shutil.copyfile(args.mission, out / "mission.yaml")  # the report reads it from here
    every = max(1, round(1.0 / (args.sample_hz * args.dt)))
    sim = FleetSimulation(mission, seed=args.seed, dt_s=args.dt)
    wall0 = time.perf_counter()
    with (
        open(out / "truth.csv", "w", newline="") as truth_fh,
        open(out / "events.jsonl", "w") as events_fh,
    ):
        writer = csv.writer(truth_fh)
        writer.writerow(TRUTH_COLUMNS)
        count = [0]

        def on_truth(rows: list) -> None:
            if count[0] % every == 0:
                writer.writerows(rows)
            count[0] += 1

        def on_event(event: dict) -> None:
            events_fh.write(json.dumps(event, sort_keys=True) + "\n")

        series = sim.run(duration, on_truth=on_truth, on_event=on_event)
    wall = time.perf_counter() - wall0
    conv = series.convergence_time_s()
    period = mission.patrol.period_s
    conv_txt = "not reached" if conv is None else f"{conv:.1f} s ({conv / period:.2f} loop periods)"
    print(
        f"mission {mission.name}: {mission.vehicles.count} UAVs, loop period {period:.2f} s, "
        f"ideal revisit {period / mission.vehicles.count:.2f} s"
    )
    print(f"simulated {duration:.0f} s in {wall:.1f} s wall")
    print(
        f"final splay error {series.splay_deg[-1]:.3f} deg, "
        f"final centre error {series.centre_m[-1]:.3f} m"
    )
    print(f"convergence time (splay < 2 deg and centre < 5 m from then on): {conv_txt}")
    print(f"wrote {out / 'truth.csv'} and {out / 'events.jsonl'}")
    if args.report:
        from companion.commands.report import summary, write_report

        print(summary(write_report(out)))
        print(f"wrote {out / 'metrics.json'}, map.png, coverage.png and errors.png")
    sys.stdout.flush()
    return 0
