"""The live page's fixed picture of a mission (pure): the loop, the base's outline, the
sensor, the period, the vehicles and spares, in local metres (north, east) from the origin,
as ``GET /api/mission`` serves it (:mod:`companion.dashboard.server`). The moving picture is
:class:`companion.dashboard.model.FleetView`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from companion.mission import Mission

__all__ = ["Geometry"]


@dataclass(frozen=True)
class Geometry:
    """The mission's fixed picture, in local metres (north, east) from the origin."""

    name: str
    origin: dict[str, float]
    loop: list[tuple[float, float]]
    outline: list[tuple[float, float]]
    outline_kind: str  # "ellipse" or "waypoints"
    centre: tuple[float, float]
    sensor_m: float
    period_s: float
    length_m: float
    vehicles: list[int]
    spares: list[dict[str, Any]] = field(default_factory=list)  # sysid, waits, north_m, east_m

    @classmethod
    def of(cls, mission: Mission, points: int = 720) -> Geometry:
        """The geometry of ``mission``: the loop sampled at ``points`` points by time."""
        patrol = mission.patrol
        loop = patrol.sample_by_time(points)
        shape = mission.perimeter.shape
        if hasattr(shape, "waypoints"):
            outline = [(w.north_m, w.east_m) for w in shape.waypoints]
            kind = "waypoints"
        else:
            outline = [(float(z.real), float(z.imag)) for z in loop]
            kind = "ellipse"
        o = mission.origin
        c0 = patrol.centre_m
        return cls(
            name=mission.name,
            origin={"lat_deg": o.lat_deg, "lon_deg": o.lon_deg, "alt_m": o.alt_m},
            loop=[(round(float(z.real), 2), round(float(z.imag), 2)) for z in loop],
            outline=[(round(n, 2), round(e, 2)) for n, e in outline],
            outline_kind=kind,
            centre=(round(c0.real, 2), round(c0.imag, 2)),
            sensor_m=float(mission.sensor.footprint_radius_m),
            period_s=float(patrol.period_s),
            length_m=float(patrol.length_m),
            vehicles=list(mission.vehicles.sysids),
            spares=[
                {"sysid": sp.sysid, "waits": sp.waits, "north_m": sp.north_m, "east_m": sp.east_m}
                for sp in mission.vehicles.spares
            ],
        )

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict (lists of ``[north_m, east_m]``)."""
        return {
            "name": self.name,
            "origin": self.origin,
            "loop": [list(p) for p in self.loop],
            "outline": [list(p) for p in self.outline],
            "outline_kind": self.outline_kind,
            "centre": list(self.centre),
            "sensor_m": self.sensor_m,
            "period_s": self.period_s,
            "length_m": self.length_m,
            "vehicles": self.vehicles,
            "spares": self.spares,
        }
