"""Firmware fleets that hold on the machine they are given (issue 48), with their figures.

    python bench/firmware_fleets.py table --autopilot px4 --runs 5 [--hogs 2] [MISSION]
    python bench/firmware_fleets.py outage --autopilot arduplane [--outage-s 20] [MISSION]
    python bench/firmware_fleets.py freeze --autopilot px4 [--freeze-s 5] [MISSION]

``table`` flies ``--runs`` fleets in a row (``companion fleet``'s own code: the speed factor it
chooses, its slow-downs, its verdict), idle or beside ``--hogs`` processes that each spin a
core, and prints one row per run: the speed factor chosen and the pace at the end, the
autopilots' achieved rate, the worst hole in a companion's state stream (vehicle s, PX4's 2 Hz
floor is 0.5), the failsafes, cross-track p95 and coverage revisit over the last 300 s and the
verdict; with each process's CPU per simulated second (the cost of one aircraft per unit of
speed factor, :data:`companion.sim.pace.CORES_PER_AIRCRAFT_X`).

``outage`` pulls UAV ``--uav``'s serial cable (ArduPlane: ``--companion-link serial``; PX4: its
UDP relay paused, ``--companion-link relay``) for ``--outage-s`` of vehicle time once the formation
has settled, and ``freeze`` stops its companion (SIGSTOP) for ``--freeze-s`` of wall time;
both print the aircraft's largest distance from the loop and whether it left the fence while
its companion was away, how long after it came back it flew in the loop's sense and was in its
slot (the splay of all N within ``SLOT_DEG``), and the others' splay as N - 1 meanwhile.
Every fleet runs with ``--retake-after-failsafe``.

The machine's load (``uptime``) is printed with every table: firmware fleets are wall-clock
bound, and the figures move with it.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.commands.fleet import _firmware_speedup
from companion.core.measures import splay_error_deg
from companion.mission import load_mission
from companion.report.rundata import load_run
from companion.report.summary import write_report
from companion.sim.fleet import FleetConfig
from companion.sim.pace import verdict

REPO = Path(__file__).resolve().parents[1]
SIX = REPO / "missions" / "ellipse_6uav.yaml"
SLOT_DEG = 10.0  # "in its slot": the formation's splay error (deg) within this
SETTLE_S = 300.0  # vehicle s after which the formation is taken as settled (events then)


def uptime() -> str:
    """The machine's load averages, as ``uptime`` prints them."""
    with contextlib.suppress(OSError):
        return "load " + ", ".join(Path("/proc/loadavg").read_text().split()[:3])
    return "load unknown"


@contextlib.contextmanager
def hogs(n: int):
    """``n`` processes that each spin a core (stopped by their pids)."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        yield procs
    finally:
        for p in procs:
            p.kill()
            p.wait()


def cpu_s(pid: int) -> float | None:
    """User + system CPU (s) of process ``pid`` so far (None once gone)."""
    try:
        f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


@dataclass
class Action:
    """Something done to one UAV's link or companion at a simulated time."""

    at_s: float
    what: str  # pull, plug, stop, cont
    sysid: int
    done: bool = False
    wall_s: float | None = None
    sim_s: float | None = None
    companion_cpu_s: float | None = None  # its companion's CPU so far, when done


def make_fleet(autopilot: str, cfg: FleetConfig, mission):
    """The firmware fleet object for ``autopilot``."""
    if autopilot == "arduplane":
        from companion.sim.arduplane.fleet import ArduPlaneFleet

        return ArduPlaneFleet(cfg, mission)
    from companion.sim.px4.fleet import Px4Fleet

    return Px4Fleet(cfg, mission)


def companion_proc(fleet, sysid: int):
    """The ``companion run`` process of ``sysid``."""
    return next(p for p in fleet.procs if p.name == f"companion {sysid}").popen


def act(fleet, a: Action) -> None:
    """Do ``a`` now."""
    if a.what == "pull":
        fleet.pull_cable(a.sysid)
    elif a.what == "plug":
        fleet.plug_cable(a.sysid)
    elif a.what == "cut":
        fleet.cut_wire(a.sysid)
    elif a.what == "mend":
        fleet.mend_wire(a.sysid)
    elif a.what == "stop":
        companion_proc(fleet, a.sysid).send_signal(signal.SIGSTOP)
    elif a.what == "cont":
        companion_proc(fleet, a.sysid).send_signal(signal.SIGCONT)
    a.done, a.wall_s, a.sim_s = True, time.monotonic(), fleet.progress.t_s
    a.companion_cpu_s = cpu_s(companion_proc(fleet, a.sysid).pid)


def fly(
    mission_path: Path,
    autopilot: str,
    out: Path,
    *,
    speedup: float | None = None,
    duration_s: float | None = None,
    companion_link: str = "tcp",
    actions: list[Action] = (),
    after_wall_s: dict[str, float] | None = None,
) -> dict:
    """One fleet run as ``companion fleet`` flies it, the ``actions`` done on the way; its
    figures. ``after_wall_s``: action -> wall s after the previous action (else by sim time)."""
    mission = load_mission(mission_path)
    args = argparse.Namespace(speedup=speedup, autopilot=autopilot)
    from companion.sim.arduplane.fleet import DEFAULT_SPEEDUP as AP_X
    from companion.sim.px4.fleet import DEFAULT_SPEEDUP as PX4_X

    x = _firmware_speedup(args, mission, AP_X if autopilot == "arduplane" else PX4_X)
    cfg = FleetConfig(
        mission_path, out, speedup=x, duration_s=duration_s, lockstep=False,
        companion_link=companion_link, retake_after_failsafe=True,
    )  # fmt: skip
    fleet = make_fleet(autopilot, cfg, mission)
    cpu: dict[str, float] = {}
    status = "done"
    t_wall = time.monotonic()
    try:
        fleet.start()
        pending = list(actions)
        while not fleet.sim_done():
            fleet.poll(0.2)
            fleet.check_alive()
            fleet.keep_pace(lambda s: print(s.strip(), flush=True))
            for i, a in enumerate(pending):
                if a.done:
                    continue
                prev = pending[i - 1] if i else None
                gap = (after_wall_s or {}).get(a.what)
                due = (
                    prev is not None and prev.done and time.monotonic() - prev.wall_s >= gap
                    if gap is not None
                    else fleet.progress.t_s >= a.at_s
                )
                if due and (prev is None or prev.done):
                    act(fleet, a)
                    print(f"bench: {a.what} UAV {a.sysid} at {a.sim_s:.1f} s", flush=True)
                break
        for p in fleet.procs + list(getattr(fleet, "instances", [])):
            popen = getattr(p, "popen", None) or getattr(p, "proc", None)
            c = cpu_s(popen.pid) if popen is not None else None
            if c is not None:
                kind = getattr(p, "name", "px4").split()[0]
                cpu[kind] = cpu.get(kind, 0.0) + c
    except Exception as exc:  # a failed run is a row of the table, not the end of it
        status = f"failed: {exc}"
    finally:
        for a in actions:
            if (
                a.what == "stop"
                and a.done
                and not any(b.what == "cont" and b.done for b in actions)
            ):
                with contextlib.suppress(Exception):
                    companion_proc(fleet, a.sysid).send_signal(signal.SIGCONT)
        fleet.stop()
    wall = time.monotonic() - t_wall
    fleet.merge_events()
    row: dict = {"speedup": x, "status": status, "wall_s": wall, "cpu_s": cpu}
    try:
        metrics = write_report(out)
        v = verdict(out, not_before_s=metrics.get("window_start_s"))
        row |= {"verdict": v.line, "held": v.held, "metrics": metrics}
    except Exception as exc:
        row |= {"verdict": f"no report: {exc}", "held": False}
    row["pace"] = fleet.pace.pace
    row["achieved"] = fleet.pace.achieved()
    row["worst_hole"] = fleet.pace.worst_hole
    row["actions"] = actions
    return row


# ---- what the aircraft did while its companion was away -------------------------------------
def away_figures(out: Path, sysid: int, t0_s: float, t1_s: float) -> dict:
    """From the truth log: UAV ``sysid``'s largest distance from the loop (m) and whether it
    stayed inside the fence from ``t0_s`` to ``t1_s`` (simulated s); after ``t1_s``, when it
    flew in the loop's sense (course within 45 deg of the loop's, held 5 s) and when the
    formation's splay error came within SLOT_DEG (held 10 s) (s after ``t1_s``); the others'
    splay error as N - 1 at ``t1_s`` (deg)."""
    run = load_run(out)
    patrol = run.mission.patrol
    tr = run.tracks[sysid]
    during = (tr.t_s >= t0_s) & (tr.t_s <= t1_s)
    dist = [patrol.phase_and_offset_of_point(complex(z))[1] for z in tr.pos_m[during]]
    fence = run.mission.fence
    inside = bool(np.all(fence.fence.contains(tr.pos_m[during]))) if fence is not None else None
    after = tr.t_s > t1_s
    sense_s = None
    good_since = None
    for t, z, c in zip(tr.t_s[after], tr.pos_m[after], tr.course_rad[after], strict=True):
        near = patrol.nearest(complex(z))
        ok = math.cos(c - near.course_rad) > math.cos(math.radians(45.0))
        good_since = (good_since if good_since is not None else t) if ok else None
        if good_since is not None and t - good_since >= 5.0:
            sense_s = good_since - t1_s
            break
    times = np.arange(math.ceil(t1_s), run.times_s[-1], 1.0)
    slot_s = None
    good_since = None
    others_at_t1 = None
    for t in times:
        phases = {}
        for s, other in run.tracks.items():
            i = min(int(np.searchsorted(other.t_s, t)), len(other.t_s) - 1)
            phases[s] = patrol.phase_of_point(complex(other.pos_m[i]))
        if others_at_t1 is None:
            others_at_t1 = splay_error_deg([p for s, p in phases.items() if s != sysid])
        ok = splay_error_deg(list(phases.values())) <= SLOT_DEG
        good_since = (good_since if good_since is not None else t) if ok else None
        if good_since is not None and t - good_since >= 10.0:
            slot_s = good_since - t1_s
            break
    late = (tr.t_s >= t0_s) & (tr.t_s <= t1_s + 10.0)  # the autopilot's modes, and after
    modes = [str(m) for m in tr.mode[late]]
    return {
        "modes_while_away": [m for i, m in enumerate(modes) if i == 0 or m != modes[i - 1]],
        "max_off_loop_m": max(dist) if dist else None,
        "inside_fence": inside,
        "loop_sense_after_s": sense_s,
        "in_slot_after_s": slot_s,
        "period_s": patrol.period_s,
        "others_splay_at_return_deg": others_at_t1,
    }


def _f(v, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def table(ns: argparse.Namespace) -> int:
    """``--runs`` fleets in a row; one row each."""
    print(f"# {ns.autopilot}, {ns.mission.name}, {ns.runs} runs, {ns.hogs} CPU hogs; {uptime()}")
    print("| run | x | pace | achieved | worst hole s | failsafes | xt p95 m | revisit | held |")
    print("|---|---|---|---|---|---|---|---|---|")
    held_all = True
    with hogs(ns.hogs):
        for k in range(ns.runs):
            out = ns.out / f"{ns.autopilot}-{k + 1}"
            row = fly(ns.mission, ns.autopilot, out, speedup=ns.speedup, duration_s=ns.duration)
            m = row.get("metrics", {})
            line = row["verdict"]
            fs = line.split(", ")[-1].split(")")[0] if "failsafe" in line else "-"
            hole = row["worst_hole"]
            print(
                f"| {k + 1} | {row['speedup']:g} | {row['pace']:g} | {_f(row['achieved'], '.2f')}"
                f" | {_f(hole[1] if hole else None, '.1f')} | {fs} | "
                f"{_f(m.get('cross_track_p95_m'), '.1f')} | "
                f"{_f(m.get('coverage_revisit_ratio'), '.2f')} | {line} ({row['status']}) |",
                flush=True,
            )
            sim = (m.get("window_end_s") or 0) or 1.0
            costs = ", ".join(f"{kk} {v / sim:.3f}" for kk, v in sorted(row["cpu_s"].items()))
            print(f"|  | CPU s per simulated s, all of a kind: {costs}; {uptime()} |", flush=True)
            held_all &= bool(row.get("held"))
    return 0 if held_all else 1


def away(ns: argparse.Namespace, what: str) -> int:
    """The outage or the freeze of one companion."""
    at = ns.at
    if what == "outage":
        if ns.autopilot == "arduplane":
            acts = [Action(at, "pull", ns.uav), Action(at + ns.outage_s, "plug", ns.uav)]
        else:  # PX4's companion link is UDP: its relay paused (the wire cut)
            acts = [Action(at, "cut", ns.uav), Action(at + ns.outage_s, "mend", ns.uav)]
        gaps = None
    else:
        acts = [Action(at, "stop", ns.uav), Action(0.0, "cont", ns.uav)]
        gaps = {"cont": ns.freeze_s}
    link = "serial" if ns.autopilot == "arduplane" else "relay" if what == "outage" else "tcp"
    out = ns.out / f"{what}-{ns.autopilot}"
    row = fly(ns.mission, ns.autopilot, out, speedup=ns.speedup, duration_s=ns.duration,
              companion_link=link, actions=acts, after_wall_s=gaps)  # fmt: skip
    print(f"# {what} of UAV {ns.uav}, {ns.autopilot}, {ns.mission.name}; {uptime()}")
    print(f"fleet: {row['verdict']} ({row['status']}); speed factor {row['speedup']:g}")
    if not all(a.done for a in acts):
        print("bench: the actions were not all done (the run ended first)")
        return 1
    sim = (row.get("metrics", {}).get("window_end_s") or 0) or 1.0
    costs = ", ".join(f"{k} {v / sim:.3f}" for k, v in sorted(row["cpu_s"].items()))
    print(f"CPU s per simulated s, all of a kind: {costs}")
    t0, t1 = acts[0].sim_s, acts[1].sim_s
    fig = away_figures(out, ns.uav, t0, t1)
    a0, a1 = acts
    if what == "outage" and ns.autopilot == "arduplane" and a0.companion_cpu_s is not None:
        fig["companion_cpu_while_gone"] = (a1.companion_cpu_s - a0.companion_cpu_s) / max(
            1e-9, a1.wall_s - a0.wall_s
        )  # cores
    fig |= link_events(out / f"uav{ns.uav}" / "events.jsonl")
    fig["wall_s"] = a1.wall_s - a0.wall_s
    print(f"away from {t0:.1f} to {t1:.1f} s ({t1 - t0:.1f} s of vehicle time)")
    for k, v in fig.items():
        print(f"  {k}: {_f(v, '.2f') if isinstance(v, float) else v}")
    print("result: " + json.dumps(fig | {"verdict": row["verdict"], "speedup": row["speedup"]}))
    return 0


def link_events(events: Path) -> dict:
    """The companion's own account: its link_lost (silent_s), link_restored (outage_s) and
    override (cause, silent_s) and retake events, in order."""
    out: dict = {"link_lost_silent_s": [], "link_restored_outage_s": [], "overrides": []}
    if not events.is_file():
        return out
    for line in events.read_text().splitlines():
        ev = json.loads(line)
        if ev["event"] == "link_lost":
            out["link_lost_silent_s"].append(ev.get("silent_s"))
        elif ev["event"] == "link_restored":
            out["link_restored_outage_s"].append(ev.get("outage_s"))
        elif ev["event"] in ("override", "retake", "resumed"):
            out["overrides"].append(
                {k: ev.get(k) for k in ("t_s", "event", "autopilot_mode", "cause", "silent_s")}
            )
    return out


def main(argv: list[str] | None = None) -> int:
    """Parse and run one of the three."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=("table", "outage", "freeze"))
    p.add_argument("mission", nargs="?", type=Path, default=SIX)
    p.add_argument("--autopilot", choices=("px4", "arduplane"), required=True)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--hogs", type=int, default=0, help="processes that each spin a core")
    p.add_argument("--speedup", type=float, help="default: what companion fleet chooses")
    p.add_argument("--duration", type=float, help="vehicle s (default: the mission's)")
    p.add_argument("--uav", type=int, default=2, help="the UAV whose companion goes away")
    p.add_argument("--at", type=float, default=SETTLE_S, help="vehicle s of the event")
    p.add_argument("--outage-s", type=float, default=20.0, help="vehicle s")
    p.add_argument("--freeze-s", type=float, default=5.0, help="wall s")
    p.add_argument("--out", type=Path, default=Path("runs/firmware-fleets"))
    ns = p.parse_args(argv)
    if ns.what == "table":
        return table(ns)
    return away(ns, ns.what)


if __name__ == "__main__":
    raise SystemExit(main())
