"""``companion report DIR``: recompute ``metrics.json`` and the plots of a run folder."""

from __future__ import annotations

import argparse
from pathlib import Path

from companion.report.summary import summary, write_report


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``report`` sub-command."""
    p = sub.add_parser(
        "report",
        help="recompute metrics.json and the plots of a run folder",
        description="Read DIR/mission.yaml, DIR/truth.csv and DIR/events.jsonl (from "
        "'companion simulate' or 'companion fleet') and write DIR/metrics.json, "
        "DIR/map.png, DIR/coverage.png and DIR/errors.png.",
    )
    p.add_argument("folder", metavar="DIR", help="run folder")
    p.add_argument("--no-plots", action="store_true", help="write metrics.json only")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the report and print its headline figures."""
    folder = Path(args.folder)
    m = write_report(folder, plots=not args.no_plots)
    print(summary(m))
    print(f"wrote {folder / 'metrics.json'}" + ("" if args.no_plots else " and the plots"))
    return 0
