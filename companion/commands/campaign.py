"""``companion campaign``: one patrol design flown over a grid of missions, worlds and seeds.

Reads a campaign spec (``docs/campaigns.md``), expands it into runs (missions x scenarios x
seeds), flies each with the in-memory engine in a Dask task (an embedded LocalCluster, or
``--scheduler``), appends one row per run to ``OUT/runs.parquet`` (skipping the runs already
there), prints the figures per scenario and draws ``OUT/summary.png``.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import TYPE_CHECKING

from companion.contracts.errors import UserError

if TYPE_CHECKING:
    from companion.campaign.grid import Grid


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``campaign`` sub-command."""
    p = sub.add_parser(
        "campaign",
        help="fly a grid of missions x scenarios x seeds in memory on Dask; a Parquet table",
        description="Fly every run of the campaign SPEC (missions x scenarios x seeds, "
        "docs/campaigns.md) with the in-memory engine, each in a Dask task, and append one "
        "row per run to OUT/runs.parquet (a rerun skips the runs already there). Prints the "
        "figures per scenario and writes OUT/summary.png. Exit status 1 if a run failed.",
    )
    p.add_argument("spec", help="campaign spec YAML file")
    p.add_argument("--out", metavar="DIR", help="campaign folder (default runs/SPEC_NAME)")
    p.add_argument(
        "--workers", type=int, default=2, metavar="N", help="worker processes (default 2)"
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="a running Dask scheduler (tcp://HOST:PORT) instead of the embedded cluster; "
        "its workers must see the mission files and run this package",
    )
    p.add_argument(
        "--batch",
        type=int,
        metavar="N",
        help="finished runs between two writes of the table (default: --workers)",
    )
    p.add_argument(
        "--retry-failed", action="store_true", help="run again the runs that recorded an error"
    )
    p.add_argument(
        "--keep-runs", action="store_true", help="keep each run folder in OUT/runs/RUN_ID"
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--show",
        metavar="RUN_ID",
        help="run nothing: print the companion simulate command line of that run",
    )
    p.add_argument("--list", action="store_true", help="run nothing: list the grid's runs")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Expand the spec and run it (or show a run); returns the exit status."""
    from companion.campaign.grid import expand
    from companion.campaign.spec import load_spec
    from sitl_model.params import Params

    if args.workers < 1 or (args.batch is not None and args.batch < 1):
        raise UserError("--workers and --batch must be >= 1")
    spec = load_spec(args.spec, Params)
    out = Path(args.out) if args.out else Path("runs") / Path(args.spec).stem
    grid = expand(spec, out, Params)
    if args.list:
        for p in grid.plans:
            print(f"{p.run_id}  {p.mission} {p.scenario} seed {p.seed} {p.duration_s:g} s")
        return 0
    if args.show:
        plan = grid.find(args.show)
        if plan is None:
            raise UserError(f"{args.spec}: no run {args.show!r} in the grid (see --list)")
        print(shlex.join(plan.simulate_argv(out)))
        return 0
    return _fly(args, grid, out)


def _fly(args: argparse.Namespace, grid: Grid, out: Path) -> int:
    from companion.campaign.execute import run_campaign
    from companion.campaign.figure import plot_summary
    from companion.campaign.summary import summary_text
    from companion.campaign.table import TABLE

    done = run_campaign(
        grid,
        out,
        workers=args.workers,
        scheduler=args.scheduler,
        batch=args.batch,
        retry_failed=args.retry_failed,
        keep_runs=args.keep_runs,
        progress=not args.no_progress,
    )
    print()
    print(summary_text(done.rows))
    if done.rows:
        plot_summary(done.rows, out / "summary.png")
    failed = sum(1 for r in done.rows if r.get("error"))
    print(
        f"\nran {done.ran} ({done.failed} failed), skipped {done.skipped}; {out / TABLE} holds "
        f"this grid's {len(done.rows)} rows ({failed} failed); figure {out / 'summary.png'}"
    )
    return 1 if failed else 0
