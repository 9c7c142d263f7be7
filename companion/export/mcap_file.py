"""Writing the export to an MCAP file (edge: the one place bytes of it are written).

The ``mcap`` package's writer: zstd-compressed chunks with message indexes and a summary
(Foxglove seeks in it), every schema ``jsonschema``-encoded and every message JSON (UTF-8),
log time = publish time = the message's vehicle time (ns since the Unix epoch, to the
microsecond), messages
written in time order. Two metadata records: ``run`` (the folder, its layout, the mission,
the origin, the files read, the time base) and ``metrics`` (``metrics.json``, each value as
JSON text); the mission file is attached as ``mission.yaml``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import Writer

from companion import __version__
from companion.contracts.errors import UserError
from companion.export import foxglove as fg
from companion.export.model import Message, RunFolder
from companion.export.topics import SCHEMAS, messages, origin_of, topic_schema

__all__ = ["Written", "write_mcap"]


@dataclass(frozen=True)
class Written:
    """What was written: the file, message counts by topic, first and last vehicle time (s)."""

    path: Path
    counts: dict[str, int]
    t_first_s: float | None
    t_last_s: float | None
    size_bytes: int


def write_mcap(run: RunFolder, out: str | Path) -> Written:
    """Write ``run`` to the MCAP file ``out`` (replaced; written beside it, then renamed).

    Raises:
        UserError: ``out`` cannot be written.
    """
    out = Path(out)
    msgs = sorted(messages(run), key=lambda m: m.t_unix_s)  # stable: a topic keeps its order
    if not msgs:
        raise UserError(f"{run.folder}: nothing to export (no position, setpoint or event)")
    tmp = out.with_name(out.name + ".part")
    try:
        with open(tmp, "wb") as fh:
            counts = _write(fh, run, msgs)
        os.replace(tmp, out)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise UserError(f"{out}: cannot write ({exc.strerror})") from None
    return Written(out, counts, msgs[0].t_unix_s, msgs[-1].t_unix_s, out.stat().st_size)


def _write(fh: Any, run: RunFolder, msgs: list[Message]) -> dict[str, int]:
    w = Writer(fh)
    w.start(profile="", library=f"companion export {__version__}")
    schema_ids: dict[str, int] = {}
    channels: dict[str, int] = {}
    counts: dict[str, int] = {}
    for topic in sorted({m.topic for m in msgs}, key=_topic_order):
        name = topic_schema(topic)
        if name not in schema_ids:
            data = json.dumps(SCHEMAS[name], separators=(",", ":")).encode()
            schema_ids[name] = w.register_schema(name, "jsonschema", data)
        channels[topic] = w.register_channel(topic, "json", schema_ids[name])
        counts[topic] = 0
    for m in msgs:
        ns = fg.time_ns(m.t_unix_s)
        data = json.dumps(m.data, separators=(",", ":"), allow_nan=False).encode()
        w.add_message(channels[m.topic], ns, data, ns, sequence=counts[m.topic])
        counts[m.topic] += 1
    w.add_metadata("run", _run_metadata(run))
    if run.metrics is not None:
        w.add_metadata("metrics", {k: json.dumps(v) for k, v in run.metrics.items()})
    if run.mission is not None and Path(run.mission.path).is_file():
        ns = fg.time_ns(msgs[0].t_unix_s)
        w.add_attachment(
            ns, ns, "mission.yaml", "application/yaml", Path(run.mission.path).read_bytes()
        )
    w.finish()
    return counts


def _run_metadata(run: RunFolder) -> dict[str, str]:
    origin = origin_of(run)
    meta = {
        "folder": str(run.folder),
        "layout": run.layout,
        "uavs": ",".join(str(s) for s in run.sysids),
        "files": ",".join(run.files),
        "time_base": "vehicle time (unix s; a simulated run's t = 0 is 2026-01-01T00:00:00Z)",
        "local_frame": "local: ENU (x east, y north, z up), m from the origin",
        "truth": "truth.csv" if run.truth else "none: positions from the tlogs",
    }
    if run.mission is not None:
        meta["mission"] = run.mission.name
    if origin is not None:
        meta.update(
            origin_lat_deg=repr(origin.lat_deg),
            origin_lon_deg=repr(origin.lon_deg),
            origin_alt_m=repr(origin.alt_m),
            origin_source=origin.source,
        )
    skipped = {s: tl.skipped for s, tl in run.tlogs.items() if tl.skipped}
    if skipped:
        meta["tlog_packets_before_vehicle_time"] = json.dumps(skipped)
    return meta


def _topic_order(topic: str) -> tuple:
    """Run topics first, then each UAV's in sysid order."""
    head = topic.strip("/").split("/")[0]
    if head.startswith("uav") and head[3:].isdigit():
        return (1, int(head[3:]), topic)
    return (0, 0, topic)
