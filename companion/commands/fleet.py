"""``companion fleet MISSION``: the whole mission over MAVLink, in one command.

Starts ``sitl-model`` and one ``companion run`` per vehicle on a fresh fleet key, uploads the
perimeter to every vehicle, lets the companions take control, shows progress in simulated
time, and on completion, Ctrl-C or SIGTERM stops every process it started and writes the
report (``truth.csv``, ``events.jsonl``, the tlogs, ``metrics.json`` and the plots).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from pathlib import Path

from companion.agent.relief.roster import run_notes
from companion.commands.options import (
    add_agent_options,
    add_battery_used_option,
    add_budget_option,
    add_link_options,
    agent_config,
    battery_used,
    link_config,
)
from companion.contracts.errors import UserError
from companion.mission import load_mission


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``fleet`` sub-command."""
    p = sub.add_parser(
        "fleet",
        help="run a mission end to end: simulator + one companion per UAV + report",
        description="Run MISSION over MAVLink: sitl-model for its vehicles, one 'companion "
        "run' per vehicle on a fresh fleet key, the mission's intruder scenario, then "
        "metrics.json and the plots. Output goes to --out (default runs/NAME-TIME).",
    )
    p.add_argument("mission", metavar="MISSION", help="mission YAML file")
    p.add_argument(
        "--speedup",
        type=float,
        default=None,
        metavar="X",
        help="simulated seconds per wall second once the companions fly: in lockstep a "
        "ceiling (default none: as fast as the companions answer), free-running the pace "
        "(default 20; 5 with --autopilot arduplane, 3 with --autopilot px4)",
    )
    p.add_argument(
        "--no-lockstep",
        "--free-run",
        dest="lockstep",
        action="store_false",
        help="run the simulator free against the wall clock instead of in lockstep with the "
        "companions (results then move with the machine's load)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds (default: the mission's scenario duration)",
    )
    p.add_argument("--out", metavar="DIR", help="output folder (default runs/NAME-TIME)")
    add_link_options(p, ("profile",))  # of every companion
    p.add_argument(
        "--autopilot",
        choices=("sitl-model", "arduplane", "px4"),
        default="sitl-model",
        help="what flies the vehicles: our simulator (default), one ArduPlane SITL "
        "instance per vehicle (real firmware; see docs/arduplane.md) or one PX4 SITL (SIH "
        "fixed-wing, still air) instance per vehicle (docs/px4.md)",
    )
    p.add_argument(
        "--px4-dir",
        metavar="DIR",
        help="the PX4 SITL folder with bin/px4 and etc (default $PX4_SITL_DIR; one of the "
        "two is needed with --autopilot px4; docs/px4.md)",
    )
    p.add_argument(
        "--arduplane-bin",
        metavar="PATH",
        help="the ArduPlane SITL binary (default $ARDUPLANE_SITL; one of the two is needed "
        "with --autopilot arduplane; docs/arduplane.md)",
    )
    p.add_argument(
        "--arduplane-base-port",
        type=int,
        metavar="PORT",
        help="first TCP port of the ArduPlane instances, 10 per instance (default: free)",
    )
    add_agent_options(p)
    p.add_argument(
        "--group",
        metavar="WHERE",
        help="the companions' group: ADDR:PORT (multicast; default 239.255.14.1 on a free "
        "port) or zenoh[:ENDPOINT,...][?...] (Zenoh peers meeting at this process; the run "
        "gets its own key expression); see docs/protocol.md",
    )
    p.add_argument(
        "--observer-group",
        metavar="WHERE",
        help="with a Zenoh --group: where this process (the progress) and the dashboard "
        "join the group instead of meeting the companions themselves, e.g. "
        "zenoh-client:tcp/127.0.0.1:7448 (a router's ground side when the companions reach "
        "it through a radio); the companions' key expression is used",
    )
    p.add_argument(
        "--faults",
        metavar="SPEC",
        help="group faults, e.g. loss=0.1,jitter=0.2,dup=0.01,reorder=0.05,seed=1",
    )
    p.add_argument(
        "--link-signing",
        action="store_true",
        help="sign every autopilot link (MAVLink 2 signing) with a fresh link.key in --out",
    )
    p.add_argument(
        "--sim-param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a simulator parameter (its world: wind, gusts, GPS errors, autopilot lag...), "
        "passed as 'sitl-model --param'; the companions are not told (repeatable), e.g. "
        "--sim-param SIM_WIND_SPD=8 --sim-param SIM_WIND_DIR=225; with --autopilot arduplane "
        "any ArduPlane parameter, with --autopilot px4 any PX4 parameter, set on every "
        "instance after the mission's",
    )
    add_battery_used_option(p)
    p.add_argument(
        "--dashboard",
        nargs="?",
        type=int,
        const=8080,
        metavar="PORT",
        help="serve the live patrol page on http://127.0.0.1:PORT/ during the run "
        "(default port 8080; see docs/dashboard.md)",
    )
    add_budget_option(p)
    p.add_argument(
        "--companion-link",
        choices=("tcp", "serial", "relay"),
        default="tcp",
        help="how each companion reaches its autopilot: directly (default: TCP to "
        "ArduPlane's SERIAL1, UDP to PX4), 'serial' (--autopilot arduplane: socat between "
        "SERIAL1 and a pseudo-terminal the companion opens as a serial device) or 'relay' "
        "(--autopilot px4: socat relaying its UDP link); both need socat",
    )
    p.add_argument(
        "--retake-after-failsafe",
        action="store_true",
        help="every companion's --retake-after-failsafe (docs/companion.md)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


class _InterruptedError(Exception):
    pass


def run(args: argparse.Namespace) -> int:
    """Run the fleet; returns the exit status (0 done, 130 interrupted, 2 bad input; a firmware
    fleet: 3 when the patrol was not held, the verdict line says why)."""
    from companion.sim.fleet import Fleet, FleetConfig

    mission = load_mission(args.mission)  # a bad mission stops here: nothing is started
    if args.speedup is not None and not (math.isfinite(args.speedup) and 0 < args.speedup <= 1000):
        raise UserError(f"--speedup must be > 0 and at most 1000, got {args.speedup}")
    from companion.sim.fleet import LOCKSTEP_MAX_SPEEDUP

    speedup = args.speedup or (LOCKSTEP_MAX_SPEEDUP if args.lockstep else 20.0)
    if args.autopilot == "arduplane":  # real firmware: free-running, its own pace
        from companion.sim.arduplane import fleet as ap

        speedup, args.lockstep = _firmware_speedup(args, mission, ap.DEFAULT_SPEEDUP), False
    if args.autopilot == "px4":  # real firmware: free-running at its speed factor
        from companion.sim.px4 import fleet as px4_fleet

        speedup, args.lockstep = _firmware_speedup(args, mission, px4_fleet.DEFAULT_SPEEDUP), False
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise UserError(f"--duration must be > 0, got {args.duration}")
    check = ap.parse_param if args.autopilot == "arduplane" else _sim_param
    if args.autopilot == "px4":
        check = px4_fleet.parse_param
    sim_params = tuple(check(text) for text in args.sim_param)
    out = (
        Path(args.out)
        if args.out
        else Path("runs") / (f"{mission.name}-{time.strftime('%Y%m%d-%H%M%S')}")
    )
    cfg = FleetConfig(
        Path(args.mission),
        out,
        speedup=speedup,
        duration_s=args.duration,
        link=link_config(args, ("profile",)),
        agent=agent_config(args),
        faults=args.faults,
        group=args.group,
        link_signing=args.link_signing,
        lockstep=args.lockstep,
        sim_params=sim_params,
        battery_used_mah=battery_used(args, mission.vehicles.all_sysids),
        dashboard_port=args.dashboard,
        group_budget_bytes_s=args.group_budget,
        observer_group=args.observer_group,
        companion_link=args.companion_link,
        retake_after_failsafe=args.retake_after_failsafe,
    )
    if args.companion_link == "serial" and args.autopilot != "arduplane":
        raise UserError("--companion-link serial: only with --autopilot arduplane")
    if args.companion_link == "relay" and args.autopilot != "px4":
        raise UserError("--companion-link relay: only with --autopilot px4")
    if args.dashboard is not None and not 1 <= args.dashboard <= 65535:
        raise UserError(f"--dashboard {args.dashboard}: expected a TCP port 1..65535")

    def on_signal(signum: int, _frame: object) -> None:
        raise _InterruptedError(signal.Signals(signum).name)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    if args.autopilot == "arduplane":
        fleet = ap.ArduPlaneFleet(cfg, mission, args.arduplane_bin, args.arduplane_base_port)
    elif args.autopilot == "px4":
        fleet = px4_fleet.Px4Fleet(cfg, mission, args.px4_dir)
    else:
        fleet = Fleet(cfg, mission)
    status = 0
    print(
        f"fleet: {mission.name}, {mission.vehicles.count} UAVs"
        + (f" and {len(mission.vehicles.spares)} spares" if mission.vehicles.spares else "")
        + f", {fleet.duration_s:g} s "
        f"simulated {_pace(cfg)}; output in {out}"
        + ("; autopilot links signed (link.key)" if cfg.link_signing else "")
        + (f"; simulator world: {' '.join(sim_params)}" if sim_params else "")
    )
    for note in run_notes(mission, fleet.duration_s, started_full=not cfg.battery_used_mah):
        print(f"fleet: note: {note}")
    if cfg.dashboard_port is not None:
        print(f"fleet: live page at http://127.0.0.1:{cfg.dashboard_port}/", flush=True)
    try:
        fleet.start()
        status = _follow(fleet, mission, not args.no_progress)
    except _InterruptedError as exc:
        print(f"\nfleet: {exc}: stopping every process and writing the report")
        status = 130
    except UserError:
        fleet.stop()
        raise
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        results = fleet.stop()
    bad = [(n, rc) for n, rc in results if rc not in (0, None, -signal.SIGINT)]
    if bad:
        print("fleet: unclean exits: " + ", ".join(f"{n} ({rc})" for n, rc in bad))
    n_events = fleet.merge_events()
    from companion.report.summary import summary, write_report

    try:
        metrics = write_report(out)
    except (UserError, ValueError, IndexError) as exc:
        print(f"fleet: no report ({exc})")
        return status or 1
    print(summary(metrics))
    print(
        f"fleet: wrote {out}/truth.csv, events.jsonl ({n_events} events), metrics.json, "
        "map.png, coverage.png, errors.png and uav*/autopilot.tlog"
    )
    if args.autopilot != "sitl-model" and status == 0:  # free-running firmware: say if it held
        from companion.sim.pace import verdict

        v = verdict(out, not_before_s=metrics.get("window_start_s"))
        pace = fleet.pace.slowed
        slowed = f" (slowed to {pace[-1][1]:g}x)" if pace else ""
        print(f"fleet: {v.line}{slowed}")
        if not v.held:
            return NOT_HELD
    return status


NOT_HELD = 3  # the exit status of a firmware fleet that did not hold the patrol


def _firmware_speedup(args: argparse.Namespace, mission, default: float) -> float:
    """The speed factor of a firmware fleet: ``--speedup``, else the one the machine can
    hold now (:func:`companion.sim.pace.choose_speedup`, said on stdout)."""
    from companion.sim.pace import choose_speedup, free_cores

    n = len(mission.vehicles.all_sysids)
    if args.speedup is not None:
        return args.speedup
    x, why = choose_speedup(n, args.autopilot, free_cores(), default)
    print(f"fleet: speed factor {x:g} ({why}; --speedup to choose)")
    return x


def _sim_param(text: str) -> str:
    """Check one ``--sim-param NAME=VALUE`` against the simulator's parameter table."""
    from sitl_model.params import ParamError, Params

    name, sep, value = text.partition("=")
    try:
        Params({name.strip(): float(value)})
    except ValueError as exc:  # ParamError is a ValueError
        why = exc if sep and isinstance(exc, ParamError) else "expected NAME=VALUE"
        raise UserError(f"--sim-param {text!r}: {why}") from None
    return f"{name.strip()}={float(value):g}"


def _pace(cfg) -> str:
    """How the simulated clock runs, for the banner."""
    if not cfg.lockstep:
        return f"at {cfg.speedup:g}x (free-running)"
    from companion.sim.fleet import LOCKSTEP_MAX_SPEEDUP

    if cfg.speedup >= LOCKSTEP_MAX_SPEEDUP:
        return "in lockstep, as fast as the companions answer"
    return f"in lockstep, at most {cfg.speedup:g}x"


def _follow(fleet, mission, show: bool) -> int:
    """Wait for the simulator to reach the duration, with a progress bar in simulated time."""
    from tqdm import tqdm

    from companion.sim.fleet import FOLLOW_S

    period = mission.patrol.period_s
    ideal = period / mission.vehicles.count
    total = round(fleet.duration_s)
    tty = sys.stderr.isatty()
    with tqdm(
        total=total,
        unit="sim s",
        disable=not show,
        dynamic_ncols=True,
        mininterval=0.5 if tty else 15.0,
        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} sim s [{elapsed}{postfix}]",
    ) as bar:
        while not fleet.sim_done():
            if not fleet.poll(FOLLOW_S):
                continue  # woken by the group's datagrams: redrawn once the tail is read
            fleet.check_alive()
            p = fleet.progress
            splay = p.splay_deg(period)
            away = sum(1 for m in p.modes.values() if m not in ("patrol", "spare"))
            states = ",".join(f"{k}:{v}" for k, v in sorted(p.alerts.items())) or "none"
            xt, unseen = p.cross_track_max_m(), p.unseen_s
            bar.set_postfix_str(
                f"cross-track {'-' if xt is None else f'{xt:.1f}'} m, unseen "
                f"{'-' if unseen is None else f'{unseen:.0f} s ({unseen / ideal:.2f} T/N)'}, "
                f"splay {'-' if splay is None else f'{splay:.2f}'} deg, away {away}, "
                f"alerts {states}",
                refresh=False,
            )
            bar.update(max(0, min(round(p.t_s), total) - bar.n))
            fleet.keep_pace(bar.write)
        bar.update(total - bar.n)
    return 0
