"""Searching a track's uncertainty (pure): where the intruder was not under the sensor at the
intercept, the prosecutor flies an outward spiral over the predicted region before it gives up
("cleared" where the spiral covered the region, else "lost": ``prosecution.py``).

The spiral is drawn in the frame that moves with the track (its centre is the predicted
position, ``Track.predict``), from one footprint radius out, one swath (``SWATH_FRACTION`` of
the footprint's diameter) between turns, its waypoints about two turn radii apart so a
turn-rate-limited aircraft can fly from one to the next. The search is done when the spiral
has covered ``SEARCH_SIGMAS`` sigma of the prediction (which grows with the track's
velocity error), once its sweep can no longer catch up with the region, or after
``max_s``, whichever is first: a bounded time away from the loop.

Outpaced. The region searched is a disc of radius ``k sigma(t)`` (``k = SEARCH_SIGMAS``), its
area ``A(t) = pi k^2 (p^2 + (v (t - t_track))^2)`` growing faster every second. The footprint
sweeps new ground at ``2 r_s V`` (m^2/s) flying at ``V``, times two losses: the spiral's turns
overlap (``SWATH_FRACTION``), and an aircraft whose turn radius ``R`` is not small against
the region spends most of its path turning outside it: a pass through the region's middle
is ``L = 2 (k sigma + r_s)`` long, the turn to come back at least ``pi R``, so only
``L / (L + pi R)`` of the path sweeps the region. The sweep starts from the footprint's disc
``pi r_s^2``. The search stops ("outpaced") once no future moment has the swept area catch up
with the region's: ``max over t' >= t of  swept(t) + s (t' - t) - A(t')  < 0`` (a quadratic in
``t'``). A search that can catch up (a small velocity error: a walker seen for long, or seen
twice) runs on to "covered" or its bound; a point seen for one short pass and reached late
(a decoy that vanished) is given up at once ("lost"), since the perimeter pays for every second of a
search that can never cover it: on the paper's ellipse in a wind the forecast got wrong,
37 s of such a search left the prosecutor's stretch unseen for two T/N (``docs/alerts.md``).

Along the road first. A moving track (at least ``ROAD_MIN_M_S``) not found where predicted
most likely turned, stopped or slowed on its way: before the spiral the prosecutor flies
``ROAD_POINTS``, each a point of a predicted path at the time it is flown (``u = v dt``
from the track's position ``p0``, ``dt`` the track's age): the turn model's quarter-turn arcs
``p0 + u (2 / pi)(1 +- i)``, the ends of a 90 deg turn at a junction ``p0 +- i u``, the last
sighting ``p0`` (stopped where seen) and half-way ``p0 + u / 2`` (slowed); the side the turn
model turns to first. Its sensor sweeps the paths between them. The paths spread at the
intruder's speed (the region grows as ``|v|^2 dt^2``), so they can be covered only while the
track is young: flown ideally at 22 m/s with a 40 m footprint against a 10 m/s vehicle, every
90 deg turn, stop and quarter-turn arc since a sighting 10 s old is found; from one 15 s old,
10 of 16, the spiral alone 1 (``tests/test_search_road.py``). It is part of the search's time
bound; "covered" is judged on the spiral only, so a road search alone never clears.

Conventions: positions ``north + i east`` (complex m), times vehicle seconds, angles rad.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field

from companion.group.messages import Track

SEARCH_SIGMAS = 3.0  # the region searched: this many sigma of the predicted position
SEARCH_MAX_S = 60.0  # default bound on a search (s)
SWATH_FRACTION = 0.8  # spiral turns this fraction of the footprint's diameter apart
MIN_STEP_RAD = math.pi / 4  # waypoints at least this far apart round the spiral
ROAD_MIN_M_S = 1.0  # a track at least this fast is searched along its predicted paths first
_Q = 2.0 / math.pi
# the road's points, as multiples of u = v dt from the track's position (see the module text)
ROAD_POINTS: tuple[complex, ...] = (
    complex(_Q, _Q),
    1j,
    0j,
    -1j,
    complex(_Q, -_Q),
    0.5 + 0j,
)


def needs_search(track: Track, t_s: float, sensor_m: float) -> bool:
    """Whether a footprint of radius ``sensor_m`` (m) over the prediction at ``t_s`` (s) left
    part of its ``SEARCH_SIGMAS`` sigma region unseen."""
    return SEARCH_SIGMAS * track.sigma_m(t_s) > sensor_m


@dataclass
class Search:
    """One search: the track it searches, from ``t0_s`` (s), with the sensor footprint
    radius and the aircraft's turn radius (m), for at most ``max_s`` (s).

    Attributes:
        k: the waypoint flown to now (0, 1, ...).
    """

    track: Track
    t0_s: float
    sensor_m: float
    turn_radius_m: float
    max_s: float = SEARCH_MAX_S
    speed_m_s: float = math.inf
    k: int = 0
    road: bool | None = None  # searched along the road first (None: a moving track)
    order: list[int] = field(default_factory=list)  # road points picked so far, in order

    def __post_init__(self) -> None:
        """A moving track is searched along its predicted paths first."""
        if self.road is None:
            self.road = abs(self.track.vel_m_s) >= ROAD_MIN_M_S

    @property
    def road_points(self) -> int:
        """How many waypoints are the road's (0 without a road search)."""
        return len(ROAD_POINTS) if self.road else 0

    def road_index(self, k: int) -> int:
        """Which of ``ROAD_POINTS`` waypoint ``k`` of the road is: the ones picked
        (:meth:`pick`) in their order, then the rest in their own."""
        if k < len(self.order):
            return self.order[k]
        rest = [i for i in range(len(ROAD_POINTS)) if i not in self.order]
        return rest[k - len(self.order)]

    def unpicked(self) -> list[int]:
        """The road points not yet picked (indices into ``ROAD_POINTS``)."""
        return [i for i in range(self.road_points) if i not in self.order]

    def pick(self, index: int) -> None:
        """Fly road point ``index`` (of ``ROAD_POINTS``, not yet picked) as the current
        waypoint: the prosecutor picks the one it reaches soonest (a turn-rate-limited
        aircraft cannot fly a fixed order through points a turn diameter apart)."""
        if not self.on_road() or len(self.order) != self.k or index in self.order:
            raise ValueError(f"road point {index} cannot be picked at waypoint {self.k}")
        self.order.append(index)

    def _road_point(self, k: int) -> complex:
        """Road waypoint ``k`` as a multiple of ``u``: the side the turn model turns to
        first (towards east of the heading for a positive rate)."""
        c = ROAD_POINTS[self.road_index(k)]
        return c.conjugate() if self.track.turn_rad_s < 0.0 else c

    def on_road(self, k: int | None = None) -> bool:
        """Whether waypoint ``k`` (default: the current one) is one of the road's."""
        return (self.k if k is None else k) < self.road_points

    def _angle_and_radius(self, k: int) -> tuple[float, float]:
        """Spiral angle (rad) and radius (m) of waypoint ``k``."""
        pitch = SWATH_FRACTION * 2.0 * self.sensor_m  # radial growth per turn (m)
        theta, r = 0.0, self.sensor_m
        for _ in range(k):
            step = max(MIN_STEP_RAD, 2.0 * self.turn_radius_m / max(r, 1.0))
            theta += step
            r = self.sensor_m + pitch * theta / (2.0 * math.pi)
        return theta, r

    def radius_m(self, k: int | None = None) -> float:
        """The spiral's radius (m) at waypoint ``k`` (default: the current one; 0 on the
        road)."""
        k = (self.k if k is None else k) - self.road_points
        return self._angle_and_radius(k)[1] if k >= 0 else 0.0

    def waypoint_m(self, t_s: float, k: int | None = None) -> complex:
        """Waypoint ``k`` (default: the current one) at ``t_s`` (s): the predicted position
        plus its spiral offset (complex m). The spiral starts on the side the track moves
        towards."""
        k = self.k if k is None else k
        if k < self.road_points:
            u = self.track.vel_m_s * max(0.0, t_s - self.track.t_s)
            return self.track.pos_m + u * self._road_point(k)
        theta, r = self._angle_and_radius(k - self.road_points)
        heading = cmath.phase(self.track.vel_m_s) if abs(self.track.vel_m_s) > 0 else 0.0
        return self.track.predict(t_s) + r * cmath.exp(1j * (heading + theta))

    def waypoint_velocity_m_s(self, k: int | None = None) -> complex:
        """How waypoint ``k`` (default: the current one) moves (complex m/s): a road point
        at its multiple of the track's velocity, the spiral with the track."""
        k = self.k if k is None else k
        if k < self.road_points:
            return self.track.vel_m_s * self._road_point(k)
        return self.track.vel_m_s

    def sweep_rate_m2_s(self, t_s: float) -> float:
        """New ground of the region the footprint sweeps per second at ``t_s`` (s), m^2/s:
        ``2 r_s V``, less the spiral's overlap and the turns flown outside the region."""
        pass_m = 2.0 * (SEARCH_SIGMAS * self.track.sigma_m(t_s) + self.sensor_m)
        inside = pass_m / (pass_m + math.pi * self.turn_radius_m)
        return SWATH_FRACTION * inside * 2.0 * self.sensor_m * self.speed_m_s

    def outpaced(self, t_s: float) -> bool:
        """Whether at ``t_s`` (s) the swept area can never again catch up with the searched
        region's (see the module's text); never while the road is searched."""
        if self.on_road():
            return False
        rate = self.sweep_rate_m2_s(t_s)
        var_rate = self.track.vel_sigma_m_s**2  # d(sigma^2)/d(age^2), m^2/s^2
        if not math.isfinite(rate) or var_rate <= 0.0:
            return False
        k2pi = math.pi * SEARCH_SIGMAS**2
        swept = math.pi * self.sensor_m**2 + rate * max(0.0, t_s - self.t0_s)
        age = max(0.0, t_s - self.track.t_s)
        best_age = max(age, rate / (2.0 * k2pi * var_rate))  # where swept - area peaks
        area = k2pi * (self.track.pos_sigma_m**2 + var_rate * best_age**2)
        return swept + rate * (best_age - age) < area

    def finished(self, t_s: float) -> str | None:
        """Why the search is over at ``t_s`` (s): "covered" (the spiral flown so far, with its
        footprint, reaches ``SEARCH_SIGMAS`` sigma of the prediction), "outpaced" (the swept
        area can no longer catch up with the region's), "time" (``max_s`` spent), or None."""
        if self.on_road():
            return "time" if t_s - self.t0_s >= self.max_s else None
        flown = self.radius_m(self.k - 1) if self.k > self.road_points else 0.0
        if flown + self.sensor_m >= SEARCH_SIGMAS * self.track.sigma_m(t_s):
            return "covered"
        if self.outpaced(t_s):
            return "outpaced"
        if t_s - self.t0_s >= self.max_s:
            return "time"
        return None
