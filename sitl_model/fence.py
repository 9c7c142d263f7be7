"""The simulated autopilot's geofence (pure): stored FENCE items in, breaches out.

ArduPilot's model, as far as this simulator honours it:

* the fence is uploaded with the mission protocol, ``mission_type`` FENCE (1): inclusion
  polygons are runs of ``MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`` (5001) items whose
  ``param1`` is the run's vertex count, lat/lon in ``x``/``y`` (degE7). Exclusion polygons,
  circles (5002-5004) and the return point (5000) are stored and returned but not enforced;
* parameters (fleet-wide, :mod:`sitl_model.params`): ``FENCE_ENABLE`` (0/1),
  ``FENCE_TYPE`` bitmask (1 = max altitude, 4 = polygon, 8 = min altitude; 2 = circle is not
  modelled), ``FENCE_ACTION`` (0 = report only, 1 = RTL), ``FENCE_ALT_MIN`` and
  ``FENCE_ALT_MAX`` (m above home);
* a vehicle is breached when it is outside every inclusion polygon (with at least one
  stored) or outside the altitude band; a new breach is reported once, and the action taken
  once, until the vehicle is back inside.

Conventions: positions complex ``north + i east`` (m) in the simulator's local frame.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from companion.core.fence import point_in_polygon, polygon_fault

FENCE_RETURN_POINT = 5000
FENCE_VERTEX_INCLUSION = 5001
FENCE_VERTEX_EXCLUSION = 5002
FENCE_CIRCLE_INCLUSION = 5003
FENCE_CIRCLE_EXCLUSION = 5004
FENCE_COMMANDS = frozenset(range(5000, 5005))
FENCE_TYPE_ALT_MAX = 1
FENCE_TYPE_POLYGON = 4
FENCE_TYPE_ALT_MIN = 8


def fence_fault(items: Sequence) -> str | None:
    """Why a FENCE upload (items with ``command``, ``param1``) is invalid, or None.

    Every item must be a fence command; polygon vertices come in runs of ``param1`` items
    of one command with ``param1`` >= 3.
    """
    i = 0
    while i < len(items):
        it = items[i]
        if it.command not in FENCE_COMMANDS:
            return f"item {i}: command {it.command} is not a fence item"
        if it.command in (FENCE_VERTEX_INCLUSION, FENCE_VERTEX_EXCLUSION):
            n = int(it.param1)
            if n < 3 or float(it.param1) != n:
                return f"item {i}: vertex count {it.param1:g} (expected at least 3)"
            run = items[i : i + n]
            if len(run) < n or any(r.command != it.command or r.param1 != it.param1 for r in run):
                return f"item {i}: polygon of {n} vertices is incomplete"
            i += n
        else:
            i += 1
    return None


def inclusion_polygons(
    items: Sequence, to_local: Callable[[float, float], complex]
) -> list[np.ndarray]:
    """The inclusion polygons (complex m) of valid stored FENCE items; ``to_local(lat_deg,
    lon_deg)`` maps a vertex into the local frame. Degenerate polygons are skipped."""
    out: list[np.ndarray] = []
    i = 0
    while i < len(items):
        it = items[i]
        if it.command in (FENCE_VERTEX_INCLUSION, FENCE_VERTEX_EXCLUSION):
            n = int(it.param1)
            if it.command == FENCE_VERTEX_INCLUSION:
                poly = np.array([to_local(r.x * 1e-7, r.y * 1e-7) for r in items[i : i + n]])
                if polygon_fault(poly) is None:
                    out.append(poly)
            i += max(n, 1)
        else:
            i += 1
    return out


def breaches(
    pos_m: np.ndarray,
    alt_m: np.ndarray,
    polygons: Sequence[Sequence[np.ndarray]],
    alt_min_m: float,
    alt_max_m: float,
    fence_type: int,
) -> list[str | None]:
    """What each vehicle breaches: "polygon", "max_alt", "min_alt" or None.

    Args:
        pos_m: positions (complex m), one per vehicle.
        alt_m: altitudes above home (m), one per vehicle.
        polygons: each vehicle's inclusion polygons (none: no horizontal fence).
        alt_min_m, alt_max_m: the altitude band (m above home).
        fence_type: the FENCE_TYPE bitmask.
    """
    pos = np.asarray(pos_m)
    inside = _inside(pos, polygons) if fence_type & FENCE_TYPE_POLYGON else None
    out: list[str | None] = []
    for i, (a, polys) in enumerate(zip(np.asarray(alt_m).tolist(), polygons, strict=True)):
        kind = None
        if inside is not None and polys and not inside[i]:
            kind = "polygon"
        if kind is None and fence_type & FENCE_TYPE_ALT_MAX and a > alt_max_m:
            kind = "max_alt"
        if kind is None and fence_type & FENCE_TYPE_ALT_MIN and a < alt_min_m:
            kind = "min_alt"
        out.append(kind)
    return out


def _inside(pos_m: np.ndarray, polygons: Sequence[Sequence[np.ndarray]]) -> list[bool]:
    """Whether each vehicle is inside one of its inclusion polygons (True without any).
    Vehicles holding the same polygons (every vehicle of a fleet, uploaded one by one) are
    tested together, one call per polygon."""
    groups: dict[tuple[bytes, ...], list[int]] = {}
    for i, polys in enumerate(polygons):
        groups.setdefault(tuple(np.asarray(p).tobytes() for p in polys), []).append(i)
    inside = [True] * len(polygons)
    for key, members in groups.items():
        if not key:
            continue
        points = pos_m[members]
        hit = np.zeros(len(members), dtype=bool)
        for poly in polygons[members[0]]:
            hit |= point_in_polygon(points, poly)
        for i, h in zip(members, hit.tolist(), strict=True):
            inside[i] = h
    return inside
