"""The mission's ``fence`` section: the geofence given, or the default grown round the loop
(docs/geofence.md)."""

from __future__ import annotations

import math

import numpy as np

from companion.core.fence import polygon_fault, signed_distance_m, support_polygon
from companion.mission.errors import MissionError
from companion.mission.model import FenceSpec, Mission, Waypoint
from companion.mission.sections.origin import Frame
from companion.mission.yamlnodes import MapReader

MAX_FENCE_VERTICES = 100
DEFAULT_FENCE_MARGIN_M = 150.0  # how far outside the loop alerts can still be served
FENCE_ALT_MARGIN_M = 50.0  # default band: the fleet's altitudes -/+ this
FENCE_LOOP_SAMPLES = 720  # loop points checked against the fence


def parse_fence(frame: Frame, top: MapReader, mission: Mission) -> FenceSpec:
    """The geofence: the ``fence`` section, or the default derived from the loop.

    Default polygon: the loop and the initial positions, grown by
    ``max(2 r, r_s) + margin_m`` where ``r = (s0 + wind) / omega_max`` is the turn radius
    at the fastest ground speed and ``r_s`` the sensor radius. A polygon given in the file
    must be simple and keep every loop point at least ``r`` inside, with every initial
    position inside. Default altitude band: the fleet's altitudes (spares included) -/+
    :data:`FENCE_ALT_MARGIN_M` (never below 0).
    """
    m = top.map("fence") if top.has("fence") else None
    if m is not None:
        m.done(("polygon", "margin_m", "min_alt_m", "max_alt_m"))
    margin = DEFAULT_FENCE_MARGIN_M
    if m is not None:
        margin = m.number("margin_m", margin, lo=0.0, hi=100_000.0, what="a distance (m)")
    alts = mission.vehicles.all_altitudes_m()
    lo_alt, hi_alt = max(0.0, min(alts) - FENCE_ALT_MARGIN_M), max(alts) + FENCE_ALT_MARGIN_M
    if m is not None:
        what = "an altitude (m above the origin)"
        lo_alt = m.number("min_alt_m", lo_alt, lo=-500.0, hi=20_000.0, what=what)
        hi_alt = m.number("max_alt_m", hi_alt, lo=-500.0, hi=20_000.0, what=what)
        if hi_alt <= lo_alt:
            raise m.error("max_alt_m", f"must be above min_alt_m ({lo_alt:g} m)")
        if min(alts) < lo_alt or max(alts) > hi_alt:
            key = "min_alt_m" if min(alts) < lo_alt else "max_alt_m"
            raise m.error(
                key,
                f"the vehicles fly at {min(alts):g} to {max(alts):g} m, outside the "
                f"fence's {lo_alt:g} to {hi_alt:g} m (expected a band around them)",
            )
    v, patrol = mission.vehicles, mission.patrol
    turn_r = (v.airspeed_m_s + mission.wind.speed_m_s) / v.max_turn_rate_rad_s
    loop = patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, FENCE_LOOP_SAMPLES, False))
    starts = np.array([complex(p.north_m, p.east_m) for p in v.initial])
    if m is None or not m.has("polygon"):
        offset = max(2.0 * turn_r, mission.sensor.footprint_radius_m) + margin
        poly = support_polygon(np.concatenate([loop, starts]), offset)
        verts = tuple(
            Waypoint(f"F{i + 1}", float(z.real), float(z.imag)) for i, z in enumerate(poly)
        )
        return FenceSpec(verts, lo_alt, hi_alt, margin, explicit=False)
    nodes, verts_l = frame.waypoints(m, "polygon", MAX_FENCE_VERTICES, "F")
    poly = np.array([complex(w.north_m, w.east_m) for w in verts_l])
    fault = polygon_fault(poly)
    if fault is not None:
        index, problem = fault
        if len(nodes) < 3:
            raise m.error("polygon", problem)
        line = nodes[index].start_mark.line + 1
        raise MissionError(frame.file, f"{m.sub('polygon')}[{index}]", problem, line)
    room = signed_distance_m(loop, poly)
    k = int(np.argmin(room))
    if room[k] < turn_r:
        where = "inside" if room[k] >= 0 else "outside"
        raise m.error(
            "polygon",
            f"the patrol loop passes {abs(room[k]):.0f} m {where} the fence at north "
            f"{loop[k].real:.0f}, east {loop[k].imag:.0f} m (expected a polygon around the "
            f"loop with at least {math.ceil(turn_r)} m of room: one turn radius, "
            "(airspeed + wind) / max turn rate)",
        )
    inside = signed_distance_m(starts, poly) > 0
    if not inside.all():
        j = int(np.flatnonzero(~inside)[0])
        raise m.error(
            "polygon",
            f"vehicle {j + 1} starts outside the fence, at north {starts[j].real:.0f}, "
            f"east {starts[j].imag:.0f} m (vehicles.initial)",
        )
    return FenceSpec(tuple(verts_l), lo_alt, hi_alt, margin, explicit=True)
