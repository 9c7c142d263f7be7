"""``sitl-model``: command line of the N-vehicle MAVLink simulator.

Exit status: 0 after SIGINT/SIGTERM or ``--duration``; 2 for bad arguments or a bad
mission file (one line on stderr, no traceback); 1 if a UDP port cannot be bound.
"""

from __future__ import annotations

import argparse
import math
import sys

from companion.contracts.argv import add_battery_used_option, join_negative_values
from companion.contracts.simulator import PORT_SPACING
from companion.mission import MissionError
from sitl_model.assembly import WorldSpec, assemble
from sitl_model.autopilot import Mode
from sitl_model.link import VehicleLink
from sitl_model.lockstep import DEFAULT_WAIT_BOUND_S
from sitl_model.server import Server, ServerConfig
from sitl_model.sim import DT_S, Simulation


def _host_port(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}")
    return host, int(port)


def _param(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    """The argument parser."""
    p = argparse.ArgumentParser(
        prog="sitl-model",
        description="N simulated ArduPlane-like fixed-wing autopilots speaking MAVLink 2 on UDP.",
    )
    p.add_argument("--vehicles", type=int, help="number of vehicles (default: the mission's, or 1)")
    p.add_argument("--mission", help="mission YAML (origin, fleet, wind, sensor, intruders)")
    p.add_argument("--base-port", type=int, default=5760, help="vehicle i listens on +10 i")
    p.add_argument("--host", default="127.0.0.1", help="address to bind")
    p.add_argument("--speedup", type=float, default=1.0, help="simulated s per wall s")
    p.add_argument("--wind-speed", type=float, help="wind speed (m/s); overrides the mission")
    p.add_argument("--wind-from", type=float, help="direction the wind blows FROM (deg)")
    p.add_argument("--truth-log", help="CSV ground truth, 10 rows per vehicle per simulated s")
    p.add_argument("--events-log", help="JSON Lines events")
    p.add_argument("--seed", type=int, default=0, help="seed of the one random generator")
    p.add_argument(
        "--gcs-out",
        type=_host_port,
        action="append",
        default=[],
        metavar="HOST:PORT",
        help="also stream every vehicle's telemetry to this address (repeatable)",
    )
    p.add_argument(
        "--start-mode",
        choices=[m.name.lower() for m in Mode],
        default="guided",
        help="mode at t = 0 (default guided: hold course until a setpoint or the timeout)",
    )
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="initial parameter value, e.g. SIM_LAG=0.5 (repeatable)",
    )
    add_battery_used_option(p)
    p.add_argument("--duration", type=float, help="stop after this many simulated s")
    p.add_argument("--status-interval", type=float, default=5.0, help="wall s between statuses")
    p.add_argument("--no-control", action="store_true", help="do not read control lines on stdin")
    p.add_argument(
        "--signing-key-file",
        metavar="FILE",
        help="MAVLink 2 link signing: every vehicle signs and accepts only frames signed with "
        "this 32-byte key (raw or hex, mode 600; the same key for all vehicles)",
    )
    p.add_argument(
        "--lockstep",
        action="store_true",
        help="advance only when every GUIDED vehicle with a controlling peer has answered its "
        "latest GLOBAL_POSITION_INT with a setpoint (--speedup is then a ceiling)",
    )
    p.add_argument(
        "--physics-hz",
        type=float,
        choices=(10.0, 50.0),
        default=None,
        help="physics steps per simulated second: 50 (20 ms) or 10 (0.1 s at once, the "
        "companions' control period, integrated exactly; default with --lockstep); telemetry "
        "is never faster than the physics",
    )
    p.add_argument(
        "--lockstep-wait",
        type=float,
        default=DEFAULT_WAIT_BOUND_S,
        metavar="S",
        help="wall seconds to wait for one answer before going on without that vehicle "
        f"(default {DEFAULT_WAIT_BOUND_S:g})",
    )
    return p


def build(args: argparse.Namespace) -> tuple[Simulation, list[VehicleLink], ServerConfig]:
    """The simulation, its vehicle links and the I/O settings from parsed arguments.

    Raises :class:`MissionError` for a bad mission and ``ValueError`` for bad arguments.
    """
    spec = WorldSpec(
        mission_path=args.mission,
        vehicles=args.vehicles,
        params=tuple(args.param),
        seed=args.seed,
        start_mode=args.start_mode,
        wind_speed_m_s=args.wind_speed,
        wind_from_deg=args.wind_from,
        battery_used_mah=tuple(args.battery_used),
    )
    sim, links = assemble(spec)
    n = len(links)
    if not (args.base_port > 0 and args.base_port + PORT_SPACING * (n - 1) < 65536):
        raise ValueError("--base-port + 10 (N - 1) must be a valid UDP port")
    if not args.speedup > 0:
        raise ValueError(f"--speedup must be > 0, got {args.speedup}")
    if not (math.isfinite(args.lockstep_wait) and args.lockstep_wait > 0):
        raise ValueError(f"--lockstep-wait must be > 0 s, got {args.lockstep_wait}")
    signing_key = None
    if args.signing_key_file is not None:
        from companion.group.keys import load_key

        signing_key = load_key(args.signing_key_file)  # UserError (a ValueError) if refused
    cfg = ServerConfig(
        host=args.host,
        base_port=args.base_port,
        speedup=args.speedup,
        gcs_out=tuple(args.gcs_out),
        truth_log=args.truth_log,
        events_log=args.events_log,
        status_interval_s=args.status_interval,
        duration_s=args.duration,
        control_stdin=not args.no_control,
        signing_key=signing_key,
        lockstep=args.lockstep,
        lockstep_wait_s=args.lockstep_wait,
        physics_every=_physics_every(args.physics_hz, args.lockstep),
    )
    return sim, links, cfg


def _physics_every(hz: float | None, lockstep: bool) -> int:
    """Physics steps of ``DT_S`` taken at once for ``--physics-hz`` (None: 10 Hz in
    lockstep, 50 Hz free running)."""
    if hz is None:
        hz = 10.0 if lockstep else 50.0
    return max(1, round(1.0 / (hz * DT_S)))


def main(argv: list[str] | None = None) -> int:
    """Run the simulator; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(join_negative_values(parser, sys.argv[1:] if argv is None else argv))
    try:
        sim, links, cfg = build(args)
    except MissionError as e:
        print(f"sitl-model: {e}", file=sys.stderr)
        return 2
    except ValueError as e:  # ParamError is a ValueError
        print(f"sitl-model: error: {e}", file=sys.stderr)
        return 2
    try:
        server = Server(sim, links, cfg)
    except OSError as e:
        print(f"sitl-model: cannot open UDP port: {e}", file=sys.stderr)
        return 1
    signed = ", link signing on" if cfg.signing_key is not None else ""
    if cfg.lockstep:
        signed += f", lockstep (wait at most {cfg.lockstep_wait_s:g} s)"
    print(
        f"sitl-model: {len(links)} vehicle(s), sysids {sim.sysids[0]}..{sim.sysids[-1]}, "
        f"UDP {cfg.host}:{cfg.base_port}+10i, speedup {cfg.speedup:g}{signed}",
        file=sys.stderr,
        flush=True,
    )
    return server.run()
