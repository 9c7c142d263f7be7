"""``companion export RUN_DIR --mcap OUT.mcap``: a run (or a companion's log folder) as MCAP.

Reads the folder (:mod:`companion.export.runfolder`), turns it into Foxglove's schemas
(:mod:`companion.export.topics`) and writes one MCAP file (:mod:`companion.export.mcap_file`);
prints what it wrote. A missing or wrong folder is one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
from datetime import UTC, datetime
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` sub-command."""
    p = sub.add_parser(
        "export",
        help="write a run folder (or a companion's log folder) as MCAP for Foxglove",
        description="Read RUN_DIR (from 'companion simulate --out', 'companion fleet', or "
        "'companion run --log-dir') and write it as one MCAP file: per UAV its position on "
        "the map (foxglove.LocationFix), pose and transform in the local frame, velocity, "
        "setpoints, mode and battery; the loop and geofence, the alerts and tracks "
        "(foxglove.GeoJSON) and the event log (foxglove.Log), in vehicle time. See "
        "docs/export.md.",
    )
    p.add_argument("folder", metavar="RUN_DIR", help="run folder or companion log folder")
    p.add_argument("--mcap", required=True, metavar="OUT.mcap", help="the MCAP file to write")
    p.add_argument(
        "--mission",
        metavar="FILE",
        help="mission YAML (origin, loop, fence) when the folder has no mission.yaml",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Export and print the summary."""
    from companion.contracts.errors import UserError
    from companion.export.mcap_file import write_mcap
    from companion.export.runfolder import read_folder

    out = Path(args.mcap)
    if out.suffix != ".mcap":
        raise UserError(f"--mcap {out}: the file name must end in .mcap")
    if not out.parent.is_dir():
        raise UserError(f"--mcap {out}: no such folder {out.parent}")
    folder = read_folder(args.folder, args.mission)
    w = write_mcap(folder, out)
    uavs = folder.sysids
    span = ""
    if w.t_first_s is not None and w.t_last_s is not None:
        first = datetime.fromtimestamp(w.t_first_s, UTC).isoformat(timespec="seconds")
        span = f", {w.t_last_s - w.t_first_s:.1f} s of vehicle time from {first}"
    print(
        f"export: {sum(w.counts.values())} messages on {len(w.counts)} topics, "
        f"{len(uavs)} UAVs ({', '.join(map(str, uavs))}){span}"
    )
    groups: dict[str, list[str]] = {}  # "run" or "uavN" -> "topic count"
    for topic, n in w.counts.items():
        head, _, rest = topic.strip("/").partition("/")
        key = head if head.startswith("uav") and head[3:].isdigit() else "run"
        groups.setdefault(key, []).append(f"{rest if key != 'run' else topic} {n}")
    for key, parts in groups.items():
        print(f"  {key}: {', '.join(parts)}")
    print(f"export: wrote {w.path} ({w.size_bytes / 1e6:.1f} MB)")
    return 0
