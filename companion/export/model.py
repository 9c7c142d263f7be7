"""What an export reads from a folder, as plain records (pure): each UAV's ground truth, each
tlog's messages, the events, the mission; the rule that puts a logged time in vehicle time;
the local frame's origin; and one exported message. Read by
:mod:`companion.export.runfolder`, turned into topics by :mod:`companion.export.topics`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pymap3d

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.mission import Mission

__all__ = ["SIM_TIME_MAX_S", "Message", "Origin", "RunFolder", "Tlog", "Truth", "vehicle_time_s"]

SIM_TIME_MAX_S = 1e9  # a time below this is simulated seconds, not Unix time (s)


@dataclass(frozen=True)
class Truth:
    """One UAV's rows of ``truth.csv``, time increasing: ``t_unix_s`` (vehicle time, s),
    ``columns`` (every numeric column by its name, arrays of that length: north_m, east_m,
    alt_m above the origin, heading_deg, course_deg, groundspeed_m_s, turn_rate_deg_s, the
    wind and battery columns where the file has them) and ``mode`` (the autopilot's mode,
    strings)."""

    sysid: int
    t_unix_s: np.ndarray
    columns: dict[str, np.ndarray]
    mode: np.ndarray


@dataclass(frozen=True)
class Tlog:
    """One UAV's ``autopilot.tlog``: the messages of :data:`TLOG_TYPES` (pymavlink objects,
    ``_timestamp`` the vehicle time in s) in file order, and how many packets were left out
    as stamped before the vehicle time was known."""

    sysid: int
    path: Path
    messages: list[Any]
    skipped: int


@dataclass(frozen=True)
class RunFolder:
    """A folder read for export (see the module doc)."""

    folder: Path
    layout: str  # "run" or "companion"
    mission: Mission | None
    truth: dict[int, Truth]
    tlogs: dict[int, Tlog]
    events: list[dict[str, Any]]  # each with "t_unix_s" added, in time order
    metrics: dict[str, Any] | None = None
    files: list[str] = field(default_factory=list)  # what was read, relative to the folder

    @property
    def sysids(self) -> list[int]:
        """Every UAV with a truth track or a tlog, ascending."""
        return sorted(set(self.truth) | set(self.tlogs))


def vehicle_time_s(t_s: float) -> float:
    """A logged time (s) as vehicle time (s since the Unix epoch): below ``SIM_TIME_MAX_S``
    it is simulated seconds since ``SIM_EPOCH_UNIX_S``."""
    return t_s + SIM_EPOCH_UNIX_S if t_s < SIM_TIME_MAX_S else t_s


@dataclass(frozen=True)
class Message:
    """One message: ``topic``, vehicle time ``t_unix_s`` (s) and its JSON-ready ``data``."""

    topic: str
    t_unix_s: float
    data: dict[str, Any]


@dataclass(frozen=True)
class Origin:
    """The local frame's origin: latitude, longitude (deg, WGS-84) and altitude (m, the
    height the local ``up`` is measured from) and where it came from."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    source: str  # "mission" or "first fix"

    def to_geodetic(
        self, north_m: np.ndarray, east_m: np.ndarray, up_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude (deg), longitude (deg), altitude (m) of local points (m)."""
        lat, lon, alt = pymap3d.ned2geodetic(
            np.asarray(north_m, dtype=float),
            np.asarray(east_m, dtype=float),
            -np.asarray(up_m, dtype=float),
            self.lat_deg,
            self.lon_deg,
            self.alt_m,
        )
        return np.asarray(lat, dtype=float), np.asarray(lon, dtype=float), np.asarray(alt)

    def to_local(
        self, lat_deg: np.ndarray, lon_deg: np.ndarray, alt_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """North, east, up (m) of geodetic points (deg, deg, m)."""
        n, e, d = pymap3d.geodetic2ned(
            np.asarray(lat_deg, dtype=float),
            np.asarray(lon_deg, dtype=float),
            np.asarray(alt_m, dtype=float),
            self.lat_deg,
            self.lon_deg,
            self.alt_m,
        )
        return np.asarray(n, dtype=float), np.asarray(e, dtype=float), -np.asarray(d)
