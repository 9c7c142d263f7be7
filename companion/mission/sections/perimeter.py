"""The mission's ``perimeter`` section (an ellipse or the corners of a convex outline) and
the loop built from it, which must be flyable within the turn-rate limit."""

from __future__ import annotations

import math

import yaml

from companion.core.loops import DEFAULT_EDGE_RADIUS_M, LoopError, LoopShape
from companion.core.outline import OUTLINE_TOL_M, OutlineFault, outline_fault
from companion.mission.errors import MissionError
from companion.mission.model import (
    EllipsePerimeter,
    Mission,
    Perimeter,
    WaypointPerimeter,
)
from companion.mission.sections.origin import Frame
from companion.mission.yamlnodes import MapReader

MAX_WAYPOINTS = 500
FLYABLE_MARGIN = 0.8  # the loop may use at most this fraction of the turn-rate limit


def parse_perimeter(frame: Frame, m: MapReader) -> Perimeter:
    m.done(("sense", "ellipse", "waypoints", "corner_radius_m", "edge_radius_m", "smoothing_deg"))
    sense = m.string("sense", "clockwise", ("clockwise", "counterclockwise"))
    if m.has("ellipse") == m.has("waypoints"):
        raise MissionError(
            frame.file, m.path, "give exactly one of 'ellipse' or 'waypoints'", m.line
        )
    if m.has("ellipse"):
        for key in ("corner_radius_m", "edge_radius_m", "smoothing_deg"):
            if m.has(key):
                raise m.error(key, "only applies to a waypoint perimeter")
        e = m.map("ellipse")
        e.done(("centre", "semi_major_m", "semi_minor_m", "major_axis_bearing_deg"))
        c = e.map("centre") if e.has("centre") else None
        if c is not None:
            c.done(("north_m", "east_m", "lat_deg", "lon_deg"))
        cn, ce = frame.point(c)[:2] if c is not None else (0.0, 0.0)
        shape: EllipsePerimeter | WaypointPerimeter = EllipsePerimeter(
            cn,
            ce,
            e.number("semi_major_m", lo=1.0, hi=100_000.0, what="a length (m)"),
            e.number("semi_minor_m", lo=1.0, hi=100_000.0, what="a length (m)"),
            e.number("major_axis_bearing_deg", 0.0, lo=-360.0, hi=360.0, what="a bearing (deg)"),
        )
    else:
        nodes, pts = frame.waypoints(m, "waypoints", MAX_WAYPOINTS, "WP")
        if len(pts) < 3:
            raise m.error("waypoints", f"expected at least 3 waypoints, got {len(pts)}")
        fault = outline_fault([complex(p.north_m, p.east_m) for p in pts])
        if fault is not None:
            raise outline_error(frame, m.sub("waypoints"), nodes, fault)
        shape = WaypointPerimeter(
            tuple(pts),
            m.number("corner_radius_m", lo=0.0, hi=50_000.0, lo_open=True, what="a radius (m)"),
            m.number(
                "edge_radius_m",
                DEFAULT_EDGE_RADIUS_M,
                lo=0.0,
                hi=1e7,
                lo_open=True,
                what="a radius (m)",
            ),
            m.number("smoothing_deg", 1.0, lo=0.0, hi=10.0, what="an angle (deg)"),
        )
    return Perimeter(shape, clockwise=(sense == "clockwise"))


def outline_error(
    frame: Frame, path: str, nodes: list[yaml.Node], fault: OutlineFault
) -> MissionError:
    """The error naming the waypoint that keeps the list from being a convex outline."""
    line = nodes[fault.index].start_mark.line + 1
    if fault.kind == "repeat" and fault.other is not None:  # a repeat names the one it repeats
        other = nodes[fault.other].start_mark.line + 1
        problem = (
            f"repeats {path}[{fault.other}] (line {other}, within {OUTLINE_TOL_M:g} m): "
            "list each corner once, the loop closes by itself"
        )
    elif fault.kind == "dent":
        problem = (
            f"lies {fault.depth_m:.0f} m inside the convex hull of the other waypoints, "
            "so the patrol loop (their rounded hull) would not pass it (expected the "
            "corners of a convex outline: remove it or move it outward)"
        )
    else:
        problem = (
            "is out of order round the outline, so the outline as listed crosses itself "
            "(expected the corners in order round the perimeter, either way)"
        )
    return MissionError(frame.file, f"{path}[{fault.index}]", problem, line)


def build_loop(top: MapReader, perimeter: Perimeter) -> LoopShape:
    """The perimeter's loop shape; one it cannot make raises the error naming its field."""
    pm = top.map("perimeter")
    try:
        return perimeter.loop()
    except LoopError as exc:
        key = "waypoints" if pm.has("waypoints") else "ellipse"
        if "edge radius" in str(exc):
            key = "edge_radius_m"
        elif "corner radius" in str(exc):
            key = "corner_radius_m"
        raise pm.error(key, str(exc)) from None


def check_flyable(top: MapReader, mission: Mission) -> None:
    """The loop must need at most FLYABLE_MARGIN of the turn-rate limit."""
    pm = top.map("perimeter")
    patrol = mission.patrol
    need = patrol.max_required_turn_rate_rad_s()
    limit = mission.vehicles.max_turn_rate_rad_s
    if need > FLYABLE_MARGIN * limit:
        key = "corner_radius_m" if pm.has("waypoints") else "ellipse"
        hint = ""
        if pm.has("waypoints"):
            s0, b = mission.vehicles.airspeed_m_s, mission.wind.speed_m_s
            r_min = (s0 + b) ** 2 / (s0 * FLYABLE_MARGIN * limit)
            hint = f"; use a corner radius of at least {math.ceil(r_min)} m"
        raise pm.error(
            key,
            f"the loop needs turn rates up to {math.degrees(need):.1f} deg/s in this wind, "
            f"more than {FLYABLE_MARGIN:.0%} of the {math.degrees(limit):g} deg/s limit "
            f"(vehicles.max_turn_rate_deg_s){hint}",
        )
