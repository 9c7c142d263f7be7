"""The mission's ``origin`` section, and the points given relative to it.

Every point of a mission (a waypoint, an ellipse's centre, a pose, a spare's place, an
intruder, a fence vertex) is given either as ``north_m``/``east_m`` in the local NED frame
at the origin or as ``lat_deg``/``lon_deg``; :meth:`Frame.point` reads both.
"""

from __future__ import annotations

from dataclasses import dataclass

import pymap3d
import yaml

from companion.mission.errors import MissionError
from companion.mission.model import Origin, Waypoint
from companion.mission.yamlnodes import MapReader

MAX_DISTANCE_M = 200_000.0


def parse_origin(m: MapReader) -> Origin:
    m.done(("lat_deg", "lon_deg", "alt_m"))
    return Origin(
        m.number("lat_deg", lo=-89.0, hi=89.0, what="a latitude (deg)"),
        m.number("lon_deg", lo=-180.0, hi=180.0, what="a longitude (deg)"),
        m.number("alt_m", 0.0, lo=-500.0, hi=9000.0, what="an altitude (m)"),
    )


@dataclass(frozen=True)
class Frame:
    """Where the sections are read: the file (for errors) and the mission's origin."""

    file: str
    origin: Origin

    def point(self, m: MapReader) -> tuple[float, float, float | None, float | None]:
        """north, east (m) of a point given as north_m/east_m or lat_deg/lon_deg."""
        local = m.has("north_m") or m.has("east_m")
        geo = m.has("lat_deg") or m.has("lon_deg")
        if local and geo:
            raise MissionError(
                self.file, m.path, "give either north_m/east_m or lat_deg/lon_deg, not both", m.line
            )
        if geo:
            lat = m.number("lat_deg", lo=-89.0, hi=89.0, what="a latitude (deg)")
            lon = m.number("lon_deg", lo=-180.0, hi=180.0, what="a longitude (deg)")
            o = self.origin
            n, e, _ = pymap3d.geodetic2ned(lat, lon, o.alt_m, o.lat_deg, o.lon_deg, o.alt_m)
            if max(abs(n), abs(e)) > MAX_DISTANCE_M:
                raise MissionError(
                    self.file,
                    m.path,
                    f"point is more than {MAX_DISTANCE_M:g} m from the origin",
                    m.line,
                )
            return float(n), float(e), lat, lon
        d = MAX_DISTANCE_M
        return (
            m.number("north_m", lo=-d, hi=d, what="a distance (m)"),
            m.number("east_m", lo=-d, hi=d, what="a distance (m)"),
            None,
            None,
        )

    def waypoints(
        self, m: MapReader, key: str, limit: int, prefix: str
    ) -> tuple[list[yaml.Node], list[Waypoint]]:
        """The list of named points at ``key`` (at most ``limit``; unnamed ones are
        ``prefix`` 1, 2, ...), with its nodes for errors that name a line."""
        nodes = m.seq(key, limit)
        points = []
        for i, node in enumerate(nodes):
            w = MapReader.of(node, self.file, f"{m.sub(key)}[{i}]")
            w.done(("name", "north_m", "east_m", "lat_deg", "lon_deg"))
            n, e, lat, lon = self.point(w)
            points.append(Waypoint(w.string("name", f"{prefix}{i + 1}"), n, e, lat, lon))
        return nodes, points
