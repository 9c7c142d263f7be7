"""The engine's speed, this tree against a commit, measured interleaved in one run.

Usage (from the repository root, the project's Python environment active)::

    python bench/speed.py --against a6a975e [--only ellipse,100uav] [--rounds 3]
        [--scale 1.0] [--keep DIR]
    python bench/speed.py --profile demo [--scale 0.2] [--top 30]
    python bench/speed.py --table RUNS.jsonl   # the table of runs saved with --save

``--against COMMIT`` checks the commit out in a temporary ``git worktree`` and runs every
measure from both trees alternately (round k runs the commit first when k is even, this
tree first when it is odd), each command with ``PYTHONPATH`` pointing at its own tree, so
the two sides share the machine's load. This tree is the working tree as it is (uncommitted
changes included). Each figure is the minimum over the rounds (the least disturbed run;
the median is printed beside it), and the ratio is the commit's over this tree's (above 1:
this tree is faster).

The measures (``--only`` takes their names, comma-separated):

=========  ==========================================================================
ellipse    ``companion simulate missions/ellipse_6uav.yaml`` (900 s, 6 UAVs)
wpafb      ``companion simulate missions/wpafb_4uav.yaml --duration 1500`` (a slice)
gen12      ``companion simulate`` of a generated 12-UAV base (seed 3, loops up to 6 km,
           ``companion.mission.generate``), its own 643 s
100uav     ``companion simulate`` of 100 UAVs on a circle (``bench/fleet.py``'s mission,
           as ``bench/inmemory.py --vehicles 100``), 60 s
demo       the README's demo, ``companion fleet missions/ellipse_6uav.yaml`` (900 s): the
           CPU of every process it starts, its wall time, and a companion's CPU per control
           tick in its own process (each companion's final status line: ``cpu`` over
           ``setpoints``, start-up included, the figure of issue 46)
campaign   ``companion campaign`` of 20 runs (the ellipse x nominal, gusts, wind_drift,
           gps x seeds 0-4), 150 s each, 2 workers
=========  ==========================================================================

``--scale F`` multiplies every simulated duration (0.2 for a quick look). Figures: CPU
(user + system of the whole process tree, ``getrusage(RUSAGE_CHILDREN)``), wall time, CPU
per simulated aircraft-second (ms), and the split of the CPU into simulator, transport
(MAVLink packing and parsing, signing, the wires and socket loops), companion, start-up
(imports) and other (report, Dask, process management), sampled in every process by
``bench/speed_sampler.py`` (loaded as ``sitecustomize``; see there for what goes where).
For the in-memory runs ``comp ms/tick`` is the companion share over the control ticks
(10 Hz per UAV). Prints a table; asserts nothing.

``--profile MEASURE`` runs one measure once from this tree with the sampler's counts per
function and prints, per kind of process, where its CPU goes (self and inclusive).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CATEGORIES = ("simulator", "transport", "companion", "startup", "other")
SHORT = {"simulator": "sim", "transport": "tr", "companion": "comp", "startup": "st",
         "other": "oth"}  # fmt: skip
MEASURES = ("ellipse", "wpafb", "gen12", "100uav", "demo", "campaign")
CONTROL_HZ = 10.0
GEN_SEED, GEN_MAX_LOOP_KM = 3, 6.0


@dataclass
class Measure:
    """One measured command: its arguments (after ``python -m companion``), the aircraft
    seconds it simulates, the nominal control ticks and how to read extra figures."""

    name: str
    label: str
    args: list[str]
    aircraft_s: float
    ticks: float
    kind: str = "simulate"  # simulate | fleet | campaign


@dataclass
class Sample:
    """One run of one measure on one side."""

    cpu_s: float
    wall_s: float
    split: dict[str, int]
    tick_ms: float | None = None  # demo: companion CPU per setpoint, own process
    answers: dict[str, float] = field(default_factory=dict)


def _setup(names: list[str], scale: float, tmp: Path) -> list[Measure]:
    """The measures asked for, with their input files written into ``tmp``."""
    sys.path.insert(0, str(REPO))
    out: list[Measure] = []
    for name in names:
        if name == "ellipse":
            d = 900.0 * scale
            args = ["simulate", "missions/ellipse_6uav.yaml", "--duration", f"{d:g}"]
            out.append(Measure(name, f"ellipse {d:g} s", args, 6 * d, 6 * d * CONTROL_HZ))
        elif name == "wpafb":
            d = 1500.0 * scale
            args = ["simulate", "missions/wpafb_4uav.yaml", "--duration", f"{d:g}"]
            out.append(Measure(name, f"wpafb {d:g} s", args, 4 * d, 4 * d * CONTROL_HZ))
        elif name == "gen12":
            from companion.mission.generate import generate

            g = generate(GEN_SEED, vehicles=12, max_loop_km=GEN_MAX_LOOP_KM)
            path = tmp / f"{g.name}.yaml"
            path.write_text(g.text)
            d = round(g.duration_s * scale)
            args = ["simulate", str(path), "--duration", f"{d:g}"]
            out.append(Measure(name, f"gen12 {d:g} s", args, 12 * d, 12 * d * CONTROL_HZ))
        elif name == "100uav":
            from bench.fleet import circle_mission

            path = tmp / "circle_100uav.yaml"
            circle_mission(100, path)
            d = 60.0 * scale
            args = ["simulate", str(path), "--duration", f"{d:g}"]
            out.append(Measure(name, f"100uav {d:g} s", args, 100 * d, 100 * d * CONTROL_HZ))
        elif name == "demo":
            d = 900.0 * scale
            args = ["fleet", "missions/ellipse_6uav.yaml", "--no-progress", "--duration", f"{d:g}"]
            out.append(Measure(name, f"demo {d:g} s", args, 6 * d, 6 * d * CONTROL_HZ, "fleet"))
        elif name == "campaign":
            d = round(150.0 * scale)
            spec = tmp / "campaign_20.yaml"
            spec.write_text(
                f"missions: [{REPO / 'missions' / 'ellipse_6uav.yaml'}]\n"
                "scenarios: [nominal, gusts, wind_drift, gps]\n"
                "seeds: {start: 0, count: 5}\n"
                f"duration_s: {d}\n"
            )
            args = ["campaign", str(spec), "--workers", "2", "--no-progress"]
            out.append(
                Measure(name, f"campaign 20x{d:g} s", args, 20 * 6 * d, 20 * 6 * d * CONTROL_HZ,
                        "campaign")
            )  # fmt: skip
        else:
            raise SystemExit(f"unknown measure {name!r}; known: {', '.join(MEASURES)}")
    return out


def clean_env(tree: Path, sampler: Path | None = None) -> dict[str, str]:
    """The environment of a command run from ``tree``: ``PYTHONPATH`` at that tree (and the
    sampler's folder), no fixed hash seed."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree) if sampler is None else f"{tree}{os.pathsep}{sampler}"
    env.pop("PYTHONHASHSEED", None)
    env.pop("SPEED_SAMPLE_DIR", None)
    return env


def checkout(commit: str, tmp: Path) -> Path:
    """A detached ``git worktree`` of ``commit`` in ``tmp`` (reused if there)."""
    tree = tmp / f"tree-{commit}"
    if not tree.exists():
        git("worktree", "add", "--detach", str(tree), commit)
    return tree


def drop_checkout(tree: Path, tmp: Path) -> None:
    """Remove :func:`checkout`'s worktree ``tree`` and its folder ``tmp``."""
    subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=REPO,
                   capture_output=True)  # fmt: skip
    shutil.rmtree(tmp, ignore_errors=True)


def _children_cpu_s() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_once(m: Measure, tree: Path, sampler: Path, work: Path, functions: bool = False) -> Sample:
    """Run measure ``m`` from ``tree`` once; its CPU, wall time, split and extra figures
    (``functions``: the sampler counts per function too, in ``work/samples``)."""
    out = work / "out"
    samples = work / "samples"
    for p in (out, samples):
        shutil.rmtree(p, ignore_errors=True)
    samples.mkdir(parents=True)
    env = clean_env(tree, sampler)
    env["SPEED_SAMPLE_DIR"] = str(samples)
    if functions:
        env["SPEED_SAMPLE_FUNCS"] = "1"
    cmd = [sys.executable, "-m", "companion", *m.args, "--out", str(out)]
    cpu0, wall0 = _children_cpu_s(), time.perf_counter()
    proc = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - wall0
    cpu = _children_cpu_s() - cpu0
    if proc.returncode != 0:
        sys.stderr.write(proc.stdout[-2000:] + proc.stderr[-3000:])
        raise SystemExit(f"{m.name} failed in {tree} (exit {proc.returncode}): {' '.join(cmd)}")
    split = dict.fromkeys(CATEGORIES, 0)
    for f in samples.glob("*.json"):
        rec = json.loads(f.read_text())
        for k, v in rec["counts"].items():
            split[k] = split.get(k, 0) + v
    s = Sample(cpu, wall, split)
    if m.kind == "fleet":
        s.tick_ms = _fleet_tick_ms(out)
    if m.kind in ("simulate", "fleet"):
        s.answers = _answers(out / "metrics.json")
    return s


_FINAL = re.compile(r"companion final .*?setpoints=(\d+) .*?cpu=([0-9.]+)s")


def _fleet_tick_ms(out: Path) -> float | None:
    """A companion's CPU per setpoint (ms) in its own process, from every companion's final
    status line (``uavN/companion.log``): total CPU over total setpoints."""
    cpu, sp = 0.0, 0
    for log in sorted(out.glob("uav*/companion.log")):
        for line in log.read_text().splitlines():
            mt = _FINAL.search(line)
            if mt:
                sp += int(mt.group(1))
                cpu += float(mt.group(2))
    return 1e3 * cpu / sp if sp else None


def _answers(path: Path) -> dict[str, float]:
    """The measures that must not move: coverage revisit, cross-track p95 (m)."""
    if not path.exists():
        return {}
    m = json.loads(path.read_text())
    keys = ("coverage_revisit_ratio", "cross_track_p95_m")
    return {k: m[k] for k in keys if isinstance(m.get(k), (int, float))}


# ---- the table -------------------------------------------------------------------------------
def _split_text(split: dict[str, int]) -> str:
    total = sum(split.values())
    if not total:
        return "-"
    return " ".join(f"{SHORT[k]} {100 * split.get(k, 0) / total:.0f}" for k in CATEGORIES)


def _best(samples: list[Sample]) -> Sample:
    return min(samples, key=lambda s: s.cpu_s)


def _fmt(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def print_table(
    measures: list[Measure], results: dict[str, dict[str, list[Sample]]], sides: list[str]
) -> None:
    """One block per measure: CPU, ms per aircraft-second, wall, the ratio, the split."""
    old, new = sides
    w = max(len(old), len(new), 10)
    print(
        f"\n{'measure':<20} {'figure':<22} {old:>{w}} {new:>{w}} {'old/new':>8}   median old, new"
    )
    for m in measures:
        a, b = results[m.name][old], results[m.name][new]
        ba, bb = _best(a), _best(b)
        rows = [
            ("CPU s", [s.cpu_s for s in a], [s.cpu_s for s in b], 1),
            ("ms CPU / aircraft-s", [1e3 * s.cpu_s / m.aircraft_s for s in a],
             [1e3 * s.cpu_s / m.aircraft_s for s in b], 3),
            ("wall s", [s.wall_s for s in a], [s.wall_s for s in b], 1),
        ]  # fmt: skip
        if m.kind == "fleet":
            rows.append(
                ("comp ms/tick (own proc)", [s.tick_ms for s in a if s.tick_ms],
                 [s.tick_ms for s in b if s.tick_ms], 3)
            )  # fmt: skip
        else:
            rows.append(
                ("comp ms/tick (share)", [_comp_tick_ms(s, m) for s in a],
                 [_comp_tick_ms(s, m) for s in b], 3)
            )  # fmt: skip
        for k, (fig, xa, xb, dg) in enumerate(rows):
            lo_a = min(xa) if xa else None
            lo_b = min(xb) if xb else None
            ratio = f"{lo_a / lo_b:8.2f}" if lo_a and lo_b else f"{'-':>8}"
            med = f"{_fmt(statistics.median(xa) if xa else None, dg)}, " + _fmt(
                statistics.median(xb) if xb else None, dg
            )
            name = m.label if k == 0 else ""
            print(
                f"{name:<20} {fig:<22} {_fmt(lo_a, dg):>{w}} {_fmt(lo_b, dg):>{w}} {ratio}   {med}"
            )
        pairs = [x.cpu_s / y.cpu_s for x, y in zip(a, b, strict=False)]  # round by round
        if pairs:
            each = " ".join(f"{r:.2f}" for r in pairs)
            print(f"{'':<20} {'CPU old/new by round':<22} median {statistics.median(pairs):.2f} "
                  f"({each})")  # fmt: skip
        print(f"{'':<20} {'split % ' + old:<22} {_split_text(ba.split)}")
        print(f"{'':<20} {'split % ' + new:<22} {_split_text(bb.split)}")
        for s_name, s in ((old, ba), (new, bb)):
            if s.answers:
                ans = ", ".join(f"{k} {v:g}" for k, v in s.answers.items())
                print(f"{'':<20} {'answers ' + s_name:<22} {ans}")
    print(
        "\nfigures: the minimum over the rounds (the median after it); old/new > 1: this tree "
        "uses less; by round: the two sides of one round, run one after the other, compared "
        "(the steadier ratio on a loaded machine). split: sim(ulator), tr(ansport), "
        "comp(anion), st(art-up), oth(er), % of the sampled CPU of the fastest run"
    )


def table_from(path: Path) -> None:
    """The table of the runs saved in ``path`` (``--save``): the sides in the order they
    first appear with the commit's first (the side a round starts with alternates)."""
    recs = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    measures: dict[str, Measure] = {}
    results: dict[str, dict[str, list[Sample]]] = {}
    sides: list[str] = []
    for r in recs:
        m = measures.setdefault(
            r["measure"],
            Measure(r["measure"], r["label"], [], r["aircraft_s"], r["ticks"], r["kind"]),
        )
        if r["side"] not in sides:
            sides.append(r["side"])
        results.setdefault(m.name, {}).setdefault(r["side"], []).append(Sample(**r["sample"]))
    if len(sides) != 2:
        raise SystemExit(f"{path}: expected two sides, found {sides}")
    for m in measures.values():
        for side in sides:
            results[m.name].setdefault(side, [])
    done = [m for m in measures.values() if all(results[m.name][s] for s in sides)]
    print(f"{path}: {len(recs)} runs")
    print_table(done, results, sides)


def _comp_tick_ms(s: Sample, m: Measure) -> float:
    total = sum(s.split.values())
    share = s.split.get("companion", 0) / total if total else 0.0
    return 1e3 * s.cpu_s * share / m.ticks


# ---- the run ---------------------------------------------------------------------------------
def git(*args: str) -> str:
    return subprocess.run(
        ["git", *args], cwd=REPO, check=True, capture_output=True, text=True
    ).stdout.strip()


def _role(argv: list[str]) -> str:
    """What a sampled process was, from its command line."""
    text = " ".join(argv)
    if "sitl_model" in text:
        return "sitl-model"
    for role in ("simulate", "fleet", "campaign", "upload"):
        if f" {role} " in f" {text} ":
            return role
    if " run " in f" {text} ":
        return "companion run"
    return "other (" + (argv[0].rsplit("/", 1)[-1] if argv else "?") + ")"


def profile(m: Measure, sampler: Path, work: Path, top: int) -> None:
    """Run ``m`` once from this tree with the sampler's function counts and print, per kind
    of process (the fleet's companions together, sitl-model, ...), the top functions."""
    s = run_once(m, REPO, sampler, work, functions=True)
    roles: dict[str, dict[str, dict[str, int]]] = {}
    for f in sorted((work / "samples").glob("*.json")):
        rec = json.loads(f.read_text())
        r = roles.setdefault(_role(rec.get("argv", [])), {"self": {}, "inclusive": {}, "n": {}})
        for kind in ("self", "inclusive"):
            for k, v in rec.get(kind, {}).items():
                r[kind][k] = r[kind].get(k, 0) + v
        r["n"]["samples"] = r["n"].get("samples", 0) + sum(rec["counts"].values())
        r["n"]["processes"] = r["n"].get("processes", 0) + 1
        for k, v in rec["counts"].items():
            r["n"][k] = r["n"].get(k, 0) + v
    print(f"{m.label}: CPU {s.cpu_s:.1f} s, wall {s.wall_s:.1f} s; split {_split_text(s.split)}")
    for role, r in sorted(roles.items(), key=lambda kv: -kv[1]["n"]["samples"]):
        n = r["n"]["samples"]
        if not n:
            continue
        share = {k: r["n"].get(k, 0) for k in CATEGORIES}
        print(f"\n{role}: {r['n']['processes']} process(es), {n} samples; {_split_text(share)}")
        for kind in ("self", "inclusive"):
            print(f"  {kind} (% of this kind's samples):")
            for k, v in sorted(r[kind].items(), key=lambda kv: -kv[1])[:top]:
                print(f"    {100 * v / n:5.1f}  {k}")


def main() -> int:
    """Measure, interleaved, and print the table (or ``--profile`` one measure)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--against", metavar="COMMIT", help="the commit to compare (required)")
    p.add_argument(
        "--profile",
        metavar="MEASURE",
        help="instead: run MEASURE once from this tree and print where each process's CPU "
        "goes, by function (the sampler's counts)",
    )
    p.add_argument("--top", type=int, default=30, help="--profile: functions shown per list")
    p.add_argument("--save", type=Path, metavar="FILE", help="append each run to FILE (JSON lines)")
    p.add_argument(
        "--table",
        type=Path,
        metavar="FILE",
        help="instead: print the table of the runs saved in FILE (--save), old side first",
    )
    p.add_argument("--only", default=",".join(MEASURES), help="measures (comma-separated)")
    p.add_argument("--rounds", type=int, default=3, help="runs per measure and side")
    p.add_argument("--scale", type=float, default=1.0, help="x every simulated duration")
    p.add_argument("--keep", type=Path, help="keep the commit's worktree and runs here")
    a = p.parse_args()
    if a.table:
        table_from(a.table)
        return 0
    if a.profile:
        with tempfile.TemporaryDirectory(prefix="speed-profile-") as d:
            tmp = Path(d)
            sampler = tmp / "sampler"
            sampler.mkdir()
            shutil.copyfile(REPO / "bench" / "speed_sampler.py", sampler / "sitecustomize.py")
            (m,) = _setup([a.profile], a.scale, tmp)
            profile(m, sampler, tmp / "work", a.top)
        return 0
    if not a.against:
        p.error("--against COMMIT is required (or --profile MEASURE)")
    names = [n.strip() for n in a.only.split(",") if n.strip()]
    old_sha = git("rev-parse", "--short", a.against)
    dirty = "+" if git("status", "--porcelain", "--untracked-files=no") else ""
    new_name = git("rev-parse", "--short", "HEAD") + dirty
    tmp = Path(tempfile.mkdtemp(prefix="speed-")) if a.keep is None else a.keep
    tmp.mkdir(parents=True, exist_ok=True)
    old_tree = checkout(old_sha, tmp)
    sampler = tmp / "sampler"
    sampler.mkdir(exist_ok=True)
    shutil.copyfile(REPO / "bench" / "speed_sampler.py", sampler / "sitecustomize.py")
    old_name = f"{old_sha}"
    sides = {old_name: old_tree, new_name: REPO}
    try:
        measures = _setup(names, a.scale, tmp)
        results: dict[str, dict[str, list[Sample]]] = {
            m.name: {s: [] for s in sides} for m in measures
        }
        print(
            f"bench/speed.py: {old_name} (old) against {new_name} (this tree), {a.rounds} "
            f"rounds, interleaved, scale {a.scale:g}; {os.cpu_count()} CPUs, load "
            f"{os.getloadavg()[0]:.2f}",
            flush=True,
        )
        for r in range(a.rounds):
            order = [old_name, new_name] if r % 2 == 0 else [new_name, old_name]
            for m in measures:
                for side in order:
                    s = run_once(m, sides[side], sampler, tmp / "work" / side / m.name)
                    results[m.name][side].append(s)
                    if a.save is not None:  # each run as it ends: a long run can be cut
                        with a.save.open("a") as f:
                            rec = {"measure": m.name, "label": m.label, "side": side,
                                   "aircraft_s": m.aircraft_s, "ticks": m.ticks,
                                   "kind": m.kind, "sample": asdict(s)}  # fmt: skip
                            f.write(json.dumps(rec) + "\n")
                    print(
                        f"  round {r + 1} {m.label:<18} {side:<10} CPU {s.cpu_s:7.2f} s, wall "
                        f"{s.wall_s:6.1f} s" + (f", tick {s.tick_ms:.3f} ms" if s.tick_ms else ""),
                        flush=True,
                    )
        print_table(measures, results, [old_name, new_name])
    finally:
        if a.keep is None:
            drop_checkout(old_tree, tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
