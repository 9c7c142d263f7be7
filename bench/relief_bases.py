"""Reliefs on bases nobody drew: generated, seeded missions flown in memory with spares.

For each seed, :func:`companion.mission.generate.generate` draws a base (a convex loop of
1 km to ``--max-loop-km``), a fleet of 3 to ``--max-vehicles`` UAVs (the
generator draws 3-12; one above the cap flies the cap), an airspeed, a turn-rate limit
and a wind of up to half the airspeed. This bench drops the drawn intruders (the figures are
the reliefs'), gives every aircraft the issue's battery (50 min, 20 % reserve, 20-minute
turnaround) and puts the spares on one runway 150 m outside the loop, beside the loop point
farthest from the loop's centre, facing along the traffic there, with ``vehicles.opening:
staggered``. The number of spares is what the companions' rotation keeps busy,
``ceil(N (relief lead + home + landing margin + turnaround) / beat)``
(``Roster.spares_needed``; docs/energy.md, "Can the spares keep the patrol up?"), plus
``--extra-spares`` (negative: fewer, at least one); the mission loader's own bound is
printed beside it. Each mission is flown for ``--duration`` simulated seconds from full
batteries (``companion.sim.inmemory.Engine``, one process per run, ``--workers`` at once).

One row per seed: the base and fleet, the spares, how many UAVs left the loop and how many
of those were relieved in their slot before their leave time, the relief warnings, the
spares passed over, the coverage revisit and the longest unseen time from the truth log
(over the report's window: from one loop period after the formation settled to the end,
every relief included), the lowest charge of an aircraft in the air; the same rows in
``results.json`` in the folder. Goals (issue 22):
revisit <= 1.15, no point unseen longer than 1.5 T/N, no aircraft below its reserve, every
relief on schedule.

Usage: ``PYTHONPATH=. python bench/relief_bases.py [--seeds 0-9] [--duration S]
[--max-loop-km KM] [--max-vehicles N] [--extra-spares K] [--workers 2] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from companion.agent.relief.roster import Roster
from companion.mission import load_mission
from companion.mission.endurance import fleet_rotation
from companion.mission.errors import MissionError
from companion.mission.generate import generate
from companion.report.metrics import model_free_measures, reference_patrol
from companion.report.rundata import load_run
from companion.sim.inmemory import Engine, EngineConfig

BATTERY = {"capacity_mah": 10000, "reserve_pct": 20, "endurance_min": 50}
TURNAROUND_S = 1200.0  # the 20 minutes
RUNWAY_OUT_M = 150.0  # the spares' runway, outside the loop (m)
FIRST_SPARE_SYSID = 100
MANY_SPARES = 60  # enough for the loader while the roster's figures are taken


def seeds_of(text: str) -> list[int]:
    """``"0-9"`` or ``"1,4,7"`` (or both, comma-separated) as a list of seeds."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def relief_mission(seed: int, max_loop_km: float, max_vehicles: int, duration_s: float,
                   extra: int, out: Path) -> tuple[Path, dict]:  # fmt: skip
    """The generated mission of ``seed`` (loop at most ``max_loop_km`` km, at most
    ``max_vehicles`` on it, ``duration_s`` s, no intruders) with batteries, the rotation's
    spares plus ``extra`` (at least one) and a staggered opening, written to ``out``; its
    path and what the row needs to know (the spares and their bounds; ``need`` None where
    the battery leaves no rotation)."""
    gm = generate(seed, max_loop_km=max_loop_km)
    if gm.vehicles > max_vehicles:  # the same base, wind and airframe, fewer on the loop
        gm = generate(seed, max_loop_km=max_loop_km, vehicles=max_vehicles)
    doc = yaml.safe_load(gm.text)
    doc["scenario"] = {"duration_s": float(duration_s)}  # no intruders: the reliefs' figures
    path = out / f"{gm.name}-relief.yaml"
    path.write_text(gm.text)  # first the patrol alone, to place the runway on its loop
    patrol = load_mission(path).patrol
    loop = patrol.sample_by_time(720)
    k = int(np.argmax(np.abs(loop - patrol.centre_m)))
    near = patrol.nearest(complex(loop[k]))
    outward = (near.point_m - patrol.centre_m) / abs(near.point_m - patrol.centre_m)
    base = near.point_m + RUNWAY_OUT_M * outward
    ground = {"north_m": round(base.real, 1), "east_m": round(base.imag, 1),
              "heading_deg": round(math.degrees(near.course_rad) % 360.0, 1)}  # fmt: skip
    info = {"seed": seed, "n": gm.vehicles, "loop_km": gm.loop_length_m / 1e3,
            "period_s": gm.period_s, "wind": gm.wind_fraction}  # fmt: skip
    v = doc["vehicles"]
    v["battery"] = dict(BATTERY)
    v["opening"] = "staggered"

    def spares(count: int) -> list[dict]:
        return [{"sysid": FIRST_SPARE_SYSID + i, "ground": dict(ground),
                 "turnaround_s": TURNAROUND_S} for i in range(count)]  # fmt: skip

    v["spares"] = spares(MANY_SPARES)  # the roster's figures need the runway, not the count
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    try:
        m = load_mission(path)
    except MissionError as exc:  # no stint at all: the loader says why
        return path, {**info, "need": None, "loader_min": str(exc).rsplit(": ", 1)[-1]}
    need = Roster(m).spares_needed(m.patrol, m.vehicles.battery, m.vehicles.count)
    rot = fleet_rotation(m.vehicles, loop, m.wind.speed_m_s)
    info = {**info, "need": need, "loader_min": rot.min_spares}
    if need is None:
        return path, info
    count = max(math.ceil(need - 1e-9) + extra, 1)
    v["spares"] = spares(count)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    info["spares"] = count
    if rot.min_spares is not None and count < rot.min_spares:
        info["error"] = f"refused by the loader: at least {rot.min_spares} spares"
    return path, info


def fly(job: tuple[Path, Path, float]) -> dict:
    """Fly the mission ``job[0]`` into the folder ``job[1]`` for ``job[2]`` s; its row, or
    ``{"error": ...}`` (a row's failure does not stop the others)."""
    path, out, duration_s = job
    try:
        engine = Engine(EngineConfig(path, out))
        wall0 = time.perf_counter()
        engine.run(duration_s)
        wall = time.perf_counter() - wall0
        engine.close()
        return {**measure(out), "wall_s": wall}
    except Exception as exc:  # reported in its row
        return {"error": f"{type(exc).__name__}: {exc}"}


def measure(out: Path) -> dict:
    """The row's figures from the run folder ``out``: its events, truth log and mission."""
    run = load_run(out)
    ev = run.events

    def kind(name: str) -> list[dict]:
        return [e for e in ev if e.get("event") == name]

    relieved = kind("relieved")
    on_time = [e for e in relieved if e["reason"] == "relieved" and e["margin_s"] >= 0.0]
    missed = [f"{e['sysid']}@{e['t_s']:.0f}" for e in relieved if e not in on_time]
    ref, _ = reference_patrol(run)
    pm = model_free_measures(run, ref)
    data = np.genfromtxt(out / "truth.csv", delimiter=",", names=True, usecols=(4, 12))
    low = float(np.min(data["battery_remaining_pct"][data["alt_m"] > 0.0]))
    return {"left": len(relieved), "on_time": len(on_time), "missed": missed,
            "late_said": len(kind("relief_late")), "passed_over": len(kind("spare_no_launch")),
            "stood_down": len(kind("relief_stood_down")),
            "revisit": pm.coverage_revisit_ratio, "unseen": pm.longest_unseen_ratio,
            "settled": pm.settled, "window": (pm.window_start_s, pm.window_end_s),
            "low_pct": low, "reserve_pct": run.mission.vehicles.battery.reserve_pct}  # fmt: skip


def main() -> int:
    """Generate, fly, print one row per seed and the totals."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-9", help="e.g. 0-9 or 3,5,8 (default 0-9)")
    ap.add_argument("--duration", type=float, default=7200.0, help="simulated s (default 2 h)")
    ap.add_argument("--max-loop-km", type=float, default=4.0, help="longest loop (km)")
    ap.add_argument("--max-vehicles", type=int, default=8, help="at most this many on station")
    ap.add_argument(
        "--extra-spares", type=int, default=0, help="spares beyond the need (-1: one short)"
    )
    ap.add_argument("--workers", type=int, default=2, help="runs at once (processes)")
    ap.add_argument("--out", type=Path, default=None, help="folder (default: temporary)")
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="relief-bases-"))
    out.mkdir(parents=True, exist_ok=True)
    infos, jobs = [], []
    for seed in seeds_of(args.seeds):
        path, info = relief_mission(seed, args.max_loop_km, args.max_vehicles, args.duration,
                                    args.extra_spares, out)  # fmt: skip
        infos.append(info)
        if info["need"] is not None and "error" not in info:
            jobs.append((path, out / f"run-{seed}", args.duration))
    t0 = time.perf_counter()
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(max(args.workers, 1), maxtasksperchild=1) as pool:
        rows = dict(zip([j[0] for j in jobs], pool.map(fly, jobs, chunksize=1), strict=True))
    print(
        f"{len(infos)} generated bases, {args.duration:g} s each, loops up to "
        f"{args.max_loop_km:g} km, {time.perf_counter() - t0:.0f} s wall; folder {out}"
    )
    print(
        "seed  N  loop km  T s  wind  spares (need, loader)  left  in slot  missed "
        "late-said passed stood revisit unseen T/N  lowest %"
    )
    totals = {"left": 0, "on_time": 0, "bad": 0}
    by_seed = {int(p.stem.split("-")[2]): r for p, r in rows.items()}
    for info in infos:
        head = (f"{info['seed']:4d} {info['n']:2d} {info['loop_km']:7.2f} {info['period_s']:5.0f}"
                f" {info['wind']:5.2f}")  # fmt: skip
        if info["need"] is None:
            print(
                f"{head}  no rotation: the battery leaves no beat on this loop "
                f"(loader: {info['loader_min']})"
            )
            continue
        r = {**info, **by_seed.get(info["seed"], {})}
        if "error" in r:
            print(f"{head}  {info['spares']:2d} ({info['need']:.2f}, {info['loader_min']})  "
                  f"not flown: {r['error']}")  # fmt: skip
            totals["bad"] += 1
            continue
        ok = (r["on_time"] == r["left"] and r["revisit"] <= 1.15 and r["unseen"] <= 1.5
              and r["low_pct"] >= r["reserve_pct"])  # fmt: skip
        totals["left"] += r["left"]
        totals["on_time"] += r["on_time"]
        totals["bad"] += not ok
        print(
            f"{head}  {info['spares']:2d} ({info['need']:.2f}, {info['loader_min']})"
            f"         {r['left']:3d}  {r['on_time']:3d}  {','.join(r['missed']) or '-':>6}"
            f"  {r['late_said']:3d}  {r['passed_over']:3d}  {r['stood_down']:3d}"
            f"  {r['revisit']:.3f}  {r['unseen']:.2f}  {r['low_pct']:.1f}"
            f"{'' if ok else '  MISSED'}{'' if r['settled'] else ' (never settled)'}"
        )
    rows_out = [{**info, **by_seed.get(info["seed"], {})} for info in infos]
    (out / "results.json").write_text(json.dumps({"rows": rows_out}, indent=1, default=str))
    print(
        f"totals: {totals['on_time']} of {totals['left']} relieved in their slot; "
        f"{totals['bad']} of {len(infos)} bases missed a goal or were not flown"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
