"""Guidance lab: the companion's estimator, agent and shaper against the simulator, in process.

A quick, deterministic loop for tuning the guidance under disturbances (no sockets, no MAVLink
bytes, no group codec: for the whole stack use ``companion simulate`` or ``companion fleet``). The
simulator is built exactly as ``sitl-model`` builds it (``sitl_model.cli.build``, through
``sitl_model.assembly.assemble``), so ``--param`` works as there; the companions are told the
mission's wind. Prints model-free figures from the true positions over the last window: cross-track
median / p95 / max and the worst coverage revisit.

    python bench/guidance_lab.py missions/ellipse_6uav.yaml --duration 700 \\
        --param SIM_WIND_TURB=1.5 --profile bank --param SIM_LAG=0.5 --param SIM_TR_EFF=0.75
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

# bench/companion.py would shadow the package when run as a script
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.agent.agent import Agent
from companion.agent.config import AgentConfig
from companion.agent.fix import Fix
from companion.core.wind import TWO_PI
from companion.link.estimate import Estimator
from companion.link.shaping import Shaper
from companion.mission import load_mission
from sitl_model.cli import build, build_parser

CONTROL_EVERY = 5  # physics steps (50 Hz) per control step: 10 Hz
STATE_EVERY = 2  # control steps per state broadcast: 5 Hz


def loop_polyline(patrol, n: int = 4000) -> np.ndarray:
    """Dense points of the loop (world, complex m)."""
    return np.asarray(patrol.point_at_phase(np.linspace(0, TWO_PI, n, endpoint=False)))


def run(args: argparse.Namespace) -> dict:
    mission = load_mission(args.mission)
    sim_args = build_parser().parse_args(
        ["--mission", args.mission, "--seed", str(args.seed)]
        + [x for p in args.param for x in ("--param", p)]
    )
    sim, links, _ = build(sim_args)
    tm = links[0].tm
    n = len(sim.sysids)
    v = mission.vehicles
    over = {
        k: v
        for k, v in (
            ("centre_gain", args.centre_gain),
            ("phase_gain", args.phase_gain),
            ("xtrack_bw_rad_s", args.hold_bw),
        )
        if v is not None
    }
    if over:
        mission = dataclasses.replace(mission, gains=dataclasses.replace(mission.gains, **over))
    wind0 = mission.wind.wind()
    ests = [
        Estimator(mission.origin, v.airspeed_m_s, wind0, heading_tau_s=args.heading_tau)
        for _ in range(n)
    ]
    agents = [Agent(s, mission, AgentConfig(lead_s=0.05)) for s in sim.sysids]
    shapers = [Shaper(args.profile, v.airspeed_m_s, v.max_turn_rate_rad_s) for _ in range(n)]
    poly = loop_polyline(mission.patrol)
    r_s = mission.sensor.footprint_radius_m
    pts = poly[:: max(1, len(poly) // int(mission.patrol.length_m / 10))]
    steps = int(args.duration * 50)
    window0 = args.duration - args.window
    xt: list[np.ndarray] = []
    last_seen = np.full(pts.size, np.nan)
    worst_gap = 0.0
    k = 0
    t_wall = time.perf_counter()
    for step in range(steps):
        sim.step()
        if step % CONTROL_EVERY:
            continue
        k += 1
        t = sim.t_s
        ms = round(t * 1000)
        outs = []
        for i in range(n):
            att = tm.attitude(i)
            ests[i].on_attitude(ms, float(att.yaw))
            if k % 5 == 0:
                ests[i].on_airspeed(float(tm.vfr_hud(i).airspeed))
            if k % 10 == 0:
                w = tm.wind(i)
                ests[i].on_autopilot_wind(t, float(w.speed), float(w.direction))
            g = tm.global_position_int(i)
            e = ests[i].from_global_position(t, ms, g.lat, g.lon, g.alt, g.vx, g.vy, g.hdg)
            shapers[i].observe(t, e.turn_rate_rad_s)
            agents[i].observe_wind(ests[i].wind_estimator.estimate(t), t)
            out = agents[i].update(Fix(t, e.pos_m, e.heading_rad, agents[i].patrol))
            if agents[i].patrol.wind != ests[i].wind:
                ests[i].set_wind(agents[i].patrol.wind)
            msg = shapers[i].setpoint(t, out.turn_rate_rad_s, e.course_rad, ms, sim.sysids[i])
            links[i].handle(msg, ("lab", 0), 0.0)
            outs.append(out)
        if k % STATE_EVERY == 0:
            for i, out in enumerate(outs):
                for j in range(n):
                    if j != i:
                        agents[j].receive_state(out.broadcast, t)
        if t >= window0:
            pos = sim.state.pos_m
            d = np.min(np.abs(pos[:, None] - poly[None, :]), axis=1)
            xt.append(d)
            cov = np.any(np.abs(pts[:, None] - pos[None, :]) <= r_s, axis=1)
            seen_before = ~np.isnan(last_seen)
            gaps = t - last_seen[cov & seen_before]
            if gaps.size:
                worst_gap = max(worst_gap, float(gaps.max()))
            last_seen[cov] = t
    xt_a = np.concatenate(xt) if xt else np.zeros(1)
    ideal = mission.patrol.period_s / n
    winds = {a.sysid: a.patrol.wind for a in agents}
    w0 = winds[sim.sysids[0]]
    return {
        "xt_med": float(np.median(xt_a)),
        "xt_p95": float(np.percentile(xt_a, 95)),
        "xt_max": float(np.max(xt_a)),
        "unseen_ratio": worst_gap / ideal,
        "wind_agreed": f"{w0.speed_m_s:.2f} m/s from {w0.from_deg:.0f}",
        "winds_equal": len(set(winds.values())) == 1,
        "wind_true": f"{abs(sim.wind_m_s):.2f} m/s",
        "gains": [round(s.gain, 3) for s in shapers],
        "wall_s": round(time.perf_counter() - t_wall, 1),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mission")
    p.add_argument("--duration", type=float, default=700.0)
    p.add_argument("--window", type=float, default=300.0)
    p.add_argument("--profile", default="turn-rate")
    p.add_argument("--param", action="append", default=[])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--heading-tau", type=float, default=3.0, help="heading filter (s)")
    p.add_argument("--centre-gain", type=float, help="override the mission's centre gain")
    p.add_argument("--phase-gain", type=float, help="override the mission's phase gain")
    p.add_argument("--hold-bw", type=float, help="cross-track hold bandwidth (rad/s)")
    p.add_argument("--boost-cap", type=float, help="override steering.MAX_PHASE_BOOST")
    args = p.parse_args()
    from companion.guidance import steering

    if args.boost_cap is not None:
        steering.MAX_PHASE_BOOST = args.boost_cap
    res = run(args)
    print(" ".join(f"{k}={v:.2f}" if isinstance(v, float) else f"{k}={v}" for k, v in res.items()))
    return 0 if math.isfinite(res["xt_p95"]) else 1


if __name__ == "__main__":
    raise SystemExit(main())
