"""``companion simulate``: the whole mission with the real stack, in memory and lockstepped.

The simulator's vehicles and world (:mod:`sitl_model`) and one real companion per vehicle
(:class:`companion.process.runner.Runner`: link supervision, estimator, Agent, setpoint shaping,
signed group), wired in memory on simulated time by :mod:`companion.sim.inmemory`. MAVLink and
group datagrams still cross as bytes. As fast as the CPU allows and deterministic: the same
mission, seed, parameters and profile give byte-identical ``truth.csv`` and
``events.jsonl``.

Prints first the fastest crossing of the sensor band the patrol is sure to see, with 0, 1
and 2 UAVs away (:mod:`companion.core.guarantee`), then writes the run folder of
``companion fleet`` (``truth.csv``, ``events.jsonl``, ``metrics.json``; the plots with
``--report``) and prints the headline metrics.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from companion.agent.relief.roster import run_notes
from companion.commands.options import (
    add_alert_options,
    add_battery_used_option,
    add_budget_option,
    battery_used,
)
from companion.contracts.errors import UserError
from companion.core.guarantee import describe
from companion.link.setpoints import PROFILE_CHOICES
from companion.mission import load_mission


def _param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    try:
        if not sep:
            raise ValueError
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` sub-command."""
    p = sub.add_parser(
        "simulate",
        help="fly the mission with the real companions and simulator in memory (fast, "
        "deterministic)",
        description="Fly MISSION in one process: the simulator's vehicles and world and one "
        "real companion per vehicle, lockstepped on simulated time, MAVLink and the signed "
        "group as bytes in memory. Writes DIR/truth.csv, DIR/events.jsonl and "
        "DIR/metrics.json (plots with --report) and prints the headline metrics.",
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
    p.add_argument("--seed", type=int, default=0, help="seed of the simulator's random generator")
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="simulator parameter at start, e.g. SIM_WIND_TURB=1.5 (repeatable; see sitl-model)",
    )
    p.add_argument(
        "--profile",
        choices=PROFILE_CHOICES,
        default="auto",
        help="setpoint profile of every companion (default %(default)s: by autopilot type, "
        "bank on the simulator)",
    )
    add_alert_options(p)
    add_battery_used_option(p)
    p.add_argument(
        "--faults",
        metavar="SPEC",
        help="group faults of every companion: loss=0.1,jitter=0.2,dup=0.01,reorder=0.05,"
        "seed=1 (jitter in vehicle s; seeded, so still deterministic)",
    )
    p.add_argument(
        "--report",
        action="store_true",
        help="also write the plots map.png, coverage.png and errors.png",
    )
    add_budget_option(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the mission in memory and write the run folder; returns the exit status."""
    from companion.group.faults import parse_faults
    from companion.report.summary import summary, write_report
    from companion.sim.inmemory import Engine, EngineConfig
    from sitl_model.params import ParamError, Params

    mission = load_mission(args.mission)
    duration = mission.duration_s if args.duration is None else args.duration
    if not (math.isfinite(duration) and 0 < duration <= 7 * 24 * 3600):
        raise UserError(f"--duration must be > 0 and at most a week of seconds, got {duration}")
    try:
        Params(dict(args.param))
    except ParamError as exc:
        raise UserError(f"--param: {exc}") from None
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output folder {out}: {exc.strerror or exc}") from None
    cfg = EngineConfig(
        Path(args.mission),
        out,
        seed=args.seed,
        params=dict(args.param),
        profile=args.profile,
        policy=args.policy,
        on_confirm=args.on_confirm,
        faults=parse_faults(args.faults) if args.faults else None,
        battery_used_mah=battery_used(args, mission.vehicles.all_sysids),
        group_budget_bytes_s=args.group_budget,
    )
    guarantee = describe([g.as_dict() for g in mission.crossing_guarantees()])
    print(f"simulate: {guarantee}")
    for note in run_notes(mission, duration, started_full=not cfg.battery_used_mah):
        print(f"simulate: note: {note}")
    wall0 = time.perf_counter()
    with Engine(cfg) as engine:
        engine.run(duration)
        n_events = engine.close()
        steps = engine.sim.steps
        t_sim, t_comp = engine.time_sim_s, engine.time_companion_s
    wall = time.perf_counter() - wall0
    print(
        f"mission {mission.name}: {mission.vehicles.count} UAVs, {duration:g} s simulated in "
        f"{wall:.1f} s wall ({duration / wall:.0f}x); simulator {1e3 * t_sim / steps:.3f} ms "
        f"per step, companions {1e3 * t_comp / steps:.3f} ms per step"
    )
    metrics = write_report(out, plots=args.report)
    print(summary(metrics))
    extra = ", map.png, coverage.png, errors.png" if args.report else ""
    print(f"wrote {out}/truth.csv, events.jsonl ({n_events} events), metrics.json{extra}")
    sys.stdout.flush()
    return 0
