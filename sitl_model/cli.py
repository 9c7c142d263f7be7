"""``sitl-model``: command line of the N-vehicle MAVLink simulator.

Exit status: 0 after SIGINT/SIGTERM or ``--duration``; 2 for bad arguments or a bad
mission file (one line on stderr, no traceback); 1 if a UDP port cannot be bound.
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from companion.core.sim_contract import PORT_SPACING
from companion.mission import MissionError, load_mission
from sitl_model.autopilot import Mode
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.link import VehicleLink
from sitl_model.lockstep import DEFAULT_WAIT_BOUND_S
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import Params
from sitl_model.server import Server, ServerConfig
from sitl_model.sim import Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

PATROL_WAYPOINTS = 16  # the fallback AUTO mission preloaded from a --mission's patrol loop


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
        "--lockstep-wait",
        type=float,
        default=DEFAULT_WAIT_BOUND_S,
        metavar="S",
        help="wall seconds to wait for one answer before going on without that vehicle "
        f"(default {DEFAULT_WAIT_BOUND_S:g})",
    )
    return p


def _setups(args: argparse.Namespace, mission) -> list[VehicleSetup]:
    if mission is None:
        n = 1 if args.vehicles is None else args.vehicles
        return [VehicleSetup(i + 1, 0.0, 300.0 * i, 0.0, 100.0 + 10.0 * i) for i in range(n)]
    v = mission.vehicles
    if args.vehicles is not None and args.vehicles != v.count:
        raise ValueError(f"--vehicles {args.vehicles} does not match the mission's {v.count}")
    return [
        VehicleSetup(sid, pose.north_m, pose.east_m, pose.heading_deg, alt)
        for sid, pose, alt in zip(v.sysids, v.initial, v.altitudes_m, strict=True)
    ]


def build(args: argparse.Namespace) -> tuple[Simulation, list[VehicleLink], ServerConfig]:
    """The simulation, its vehicle links and the I/O settings from parsed arguments.

    Raises :class:`MissionError` for a bad mission and ``ValueError`` for bad arguments.
    """
    mission = load_mission(args.mission) if args.mission else None
    setups = _setups(args, mission)
    if not 1 <= len(setups) <= 250:
        raise ValueError(f"--vehicles must be 1..250, got {len(setups)}")
    if not (args.base_port > 0 and args.base_port + PORT_SPACING * (len(setups) - 1) < 65536):
        raise ValueError("--base-port + 10 (N - 1) must be a valid UDP port")
    if args.start_mode == "auto" and mission is None:
        raise ValueError("--start-mode auto needs a --mission (its patrol is the AUTO mission)")
    if not args.speedup > 0:
        raise ValueError(f"--speedup must be > 0, got {args.speedup}")
    if not (math.isfinite(args.lockstep_wait) and args.lockstep_wait > 0):
        raise ValueError(f"--lockstep-wait must be > 0 s, got {args.lockstep_wait}")
    if (args.wind_speed is None) != (args.wind_from is None):
        raise ValueError("give --wind-speed and --wind-from together")
    overrides: dict[str, float] = {}
    frame = LocalFrame(*DEFAULT_ORIGIN)
    if mission is not None:
        overrides |= {
            "SIM_AIRSPEED": mission.vehicles.airspeed_m_s,
            "SIM_TURN_MAX": mission.vehicles.max_turn_rate_deg_s,
            "SIM_WIND_SPD": mission.wind.speed_m_s,
            "SIM_WIND_DIR": mission.wind.from_deg % 360.0,
            "SIM_SENS_RAD": mission.sensor.footprint_radius_m,
        }
        if mission.fence is not None:  # the band of the fence loaded below (still disabled)
            overrides |= {
                "FENCE_ALT_MIN": mission.fence.min_alt_m,
                "FENCE_ALT_MAX": mission.fence.max_alt_m,
                "FENCE_TYPE": 13.0,  # max altitude, polygon, min altitude
            }
        o = mission.origin
        frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    if args.wind_speed is not None:
        overrides |= {"SIM_WIND_SPD": args.wind_speed, "SIM_WIND_DIR": args.wind_from % 360}
    overrides |= dict(args.param)
    signing_key = None
    if args.signing_key_file is not None:
        from companion.group.keys import load_key

        signing_key = load_key(args.signing_key_file)  # UserError (a ValueError) if refused
    sim = Simulation(
        setups,
        Params(overrides),
        frame,
        mission.intruders if mission else (),
        seed=args.seed,
        start_mode=Mode[args.start_mode.upper()],
    )
    tm = Telemetry(sim)
    patrol_points = None
    if mission is not None:
        patrol_points = mission.patrol.sample_by_time(PATROL_WAYPOINTS)
    links = []
    fence: tuple = ()  # every vehicle holds the mission's fence, as it holds the patrol
    if mission is not None and mission.fence is not None:
        fence = sim.fence_items(np.array(mission.fence.fence.polygon_m))
    for i in range(len(setups)):
        items = () if patrol_points is None else sim.patrol_items(i, patrol_points)
        protocol = MissionProtocol(items, home=sim.home_item(), fence=fence)
        links.append(VehicleLink(sim, i, tm, protocol))
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
    )
    return sim, links, cfg


def main(argv: list[str] | None = None) -> int:
    """Run the simulator; returns the exit status."""
    from companion.core.argv import join_negative_values

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
