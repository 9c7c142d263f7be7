"""Reading a run folder: the mission, the truth log (per vehicle) and the events.

The events are kept as read (dicts: the simulator's, the Runners' and the Agents');
:attr:`RunData.agent_events` are the Agents' ones, typed (:mod:`companion.agent.events`).
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from companion.agent.events import AgentEvent, AlertTasked, EventRecordError, Rejoined, parse_event
from companion.agent.relief.events import ReliefInSlot, Relieved
from companion.contracts.errors import UserError
from companion.contracts.simulator import (
    TRUTH_COLUMNS,
    TRUTH_COLUMNS_ENERGY,
    TRUTH_COLUMNS_NO_WIND,
)
from companion.mission import Mission, load_mission


@dataclass(frozen=True)
class Track:
    """One vehicle's truth samples (arrays of equal length, time increasing)."""

    sysid: int
    t_s: np.ndarray
    pos_m: np.ndarray  # complex north + i east (m)
    course_rad: np.ndarray
    mode: np.ndarray  # strings
    wind_m_s: np.ndarray | None = None  # true wind at the UAV, complex north + i east (m/s)


@dataclass(frozen=True)
class Away:
    """A UAV away from the formation for an alert: from tasking until back in its slot."""

    sysid: int
    alert_id: str
    t0_s: float
    t1_s: float


@dataclass(frozen=True)
class RunData:
    """A run folder, read."""

    folder: Path
    mission: Mission
    tracks: dict[int, Track]
    events: list[dict]

    @property
    def times_s(self) -> np.ndarray:
        """Sample times common to every vehicle (s)."""
        common = None
        for tr in self.tracks.values():
            common = tr.t_s if common is None else np.intersect1d(common, tr.t_s)
        return common if common is not None else np.empty(0)

    @cached_property
    def agent_events(self) -> list[AgentEvent]:
        """The Agents' events, typed, sorted by time (s; stable: the log's order at a tie).

        Raises:
            UserError: a record of an Agent event kind without that kind's fields.
        """
        out = []
        for rec in self.events:
            try:
                ev = parse_event(rec)
            except EventRecordError as err:
                raise UserError(f"{self.folder / 'events.jsonl'}: {err}") from None
            if ev is not None:
                out.append(ev)
        return sorted(out, key=lambda e: e.t_s)

    def off_station_windows(self) -> list[Away]:
        """The reliefs' time off the loop (``alert_id`` "relief"), from each UAV's own
        events: a spare from the start until it holds its slot, a relieved UAV from
        leaving until it holds a slot again (flying home, on the ground, flying in)."""
        spares = {sp.sysid for sp in self.mission.vehicles.spares}
        open_ = dict.fromkeys(spares, float(self.times_s[0]) if len(self.times_s) else 0.0)
        out = []
        for ev in self.agent_events:
            if isinstance(ev, Relieved):
                open_[ev.sysid] = float(ev.t_s)
            elif isinstance(ev, ReliefInSlot) and ev.sysid in open_:
                out.append(Away(int(ev.sysid), "relief", open_.pop(ev.sysid), float(ev.t_s)))
        end = (float(self.times_s[-1]) if len(self.times_s) else 0.0) + 1e-3
        out.extend(Away(int(s), "relief", t0, end) for s, t0 in open_.items())
        return sorted(out, key=lambda a: (a.t0_s, a.sysid))

    def away_windows(self) -> list[Away]:
        """Prosecution episodes, from each prosecutor's own tasking event to its rejoin."""
        out, open_ = [], {}
        for ev in self.agent_events:
            if isinstance(ev, AlertTasked) and ev.sysid == ev.prosecutor_sysid:
                open_[ev.sysid] = (ev.alert_id, float(ev.t_s))
            elif isinstance(ev, Rejoined) and ev.sysid in open_:
                alert_id, t0 = open_.pop(ev.sysid)
                out.append(Away(int(ev.sysid), alert_id, t0, float(ev.t_s)))
        # still away when the run ended: the window covers the last sample too
        end = (float(self.times_s[-1]) if len(self.times_s) else 0.0) + 1e-3
        out.extend(Away(int(s), a, t0, end) for s, (a, t0) in open_.items())
        return sorted(out, key=lambda a: a.t0_s)


def load_run(folder: str | Path) -> RunData:
    """Read ``mission.yaml``, ``truth.csv`` and ``events.jsonl`` from ``folder``."""
    folder = Path(folder)
    for name in ("mission.yaml", "truth.csv"):
        if not (folder / name).is_file():
            raise UserError(f"{folder}: not a run folder (no {name})")
    mission = load_mission(folder / "mission.yaml")
    rows: dict[int, list[tuple]] = {}
    with open(folder / "truth.csv", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        known = (TRUTH_COLUMNS, TRUTH_COLUMNS_ENERGY, TRUTH_COLUMNS_NO_WIND)
        if header is None or tuple(header) not in known:
            raise UserError(
                f"{folder / 'truth.csv'}: expected the columns {','.join(TRUTH_COLUMNS)}"
            )
        has_wind = tuple(header) != TRUTH_COLUMNS_NO_WIND  # the battery's columns come after
        for line, row in enumerate(reader, start=2):
            try:
                wind = (
                    (float(row[10]), float(row[11]))
                    if has_wind and len(row) >= 12
                    else (np.nan, np.nan)
                )
                rows.setdefault(int(row[1]), []).append(
                    (float(row[0]), float(row[2]), float(row[3]), float(row[6]), row[9], *wind)
                )
            except (ValueError, IndexError):
                raise UserError(f"{folder / 'truth.csv'}:{line}: malformed row") from None
    tracks = {}
    for sysid, r in rows.items():
        r.sort(key=lambda x: x[0])
        a = np.array([x[:4] + x[5:] for x in r], dtype=float)
        tracks[sysid] = Track(
            sysid,
            a[:, 0],
            a[:, 1] + 1j * a[:, 2],
            np.radians(a[:, 3]),
            np.array([x[4] for x in r]),
            a[:, 4] + 1j * a[:, 5] if has_wind else None,
        )
    events = []
    path = folder / "events.jsonl"
    if path.is_file():
        with open(path) as fh:
            for line in fh:
                line = line.strip()
                if line:
                    try:
                        events.append(json.loads(line))
                    except json.JSONDecodeError:
                        continue
    return RunData(folder, mission, tracks, events)
