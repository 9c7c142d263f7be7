"""``companion guarantee``: the fastest crossing a mission's patrol is sure to see, and how
many UAVs it takes to see a faster one.

Edge of :mod:`companion.core.guarantee` (the derivation, the assumptions): reads the mission
(loop, airspeed, wind, sensor, N), prints the speed up to which every crossing of the sensor
band is seen with 0, 1 and 2 UAVs away, and with ``--speed V`` the fewest UAVs on this loop
sure to see a crossing at V m/s (``--away K``: with K of them away). ``--json`` prints one
JSON object instead.
"""

from __future__ import annotations

import argparse
import json
import math

from companion.contracts.errors import UserError
from companion.core.guarantee import MAX_VEHICLES, describe, vehicles_needed
from companion.mission import load_mission


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``guarantee`` sub-command."""
    p = sub.add_parser(
        "guarantee",
        help="the fastest crossing the patrol is sure to see; UAVs needed for a speed",
        description="The fastest crossing of the sensor band (2 r_s wide along the loop) "
        "that MISSION's patrol is sure to see, with 0, 1 and 2 UAVs away; with --speed, the "
        "fewest UAVs on this loop sure to see a crossing that fast.",
    )
    p.add_argument("mission", help="mission YAML file")
    p.add_argument(
        "--speed", type=float, metavar="V", help="a crossing speed (m/s): how many UAVs see it"
    )
    p.add_argument("--away", type=int, default=0, metavar="K", help="with K UAVs away (default 0)")
    p.add_argument("--json", action="store_true", help="one JSON object instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the guarantee (and the UAVs needed); 1 if no formation sees ``--speed``."""
    if args.speed is not None and not (math.isfinite(args.speed) and args.speed > 0):
        raise UserError(f"--speed must be a speed > 0 m/s, got {args.speed}")
    if not 0 <= args.away < MAX_VEHICLES:
        raise UserError(f"--away must be from 0 to {MAX_VEHICLES - 1}, got {args.away}")
    m = load_mission(args.mission)
    records = [g.as_dict() for g in m.crossing_guarantees()]
    out: dict = {
        "mission": m.name,
        "vehicles": m.vehicles.count,
        "loop_length_m": round(m.patrol.length_m, 1),
        "period_s": round(m.patrol.period_s, 3),
        "airspeed_m_s": m.vehicles.airspeed_m_s,
        "wind_speed_m_s": m.wind.speed_m_s,
        "footprint_radius_m": m.sensor.footprint_radius_m,
        "guarantees": records,
    }
    needed = None
    if args.speed is not None:
        needed = vehicles_needed(
            args.speed,
            m.patrol.period_s,
            m.sensor.footprint_radius_m,
            m.vehicles.airspeed_m_s,
            m.wind.speed_m_s,
            away=args.away,
        )
        out |= {"speed_m_s": args.speed, "away": args.away, "vehicles_needed": needed}
    if args.json:
        print(json.dumps(out))
    else:
        print(
            f"mission {m.name}: {m.vehicles.count} UAVs at {m.vehicles.airspeed_m_s:g} m/s on a "
            f"{m.patrol.length_m / 1e3:.2f} km loop, period T {m.patrol.period_s:.1f} s in "
            f"the mission's wind ({m.wind.speed_m_s:g} m/s), sensor footprint r_s "
            f"{m.sensor.footprint_radius_m:g} m"
        )
        print(describe(records))
        if args.speed is not None:
            print(_needed_line(m, args.speed, args.away, needed))
    return 1 if args.speed is not None and needed is None else 0


def _needed_line(m, speed_m_s: float, away: int, needed: int | None) -> str:
    """What ``--speed`` asks, answered in one line."""
    with_away = f" with {away} away" if away else ""
    if needed is None:
        return (
            f"to see a {speed_m_s:g} m/s crossing{with_away}: no formation of up to "
            f"{MAX_VEHICLES} UAVs on this loop"
        )
    g = m.crossing_guarantee(away=away, vehicles=needed)
    sure = "any speed" if g.continuous else f"{g.sure_m_s:.2f} m/s"
    return (
        f"to see a {speed_m_s:g} m/s crossing{with_away}: {needed} UAVs on this loop "
        f"(gap {g.gap_s:.1f} s, sure up to {sure}; the mission has {m.vehicles.count})"
    )
