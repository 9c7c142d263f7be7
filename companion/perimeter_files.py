"""Perimeter sources for ``companion upload`` (pure parsing, no I/O beyond reading text).

* mission YAML (:func:`companion.mission.load_mission`): the patrol loop sampled equally in
  time (an ellipse or rounded hull as points), at each vehicle's altitude;
* QGroundControl ``.plan`` (JSON): the mission's NAV_WAYPOINT items (``SimpleItem``,
  command 16), latitude/longitude in params 5/6 (index 4/5), altitude param 7 (index 6);
* ``QGC WPL 110`` waypoint files (tab separated: seq, current, frame, command, p1..p4, lat,
  lon, alt, autocontinue); line seq 0 is the home position and is skipped.

Every parser returns :class:`PerimeterPoint` values (degrees, metres above home) or raises
:class:`companion.errors.UserError` naming the file and the problem.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

MAV_CMD_NAV_WAYPOINT = 16


@dataclass(frozen=True)
class PerimeterPoint:
    """One perimeter waypoint: WGS-84 latitude/longitude (deg), altitude above home (m)."""

    lat_deg: float
    lon_deg: float
    alt_m: float


def _check(points: list[PerimeterPoint], name: str) -> list[PerimeterPoint]:
    from companion.errors import UserError

    if len(points) < 3:
        raise UserError(f"{name}: a perimeter needs at least 3 waypoints, found {len(points)}")
    for p in points:
        if not (
            math.isfinite(p.lat_deg + p.lon_deg + p.alt_m)
            and -90 <= p.lat_deg <= 90
            and -180 <= p.lon_deg <= 180
        ):
            raise UserError(f"{name}: waypoint {p} is not a position")
    return points


def parse_plan(text: str, name: str = "<plan>") -> list[PerimeterPoint]:
    """NAV_WAYPOINT items of a QGroundControl .plan file."""
    from companion.errors import UserError

    try:
        doc = json.loads(text)
        items = doc["mission"]["items"]
    except (ValueError, KeyError, TypeError):
        raise UserError(f"{name}: not a QGroundControl .plan file (no mission.items)") from None
    points = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or item.get("type") != "SimpleItem":
            continue
        if item.get("command") != MAV_CMD_NAV_WAYPOINT:
            continue
        params = item.get("params")
        try:
            points.append(PerimeterPoint(float(params[4]), float(params[5]), float(params[6])))
        except (TypeError, ValueError, IndexError):
            raise UserError(
                f"{name}: mission item {i} has no latitude/longitude/altitude"
            ) from None
    return _check(points, name)


def parse_wpl(text: str, name: str = "<waypoints>") -> list[PerimeterPoint]:
    """NAV_WAYPOINT lines of a ``QGC WPL 110`` file (the home line, seq 0, skipped)."""
    from companion.errors import UserError

    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines or not lines[0].startswith("QGC WPL 110"):
        raise UserError(f"{name}: not a 'QGC WPL 110' waypoint file")
    points = []
    for n, ln in enumerate(lines[1:], start=2):
        f = ln.split("\t") if "\t" in ln else ln.split()
        try:
            seq, command = int(f[0]), int(f[3])
            lat, lon, alt = float(f[8]), float(f[9]), float(f[10])
        except (ValueError, IndexError):
            raise UserError(f"{name}:{n}: expected 12 tab-separated fields") from None
        if seq == 0 or command != MAV_CMD_NAV_WAYPOINT:
            continue
        points.append(PerimeterPoint(lat, lon, alt))
    return _check(points, name)


def loop_points(mission, count: int, alt_m: float) -> list[PerimeterPoint]:
    """The mission's patrol loop as ``count`` points equally spaced in time, at ``alt_m``."""
    import pymap3d

    o = mission.origin
    pts = mission.patrol.sample_by_time(count)
    lat, lon, _ = pymap3d.ned2geodetic(pts.real, pts.imag, 0.0, o.lat_deg, o.lon_deg, o.alt_m)
    return [PerimeterPoint(float(a), float(b), alt_m) for a, b in zip(lat, lon, strict=True)]
