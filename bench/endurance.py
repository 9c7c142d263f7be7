"""Endurance benchmark: a long in-memory patrol with reliefs (docs/energy.md, "Reliefs").

Flies ``missions/ellipse_all_day.yaml`` (the paper's ellipse, 6 on station, 5 spares on the
ground, 50-minute batteries, 20 % reserve, 20-minute turnaround; ``--mission
missions/ellipse_relief.yaml`` for its 4 spares) with
:class:`companion.sim.inmemory.Engine` for ``--duration`` simulated seconds and prints:
the coverage revisit and the longest unseen time from the truth log (the report's
model-free measures, over its window: from one loop period after the formation settled to
the end, every relief included), the lowest charge of an aircraft in the air, and the
reliefs (how many, how long before its leave time each tired UAV was relieved, the late
ones, the spares that did not launch).

Issue 22 asks for 2 spares; with these batteries and turnaround that cannot hold (a spare is
ready every 10.6 min, a relief is needed every 6.5 min; the mission loader refuses it). The
loader's fewest is 4, but the companions' rotation needs 4.68 on average, so 4 miss one
relief in the first cycle and the all-day mission has 5 (docs/energy.md).

A fleet that starts full would need all six reliefs within a few minutes of each other:
more at once than the spares can give. ``--start`` says how the run avoids that:

* ``opening`` (the default): every battery full, and the mission's ``vehicles.opening:
  staggered`` (the product's way, docs/energy.md "The opening"): the last patrol UAV leaves
  when its battery says, each one before it one ``beat / N`` earlier;
* ``batteries``: the batteries set as a steady rotation would have them, one leave time
  every ``beat / N`` from ``--first-leave-s`` on (the bench acting as the world);
* ``full``: every battery full and nothing staggered (it shows why the opening is needed).

Usage: ``PYTHONPATH=. python bench/endurance.py [--duration S] [--out DIR]
[--start opening|batteries|full] [--extra-spares K]``.
Goals (issue 22): coverage revisit <= 1.15, no point unseen longer than 1.5 T/N, no aircraft
below its reserve, every relief on schedule.
"""

from __future__ import annotations

import argparse
import copy
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from companion.agent.relief.duty import LAND_MARGIN_S
from companion.agent.relief.roster import Roster
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.mission import load_mission
from companion.mission.endurance import fleet_rotation
from companion.report.metrics import model_free_measures, reference_patrol
from companion.report.rundata import load_run
from companion.sim.inmemory import Engine, EngineConfig

MISSION = REPO / "missions" / "ellipse_all_day.yaml"


def stagger(engine: Engine, first_leave_s: float) -> list[float]:
    """Set the patrol UAVs' used charge (mAh) so that, at cruise, they must leave one
    ``beat / N`` apart from ``first_leave_s`` (s), as the rotation then keeps them (each
    slot comes due every beat, ``Roster.beat_s``); returns the planned leave times (s)."""
    v = engine.mission.vehicles
    b = v.battery
    patrol = engine.mission.patrol
    rot = fleet_rotation(v, patrol.sample_by_time(720), engine.mission.wind.speed_m_s)
    beat_s = Roster(engine.mission).beat_s(patrol, b)
    every_s = rot.relief_every_min * 60.0 if beat_s is None else beat_s / len(v.sysids)
    rate_mah_s = b.capacity_mah / (b.endurance_min * 60.0)
    home_s = rot.transit_min * 60.0 + LAND_MARGIN_S
    leaves = []
    for k, sysid in enumerate(v.sysids):
        leave = first_leave_s + k * every_s
        used = b.capacity_mah - b.reserve_mah - rate_mah_s * (leave + home_s)
        engine.sim.batteries.consumed_mah[engine.sim.sysids.index(sysid)] = max(used, 0.0)
        leaves.append(leave)
    return leaves


def mission_copy(mission: Path, extra: int, opening: str, out: Path) -> Path:
    """A copy of ``mission`` in ``out`` with ``extra`` more spares like its last one (the
    next sysids) and ``vehicles.opening`` set to ``opening``; its path."""
    doc = yaml.safe_load(mission.read_text())
    spares = doc["vehicles"]["spares"]
    for _ in range(extra):
        spares.append({**copy.deepcopy(spares[-1]), "sysid": int(spares[-1]["sysid"]) + 1})
    doc["vehicles"]["opening"] = opening
    doc["name"] = f"{doc['name']}_{len(spares)}_spares"
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{mission.stem}_{len(spares)}_spares_{opening}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def main() -> int:
    """Fly, then print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mission", type=Path, default=MISSION)
    ap.add_argument("--duration", type=float, default=6 * 3600.0, help="simulated s")
    ap.add_argument("--out", type=Path, default=None, help="run folder (default: temporary)")
    ap.add_argument(
        "--start",
        choices=("opening", "batteries", "full"),
        default="opening",
        help="a staggered opening from full batteries (default), batteries set as a "
        "rotation would have them, or full and nothing staggered",
    )
    ap.add_argument("--first-leave-s", type=float, default=380.0, help="--start batteries")
    ap.add_argument(
        "--extra-spares",
        type=int,
        default=0,
        help="add this many spares like the mission's last (a rotation with slack)",
    )
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="endurance-"))
    opening = "staggered" if args.start == "opening" else "battery"
    path = mission_copy(args.mission, max(args.extra_spares, 0), opening, out)
    mission = load_mission(path)
    engine = Engine(EngineConfig(path, out))
    print(f"start: {args.start} (vehicles.opening: {opening})")
    if args.start == "batteries":
        leaves = stagger(engine, args.first_leave_s)
        print("staggered batteries: planned leave times " + ", ".join(f"{t:.0f}" for t in leaves))
    wall0, cpu0 = time.perf_counter(), time.process_time()

    def progress(t_s: float) -> None:
        if t_s % 1800.0 < 10.0:
            print(
                f"  {t_s:.0f} s simulated, {time.perf_counter() - wall0:.0f} s wall",
                file=sys.stderr,
            )

    engine.run(args.duration, progress=progress)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    engine.close()
    v = mission.vehicles
    print(f"{mission.name}: {v.count} on station, {len(v.spares)} spares, "
          f"{args.duration:g} s simulated in {wall:.0f} s wall, {cpu:.0f} s CPU")  # fmt: skip
    run = load_run(out)
    ref, _ = reference_patrol(run)
    m = model_free_measures(run, ref)
    print(f"coverage: window {m.window_start_s:.0f}-{m.window_end_s:.0f} s "
          f"({'settled' if m.settled else 'never settled'}), revisit "
          f"{m.coverage_revisit_ratio:.3f}, longest unseen {m.longest_unseen_s:.1f} s = "
          f"{m.longest_unseen_ratio:.2f} T/N, cross-track p95 {m.cross_track_p95_m:.1f} m, "
          f"max {m.cross_track_max_m:.1f} m (T/N {ref.period_s / v.count:.2f} s)")  # fmt: skip
    ev = [
        {**e, "t_s": e["t_s"] - SIM_EPOCH_UNIX_S}
        for e in engine.companion_events
        if e.get("t_s") is not None
    ]
    kinds = {k: [e for e in ev if e.get("event") == k] for k in (
        "relief_launched", "relief_in_slot", "relieved", "relief_landed", "relief_late",
        "spare_no_launch")}  # fmt: skip
    relieved = kinds["relieved"]
    on_time = [e for e in relieved if e["reason"] == "relieved" and e["margin_s"] >= 0.0]
    margins = [e["margin_s"] for e in relieved]
    takes = [e["took_s"] for e in kinds["relief_in_slot"]]
    print(f"reliefs: {len(relieved)} UAVs left the loop, {len(on_time)} relieved in their "
          f"slot before their leave time; margin min {min(margins, default=float('nan')):.0f} s, "
          f"median {np.median(margins) if margins else float('nan'):.0f} s; "
          f"launch to slot median {np.median(takes) if takes else float('nan'):.0f} s, "
          f"max {max(takes, default=float('nan')):.0f} s; {len(kinds['relief_landed'])} "
          f"landings; late announced {len(kinds['relief_late'])} "
          f"({sorted({e['sysid'] for e in kinds['relief_late']})}); spares passed over "
          f"{len(kinds['spare_no_launch'])}")  # fmt: skip
    first = relieved[: v.count]
    print(
        "first stints ended at " + ", ".join(f"{e['t_s']:.0f} s (UAV {e['sysid']})" for e in first)
    )
    low = _lowest_in_air(out)
    print(f"battery: lowest charge of an aircraft in the air {low:.1f} % (reserve "
          f"{v.battery.reserve_pct:g} %)")  # fmt: skip
    print(f"run folder: {out}")
    return 0


def _lowest_in_air(out: Path) -> float:
    """The lowest ``battery_remaining_pct`` of a truth row in the air (altitude > 0)."""
    data = np.genfromtxt(out / "truth.csv", delimiter=",", names=True, usecols=(4, 12))
    air = data["alt_m"] > 0.0
    return float(np.min(data["battery_remaining_pct"][air]))


if __name__ == "__main__":
    raise SystemExit(main())
