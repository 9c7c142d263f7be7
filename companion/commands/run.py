"""``companion run``: fly one UAV of the patrol from its companion computer.

Links to the autopilot with pymavlink (``--connect``, any mavutil URL) as component 191,
joins the signed group (UDP multicast or Zenoh, ``--group``), and runs the Agent on the
vehicle's time (see ``docs/companion.md``). SIGINT/SIGTERM stop it cleanly: exit 0, sockets
closed, logs flushed. Bad input (mission, flags, key file) exits 2 with one line.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from companion.commands.options import (
    add_agent_options,
    add_budget_option,
    add_group_options,
    add_link_options,
    agent_config,
    link_config,
)
from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import parse_group
from companion.group.faults import parse_faults
from companion.group.keys import signing_from_key_file
from companion.group.transport import Group, open_group
from companion.link.connection import AutopilotLink, link_signing
from companion.link.tlog import TlogWriter
from companion.mission import Mission, MissionError, load_mission
from companion.process.config import RunConfig, telemetry_rates_hz
from companion.process.event_log import EventLog
from companion.process.runner import Runner


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` sub-command."""
    p = sub.add_parser(
        "run",
        help="fly one UAV: link to its autopilot, join the group, patrol and answer alerts",
        description=(
            "The companion process of one UAV (docs/design.md §4-5, §7). "
            "Time is the vehicle's."
        ),
    )
    p.add_argument("--connect", required=True, metavar="URL", help="autopilot link (mavutil URL)")
    p.add_argument("--mission", metavar="FILE", help="mission YAML (default: from the autopilot)")
    add_link_options(p)
    add_agent_options(p)
    add_group_options(p)
    p.add_argument("--key-file", metavar="FILE", help="fleet signing key (32 bytes, mode 600)")
    p.add_argument("--insecure", action="store_true", help="unsigned group (test benches only)")
    p.add_argument("--state-dir", metavar="DIR", help="signing-timestamp state (default: by key)")
    p.add_argument(
        "--link-key-file",
        metavar="FILE",
        help="sign the autopilot link (MAVLink 2 signing) with this key (32 bytes, mode 600); "
        "unsigned or badly signed frames from the link are then refused",
    )
    p.add_argument(
        "--faults",
        metavar="SPEC",
        help="group faults: loss=0.1,jitter=0.2,dup=0.01,reorder=0.05,seed=1 (jitter in vehicle s)",
    )
    p.add_argument("--log-dir", metavar="DIR", help="write events.jsonl and autopilot.tlog here")
    p.add_argument(
        "--take-control",
        action="store_true",
        help="switch to GUIDED (PX4: OFFBOARD) itself once the aircraft flies (never arms)",
    )
    p.add_argument(
        "--retake-after-failsafe",
        action="store_true",
        help="take the aircraft back (GUIDED; PX4: OFFBOARD) after a failsafe the companion's "
        "own silence caused (a stall, a lost link), once its link and steps are healthy "
        "again; never after a pilot's mode change (docs/companion.md)",
    )
    p.add_argument("--sysid", type=int, metavar="ID", help="accept only this autopilot system id")
    add_budget_option(p)
    p.add_argument("--no-adapt", action="store_true", help="open-loop setpoints (no gain estimate)")
    p.add_argument(
        "--boot-epoch",
        type=float,
        metavar="UNIX_S",
        help="vehicle time = UNIX_S + the autopilot's time_boot_ms, SYSTEM_TIME ignored (a "
        "fleet of PX4 SITL instances, whose SYSTEM_TIME is the host's clock; docs/px4.md)",
    )
    p.add_argument(
        "--status-interval",
        type=float,
        default=0.0,
        metavar="S",
        help="wall seconds between status lines on stderr (0: only at exit)",
    )
    p.set_defaults(func=run)


def check_args(args: argparse.Namespace) -> None:
    """Refuse inconsistent flags (UserError); the link's and the Agent's options are checked
    by :func:`~companion.commands.options.link_config` and ``agent_config``."""
    if args.key_file is None and not args.insecure:
        raise UserError(
            "the group is signed: give --key-file FILE (or --insecure for a test bench)"
        )
    if args.key_file is not None and args.insecure:
        raise UserError("--key-file and --insecure exclude each other")
    if args.status_interval < 0:
        raise UserError("--status-interval must be >= 0")
    if args.sysid is not None and not 1 <= args.sysid <= 254:
        raise UserError("--sysid must be in 1..254")


class _StoppedError(Exception):
    """SIGINT/SIGTERM before the runner's loop started."""


def run(args: argparse.Namespace) -> int:
    """Build the link, group and runner; serve until SIGINT/SIGTERM (then exit 0)."""
    check_args(args)
    setpoints = link_config(args, adapt=not args.no_adapt)
    agent = agent_config(args).at_rate(setpoints.rate_hz)  # decides at the setpoint rate
    where = parse_group(args.group)
    faults = parse_faults(args.faults) if args.faults else None
    if args.key_file is not None:
        signing_from_key_file(args.key_file, 0, state_dir=args.state_dir)  # fail early if bad
    link_check = None
    if args.link_key_file is not None:
        link_check = link_signing(args.link_key_file, args.sysid, state_dir=args.state_dir)
    mission: Mission | None = None
    if args.mission is not None:
        try:
            mission = load_mission(args.mission)
        except MissionError as exc:
            raise UserError(str(exc)) from None
    log_dir = Path(args.log_dir) if args.log_dir else None
    if log_dir is not None:
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"--log-dir {log_dir}: {exc.strerror}") from None
    runner: Runner | None = None

    def on_signal(*_: object) -> None:
        if runner is None:
            raise _StoppedError
        runner.stop()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    tlog = TlogWriter(log_dir / "autopilot.tlog") if log_dir is not None else None
    link: AutopilotLink | None = None
    try:

        def stamp_us() -> int:  # vehicle time once known (see companion.link.tlog)
            if runner is not None and runner.now_s is not None:
                return int(runner.now_s * 1e6)
            return int(time.time() * 1e6)

        def rates(autopilot: int | None) -> dict[str, float]:  # by the HEARTBEAT's type
            return telemetry_rates_hz(setpoints.rate_hz, autopilot)

        link = AutopilotLink(
            args.connect,
            sysid=args.sysid,
            rates_hz=rates,
            tlog=tlog,
            stamp_us=stamp_us,
            signing=link_check,
        )
        if mission is None:
            from companion.link.mission_protocol.from_autopilot import mission_from_autopilot

            print(
                f"companion: waiting for the autopilot on {args.connect} (to read its mission)",
                file=sys.stderr,
                flush=True,
            )
            mission = mission_from_autopilot(link)

        def vehicle_time() -> float:
            return runner.now_s if runner is not None and runner.now_s is not None else 0.0

        def group_factory(sysid: int) -> Group:
            signing: Signing | None = None
            if args.key_file is not None:
                signing = signing_from_key_file(args.key_file, sysid, state_dir=args.state_dir)
            return open_group(
                where, sysid, signing, iface=args.group_iface, faults=faults, clock=vehicle_time
            )

        config = RunConfig(
            mission=mission,
            link=setpoints,
            agent=agent,
            take_control=args.take_control,
            status_interval_s=args.status_interval,
            boot_epoch_s=args.boot_epoch,
            group_budget_bytes_s=args.group_budget,
            retake_after_failsafe=args.retake_after_failsafe,
        )
        events = EventLog(log_dir / "events.jsonl" if log_dir is not None else None)
        runner = Runner(config, link, group_factory, events, status_out=sys.stderr)
        return runner.run()
    except _StoppedError:
        return 0
    finally:
        if runner is None:  # stopped or failed before the loop: close what is open
            if link is not None:
                link.close()
            if tlog is not None:
                tlog.close()
        for s, h in previous.items():
            signal.signal(s, h)
