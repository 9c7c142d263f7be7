"""The fastest crossing the patrol is sure to see: the guarantee an operator can plan with (pure).

A perimeter patrol sees a band along its loop: the points within the sensor footprint radius
``r_s`` of the loop, ``2 r_s`` wide. An intruder that crosses the band between two passes can
go unseen; how fast it may cross and still be seen for sure depends on the band's width, the
time between passes and the patrol's ground speed. This module states that speed.

Conventions (as everywhere): SI units, the unit in the name; the crossing angle ``alpha`` is
measured from the loop's tangent in the patrol's sense of travel (90 deg: straight across;
below 90 deg the intruder moves along with the patrol, above it against).

The model (its assumptions, stated once):

* The sensor sees an intruder within ``r_s`` of the UAV, horizontally (a disc under it).
* The UAVs on the loop fly it at the patrol's ground speed ``s``, one past each loop point
  every ``G`` s at most (the **gap**, centre to centre). In wind ``s`` varies with the course
  between ``s0 - beta`` and ``s0 + beta``; the speed promised does not depend on it (only
  the worst angle and whether the discs overlap do).
* Locally the loop is straight over the crossing (its radius of curvature well above
  ``r_s``): along-loop ``x``, across ``y``. ``tests/test_guarantee.py`` checks the result on
  generated bases, corners included, against a brute-force simulation of crossings.

The derivation. Seen from the UAVs (a frame moving along the loop at ``s``), the sensor discs
stand still on the loop line, ``D = s G`` apart, and an intruder moving at ``v < s`` over the
ground drifts back through them: its velocity in that frame is its own less ``s`` along the
loop, so its direction of travel stays within ``asin(v / s)`` of straight back. To cross the
band unseen it must go from one edge to the other between two discs, and the steepest way
between two discs of radius ``r_s`` whose centres are ``D`` apart is their inner common
tangent, at ``asin(2 r_s / D)`` to the loop. A path whose direction is never steeper than
that of the tangent cannot get through (it would have to rise faster than the tangent
between the two discs); so every crossing is seen when ``v / s <= 2 r_s / D``, i.e.::

    v* = 2 r_s / G        (= 2 r_s N / T with every UAV on the loop, evenly splayed)

and a straight crossing slightly faster, along that tangent (at ``acos(2 r_s / (G s))`` from
the loop's tangent, leaning with the patrol; :attr:`CrossingGuarantee.worst_angle_deg`),
timed to pass half-way between two UAVs, is missed. Straight across the loop the bound is
looser, ``1 / sqrt((G / 2 r_s)^2 - 1 / s^2)``, but the operator cannot choose the angle.
The speed of the patrol drops out: it sets the worst angle, not the speed.

It holds for any path through the band, turns and stops included, as long as the intruder
never moves faster than ``v*`` over the ground while it goes from one edge of the band to
the other (a stop is straight back in the UAVs' frame, the least steep of all). It promises
nothing about an intruder that enters the band and leaves it on the side it came from, nor
about one that never reaches the band; and it assumes the UAVs on the loop (a cross-track
error ``e`` narrows the band on one side by ``e``).

When the discs of successive UAVs overlap along the loop (``s G <= 2 r_s`` at the fastest
ground speed), the loop line itself is always under a sensor: every crossing is seen,
whatever its speed (``v* = inf``).

The gap ``G``:

* every UAV on the loop (``k = 0``), evenly splayed in time-phase: ``T / N`` exactly, wind
  included (the time-phase advances at ``2 pi / T`` for all);
* with ``k`` UAVs away (prosecuting, tracking): the bound the product holds an episode to, a
  loop point unseen at most ``1.5 N / (N - k)`` T/N (:data:`AWAY_UNSEEN_REVISITS`; the goal of
  ``companion/report/episodes.py``); a point is covered by a pass for ``2 r_s / s``, so the
  gap is at most that bound plus ``2 r_s / s`` at the slowest ground speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

AWAY_UNSEEN_REVISITS = 1.5
"""With k UAVs away a loop point goes unseen at most this many revisits of those left,
``N / (N - k)`` T/N (the bound of an alert episode, ``companion/report/episodes.py``)."""
MAX_VEHICLES = 1000  # the largest formation :func:`vehicles_needed` looks at


@dataclass(frozen=True)
class CrossingGuarantee:
    """What the patrol is sure to see.

    Attributes:
        vehicles: UAVs on the loop when none is away (N).
        away: UAVs away (k); ``vehicles - away`` patrol.
        footprint_radius_m: sensor footprint radius r_s (m); the band is 2 r_s wide.
        period_s: loop period T (s).
        gap_s: the longest time between two UAVs over one loop point (s), centre to centre.
        slowest_ground_speed_m_s: the patrol's slowest ground speed (m/s), s0 - beta.
        fastest_ground_speed_m_s: its fastest (m/s), s0 + beta.
        sure_m_s: the fastest crossing at any angle, along any path, that is sure to be
            seen: 2 r_s / G (m/s; inf: every crossing). The figure to plan with.
        across_m_s: the fastest crossing straight across the loop (90 deg) sure to be seen
            wherever it crosses, ``1 / sqrt((G / 2 r_s)^2 - 1 / s^2)`` at the fastest
            ground speed (m/s, >= ``sure_m_s``; inf: every crossing).
        worst_angle_deg: the angle from the loop's tangent of the straight crossing just
            faster than ``sure_m_s`` that can be missed (deg; 90 = straight across), at the
            slowest ground speed.
        continuous: the discs of successive UAVs overlap along the whole loop, so every
            crossing is seen whatever its speed.
    """

    vehicles: int
    away: int
    footprint_radius_m: float
    period_s: float
    gap_s: float
    slowest_ground_speed_m_s: float
    fastest_ground_speed_m_s: float
    sure_m_s: float
    across_m_s: float
    worst_angle_deg: float
    continuous: bool

    def as_dict(self) -> dict:
        """JSON-ready (an infinite speed is None, with ``continuous`` True)."""

        def r(x: float, nd: int = 3) -> float | None:
            return round(x, nd) if math.isfinite(x) else None

        return {
            "vehicles": self.vehicles,
            "away": self.away,
            "on_loop": self.vehicles - self.away,
            "footprint_radius_m": self.footprint_radius_m,
            "period_s": r(self.period_s),
            "gap_s": r(self.gap_s),
            "slowest_ground_speed_m_s": r(self.slowest_ground_speed_m_s),
            "sure_m_s": r(self.sure_m_s),
            "across_m_s": r(self.across_m_s),
            "worst_angle_deg": r(self.worst_angle_deg, 1),
            "continuous": self.continuous,
        }


def revisit_gap_s(
    period_s: float,
    vehicles: int,
    away: int = 0,
    footprint_radius_m: float = 0.0,
    slowest_ground_speed_m_s: float = math.inf,
) -> float:
    """The longest time between two UAVs over one loop point (s), centre to centre.

    ``T / N`` with every UAV on the loop (``away`` = 0); with ``away`` = k >= 1 the product's
    bound ``1.5 N / (N - k)`` T/N on a point's unseen time plus the time a pass covers it,
    ``2 r_s / s`` (``footprint_radius_m`` m, ``slowest_ground_speed_m_s`` m/s). See the
    module doc.

    Raises:
        ValueError: not ``0 <= away < vehicles``, or a period that is not > 0.
    """
    if not (isinstance(vehicles, int) and isinstance(away, int) and 0 <= away < vehicles):
        raise ValueError(f"expected 0 <= away < vehicles, got {away!r} of {vehicles!r}")
    if not (math.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period_s must be > 0, got {period_s!r}")
    if away == 0:
        return period_s / vehicles
    unseen = AWAY_UNSEEN_REVISITS * period_s / (vehicles - away)
    return unseen + 2.0 * footprint_radius_m / slowest_ground_speed_m_s


def sure_speed_m_s(footprint_radius_m: float, gap_s: float) -> float:
    """The fastest crossing sure to be seen, at any angle and along any path (m/s):
    ``2 r_s / G`` for a footprint radius ``footprint_radius_m`` = r_s (m) and a gap
    ``gap_s`` = G (s) (the module doc; inf is :func:`crossing_guarantee`'s to say)."""
    return 2.0 * footprint_radius_m / gap_s


def worst_angle_deg(footprint_radius_m: float, gap_s: float, ground_speed_m_s: float) -> float:
    """The crossing angle from the loop's tangent (deg) of the straight crossing at
    :func:`sure_speed_m_s` that grazes two discs: ``acos(2 r_s / (G s))``, leaning with the
    patrol (90 deg when the discs touch or overlap)."""
    return math.degrees(math.acos(min(1.0, 2.0 * footprint_radius_m / (gap_s * ground_speed_m_s))))


def crossing_guarantee(
    period_s: float,
    vehicles: int,
    footprint_radius_m: float,
    airspeed_m_s: float,
    wind_speed_m_s: float,
    away: int = 0,
) -> CrossingGuarantee:
    """What a patrol of ``vehicles`` UAVs (``away`` of them away) on a loop of period
    ``period_s`` (s), with sensor footprint radius ``footprint_radius_m`` (m), airspeed
    ``airspeed_m_s`` and wind ``wind_speed_m_s`` (m/s), is sure to see.

    Raises:
        ValueError: not ``0 <= away < vehicles``; a radius, airspeed or period that is not
            > 0; a wind not below the airspeed.
    """
    for name, x in (("footprint_radius_m", footprint_radius_m), ("airspeed_m_s", airspeed_m_s)):
        if not (math.isfinite(x) and x > 0):
            raise ValueError(f"{name} must be > 0, got {x!r}")
    if not (math.isfinite(wind_speed_m_s) and 0 <= wind_speed_m_s < airspeed_m_s):
        raise ValueError(f"expected 0 <= wind < airspeed, got {wind_speed_m_s!r}")
    slow = airspeed_m_s - wind_speed_m_s
    fast = airspeed_m_s + wind_speed_m_s
    gap = revisit_gap_s(period_s, vehicles, away, footprint_radius_m, slow)
    continuous = fast * gap <= 2.0 * footprint_radius_m
    k = gap / (2.0 * footprint_radius_m)  # s/m; k * fast > 1 unless continuous
    across = math.inf if continuous else 1.0 / math.sqrt(k * k - 1.0 / fast**2)
    return CrossingGuarantee(
        vehicles=vehicles,
        away=away,
        footprint_radius_m=footprint_radius_m,
        period_s=period_s,
        gap_s=gap,
        slowest_ground_speed_m_s=slow,
        fastest_ground_speed_m_s=fast,
        sure_m_s=math.inf if continuous else sure_speed_m_s(footprint_radius_m, gap),
        across_m_s=across,
        worst_angle_deg=worst_angle_deg(footprint_radius_m, gap, slow),
        continuous=continuous,
    )


def vehicles_needed(
    speed_m_s: float,
    period_s: float,
    footprint_radius_m: float,
    airspeed_m_s: float,
    wind_speed_m_s: float,
    away: int = 0,
    most: int = MAX_VEHICLES,
) -> int | None:
    """The fewest UAVs N (with ``away`` of them away) sure to see every crossing no faster
    than ``speed_m_s`` (m/s) on this loop (:func:`crossing_guarantee`'s other arguments), or
    None when no formation of at most ``most`` does (with UAVs away the gap is never below
    ``2 r_s / s`` at the slowest ground speed, so a crossing that fast is never promised).

    Raises:
        ValueError: a speed that is not > 0, or :func:`crossing_guarantee`'s.
    """
    if not (math.isfinite(speed_m_s) and speed_m_s > 0):
        raise ValueError(f"speed_m_s must be > 0, got {speed_m_s!r}")
    for n in range(away + 1, most + 1):
        g = crossing_guarantee(
            period_s, n, footprint_radius_m, airspeed_m_s, wind_speed_m_s, away=away
        )
        if g.sure_m_s >= speed_m_s:
            return n
    return None


def describe(records: list[dict]) -> str:
    """One line for an operator from :meth:`CrossingGuarantee.as_dict` records (0, 1, ...
    away, in order): the fastest crossing sure to be seen and what it rests on."""
    if not records:
        return ""

    def speed(rec: dict) -> str:
        return "any speed" if rec["sure_m_s"] is None else f"{rec['sure_m_s']:.2f} m/s"

    first = records[0]
    away = ", ".join(f"{r['away']} away {speed(r)}" for r in records[1:])
    return (
        f"crossings sure to be seen: up to {speed(first)} with {first['on_loop']} UAVs on the "
        f"loop (band 2 r_s = {2 * first['footprint_radius_m']:.0f} m, T/N "
        f"{first['gap_s']:.1f} s: 2 r_s N / T)" + (f"; with {away}" if away else "")
    )
