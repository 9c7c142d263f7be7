"""Typed, frozen mission model (YAML version 1).

Positions are local north/east metres from the mission origin (the YAML may give lat/lon;
the loader converts them). Angles at this edge are degrees with the unit in the name; the
methods that feed the pure core return radians and :class:`companion.core` objects.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from companion.core.fence import Fence
from companion.core.loops import EllipseLoop, LoopShape, SmoothLoop, rounded_hull
from companion.core.patrol import Patrol
from companion.core.wind import Wind
from companion.guidance.steering import CentreForm, Gains

IntruderKind = Literal["static", "moving", "decoy"]
SpareWait = Literal["ground", "holding"]


@dataclass(frozen=True)
class Origin:
    """Mission origin: the local tangent plane's reference point (WGS-84)."""

    lat_deg: float
    lon_deg: float
    alt_m: float


@dataclass(frozen=True)
class Waypoint:
    """A perimeter landmark, local (m) and, when given that way, geodetic (deg)."""

    name: str
    north_m: float
    east_m: float
    lat_deg: float | None = None
    lon_deg: float | None = None


@dataclass(frozen=True)
class EllipsePerimeter:
    """Ellipse: centre (m), semi-axis along ``major_axis_bearing_deg`` and across (m)."""

    centre_north_m: float
    centre_east_m: float
    semi_major_m: float
    semi_minor_m: float
    major_axis_bearing_deg: float = 0.0


@dataclass(frozen=True)
class WaypointPerimeter:
    """Rounded convex hull of landmarks: corner radius ``r_c``, edge arc radius ``R0`` (m), and
    the course-smoothing of the curvature (deg; 0 keeps the C1 hull, see ``SmoothLoop``)."""

    waypoints: tuple[Waypoint, ...]
    corner_radius_m: float
    edge_radius_m: float
    smoothing_deg: float = 1.0


@dataclass(frozen=True)
class Perimeter:
    """The patrol loop and its sense of travel."""

    shape: EllipsePerimeter | WaypointPerimeter
    clockwise: bool = True

    def loop(self) -> LoopShape:
        """The loop shape for the pure core (world frame)."""
        s = self.shape
        if isinstance(s, EllipsePerimeter):
            return EllipseLoop(
                complex(s.centre_north_m, s.centre_east_m),
                s.semi_major_m,
                s.semi_minor_m,
                float(np.radians(s.major_axis_bearing_deg)),
            )
        pts = np.array([complex(w.north_m, w.east_m) for w in s.waypoints])
        hull = rounded_hull(pts, s.corner_radius_m, s.edge_radius_m)
        if s.smoothing_deg > 0:
            return SmoothLoop.of(hull, float(np.radians(s.smoothing_deg)))
        return hull


@dataclass(frozen=True)
class WindSpec:
    """Steady wind: speed (m/s), the direction it blows FROM (deg), optional gusts (m/s rms)."""

    speed_m_s: float
    from_deg: float
    gust_std_m_s: float = 0.0

    def wind(self) -> Wind:
        """As a core :class:`Wind`."""
        return Wind.from_meteo(self.speed_m_s, self.from_deg)


@dataclass(frozen=True)
class Pose:
    """A vehicle's initial pose: local position (m) and air heading (deg)."""

    north_m: float
    east_m: float
    heading_deg: float


@dataclass(frozen=True)
class Battery:
    """A battery as the mission plans with it (docs/energy.md).

    Attributes:
        capacity_mah: capacity (mAh).
        reserve_pct: charge still in it at landing (% of the capacity).
        endurance_min: level flight at the cruise airspeed from full to 0 % (min); given, or
            worked out from ``cruise_current_a``.
        voltage_v: the full pack's voltage at rest (V).
        cruise_current_a: the current at cruise (A) when that is how the file gave the
            consumption, else None.
    """

    capacity_mah: float
    reserve_pct: float
    endurance_min: float
    voltage_v: float = 12.6
    cruise_current_a: float | None = None

    @property
    def usable_min(self) -> float:
        """Flight time before the reserve (min): ``endurance_min (1 - reserve_pct / 100)``."""
        return self.endurance_min * (1.0 - self.reserve_pct / 100.0)

    @property
    def reserve_mah(self) -> float:
        """The reserve (mAh)."""
        return self.capacity_mah * self.reserve_pct / 100.0


SPARE_ALT_STEP_M = 10.0  # spares fly at least this far apart, above the patrol (m)


@dataclass(frozen=True)
class Spare:
    """A UAV that is not on the patrol at the start and waits to relieve one.

    Attributes:
        sysid: its MAVLink system id (distinct from the patrol's and the other spares').
        waits: "ground" (on its launch point, where it also recharges) or "holding"
            (loitering in the air at its holding point; it recharges at home, the origin).
        north_m, east_m: where it waits (m from the origin).
        alt_m: the holding altitude (m above the origin); None on the ground.
        turnaround_s: from landing to ready again with a full battery (s).
        battery: its own battery, or None for the fleet's (``Vehicles.battery``).
        heading_deg: on the ground, the way it faces and takes off (its runway; deg from
            North, default North).
    """

    sysid: int
    waits: SpareWait
    north_m: float
    east_m: float
    alt_m: float | None
    turnaround_s: float
    battery: Battery | None = None
    heading_deg: float = 0.0

    @property
    def base_m(self) -> complex:
        """Where it lands and recharges (m): its launch point, or home for a holding spare."""
        return complex(self.north_m, self.east_m) if self.waits == "ground" else 0j


@dataclass(frozen=True)
class Vehicles:
    """The fleet.

    Attributes:
        count: number of vehicles N.
        sysids: MAVLink system id of each vehicle.
        airspeed_m_s: airspeed (m/s).
        max_turn_rate_deg_s: turn-rate limit (deg/s).
        altitudes_m: altitude of each vehicle above the origin (m).
        initial: initial pose of each vehicle.
        battery: the patrol UAVs' battery (and the spares' unless they have their own), or
            None: no battery section, nothing about energy is checked.
        spares: the UAVs waiting to relieve the patrol.
        altitude_step_m: the step between the patrol's altitudes (m); the spares continue
            the ladder above them (:meth:`altitude_m`).
        opening: how the patrol UAVs' first stints end (docs/energy.md, "The opening"):
            ``battery`` (each leaves when its battery says) or ``staggered`` (the last in
            ``sysids`` order when its battery says, each one before it one ``beat / N``
            earlier, so that a fleet that starts full starts the rotation spaced).
    """

    count: int
    sysids: tuple[int, ...]
    airspeed_m_s: float
    max_turn_rate_deg_s: float
    altitudes_m: tuple[float, ...]
    initial: tuple[Pose, ...]
    battery: Battery | None = None
    spares: tuple[Spare, ...] = ()
    altitude_step_m: float = 0.0
    opening: str = "battery"

    def altitude_m(self, sysid: int) -> float:
        """The altitude ``sysid`` flies at on the patrol (m above the origin): a patrol UAV
        its own; spare ``k`` (0, 1, ... in the mission's order) ``k + 1`` steps above the
        highest patrol UAV, the step being ``altitude_step_m`` or at least
        :data:`SPARE_ALT_STEP_M`, so that no spare shares an altitude with any other
        aircraft of the fleet (it flies in across the loop, beside the UAV it relieves). A
        sysid that is neither: the first altitude."""
        if sysid in self.sysids:
            return self.altitudes_m[self.sysids.index(sysid)]
        ids = [sp.sysid for sp in self.spares]
        if sysid in ids:
            step = max(self.altitude_step_m, SPARE_ALT_STEP_M)
            return max(self.altitudes_m) + (ids.index(sysid) + 1) * step
        return self.altitudes_m[0]

    @property
    def all_sysids(self) -> tuple[int, ...]:
        """Every vehicle's system id, the patrol's then the spares' in the mission's order:
        the simulator's vehicle order (``sitl_model.assembly``), so vehicle ``i`` of this
        tuple is the one on ``base_port + PORT_SPACING * i``."""
        return self.sysids + tuple(sp.sysid for sp in self.spares)

    def all_altitudes_m(self) -> tuple[float, ...]:
        """Every altitude the fleet flies on the patrol, spares included (m above origin)."""
        return self.altitudes_m + tuple(self.altitude_m(sp.sysid) for sp in self.spares)

    @property
    def max_turn_rate_rad_s(self) -> float:
        """Turn-rate limit (rad/s)."""
        return float(np.radians(self.max_turn_rate_deg_s))


@dataclass(frozen=True)
class Sensor:
    """Downward sensor: a disc of ``footprint_radius_m`` (m) under the vehicle."""

    footprint_radius_m: float


@dataclass(frozen=True)
class Intruder:
    """A scheduled intruder.

    Attributes:
        id: unique name.
        kind: "static", "moving" (constant velocity) or "decoy" (vanishes once seen).
        appear_t_s: time it appears (s, simulated).
        north_m, east_m: position when it appears (m).
        velocity_north_m_s, velocity_east_m_s: ground velocity (m/s), moving kind only.
        vanish_t_s: absolute time it vanishes (s), or None.
        vanish_after_detection_s: a decoy vanishes this long after it is first detected (s).
    """

    id: str
    kind: IntruderKind
    appear_t_s: float
    north_m: float
    east_m: float
    velocity_north_m_s: float = 0.0
    velocity_east_m_s: float = 0.0
    vanish_t_s: float | None = None
    vanish_after_detection_s: float | None = None

    def position_m(self, t_s: float) -> complex:
        """Position at time ``t_s`` (complex m), ignoring whether it is present."""
        dt = max(0.0, t_s - self.appear_t_s)
        return complex(
            self.north_m + self.velocity_north_m_s * dt, self.east_m + self.velocity_east_m_s * dt
        )

    @property
    def velocity_m_s(self) -> complex:
        """Ground velocity (complex m/s)."""
        return complex(self.velocity_north_m_s, self.velocity_east_m_s)

    def present(self, t_s: float, first_detected_t_s: float | None = None) -> bool:
        """Whether it exists at ``t_s`` (s), given when it was first detected (s) if ever."""
        if t_s < self.appear_t_s:
            return False
        if self.vanish_t_s is not None and t_s >= self.vanish_t_s:
            return False
        return not (
            self.vanish_after_detection_s is not None
            and first_detected_t_s is not None
            and t_s >= first_detected_t_s + self.vanish_after_detection_s
        )


@dataclass(frozen=True)
class FenceSpec:
    """The mission's geofence: an inclusion polygon and an altitude band.

    Attributes:
        vertices: the polygon's vertices in order (local m; lat/lon kept when given so).
        min_alt_m, max_alt_m: the altitude band (m above the origin, i.e. home).
        margin_m: room added beyond the turn-derived offset of a default polygon (m).
        explicit: the polygon was given in the file (else derived from the loop).
    """

    vertices: tuple[Waypoint, ...]
    min_alt_m: float
    max_alt_m: float
    margin_m: float
    explicit: bool

    @property
    def fence(self) -> Fence:
        """As a core :class:`Fence` (local polygon)."""
        return Fence(
            tuple(complex(v.north_m, v.east_m) for v in self.vertices),
            self.min_alt_m,
            self.max_alt_m,
        )


@dataclass(frozen=True)
class Mission:
    """A whole mission, as read from one YAML file."""

    path: str
    name: str
    description: str
    origin: Origin
    perimeter: Perimeter
    wind: WindSpec
    vehicles: Vehicles
    gains: Gains
    sensor: Sensor
    intruders: tuple[Intruder, ...]
    duration_s: float
    fence: FenceSpec | None = None  # always set by the loader; None: no fence

    @cached_property
    def patrol(self) -> Patrol:
        """The patrol loop with its time-phase tables (built once)."""
        return Patrol.build(
            self.perimeter.loop(),
            self.vehicles.airspeed_m_s,
            self.wind.wind(),
            clockwise=self.perimeter.clockwise,
        )


CENTRE_FORMS: tuple[CentreForm, ...] = ("fixed", "mean")
INTRUDER_KINDS: tuple[IntruderKind, ...] = ("static", "moving", "decoy")
