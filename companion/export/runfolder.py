"""Reading a folder to export: a run of ours, or a real companion's log folder (edge: files).

Two layouts are recognised:

* **a run** (``companion simulate --out``, ``companion fleet``): ``truth.csv`` (the
  simulator's ground truth, :mod:`companion.contracts.simulator`), ``events.jsonl`` (merged,
  simulated seconds), ``mission.yaml``, ``metrics.json``, and per UAV ``uavN/events.jsonl``
  and, from ``companion fleet``, ``uavN/autopilot.tlog``;
* **a companion's log folder** (``companion run --log-dir DIR``): ``autopilot.tlog`` and
  ``events.jsonl`` of one UAV, no mission (give it with ``--mission``).

Times. Everything is returned in **vehicle time**, seconds since the Unix epoch: a run's
simulated seconds ``t`` (``truth.csv``, the merged ``events.jsonl``) are
``SIM_EPOCH_UNIX_S + t`` (the SYSTEM_TIME the simulated autopilots send); an event's ``t_s``
below 1e9 s is taken as simulated seconds, any other as vehicle time already. A tlog is
stamped with the wall clock until the companion learns the vehicle's time from SYSTEM_TIME,
then with vehicle time (:mod:`companion.link.tlog`): its packets are kept from the first
one stamped within :data:`CLOCK_MATCH_S` of the newest SYSTEM_TIME heard, the earlier ones
counted in :attr:`Tlog.skipped`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from companion.contracts.errors import UserError
from companion.contracts.simulator import (
    SIM_EPOCH_UNIX_S,
    TRUTH_COLUMNS,
    TRUTH_COLUMNS_ENERGY,
    TRUTH_COLUMNS_NO_WIND,
)
from companion.export.model import RunFolder, Tlog, Truth, vehicle_time_s
from companion.mission import load_mission

__all__ = ["CLOCK_MATCH_S", "TLOG_TYPES", "read_folder"]

CLOCK_MATCH_S = 5.0  # a tlog stamp this close to SYSTEM_TIME's is vehicle time (s)
TLOG_TYPES = (  # what the export reads from a tlog
    "HEARTBEAT",
    "SYSTEM_TIME",
    "GLOBAL_POSITION_INT",
    "SYS_STATUS",
    "BATTERY_STATUS",
    "SET_ATTITUDE_TARGET",
    "SET_POSITION_TARGET_GLOBAL_INT",
    "COMMAND_INT",
    "COMMAND_LONG",
    "STATUSTEXT",
)
_UAV_DIR = re.compile(r"^uav(\d+)$")


def read_folder(folder: str | Path, mission_path: str | Path | None = None) -> RunFolder:
    """Read ``folder`` (a run of ours or a companion's log folder) for export.

    Args:
        folder: the folder.
        mission_path: the mission YAML when the folder has none (or to override its own).

    Raises:
        UserError: no such folder, not a run or log folder, an unreadable file in it.
    """
    folder = Path(folder)
    if not folder.exists():
        raise UserError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise UserError(f"{folder}: not a folder")
    uav_dirs = _uav_dirs(folder)
    if (folder / "truth.csv").is_file() or uav_dirs:
        layout = "run"
    elif (folder / "autopilot.tlog").is_file():
        layout = "companion"
    else:
        raise UserError(
            f"{folder}: not a run folder (expected truth.csv, uavN/autopilot.tlog, or a "
            "companion's autopilot.tlog)"
        )
    files: list[str] = []
    mission = None
    path = Path(mission_path) if mission_path is not None else folder / "mission.yaml"
    if mission_path is not None or path.is_file():
        if not path.is_file():
            raise UserError(f"{path}: no such mission file")
        mission = load_mission(path)
        files.append(str(path) if mission_path is not None else path.name)
    truth: dict[int, Truth] = {}
    if (folder / "truth.csv").is_file():
        truth = _read_truth(folder / "truth.csv")
        files.append("truth.csv")
    tlogs: dict[int, Tlog] = {}
    if layout == "run":
        for sysid, d in uav_dirs.items():
            if (d / "autopilot.tlog").is_file():
                tlogs[sysid] = _read_tlog(d / "autopilot.tlog", sysid)
                files.append(f"{d.name}/autopilot.tlog")
    else:
        tl = _read_tlog(folder / "autopilot.tlog", None)
        tlogs[tl.sysid] = tl
        files.append("autopilot.tlog")
    events: list[dict[str, Any]] = []
    if (folder / "events.jsonl").is_file():
        events = _read_events(folder / "events.jsonl")
        files.append("events.jsonl")
    else:
        for d in uav_dirs.values():
            if (d / "events.jsonl").is_file():
                events += _read_events(d / "events.jsonl")
                files.append(f"{d.name}/events.jsonl")
    events.sort(key=lambda e: e["t_unix_s"])
    metrics = None
    if (folder / "metrics.json").is_file():
        try:
            metrics = json.loads((folder / "metrics.json").read_text())
        except (OSError, ValueError) as exc:
            raise UserError(f"{folder / 'metrics.json'}: unreadable ({exc})") from None
        files.append("metrics.json")
    if not truth and not tlogs:
        raise UserError(f"{folder}: nothing to export (no truth.csv rows and no tlog)")
    return RunFolder(folder, layout, mission, truth, tlogs, events, metrics, files)


def _uav_dirs(folder: Path) -> dict[int, Path]:
    out = {}
    for d in folder.iterdir():
        m = _UAV_DIR.match(d.name)
        if m and d.is_dir() and any((d / f).is_file() for f in ("autopilot.tlog", "events.jsonl")):
            out[int(m.group(1))] = d
    return dict(sorted(out.items()))


def _read_truth(path: Path) -> dict[int, Truth]:
    """``truth.csv`` by UAV (pyarrow: a day's log has millions of rows)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    with open(path) as fh:
        header = tuple(fh.readline().strip().split(","))
    if header not in (TRUTH_COLUMNS, TRUTH_COLUMNS_ENERGY, TRUTH_COLUMNS_NO_WIND):
        raise UserError(f"{path}: expected the columns {','.join(TRUTH_COLUMNS)}")
    types = {c: pa.float64() for c in header}
    types.update(sysid=pa.int64(), mode=pa.string())
    try:
        table = pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types=types))
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"{path}: malformed ({str(exc).splitlines()[0]})") from None
    cols = {c: table.column(c).to_numpy(zero_copy_only=False) for c in header}
    out = {}
    for sysid in np.unique(cols["sysid"]):
        k = np.flatnonzero(cols["sysid"] == sysid)
        k = k[np.argsort(cols["t_s"][k], kind="stable")]
        numeric = {
            c: np.asarray(v[k], dtype=float)
            for c, v in cols.items()
            if c not in ("t_s", "sysid", "mode")
        }
        t = np.asarray(cols["t_s"][k], dtype=float)
        out[int(sysid)] = Truth(
            int(sysid), t + SIM_EPOCH_UNIX_S, numeric, np.asarray(cols["mode"][k], dtype=str)
        )
    return out


def _read_tlog(path: Path, sysid: int | None) -> Tlog:
    """The messages of :data:`TLOG_TYPES` of one tlog in vehicle time (module doc); the
    UAV's sysid is the autopilot's (its HEARTBEAT's source) when ``sysid`` is None."""
    from pymavlink import mavutil

    try:
        conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    except OSError as exc:
        raise UserError(f"{path}: unreadable ({exc.strerror})") from None
    kept: list[Any] = []
    skipped = 0
    newest_clock: float | None = None  # SYSTEM_TIME's newest time_unix_usec (s)
    vehicle = False
    try:
        while True:
            msg = conn.recv_match(type=list(TLOG_TYPES))
            if msg is None:
                break
            t = msg.get_type()
            if t == "SYSTEM_TIME" and msg.time_unix_usec:
                newest_clock = msg.time_unix_usec / 1e6
            if not vehicle:
                vehicle = newest_clock is not None and (
                    abs(msg._timestamp - newest_clock) <= CLOCK_MATCH_S
                )
                if not vehicle:
                    skipped += 1
                    continue
            if sysid is None and t == "HEARTBEAT" and msg.get_srcComponent() == 1:
                sysid = int(msg.get_srcSystem())
            kept.append(msg)
    finally:
        conn.close()
    if sysid is None:
        raise UserError(f"{path}: no autopilot HEARTBEAT in vehicle time (not a tlog?)")
    return Tlog(sysid, path, kept, skipped)


def _read_events(path: Path) -> list[dict[str, Any]]:
    """The events of one ``events.jsonl`` with a time, each with ``t_unix_s`` (vehicle s)."""
    out = []
    with open(path) as fh:
        for line in fh:
            try:
                ev = json.loads(line)
            except ValueError:
                continue  # a line cut by a crash
            t = ev.get("t_s") if isinstance(ev, dict) else None
            if isinstance(t, int | float) and not isinstance(t, bool) and np.isfinite(t):
                ev["t_unix_s"] = vehicle_time_s(float(t))
                out.append(ev)
    return out
