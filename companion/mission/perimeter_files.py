"""Perimeter sources for ``companion upload`` (pure parsing, no I/O beyond reading text).

* mission YAML (:func:`companion.mission.load_mission`): the patrol loop sampled equally in
  time (an ellipse or rounded hull as points), at each vehicle's altitude;
* QGroundControl ``.plan`` (JSON): the mission's NAV_WAYPOINT items (``SimpleItem``,
  command 16), latitude/longitude in params 5/6 (index 4/5), altitude param 7 (index 6);
* ``QGC WPL 110`` waypoint files (tab separated: seq, current, frame, command, p1..p4, lat,
  lon, alt, autocontinue); line seq 0 is the home position and is skipped.

Every parser returns :class:`PerimeterPoint` values (degrees, metres above home) or raises
:class:`companion.contracts.errors.UserError` naming the file, the line and the problem. The points
are held to the mission loader's rule for waypoints: the corners of a convex outline, each
once, in order (:mod:`companion.core.outline`), since the loop flown is their rounded hull.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import pymap3d

from companion.contracts.errors import UserError
from companion.core.outline import OUTLINE_TOL_M, outline_fault

if TYPE_CHECKING:
    from companion.mission.model import Mission

MAV_CMD_NAV_WAYPOINT = 16


@dataclass(frozen=True)
class PerimeterPoint:
    """One perimeter waypoint: WGS-84 latitude/longitude (deg), altitude above home (m)."""

    lat_deg: float
    lon_deg: float
    alt_m: float


def _check(
    points: list[PerimeterPoint], name: str, where: list[tuple[int | None, str]]
) -> list[PerimeterPoint]:
    """Refuse too few points, non-positions and lists that are not a convex outline.

    ``where`` gives, per point, its 1-based line (or None) and a label such as ``seq 3``.
    """

    def at(i: int) -> str:
        line, label = where[i]
        return f"{name}:{line}: {label}" if line is not None else f"{name}: {label}"

    if len(points) < 3:
        raise UserError(f"{name}: a perimeter needs at least 3 waypoints, found {len(points)}")
    for i, p in enumerate(points):
        if not (
            math.isfinite(p.lat_deg + p.lon_deg + p.alt_m)
            and -90 <= p.lat_deg <= 90
            and -180 <= p.lon_deg <= 180
        ):
            raise UserError(f"{at(i)}: waypoint {p} is not a position")
    o = points[0]
    n, e, _ = pymap3d.geodetic2ned(
        [p.lat_deg for p in points], [p.lon_deg for p in points], o.alt_m,
        o.lat_deg, o.lon_deg, o.alt_m,
    )  # fmt: skip
    fault = outline_fault([complex(a, b) for a, b in zip(n, e, strict=True)])
    if fault is None:
        return points
    if fault.kind == "repeat" and fault.other is not None:  # a repeat names the one it repeats
        problem = (
            f"repeats {where[fault.other][1]} (within {OUTLINE_TOL_M:g} m): list each corner "
            "once, the loop closes by itself"
        )
    elif fault.kind == "dent":
        problem = (
            f"lies {fault.depth_m:.0f} m inside the convex hull of the other waypoints, so the "
            "patrol loop (their rounded hull) would not pass it (expected the corners of a "
            "convex outline: remove it or move it outward)"
        )
    else:
        problem = (
            "is out of order round the outline, so the outline as listed crosses itself "
            "(expected the corners in order round the perimeter, either way)"
        )
    raise UserError(f"{at(fault.index)}: {problem}")


def _plan_item_lines(text: str) -> list[int] | None:
    """1-based line where each entry of ``mission.items`` starts, or None if not found.

    A positional walk of the (already valid) JSON: values are skipped whole by the standard
    decoder, so only the two objects on the way and the items list are stepped through.
    """
    dec = json.JSONDecoder()

    def ws(p: int) -> int:  # past the white space from p (none: p)
        while p < len(text) and text[p] in " \t\n\r":
            p += 1
        return p

    def value_of(p: int, key: str) -> int | None:  # p at "{": start of that key's value
        p = ws(p + 1)
        while text[p] != "}":
            k, p = dec.raw_decode(text, p)
            p = ws(ws(p) + 1)  # past ":"
            if k == key:
                return p
            p = ws(dec.raw_decode(text, p)[1])
            if text[p] == ",":
                p = ws(p + 1)
        return None

    try:
        p = value_of(ws(0), "mission")
        p = value_of(p, "items") if p is not None and text[p] == "{" else None
        if p is None or text[p] != "[":
            return None
        lines = []
        p = ws(p + 1)
        while text[p] != "]":
            lines.append(text.count("\n", 0, p) + 1)
            p = ws(dec.raw_decode(text, p)[1])
            if text[p] == ",":
                p = ws(p + 1)
        return lines
    except (ValueError, IndexError, RecursionError):
        return None


def parse_plan(text: str, name: str = "<plan>") -> list[PerimeterPoint]:
    """NAV_WAYPOINT items of a QGroundControl .plan file."""
    try:
        doc = json.loads(text)
        items = doc["mission"]["items"]
        if not isinstance(items, list):
            raise TypeError
    except json.JSONDecodeError as exc:
        raise UserError(
            f"{name}:{exc.lineno}: not a QGroundControl .plan file ({exc.msg})"
        ) from None
    except (ValueError, KeyError, TypeError, RecursionError):
        raise UserError(f"{name}: not a QGroundControl .plan file (no mission.items)") from None
    found = _plan_item_lines(text)
    item_lines: list[int | None] = [None] * len(items)
    if found is not None and len(found) == len(items):
        item_lines = list(found)
    points = []
    where: list[tuple[int | None, str]] = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or item.get("type") != "SimpleItem":
            continue
        if item.get("command") != MAV_CMD_NAV_WAYPOINT:
            continue
        params: Any = item.get("params")  # JSON: anything; what is not 7 numbers is refused
        try:
            points.append(PerimeterPoint(float(params[4]), float(params[5]), float(params[6])))
        except (TypeError, ValueError, IndexError):
            raise UserError(
                f"{name}: mission item {i} has no latitude/longitude/altitude"
            ) from None
        where.append((item_lines[i], f"mission.items[{i}]"))
    return _check(points, name, where)


def parse_wpl(text: str, name: str = "<waypoints>") -> list[PerimeterPoint]:
    """NAV_WAYPOINT lines of a ``QGC WPL 110`` file (the home line, seq 0, skipped)."""
    lines = [(n, ln) for n, ln in enumerate(text.splitlines(), start=1) if ln.strip()]
    if not lines or not lines[0][1].startswith("QGC WPL 110"):
        raise UserError(f"{name}: not a 'QGC WPL 110' waypoint file")
    points = []
    where: list[tuple[int | None, str]] = []
    for n, ln in lines[1:]:
        f = ln.split("\t") if "\t" in ln else ln.split()
        try:
            seq, command = int(f[0]), int(f[3])
            lat, lon, alt = float(f[8]), float(f[9]), float(f[10])
        except (ValueError, IndexError):
            raise UserError(f"{name}:{n}: expected 12 tab-separated fields") from None
        if seq == 0 or command != MAV_CMD_NAV_WAYPOINT:
            continue
        points.append(PerimeterPoint(lat, lon, alt))
        where.append((n, f"seq {seq}"))
    return _check(points, name, where)


def loop_points(mission: Mission, count: int, alt_m: float) -> list[PerimeterPoint]:
    """The mission's patrol loop as ``count`` points equally spaced in time, at ``alt_m``."""
    o = mission.origin
    pts = mission.patrol.sample_by_time(count)
    lat, lon, _ = pymap3d.ned2geodetic(pts.real, pts.imag, 0.0, o.lat_deg, o.lon_deg, o.alt_m)
    return [PerimeterPoint(float(a), float(b), alt_m) for a, b in zip(lat, lon, strict=True)]
