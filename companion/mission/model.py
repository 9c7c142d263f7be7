"""Typed, frozen mission model (YAML version 1).

Positions are local north/east metres from the mission origin (the YAML may give lat/lon;
the loader converts them). Angles at this edge are degrees with the unit in the name; the
methods that feed the pure core return radians and :class:`companion.core` objects.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np

from companion.core.fence import Fence
from companion.core.guarantee import CrossingGuarantee, crossing_guarantee
from companion.core.loops import EllipseLoop, LoopShape, SmoothLoop, rounded_hull
from companion.core.patrol import Patrol
from companion.core.wind import Wind
from companion.guidance.steering import CentreForm, Gains

IntruderKind = Literal["static", "moving", "decoy", "path"]
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


MAX_INTRUDER_SPEED_M_S = 60.0  # the fastest leg of a path intruder (m/s)
ZERO_LEG_M = 0.01  # a leg shorter than this (m) has no length: it is a wait where it is


@dataclass(frozen=True)
class Leg:
    """One leg of a path intruder: straight from the point before (m) to this one at
    ``speed_m_s`` (m/s, > 0), then ``wait_s`` (s, >= 0) there before the next leg.

    Attributes:
        north_m, east_m: the point the leg ends at (local m).
        speed_m_s: ground speed along the leg (m/s).
        wait_s: how long it stays at the point once there (s).
    """

    north_m: float
    east_m: float
    speed_m_s: float
    wait_s: float = 0.0

    @property
    def point_m(self) -> complex:
        """The leg's end point (complex m)."""
        return complex(self.north_m, self.east_m)


@dataclass(frozen=True)
class Intruder:
    """A scheduled intruder.

    Attributes:
        id: unique name.
        kind: "static", "moving" (constant velocity), "decoy" (vanishes once seen) or "path"
            (straight legs in turn, each at its own speed, with waits).
        appear_t_s: time it appears (s, simulated).
        north_m, east_m: position when it appears (m).
        velocity_north_m_s, velocity_east_m_s: ground velocity (m/s), moving kind only.
        vanish_t_s: absolute time it vanishes (s), or None.
        vanish_after_detection_s: a decoy vanishes this long after it is first detected (s).
        path: the legs of a path intruder, in order from where it appears (empty for the
            other kinds). It leaves at ``appear_t_s``; after its last leg it stays at the
            last point (until ``vanish_t_s``, if any).

    Motion (:meth:`position_m`, :meth:`velocity_at_m_s`) is exact: constant velocity from
    ``appear_t_s`` for the first three kinds; piecewise linear through the knots of
    :attr:`knots` for a path (a leg of length ``d`` takes ``d / speed_m_s`` s, then its
    ``wait_s``). Before it appears it is where it appears.
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
    path: tuple[Leg, ...] = ()

    @cached_property
    def knots(self) -> tuple[tuple[float, ...], tuple[complex, ...]]:
        """A path's schedule: the knot times (s, non-decreasing; a wait is two knots at one
        point) and points (complex m), from ``(appear_t_s, start)`` to the end of its last
        leg's wait. For the other kinds one knot, where and when it appears."""
        times, points = [self.appear_t_s], [complex(self.north_m, self.east_m)]
        for leg in self.path:
            here, there = points[-1], leg.point_m
            d = abs(there - here)
            if d >= ZERO_LEG_M:
                times.append(times[-1] + d / leg.speed_m_s)
                points.append(there)
            if leg.wait_s > 0:
                times.append(times[-1] + leg.wait_s)
                points.append(points[-1])
        return tuple(times), tuple(points)

    @property
    def path_end_t_s(self) -> float:
        """When a path intruder is at its last point with its last wait over (s); for the
        other kinds ``appear_t_s``."""
        return self.knots[0][-1]

    def _segment(self, t_s: float) -> int:
        """The knot index ``j`` with ``times[j] <= t_s < times[j + 1]`` (a path only), -1
        before it leaves, the last knot after its path ends."""
        return bisect.bisect_right(self.knots[0], t_s) - 1

    def position_m(self, t_s: float) -> complex:
        """Position at time ``t_s`` (complex m), ignoring whether it is present."""
        if self.kind != "path":
            dt = max(0.0, t_s - self.appear_t_s)
            return complex(
                self.north_m + self.velocity_north_m_s * dt,
                self.east_m + self.velocity_east_m_s * dt,
            )
        times, points = self.knots
        j = self._segment(t_s)
        if j < 0:
            return points[0]
        if j >= len(times) - 1:
            return points[-1]
        f = (t_s - times[j]) / (times[j + 1] - times[j])
        return points[j] + f * (points[j + 1] - points[j])

    def positions_m(self, t_s: np.ndarray) -> np.ndarray:
        """Positions at the times ``t_s`` (s, any shape): complex m, the same values as
        :meth:`position_m` at each, vectorised."""
        t = np.asarray(t_s, dtype=float)
        if self.kind != "path":
            dt = np.maximum(0.0, t - self.appear_t_s)
            return (self.north_m + self.velocity_north_m_s * dt) + 1j * (
                self.east_m + self.velocity_east_m_s * dt
            )
        times, points = self.knots
        z = np.asarray(points, dtype=complex)
        return np.interp(t, times, z.real) + 1j * np.interp(t, times, z.imag)

    def velocity_at_m_s(self, t_s: float) -> complex:
        """Ground velocity at time ``t_s`` (complex m/s): a path's leg velocity, 0 while it
        waits, before it leaves and after its last leg (at a knot, the segment that starts
        there)."""
        if self.kind != "path":
            return complex(self.velocity_north_m_s, self.velocity_east_m_s)
        times, points = self.knots
        j = self._segment(t_s)
        if j < 0 or j >= len(times) - 1:
            return 0j
        return (points[j + 1] - points[j]) / (times[j + 1] - times[j])

    @property
    def velocity_m_s(self) -> complex:
        """Ground velocity when it appears (complex m/s): a moving intruder's constant
        velocity; for a path see :meth:`velocity_at_m_s`."""
        return self.velocity_at_m_s(self.appear_t_s)

    @property
    def max_speed_m_s(self) -> float:
        """Its fastest ground speed (m/s): a path's fastest leg with a length."""
        return self.max_speed_between_m_s(-math.inf, math.inf)

    def max_speed_between_m_s(self, t0_s: float, t1_s: float) -> float:
        """Its fastest ground speed (m/s) at any time in ``[t0_s, t1_s]`` (s): exact, over
        the legs of a path under way then (0 if it only waits); constant for the others."""
        if self.kind != "path":
            return abs(complex(self.velocity_north_m_s, self.velocity_east_m_s))
        times, points = self.knots
        return max(
            (
                abs(points[j + 1] - points[j]) / (times[j + 1] - times[j])
                for j in range(len(times) - 1)
                if times[j + 1] > times[j] and times[j] <= t1_s and times[j + 1] >= t0_s
            ),
            default=0.0,
        )

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

    def crossing_guarantee(self, away: int = 0, vehicles: int | None = None) -> CrossingGuarantee:
        """The fastest crossing of the sensor band this patrol is sure to see
        (:mod:`companion.core.guarantee`): ``vehicles`` UAVs on the loop (default the
        mission's N), ``away`` of them away, on its loop at its airspeed in its wind, with
        its sensor.

        Raises:
            ValueError: not ``0 <= away < vehicles``.
        """
        return crossing_guarantee(
            self.patrol.period_s,
            self.vehicles.count if vehicles is None else vehicles,
            self.sensor.footprint_radius_m,
            self.vehicles.airspeed_m_s,
            self.wind.speed_m_s,
            away=away,
        )

    def crossing_guarantees(self, most_away: int = 2) -> list[CrossingGuarantee]:
        """:meth:`crossing_guarantee` with 0, 1, ... ``most_away`` UAVs away (fewer for a
        smaller formation: one at least stays on the loop)."""
        return [
            self.crossing_guarantee(k) for k in range(min(most_away, self.vehicles.count - 1) + 1)
        ]


CENTRE_FORMS: tuple[CentreForm, ...] = ("fixed", "mean")
INTRUDER_KINDS: tuple[IntruderKind, ...] = ("static", "moving", "decoy", "path")
