"""Same answers: the shipped missions flown by this tree and by a commit, their measures side by
side against issue 46's tolerances.

Usage (from the repository root, the project's Python environment active)::

    python bench/same_answers.py --against a6a975e [--only ellipse_6uav,wpafb_4uav]
        [--jobs 2] [--keep DIR]

Each mission is flown with ``companion simulate`` from both trees (the commit in a temporary
``git worktree``, as ``bench/speed.py`` does; ``--jobs 2`` flies the two sides at once) and
each ``metrics.json`` is read. Compared: the coverage revisit ratio (within 0.01), the
cross-track p95 (within 0.2 m), the alerts raised and each intruder's prosecution outcomes
(the same), false clears (0). The runs:

===============  =========================================================================
ellipse_6uav     ``missions/ellipse_6uav.yaml`` (900 s, the paper's decoy)
ellipse_relief   ``missions/ellipse_relief.yaml --battery-used 3=5800 --duration 800``
                 (one relief: docs/energy.md's figure)
wpafb_4uav       ``missions/wpafb_4uav.yaml`` (8000 s)
ellipse_all_day  ``missions/ellipse_all_day.yaml`` (7200 s; not in the default set)
wpafb_all_day    ``missions/wpafb_all_day.yaml`` (21600 s; not in the default set)
===============  =========================================================================

Prints a table and "all within" or what is not; exit status 0 either way (a figure, not a
test).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from speed import REPO, checkout, clean_env, drop_checkout, git

RUNS: dict[str, list[str]] = {
    "ellipse_6uav": ["missions/ellipse_6uav.yaml"],
    "ellipse_relief": ["missions/ellipse_relief.yaml", "--battery-used", "3=5800",
                       "--duration", "800"],
    "wpafb_4uav": ["missions/wpafb_4uav.yaml"],
    "ellipse_all_day": ["missions/ellipse_all_day.yaml"],
    "wpafb_all_day": ["missions/wpafb_all_day.yaml"],
}  # fmt: skip
DEFAULT = ("ellipse_6uav", "ellipse_relief", "wpafb_4uav")
REVISIT_TOL = 0.01
XTRACK_TOL_M = 0.2


def fly(tree: Path, args: list[str], out: Path) -> dict:
    """``companion simulate`` from ``tree``; its metrics.json (raises on failure)."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "companion", "simulate", *args, "--out", str(out)]
    proc = subprocess.run(cmd, cwd=tree, env=clean_env(tree), capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} in {tree}: {proc.stderr[-2000:]}")
    return json.loads((out / "metrics.json").read_text())


def outcomes(m: dict) -> dict[str, list[str]]:
    """Each intruder's prosecution outcomes, in order."""
    return {
        e["intruder_id"]: [p["outcome"] for p in e.get("prosecutions", [])]
        for e in m.get("intruder_episodes", [])
    }


def false_clears(m: dict) -> int:
    """False clears over every intruder episode."""
    return sum(int(e.get("false_clears", 0)) for e in m.get("intruder_episodes", []))


def compare(name: str, old: dict, new: dict) -> list[tuple[str, str, str, str, bool]]:
    """Rows (measure, old, new, tolerance, within) for one mission."""
    rows = []
    for key, tol in (("coverage_revisit_ratio", REVISIT_TOL), ("cross_track_p95_m", XTRACK_TOL_M)):
        a, b = old.get(key), new.get(key)
        ok = a is not None and b is not None and abs(a - b) <= tol + 1e-12
        rows.append((key, f"{a}", f"{b}", f"+-{tol:g}", ok))
    a, b = old.get("alerts_raised"), new.get("alerts_raised")
    rows.append(("alerts_raised", f"{a}", f"{b}", "same", a == b))
    oa, ob = outcomes(old), outcomes(new)
    rows.append(("outcomes", json.dumps(oa), json.dumps(ob), "same", oa == ob))
    fa, fb = false_clears(old), false_clears(new)
    rows.append(("false_clears", f"{fa}", f"{fb}", "0", fb == 0))
    return rows


def main() -> int:
    """Fly, compare, print."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--against", required=True, metavar="COMMIT")
    p.add_argument("--only", default=",".join(DEFAULT), help=f"runs, of {', '.join(RUNS)}")
    p.add_argument("--jobs", type=int, default=2, help="runs at once (default 2)")
    p.add_argument("--keep", type=Path, help="keep the worktree and the run folders here")
    p.add_argument(
        "--reuse-old",
        action="store_true",
        help="with --keep: take the commit's runs already in DIR/runs/old instead of flying "
        "them again (the commit's code does not change)",
    )
    a = p.parse_args()
    names = [n for n in a.only.split(",") if n]
    for n in names:
        if n not in RUNS:
            raise SystemExit(f"unknown run {n!r}; known: {', '.join(RUNS)}")
    tmp = Path(tempfile.mkdtemp(prefix="answers-")) if a.keep is None else a.keep
    tmp.mkdir(parents=True, exist_ok=True)
    old_sha = git("rev-parse", "--short", a.against)
    new_name = git("rev-parse", "--short", "HEAD") + (
        "+" if git("status", "--porcelain", "--untracked-files=no") else ""
    )
    old_tree = checkout(old_sha, tmp)
    try:
        jobs = [(n, side, tree) for n in names for side, tree in (("old", old_tree), ("new", REPO))]
        metrics: dict[tuple[str, str], dict] = {}
        if a.reuse_old and a.keep is not None:
            for n in names:
                done = tmp / "runs" / "old" / n / "metrics.json"
                if done.exists():
                    metrics[(n, "old")] = json.loads(done.read_text())
        with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
            futures = {
                (n, side): pool.submit(fly, tree, RUNS[n], tmp / "runs" / side / n)
                for n, side, tree in jobs
                if (n, side) not in metrics
            }
            metrics |= {k: f.result() for k, f in futures.items()}
        print(f"same answers: {old_sha} (old) against {new_name} (this tree)")
        print(f"{'mission':<16} {'measure':<24} {'old':>10} {'new':>10} {'tolerance':>10}  within")
        bad = []
        for n in names:
            for measure, va, vb, tol, ok in compare(n, metrics[(n, "old")], metrics[(n, "new")]):
                if len(va) > 10 or len(vb) > 10:
                    print(f"{n:<16} {measure:<24} {tol:>32}  {'yes' if ok else 'NO'}")
                    print(f"{'':<16}   old {va}\n{'':<16}   new {vb}")
                else:
                    print(f"{n:<16} {measure:<24} {va:>10} {vb:>10} {tol:>10}  "
                          f"{'yes' if ok else 'NO'}")  # fmt: skip
                if not ok:
                    bad.append(f"{n} {measure}")
        print("all within the tolerances" if not bad else "NOT within: " + "; ".join(bad))
    finally:
        if a.keep is None:
            drop_checkout(old_tree, tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
