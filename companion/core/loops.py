"""Strictly convex patrol loops described by course (docs/design.md §3).

A loop ``C`` is written as ``P(gamma) = c0 + rho(gamma)`` where ``gamma`` is the ground
course of the tangent (rad, compass) and ``d rho / d gamma = R(gamma) exp(i gamma)`` with the
radius of curvature ``R > 0`` (eq. 10). Shapes here are in the *canonical* sense of travel:
gamma increasing, i.e. right turns, clockwise on a north-up map. A counter-clockwise patrol
is handled by :class:`companion.core.patrol.Patrol` as the mirror image (east -> -east).

Positions are complex ``north + i east`` (m). All methods broadcast over arrays of gamma.
"""

from __future__ import annotations

import cmath
import itertools
import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import cache, cached_property
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from companion.core.wind import TWO_PI, wrap_2pi

DEFAULT_EDGE_RADIUS_M = 50_000.0


class LoopError(ValueError):
    """A loop cannot be built from the given geometry."""


@dataclass(frozen=True)
class EllipseLoop:
    """Ellipse with semi-axis ``a`` along compass bearing ``chi`` and ``b`` across it.

    Attributes:
        centre_m: centre ``c0`` (complex north + i east, m).
        semi_major_m: semi-axis ``a`` along ``axis_bearing_rad`` (m), > 0.
        semi_minor_m: semi-axis ``b`` across it (m), > 0 (may exceed ``a``).
        axis_bearing_rad: compass bearing ``chi`` of the ``a`` axis (rad).
    """

    centre_m: complex
    semi_major_m: float
    semi_minor_m: float
    axis_bearing_rad: float = 0.0

    def __post_init__(self) -> None:
        """Check the semi-axes."""
        for name in ("semi_major_m", "semi_minor_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise LoopError(f"{name} must be a finite number > 0, got {v!r}")

    @property
    def breakpoints_rad(self) -> np.ndarray:
        """Courses where R jumps: none for an ellipse."""
        return np.empty(0)

    def _n(self, gamma: ArrayLike) -> np.ndarray:
        return np.asarray(gamma, dtype=float) - np.pi / 2 - self.axis_bearing_rad

    @cached_property
    def _axis_turn(self) -> complex:
        """``exp(i chi)``, the rotation of the ellipse's axes."""
        return cmath.exp(1j * self.axis_bearing_rad)

    @overload
    def radius(self, gamma: float) -> float: ...
    @overload
    def radius(self, gamma: ArrayLike) -> np.ndarray: ...
    def radius(self, gamma: ArrayLike) -> np.ndarray | float:
        """Radius of curvature ``R(gamma)`` (m); a float for a float ``gamma`` (rad)."""
        a, b = self.semi_major_m, self.semi_minor_m
        if isinstance(gamma, float):  # the control step's case: math, same values as numpy
            n = gamma - math.pi / 2 - self.axis_bearing_rad
            return a * a * b * b / (a * a * math.cos(n) ** 2 + b * b * math.sin(n) ** 2) ** 1.5
        n = self._n(gamma)
        return a * a * b * b / (a * a * np.cos(n) ** 2 + b * b * np.sin(n) ** 2) ** 1.5

    @overload
    def offset(self, gamma: float) -> complex: ...
    @overload
    def offset(self, gamma: ArrayLike) -> np.ndarray: ...
    def offset(self, gamma: ArrayLike) -> np.ndarray | complex:
        """Offset ``rho(gamma)`` of the loop point with tangent course gamma from c0 (m);
        a complex for a float ``gamma`` (rad)."""
        a, b = self.semi_major_m, self.semi_minor_m
        if isinstance(gamma, float):  # the control step's case: math, same values as numpy
            n = gamma - math.pi / 2 - self.axis_bearing_rad
            cos_n, sin_n = math.cos(n), math.sin(n)
            num = a * a * cos_n + 1j * b * b * sin_n
            return self._axis_turn * num * (1.0 / math.sqrt(a * a * cos_n**2 + b * b * sin_n**2))
        n = self._n(gamma)
        num = a * a * np.cos(n) + 1j * b * b * np.sin(n)
        return (
            np.exp(1j * self.axis_bearing_rad)
            * num
            / np.sqrt(a * a * np.cos(n) ** 2 + b * b * np.sin(n) ** 2)
        )

    def offset_and_radius(self, gamma: float) -> tuple[complex, float]:
        """:meth:`offset` (complex m) and :meth:`radius` (m) at one course ``gamma`` (rad),
        sharing its sine and cosine (the nearest-point search's step)."""
        a2, b2 = self.semi_major_m**2, self.semi_minor_m**2
        n = gamma - math.pi / 2 - self.axis_bearing_rad
        cos_n, sin_n = math.cos(n), math.sin(n)
        q = a2 * cos_n * cos_n + b2 * sin_n * sin_n
        root = math.sqrt(q)
        return self._axis_turn * complex(a2 * cos_n, b2 * sin_n) / root, a2 * b2 / (q * root)

    def length_m(self) -> float:
        """Perimeter (m), by Gauss-Legendre quadrature of R over gamma."""
        x, w = _gauss_legendre_64()
        edges = np.linspace(0.0, TWO_PI, 33)
        total = 0.0
        for lo, hi in itertools.pairwise(edges):
            g = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
            total += 0.5 * (hi - lo) * float(np.sum(w * self.radius(g)))
        return total

    def mirrored(self) -> EllipseLoop:
        """Mirror image east -> -east."""
        return EllipseLoop(
            self.centre_m.conjugate(), self.semi_major_m, self.semi_minor_m, -self.axis_bearing_rad
        )


_Num = float | complex | np.ndarray  # a scalar or an array, as numpy broadcasts


@overload
def hermite_poly(u: float, h: float, y0: float, d0: float, y1: float, d1: float) -> float: ...
@overload
def hermite_poly(
    u: float, h: float, y0: complex, d0: complex, y1: complex, d1: complex
) -> complex: ...
@overload
def hermite_poly(u: np.ndarray, h: _Num, y0: _Num, d0: _Num, y1: _Num, d1: _Num) -> np.ndarray: ...
def hermite_poly(u: _Num, h: _Num, y0: _Num, d0: _Num, y1: _Num, d1: _Num) -> _Num:
    """The cubic Hermite polynomial at ``u`` in [0, 1] (dimensionless) of an interval of
    width ``h`` (the table's x unit: rad or s), from values ``y0``, ``y1`` and slopes ``d0``,
    ``d1`` (y unit per x unit) at its ends; floats, complexes or arrays alike
    (:class:`SmoothLoop` and the time-phase tables of :mod:`companion.core.patrol`)."""
    u2, u3 = u * u, u * u * u
    return (
        (2 * u3 - 3 * u2 + 1) * y0
        + (u3 - 2 * u2 + u) * h * d0
        + (-2 * u3 + 3 * u2) * y1
        + (u3 - u2) * h * d1
    )


@cache
def _gauss_legendre_64() -> tuple[np.ndarray, np.ndarray]:
    """64-point Gauss-Legendre nodes and weights on [-1, 1] (an eigenvalue problem: once)."""
    x, w = np.polynomial.legendre.leggauss(64)
    x.flags.writeable = w.flags.writeable = False
    return x, w


def circle(centre_m: complex, radius_m: float) -> EllipseLoop:
    """A circle of radius ``radius_m`` (m) about ``centre_m``."""
    return EllipseLoop(centre_m, radius_m, radius_m, 0.0)


@dataclass(frozen=True)
class ArcLoop:
    """A C1 loop made of circular arcs, e.g. the rounded convex hull of waypoints.

    Piece ``j`` covers courses ``[start_rad[j], start_rad[j+1])`` (cyclically) and its points
    are ``arc_centre_m[j] + radius_m[j] exp(i (gamma - pi/2))``. ``start_rad`` is increasing
    and lies in ``[start_rad[0], start_rad[0] + 2 pi)``.

    Attributes:
        centre_m: the loop's reference centre ``c0`` (m).
        start_rad: course at which each piece starts (rad).
        arc_centre_m: centre of curvature of each piece (m, complex).
        radius_m: radius of each piece (m), > 0.
        vertices_m: hull vertices in travel order (m), for maps and missions.
        corner_radius_m: corner radius ``r_c`` (m).
        edge_radius_m: edge arc radius ``R0`` (m).
    """

    centre_m: complex
    start_rad: np.ndarray
    arc_centre_m: np.ndarray
    radius_m: np.ndarray
    vertices_m: np.ndarray
    corner_radius_m: float
    edge_radius_m: float

    @property
    def breakpoints_rad(self) -> np.ndarray:
        """Courses where R jumps, wrapped to [0, 2 pi) and sorted (rad)."""
        return np.sort(wrap_2pi(self.start_rad))

    def _piece(self, gamma: ArrayLike) -> np.ndarray:
        g0 = self.start_rad[0]
        rel = wrap_2pi(np.asarray(gamma, dtype=float) - g0)
        idx = np.searchsorted(self.start_rad - g0, rel, side="right") - 1
        return np.clip(idx, 0, len(self.start_rad) - 1)

    @overload
    def radius(self, gamma: float) -> float: ...
    @overload
    def radius(self, gamma: ArrayLike) -> np.ndarray: ...
    def radius(self, gamma: ArrayLike) -> np.ndarray | float:
        """Radius of curvature ``R(gamma)`` (m), right-continuous at the joints; a float for a
        float ``gamma`` (rad)."""
        if isinstance(gamma, float):
            return self.offset_and_radius(gamma)[1]
        return self.radius_m[self._piece(gamma)]

    @cached_property
    def _lists(self) -> tuple[float, list[float], list[complex], list[float]]:
        """The first piece's start (rad), the starts relative to it (rad), the pieces'
        centres (complex m) and radii (m), as lists (for one course at a time)."""
        g0 = float(self.start_rad[0])
        rel = (self.start_rad - g0).tolist()
        return g0, rel, self.arc_centre_m.tolist(), self.radius_m.tolist()

    def offset_and_radius(self, gamma: float) -> tuple[complex, float]:
        """:meth:`offset` (complex m) and :meth:`radius` (m) at one course ``gamma`` (rad)."""
        g0, rel, centres, radii = self._lists
        j = min(max(bisect_right(rel, (gamma - g0) % TWO_PI) - 1, 0), len(rel) - 1)
        r = radii[j]
        return centres[j] + r * cmath.exp(1j * (gamma - math.pi / 2)) - self.centre_m, r

    @overload
    def offset(self, gamma: float) -> complex: ...
    @overload
    def offset(self, gamma: ArrayLike) -> np.ndarray: ...
    def offset(self, gamma: ArrayLike) -> np.ndarray | complex:
        """Offset ``rho(gamma)`` of the loop point with tangent course gamma from c0 (m); a
        complex for a float ``gamma`` (rad)."""
        if isinstance(gamma, float):
            return self.offset_and_radius(gamma)[0]
        j = self._piece(gamma)
        g = np.asarray(gamma, dtype=float)
        return (
            self.arc_centre_m[j] + self.radius_m[j] * np.exp(1j * (g - np.pi / 2)) - self.centre_m
        )

    def length_m(self) -> float:
        """Perimeter (m), exact: sum of radius times turned angle."""
        span = np.diff(np.append(self.start_rad, self.start_rad[0] + TWO_PI))
        return float(np.sum(self.radius_m * span))

    def mirrored(self) -> ArcLoop:
        """Mirror image east -> -east (travel order reversed so courses still increase)."""
        return rounded_hull(
            np.conj(self.vertices_m[::-1]),
            corner_radius_m=self.corner_radius_m,
            edge_radius_m=self.edge_radius_m,
            centre_m=self.centre_m.conjugate(),
            _ordered=True,
        )


def rounded_hull(
    points_m: ArrayLike,
    corner_radius_m: float,
    edge_radius_m: float = DEFAULT_EDGE_RADIUS_M,
    centre_m: complex | None = None,
    _ordered: bool = False,
) -> ArcLoop:
    """The strictly convex loop around waypoints (docs/design.md §3).

    Take the convex hull, replace each edge by an outward arc of radius ``edge_radius_m``
    through its two vertices, then take the Minkowski sum with a disc of radius
    ``corner_radius_m``. ``R`` is ``corner_radius_m`` at corners and
    ``edge_radius_m + corner_radius_m`` along edges.

    Args:
        points_m: waypoints, complex ``north + i east`` (m).
        corner_radius_m: corner radius ``r_c`` (m), > 0.
        edge_radius_m: edge arc radius ``R0`` (m), > 0.
        centre_m: reference centre ``c0`` (m); default the hull's area centroid.

    Raises:
        LoopError: fewer than 3 distinct non-collinear points, non-finite values, or an
            edge radius too small for the hull's corners.
    """
    pts = np.asarray(points_m, dtype=complex).ravel()
    if not np.all(np.isfinite(pts)):
        raise LoopError("waypoints must be finite numbers")
    for name, v in (("corner radius", corner_radius_m), ("edge radius", edge_radius_m)):
        if not (np.isfinite(v) and v > 0):
            raise LoopError(f"{name} must be a finite number > 0 m, got {v!r}")
    if _ordered:
        verts = pts
    else:
        uniq = np.unique(np.round(pts, 6))
        if len(uniq) < 3:
            raise LoopError(f"need at least 3 distinct waypoints, got {len(uniq)}")
        xy = np.column_stack([uniq.real, uniq.imag])
        from scipy.spatial import ConvexHull, QhullError  # loaded only here (0.27 s of start-up)

        try:
            hull = ConvexHull(xy)
        except QhullError as exc:
            raise LoopError("waypoints are collinear: their convex hull has no area") from exc
        # Qhull lists 2-D hull vertices counter-clockwise in (x=north, y=east), which is
        # clockwise on a north-up map: the canonical sense of travel.
        verts = uniq[hull.vertices]
        if hull.volume <= 1e-6 * max(1.0, float(np.ptp(xy, axis=0).max()) ** 2):
            raise LoopError("waypoints are collinear: their convex hull has no area")
    n = len(verts)
    chord = np.roll(verts, -1) - verts
    length = np.abs(chord)
    if np.any(length <= 0):
        raise LoopError("waypoints repeat")
    if np.any(length >= 2 * edge_radius_m):
        raise LoopError(f"edge radius {edge_radius_m} m is smaller than half a hull edge")
    phi = np.angle(chord)
    half = np.arcsin(length / (2 * edge_radius_m))
    edge_start = phi - half
    edge_end = phi + half
    corner_turn = wrap_2pi(edge_start - np.roll(edge_end, 1))  # at vertex j
    if np.any(corner_turn <= 1e-9) or np.any(corner_turn >= np.pi):
        raise LoopError("edge radius too small for the hull's corners (arcs would not be convex)")
    # Pieces in travel order: corner at vertex 0, edge 0, corner at vertex 1, edge 1, ...
    starts = []
    centres = []
    radii = []
    course = float(edge_start[0] - corner_turn[0])
    for j in range(n):
        starts.append(course)
        centres.append(verts[j])
        radii.append(corner_radius_m)
        course += float(corner_turn[j])
        starts.append(course)
        # centre of the edge arc: R0 to the right of the start tangent at vertex j
        centres.append(verts[j] - edge_radius_m * np.exp(1j * (edge_start[j] - np.pi / 2)))
        radii.append(edge_radius_m + corner_radius_m)
        course += float(2 * half[j])
    if abs(course - starts[0] - TWO_PI) > 1e-6:
        raise LoopError("hull turning does not add up to one revolution")
    if centre_m is None:
        x, y = verts.real, verts.imag
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        area = 0.5 * np.sum(cross)
        centre_m = complex(
            np.sum((x + np.roll(x, -1)) * cross) / (6 * area),
            np.sum((y + np.roll(y, -1)) * cross) / (6 * area),
        )
    return ArcLoop(
        centre_m=complex(centre_m),
        start_rad=np.asarray(starts),
        arc_centre_m=np.asarray(centres, dtype=complex),
        radius_m=np.asarray(radii, dtype=float),
        vertices_m=verts,
        corner_radius_m=float(corner_radius_m),
        edge_radius_m=float(edge_radius_m),
    )


@dataclass(frozen=True)
class SmoothLoop:
    """A loop whose curvature has been smoothed in course: C2 instead of C1.

    ``R_s = R * g`` (circular convolution in gamma with a Gaussian of standard deviation
    ``smoothing_rad``). Convolution multiplies each Fourier coefficient of ``R`` by the
    kernel's, so the closure condition ``int R exp(i gamma) d gamma = 0`` (the first
    coefficient) still holds exactly, the length ``int R d gamma`` is unchanged, and
    ``R_s >= min R``: still strictly convex and no tighter than the original. ``rho`` is
    integrated spectrally and evaluated by cubic Hermite interpolation on a fine grid.

    Why: a rounded hull's curvature jumps at every corner/edge joint (from ``1/r_c`` to
    ``1/(R0 + r_c)``). A sampled-data controller that holds its turn rate over a control
    period overshoots the course at each joint, and on an edge of radius ``R0`` a course
    error ``d gamma`` shows up as a centre error ``R0 d gamma`` (tens of metres for
    R0 = 50 km). A continuous curvature removes those kicks.

    Attributes:
        base: the loop that was smoothed.
        smoothing_rad: kernel standard deviation (rad of course).
    """

    base: ArcLoop
    smoothing_rad: float
    _g: np.ndarray  # uniform grid [0, 2 pi] (rad)
    _r: np.ndarray  # smoothed R on the grid (m)
    _rho: np.ndarray  # offset on the grid (m, complex)

    @classmethod
    def of(cls, base: ArcLoop, smoothing_rad: float, grid: int = 1 << 16) -> SmoothLoop:
        """Smooth ``base`` with a Gaussian of ``smoothing_rad`` (rad) in course."""
        if not (np.isfinite(smoothing_rad) and 0 < smoothing_rad < 0.5):
            raise LoopError(f"smoothing must be between 0 and 0.5 rad, got {smoothing_rad!r}")
        g = np.arange(grid) * (TWO_PI / grid)
        coeff = np.fft.fft(base.radius(g)) / grid
        freq = np.fft.fftfreq(grid, d=1.0 / grid)  # integer frequencies
        coeff *= np.exp(-0.5 * (freq * smoothing_rad) ** 2)
        coeff[1] = coeff[-1] = 0.0  # closure: exact for the smoothed loop
        r_s = np.real(np.fft.ifft(coeff) * grid)
        # R e^{i g} has coefficient coeff[k - 1] at frequency k; integrate term by term
        shifted = np.roll(coeff, 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_c = np.where(freq != 0, shifted / (1j * freq), 0.0)
        rho = np.fft.ifft(rho_c) * grid
        rho += np.mean(base.offset(g) - rho)  # stay centred on the original loop
        g = np.append(g, TWO_PI)
        return cls(base, float(smoothing_rad), g, np.append(r_s, r_s[0]), np.append(rho, rho[0]))

    @property
    def centre_m(self) -> complex:
        """Reference centre ``c0`` (m), as the base loop's."""
        return self.base.centre_m

    @property
    def vertices_m(self) -> np.ndarray:
        """The base loop's hull vertices (m)."""
        return self.base.vertices_m

    @property
    def breakpoints_rad(self) -> np.ndarray:
        """Courses where R jumps: none."""
        return np.empty(0)

    @cached_property
    def _lists(self) -> tuple[float, int, list[float], list[float], list[complex]]:
        """Grid step (rad), last interval, and the grid, R and rho tables as lists."""
        return (
            float(self._g[1]),
            len(self._g) - 2,
            self._g.tolist(),
            self._r.tolist(),
            self._rho.tolist(),
        )

    def _locate_float(self, gamma: float) -> tuple[int, float]:
        """:meth:`_locate` of one course (rad): the same arithmetic on floats."""
        h, last, g, _, _ = self._lists
        x = wrap_2pi(gamma)
        j = min(int(x / h), last)
        return j, (x - g[j]) / h

    def _locate(self, gamma: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        x = wrap_2pi(np.asarray(gamma, dtype=float))
        h = self._g[1]
        j = np.minimum((x / h).astype(int), len(self._g) - 2)
        return j, (x - self._g[j]) / h

    @overload
    def radius(self, gamma: float) -> float: ...
    @overload
    def radius(self, gamma: ArrayLike) -> np.ndarray: ...
    def radius(self, gamma: ArrayLike) -> np.ndarray | float:
        """Smoothed radius of curvature (m), linear between grid nodes; a float for a float
        ``gamma`` (rad)."""
        if isinstance(gamma, float):  # the control step's case: same values as numpy
            j, u = self._locate_float(gamma)
            r = self._lists[3]
            return r[j] * (1 - u) + r[j + 1] * u
        j, u = self._locate(gamma)
        return self._r[j] * (1 - u) + self._r[j + 1] * u

    @overload
    def offset(self, gamma: float) -> complex: ...
    @overload
    def offset(self, gamma: ArrayLike) -> np.ndarray: ...
    def offset(self, gamma: ArrayLike) -> np.ndarray | complex:
        """Offset ``rho(gamma)`` from c0 (m, complex), cubic Hermite on the grid; a complex
        for a float ``gamma`` (rad)."""
        if isinstance(gamma, float):  # the control step's case: same values as numpy
            j, u = self._locate_float(gamma)
            h, _, g, r, rho = self._lists
            d0 = r[j] * cmath.exp(1j * g[j])
            d1 = r[j + 1] * cmath.exp(1j * g[j + 1])
            return hermite_poly(u, h, rho[j], d0, rho[j + 1], d1)
        j, u = self._locate(gamma)
        h = self._g[1]
        d0 = self._r[j] * np.exp(1j * self._g[j])
        d1 = self._r[j + 1] * np.exp(1j * self._g[j + 1])
        return hermite_poly(u, h, self._rho[j], d0, self._rho[j + 1], d1)

    def offset_and_radius(self, gamma: float) -> tuple[complex, float]:
        """:meth:`offset` (complex m) and :meth:`radius` (m) at one course ``gamma`` (rad)."""
        j, u = self._locate_float(gamma)
        h, _, g, r, rho = self._lists
        r0, r1 = r[j], r[j + 1]
        d0 = r0 * cmath.exp(1j * g[j])
        d1 = r1 * cmath.exp(1j * g[j + 1])
        return hermite_poly(u, h, rho[j], d0, rho[j + 1], d1), r0 * (1 - u) + r1 * u

    def length_m(self) -> float:
        """Perimeter (m): unchanged by the smoothing."""
        return self.base.length_m()

    def mirrored(self) -> SmoothLoop:
        """Mirror image east -> -east."""
        return SmoothLoop.of(self.base.mirrored(), self.smoothing_rad, len(self._g) - 1)


LoopShape = EllipseLoop | ArcLoop | SmoothLoop
