"""A patrol loop flown at constant airspeed in steady wind: time-phase tables (eq. 13-15).

:class:`Patrol` binds a loop shape, the sense of travel, the airspeed and the wind, and
tabulates the time along the loop ``t(gamma) = int_0^gamma R / s d gamma'``, the period
``T = t(2 pi)`` and the time-phase ``psi = 2 pi t / T`` once, then evaluates them and their
inverse by cubic Hermite interpolation with the exact derivatives (error O(h^4)).

Frames. Its public methods take and return *world* quantities (complex ``north + i east``
positions in m, compass courses in rad). Internally everything is computed in the canonical
frame where the loop is flown clockwise (course increasing); a counter-clockwise patrol is
the mirror image east -> -east, so positions are conjugated, angles and turn rates negated.
Time-phase is always increasing along the direction of travel, in [0, 2 pi).
"""

from __future__ import annotations

import cmath
import math
from bisect import bisect_right
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike

from companion.core.loops import LoopShape, hermite_poly
from companion.core.wind import (
    TWO_PI,
    Wind,
    ground_velocity,
    groundspeed_from_course,
    heading_from_course,
    turn_rate_from_course_rate,
    wrap_2pi,
    wrap_pi,
)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)

# Memos kept on a Patrol (first in, first out). In the in-memory engine every member holds the
# mission's Patrol (and, once they agree a wind, the one :meth:`Patrol.with_wind` built for the
# first of them), so a shared position is placed on the loop once, not by each of N - 1 members.
NEAREST_MEMO = 1024  # positions: 64 thrashed at 100 UAVs (a hit in 70), 1024 keeps a step's
WIND_MEMO = 4  # re-timed loops
# The nearest loop point by Newton's method: converged once a step moves the course by less
# than this (rad; the error left is then of the order of its square: 1e-12 rad, a micrometre
# at 1 km of radius), given up after so many steps
NEWTON_TOL_RAD = 1e-6
NEWTON_MAX_STEPS = 12
# A point inside the loop deeper than this fraction of the loop's least radius of curvature
# is placed by the global search (a nearer point may exist; see Patrol.nearest_canon)
INSIDE_REACH = 0.99

_T = TypeVar("_T")


def _remembered(memo: dict, key: object, limit: int, compute: Callable[[], _T]) -> _T:
    """``memo[key]``, or ``compute()`` kept there (the oldest entry dropped beyond ``limit``
    entries); a None ``key`` is computed and never kept."""
    if key is not None and (hit := memo.get(key)) is not None:
        return hit
    value = compute()
    if key is not None:
        if len(memo) >= limit:
            del memo[next(iter(memo))]
        memo[key] = value
    return value


@dataclass(frozen=True)
class Nearest:
    """The point of the loop nearest a given point.

    Attributes:
        point_m: the loop point (world, complex m).
        course_rad: tangent ground course there, in the sense of travel (rad, world).
        phase_rad: its time-phase (rad).
        distance_m: distance from the given point (m).
    """

    point_m: complex
    course_rad: float
    phase_rad: float
    distance_m: float


class LoopPoint(NamedTuple):
    """Where a point is against the loop: its nearest loop point's tangent course in the
    canonical frame (rad), its outward offset from there (m, positive outside, canonical
    frame) and that loop point's time-phase (rad, [0, 2 pi))."""

    course_canon_rad: float
    offset_m: float
    phase_rad: float


def _unset() -> np.ndarray:
    """An empty table: :meth:`Patrol.build` gives every one."""
    return np.empty(0)


def _hermite(
    x: np.ndarray, xs: np.ndarray, ys: np.ndarray, d_lo: np.ndarray, d_hi: np.ndarray
) -> np.ndarray:
    """Piecewise cubic Hermite: ``d_lo[j]`` / ``d_hi[j]`` are slopes at the ends of interval j."""
    j = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    h = xs[j + 1] - xs[j]
    return hermite_poly((x - xs[j]) / h, h, ys[j], d_lo[j], ys[j + 1], d_hi[j])


def _hermite_float(
    x: float, xs: list[float], ys: list[float], d_lo: list[float], d_hi: list[float]
) -> float:
    """:func:`_hermite` at one point, on the tables as lists: the same arithmetic in the same
    order, so the same value, without numpy's per-call cost."""
    j = min(max(bisect_right(xs, x) - 1, 0), len(xs) - 2)
    x0 = xs[j]
    h = xs[j + 1] - x0
    return hermite_poly((x - x0) / h, h, ys[j], d_lo[j], ys[j + 1], d_hi[j])


@dataclass(frozen=True)
class Patrol:
    """A loop, its sense of travel, airspeed and wind, with time-phase tables.

    Build it with :meth:`Patrol.build`.

    Attributes:
        shape_world: the loop as given (world frame).
        clockwise: True for clockwise travel on a north-up map (course increasing).
        airspeed_m_s: airspeed ``s0`` (m/s).
        wind: wind (world frame).
        shape: the loop in the canonical frame.
        wind_canon: the wind in the canonical frame.
        period_s: loop period ``T`` (s).
        length_m: loop length (m).
    """

    shape_world: LoopShape
    clockwise: bool
    airspeed_m_s: float
    wind: Wind
    shape: LoopShape = field(repr=False)
    wind_canon: Wind = field(repr=False)
    period_s: float = 0.0
    length_m: float = 0.0
    _g: np.ndarray = field(default_factory=_unset, repr=False)  # course nodes (canonical, rad)
    _t: np.ndarray = field(default_factory=_unset, repr=False)  # time at nodes (s)
    _dt_lo: np.ndarray = field(default_factory=_unset, repr=False)  # dt/dgamma, left ends (s/rad)
    _dt_hi: np.ndarray = field(default_factory=_unset, repr=False)  # dt/dgamma, right ends (s/rad)
    _arc: np.ndarray = field(default_factory=_unset, repr=False)  # arc length at nodes (m)
    _pts: np.ndarray = field(default_factory=_unset, repr=False)  # canonical points at nodes (m)

    @classmethod
    def build(
        cls,
        shape: LoopShape,
        airspeed_m_s: float,
        wind: Wind,
        clockwise: bool = True,
        nodes: int = 2048,
    ) -> Patrol:
        """Tabulate time along ``shape`` flown at ``airspeed_m_s`` (m/s) in ``wind``.

        Raises:
            ValueError: wind not slower than the airspeed, or a non-positive airspeed.
        """
        if not (np.isfinite(airspeed_m_s) and airspeed_m_s > 0):
            raise ValueError(f"airspeed must be a finite number > 0 m/s, got {airspeed_m_s!r}")
        wind.check_against(airspeed_m_s)
        canon = shape if clockwise else shape.mirrored()
        wind_c = wind if clockwise else Wind(wind.speed_m_s, float(wrap_2pi(-wind.towards_rad)))
        g = np.union1d(np.linspace(0.0, TWO_PI, nodes + 1), canon.breakpoints_rad)
        lo, hi = g[:-1], g[1:]
        half = 0.5 * (hi - lo)
        gq = (0.5 * (hi + lo))[:, None] + half[:, None] * _GL_X[None, :]
        rate = canon.radius(gq) / groundspeed_from_course(airspeed_m_s, gq, wind_c)
        dt = half * (rate @ _GL_W)
        t = np.concatenate([[0.0], np.cumsum(dt)])
        arc = np.concatenate([[0.0], np.cumsum(half * (canon.radius(gq) @ _GL_W))])
        eps = 1e-12
        d_lo = canon.radius(lo + eps) / groundspeed_from_course(airspeed_m_s, lo, wind_c)
        d_hi = canon.radius(hi - eps) / groundspeed_from_course(airspeed_m_s, hi, wind_c)
        return cls(
            shape_world=shape,
            clockwise=clockwise,
            airspeed_m_s=float(airspeed_m_s),
            wind=wind,
            shape=canon,
            wind_canon=wind_c,
            period_s=float(t[-1]),
            length_m=float(canon.length_m()),
            _g=g,
            _t=t,
            _dt_lo=d_lo,
            _dt_hi=d_hi,
            _arc=arc,
            _pts=canon.centre_m + canon.offset(g[:-1]),
        )

    def with_wind(self, wind: Wind) -> Patrol:
        """The same loop, sense and airspeed in another ``wind`` (new time-phase tables).

        The last few are kept: the same wind (bit for bit) gives the same object, so the
        members that follow one agreed wind share its tables and memos."""
        # 0.0 == -0.0: a zero component is never a key, so equal keys are equal bits
        key = (wind.speed_m_s, wind.towards_rad) if wind.speed_m_s and wind.towards_rad else None
        return _remembered(
            self._wind_memo,
            key,
            WIND_MEMO,
            lambda: Patrol.build(self.shape_world, self.airspeed_m_s, wind, self.clockwise),
        )

    @cached_property
    def _wind_memo(self) -> dict[tuple[float, float], Patrol]:
        """:meth:`with_wind`'s results by (speed m/s, towards rad)."""
        return {}

    @cached_property
    def derived(self) -> dict[object, object]:
        """What other modules work out once from this patrol (the steering law's constants
        for its gains, :mod:`companion.guidance.steering`), by their own keys."""
        return {}

    @cached_property
    def _point_memo(self) -> dict[complex, LoopPoint]:
        """:meth:`loop_point`'s results by world position (complex m)."""
        return {}

    @cached_property
    def _nearest_memo(self) -> dict[complex, tuple[float, float]]:
        """:meth:`nearest_canon`'s results by canonical position (complex m)."""
        return {}

    # ---- tables as lists, for one point at a time (built once, on first use) --------------
    @cached_property
    def _time_table(self) -> tuple[list[float], list[float], list[float], list[float]]:
        """Course nodes, times, and slopes at both ends (for :meth:`time_along`)."""
        return self._g.tolist(), self._t.tolist(), self._dt_lo.tolist(), self._dt_hi.tolist()

    @cached_property
    def _course_rate(self) -> tuple[np.ndarray, np.ndarray]:
        """dgamma/dt at the left and right ends of each interval (rad/s)."""
        return 1.0 / self._dt_lo, 1.0 / self._dt_hi

    @cached_property
    def _course_table(self) -> tuple[list[float], list[float], list[float], list[float]]:
        """Times, course nodes, and slopes at both ends (for :meth:`course_after`)."""
        lo, hi = self._course_rate
        return self._t.tolist(), self._g.tolist(), lo.tolist(), hi.tolist()

    def turn_radius_m(self, max_turn_rate_rad_s: float) -> float:
        """The widest turn radius (m) at a turn-rate limit (rad/s): at the fastest ground
        speed, airspeed plus wind, ``(s0 + |w|) / omega_max``."""
        return (self.airspeed_m_s + abs(self.wind.vector)) / max_turn_rate_rad_s

    # ---- frame changes -------------------------------------------------------------------
    @property
    def sense(self) -> int:
        """+1 for clockwise travel, -1 for counter-clockwise."""
        return 1 if self.clockwise else -1

    @overload
    def to_canon(self, z: complex) -> complex: ...  # type: ignore[overload-overlap]
    @overload
    def to_canon(self, z: ArrayLike) -> np.ndarray: ...
    def to_canon(self, z: ArrayLike) -> np.ndarray | complex:
        """World position or vector -> canonical frame (its own inverse); a complex for a
        complex."""
        if isinstance(z, complex):
            return z if self.clockwise else z.conjugate()
        z = np.asarray(z, dtype=complex)
        return z if self.clockwise else np.conj(z)

    @overload
    def angle_to_canon(self, angle_rad: float) -> float: ...
    @overload
    def angle_to_canon(self, angle_rad: ArrayLike) -> np.ndarray: ...
    def angle_to_canon(self, angle_rad: ArrayLike) -> np.ndarray | float:
        """World angle or turn rate -> canonical frame (its own inverse); a float for a
        float."""
        if isinstance(angle_rad, float):
            return self.sense * angle_rad
        return self.sense * np.asarray(angle_rad, dtype=float)

    @property
    def centre_m(self) -> complex:
        """Reference centre ``c0`` (world, complex m)."""
        return self.shape_world.centre_m

    # ---- time-phase ----------------------------------------------------------------------
    def time_along(self, course_canon_rad: ArrayLike) -> np.ndarray:
        """Time ``t(gamma)`` (s) from course 0 to canonical course gamma, in [0, T); a float
        for a float."""
        if isinstance(course_canon_rad, float):
            return _hermite_float(wrap_2pi(course_canon_rad), *self._time_table)
        g = wrap_2pi(np.asarray(course_canon_rad, dtype=float))
        return _hermite(g, self._g, self._t, self._dt_lo, self._dt_hi)

    def arc_length_at_phase(self, phase_rad: ArrayLike) -> np.ndarray:
        """Distance along the loop (m, [0, L)) from course 0 to the point at ``phase_rad``."""
        g = self.course_after(np.asarray(phase_rad, dtype=float) * self.period_s / TWO_PI)
        return np.interp(g, self._g, self._arc)

    def course_after(self, time_s: ArrayLike) -> np.ndarray:
        """Canonical course gamma (rad, [0, 2 pi)) reached after ``time_s`` (s) from course 0;
        a float for a float."""
        if isinstance(time_s, float):
            return _hermite_float(time_s % self.period_s, *self._course_table)
        t = np.asarray(time_s, dtype=float) % self.period_s
        return _hermite(t, self._t, self._g, *self._course_rate)

    def phase_of_course(self, course_rad: ArrayLike) -> np.ndarray:
        """Time-phase ``psi`` (rad, [0, 2 pi)) of the loop point with world course (rad)."""
        t = self.time_along(self.angle_to_canon(course_rad))
        return wrap_2pi(TWO_PI * t / self.period_s)

    def course_at_phase(self, phase_rad: ArrayLike) -> np.ndarray:
        """World tangent course (rad, [-pi, pi)) at time-phase ``phase_rad``."""
        g = self.course_after(np.asarray(phase_rad, dtype=float) * self.period_s / TWO_PI)
        return wrap_pi(self.angle_to_canon(g))

    def point_at_phase(self, phase_rad: ArrayLike) -> np.ndarray:
        """World loop point (complex m) at time-phase ``phase_rad``."""
        g = self.course_after(np.asarray(phase_rad, dtype=float) * self.period_s / TWO_PI)
        return self.to_canon(self.shape.centre_m + self.shape.offset(g))

    def point_at_course(self, course_rad: ArrayLike) -> np.ndarray:
        """World loop point (complex m) whose tangent has world course ``course_rad``."""
        g = self.angle_to_canon(course_rad)
        return self.to_canon(self.shape.centre_m + self.shape.offset(g))

    # ---- a vehicle relative to the loop --------------------------------------------------
    def centre_and_phase(
        self, pos_m: ArrayLike, heading_rad: ArrayLike
    ) -> tuple[np.ndarray, np.ndarray]:
        """Loop centre ``c_k = r_k - rho(gamma_k)`` (world, m) and time-phase ``psi_k`` (rad).

        ``gamma_k`` is the vehicle's ground course from its air heading and the wind. For one
        vehicle (a complex position, a float heading) Python scalars throughout: a complex
        and a float.
        """
        if isinstance(pos_m, complex) and isinstance(heading_rad, float):
            v = self.airspeed_m_s * cmath.exp(1j * heading_rad) + self.wind.vector
            return self.centre_and_phase_of_course(pos_m, math.atan2(v.imag, v.real))
        v = ground_velocity(self.airspeed_m_s, heading_rad, self.wind)
        return self.centre_and_phase_from_course(pos_m, np.angle(v))

    def centre_and_phase_of_course(
        self, pos_m: complex, course_rad: float
    ) -> tuple[complex, float]:
        """:meth:`centre_and_phase_from_course` of one vehicle (world m, rad): a complex centre
        (world m) and a float time-phase (rad, [0, 2 pi))."""
        if self.clockwise:
            c = pos_m - self.shape.offset(course_rad)
            g_c = course_rad
        else:
            g_c = -course_rad
            c = (pos_m.conjugate() - self.shape.offset(g_c)).conjugate()
        t = _hermite_float(g_c % TWO_PI, *self._time_table)
        return c, (TWO_PI * t / self.period_s) % TWO_PI

    def centre_and_phase_from_course(
        self, pos_m: ArrayLike, course_rad: ArrayLike
    ) -> tuple[np.ndarray, np.ndarray]:
        """Loop centre (world, m) and time-phase (rad) of vehicles at ground course (rad)."""
        g_c = self.angle_to_canon(course_rad)
        c = self.to_canon(self.to_canon(pos_m) - self.shape.offset(g_c))
        return c, wrap_2pi(TWO_PI * self.time_along(g_c) / self.period_s)

    def phase_of_point(self, pos_m: complex) -> float:
        """Time-phase (rad, [0, 2 pi)) of the loop point nearest ``pos_m`` (world, complex m):
        where along the loop a vehicle is, whatever its course (unlike
        :meth:`centre_and_phase`, which reads the phase from the course)."""
        return self.phase_and_offset_of_point(pos_m)[0]

    def phase_and_offset_of_point(
        self, pos_m: complex, guess_rad: float | None = None
    ) -> tuple[float, float]:
        """:meth:`phase_of_point` (rad) and the distance (m) of ``pos_m`` from the loop
        (:meth:`loop_point`; ``guess_rad`` as there)."""
        p = self.loop_point(pos_m, guess_rad)
        return p.phase_rad, abs(p.offset_m)

    def loop_point_on_course(self, pos_m: complex, course_rad: float) -> LoopPoint:
        """:meth:`loop_point` of ``pos_m`` (complex m) for an aircraft on ground course
        ``course_rad`` (rad, compass): searched from the loop's tangent parallel to it."""
        return self.loop_point(pos_m, course_rad if self.clockwise else -course_rad)

    def loop_point(self, pos_m: complex, guess_rad: float | None = None) -> LoopPoint:
        """Where ``pos_m`` (world, complex m) is against the loop (:class:`LoopPoint`): the
        nearest loop point (:meth:`nearest_canon`, ``guess_rad`` its canonical course if
        known), the offset from it and its time-phase. The last positions' results are kept
        (:data:`NEAREST_MEMO`: in memory every member places the same shared position)."""
        memo = self._point_memo
        # 0.0 == -0.0: a zero component is never a key, so equal keys are equal bits
        key = pos_m if pos_m.real and pos_m.imag else None
        if key is not None and (hit := memo.get(key)) is not None:
            return hit
        r = pos_m if self.clockwise else pos_m.conjugate()
        g, d_out = self.nearest_canon(r, guess_rad)
        t = _hermite_float(g % TWO_PI, *self._time_table)
        value = LoopPoint(g, d_out, (TWO_PI * t / self.period_s) % TWO_PI)
        if key is not None:
            if len(memo) >= NEAREST_MEMO:
                del memo[next(iter(memo))]
            memo[key] = value
        return value

    def nearest(self, point_m: complex) -> Nearest:
        """The point of the loop nearest ``point_m`` (world, complex m), with its tangent."""
        from scipy.optimize import minimize_scalar  # loaded only here (a second of start-up)

        p_c = complex(self.to_canon(point_m))
        g = self._g[:-1]
        j = int(np.argmin(np.abs(self._pts - p_c)))  # _pts: the loop's points at g
        lo, hi = g[j - 1] if j > 0 else g[-1] - TWO_PI, g[j + 1] if j + 1 < len(g) else TWO_PI
        res = minimize_scalar(
            lambda x: abs(self.shape.centre_m + complex(self.shape.offset(x)) - p_c),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-10},
        )
        gc = float(wrap_2pi(res.x))
        point = complex(self.to_canon(self.shape.centre_m + self.shape.offset(gc)))
        return Nearest(
            point_m=point,
            course_rad=float(wrap_pi(self.angle_to_canon(gc))),
            phase_rad=float(wrap_2pi(TWO_PI * self.time_along(gc) / self.period_s)),
            distance_m=abs(point - complex(point_m)),
        )

    def nearest_canon(
        self, r_canon: complex, guess_rad: float | None = None
    ) -> tuple[float, float]:
        """Tangent course (rad) of the loop point nearest ``r_canon`` and the outward offset
        (m, positive outside), both in the canonical frame; the last positions' results are
        kept (:data:`NEAREST_MEMO`).

        Newton's method on ``<r - p(g), e^{ig}> = 0`` (derivative ``-(R + d)``) from
        ``guess_rad`` (e.g. the aircraft's own course, or where the same member was placed
        last): a point where ``r - p(g)`` is normal to the loop is the nearest when it lies
        outside (the projection onto a convex set is unique and is its only such point) or
        inside by less than the least radius of curvature ``R_min`` (the disc of radius
        ``R_min`` touching the loop there lies inside it, Blaschke's rolling theorem, so no
        loop point is nearer). Without a guess, or when Newton does not converge there or
        finds a deeper point, the nearest tabulated node starts it (a global search).
        """
        memo = self._nearest_memo
        # 0.0 == -0.0: a zero component is never a key, so equal keys are equal bits
        key = r_canon if r_canon.real and r_canon.imag else None
        if key is not None and (hit := memo.get(key)) is not None:
            return hit
        got = None
        if guess_rad is not None:
            got = self._newton(r_canon, guess_rad)
            if got is not None and got[1] < 0.0 and -got[1] >= self._inside_reach_m:
                got = None
        if got is None:
            got = self._nearest_canon(r_canon)
        if key is not None:
            if len(memo) >= NEAREST_MEMO:
                del memo[next(iter(memo))]
            memo[key] = got
        return got

    @cached_property
    def _inside_reach_m(self) -> float:
        """Depth inside the loop (m) within which a normal point is the nearest:
        :data:`INSIDE_REACH` of the least radius of curvature on the course nodes."""
        return INSIDE_REACH * float(np.min(self.shape.radius(self._g)))

    def _newton(self, r_canon: complex, g: float) -> tuple[float, float] | None:
        """Newton's method for the loop point normal to ``r_canon`` from course ``g`` (rad):
        (course rad, outward offset m), or None if it does not converge."""
        step_of = self.shape.offset_and_radius
        rel = r_canon - self.shape.centre_m
        for _ in range(NEWTON_MAX_STEPS):
            off, radius = step_of(g)
            z = complex(math.cos(g), -math.sin(g)) * (rel - off)  # e^{-ig} (r - p(g))
            d_out = -z.imag
            step = z.real / max(radius + d_out, 0.2 * radius)
            g += step
            if abs(step) < NEWTON_TOL_RAD:
                off, _ = step_of(g)
                return g, -(complex(math.cos(g), -math.sin(g)) * (rel - off)).imag
        return None

    def _nearest_canon(self, r_canon: complex) -> tuple[float, float]:
        """The global search: the nearest tabulated node, then Newton's method."""
        j = int(np.argmin(np.abs(self._pts - r_canon)))
        g = float(self._g[j])
        got = self._newton(r_canon, g)
        if got is not None:
            return got
        shape = self.shape  # not converged (a point near a centre of curvature): 3 steps
        for _ in range(3):
            e = cmath.exp(1j * g)
            rel = r_canon - shape.centre_m - complex(shape.offset(g))
            along = (e.conjugate() * rel).real
            d_out = (1j * e.conjugate() * rel).real
            r = float(shape.radius(g))
            g += along / max(r + d_out, 0.2 * r)
        e = cmath.exp(1j * g)
        d_out = (1j * e.conjugate() * (r_canon - shape.centre_m - complex(shape.offset(g)))).real
        return g, float(d_out)

    def required_turn_rate(self, course_canon_rad: ArrayLike) -> np.ndarray:
        """Air turn rate (rad/s, canonical sense) that holds the loop at canonical course."""
        g = np.asarray(course_canon_rad, dtype=float)
        s = groundspeed_from_course(self.airspeed_m_s, g, self.wind_canon)
        heading = heading_from_course(self.airspeed_m_s, g, self.wind_canon)
        nu = s / self.shape.radius(g)
        return turn_rate_from_course_rate(self.airspeed_m_s, heading, nu, self.wind_canon)

    def max_required_turn_rate_rad_s(self) -> float:
        """Largest turn rate needed to fly the loop exactly (rad/s)."""
        g = np.concatenate([self._g, self._g[1:-1] - 1e-9])
        return float(np.max(self.required_turn_rate(g)))

    def sample_by_time(self, count: int) -> np.ndarray:
        """``count`` world points equally spaced in time along the loop (complex m)."""
        return self.point_at_phase(np.arange(count) * TWO_PI / count)
