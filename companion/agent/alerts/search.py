"""Searching a track's uncertainty (pure): where the intruder was not under the sensor at the
intercept, the prosecutor flies an outward spiral over the predicted region before it clears.

The spiral is drawn in the frame that moves with the track (its centre is the predicted
position, ``Track.predict``), from one footprint radius out, one swath (``SWATH_FRACTION`` of
the footprint's diameter) between turns, its waypoints about two turn radii apart so a
turn-rate-limited aircraft can fly from one to the next. The search is done when the spiral
has covered ``SEARCH_SIGMAS`` sigma of the prediction (which grows with the track's
velocity error) or after ``max_s``, whichever is first: a bounded time away from the loop.

:func:`needs_search` is the test at the intercept: none is needed when the sensor footprint
over the predicted position already covered ``SEARCH_SIGMAS`` sigma.

Conventions: positions ``north + i east`` (complex m), times vehicle seconds, angles rad.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

from companion.group.messages import Track

SEARCH_SIGMAS = 3.0  # the region searched: this many sigma of the predicted position
SEARCH_MAX_S = 60.0  # default bound on a search (s)
SWATH_FRACTION = 0.8  # spiral turns this fraction of the footprint's diameter apart
MIN_STEP_RAD = math.pi / 4  # waypoints at least this far apart round the spiral


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
    k: int = 0

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
        """The spiral's radius (m) at waypoint ``k`` (default: the current one)."""
        return self._angle_and_radius(self.k if k is None else k)[1]

    def waypoint_m(self, t_s: float, k: int | None = None) -> complex:
        """Waypoint ``k`` (default: the current one) at ``t_s`` (s): the predicted position
        plus its spiral offset (complex m). The spiral starts on the side the track moves
        towards."""
        theta, r = self._angle_and_radius(self.k if k is None else k)
        heading = cmath.phase(self.track.vel_m_s) if abs(self.track.vel_m_s) > 0 else 0.0
        return self.track.predict(t_s) + r * cmath.exp(1j * (heading + theta))

    def finished(self, t_s: float) -> str | None:
        """Why the search is over at ``t_s`` (s): "covered" (the spiral flown so far, with its
        footprint, reaches ``SEARCH_SIGMAS`` sigma of the prediction), "time" (``max_s``
        spent), or None."""
        flown = self.radius_m(self.k - 1) if self.k > 0 else 0.0
        if flown + self.sensor_m >= SEARCH_SIGMAS * self.track.sigma_m(t_s):
            return "covered"
        if t_s - self.t0_s >= self.max_s:
            return "time"
        return None
