"""Geofence geometry (pure): an inclusion polygon plus altitude bounds.

Conventions (as everywhere in :mod:`companion.core`): points are complex numbers
``north + i east`` in metres in the mission's local frame; a polygon is the sequence of its
vertices in order (either sense), closed implicitly (the last vertex joins the first).

* :func:`point_in_polygon`: even-odd ray casting, vectorised over points and edges;
* :func:`signed_distance_m`: distance to the boundary, positive inside, negative outside;
* :func:`support_polygon`: a polygon circumscribing a point set grown by a distance (the
  default fence: the loop offset outward);
* :func:`polygon_fault`: why a vertex list is not a usable simple polygon, or None;
* :func:`first_outside`: the first sample of a track that leaves the polygon, or None.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

REPEAT_TOL_M = 1.0  # two vertices closer than this are the same vertex
DEFAULT_SIDES = 32  # sides of a default (support) polygon


@dataclass(frozen=True)
class Fence:
    """An inclusion polygon (local m) and the altitude band (m above the origin/home).

    Attributes:
        polygon_m: the vertices in order (complex north + i east, m), at least 3.
        min_alt_m: lowest allowed altitude (m above home).
        max_alt_m: highest allowed altitude (m above home).
    """

    polygon_m: tuple[complex, ...]
    min_alt_m: float
    max_alt_m: float

    def contains(self, points_m: ArrayLike) -> np.ndarray:
        """Whether each point (complex m) is inside the polygon (bool array)."""
        return point_in_polygon(points_m, self.polygon_m)

    def first_outside(self, track_m: ArrayLike) -> int | None:
        """Index of the first point of ``track_m`` (complex m) outside the polygon, or None."""
        return first_outside(track_m, self.polygon_m)


def _edges(polygon_m: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(polygon_m, dtype=complex).ravel()
    return a, np.roll(a, -1)


def point_in_polygon(points_m: ArrayLike, polygon_m: ArrayLike) -> np.ndarray:
    """Whether each point lies inside the polygon (even-odd rule; bool array of the points'
    shape). A point exactly on the boundary may count either way."""
    p = np.asarray(points_m, dtype=complex)
    a, b = _edges(polygon_m)
    x, y = p.real[..., None], p.imag[..., None]  # north, east
    ax, ay, bx, by = a.real, a.imag, b.real, b.imag
    straddles = (ay > y) != (by > y)  # the edge crosses the line east = y
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = ax + (y - ay) * (bx - ax) / (by - ay)
    crossings = np.count_nonzero(straddles & (x < x_cross), axis=-1)
    return crossings % 2 == 1


def signed_distance_m(points_m: ArrayLike, polygon_m: ArrayLike) -> np.ndarray:
    """Distance (m) from each point to the polygon's boundary: positive inside, negative
    outside (array of the points' shape)."""
    p = np.asarray(points_m, dtype=complex)
    a, b = _edges(polygon_m)
    d = b - a
    length2 = np.maximum(np.abs(d) ** 2, 1e-18)
    rel = p[..., None] - a
    s = np.clip((rel.real * d.real + rel.imag * d.imag) / length2, 0.0, 1.0)
    dist = np.min(np.abs(rel - s * d), axis=-1)
    return np.where(point_in_polygon(p, polygon_m), dist, -dist)


def support_polygon(points_m: ArrayLike, offset_m: float, sides: int = DEFAULT_SIDES) -> np.ndarray:
    """A convex polygon (``sides`` vertices, clockwise on the map) containing every point
    of ``points_m`` grown by ``offset_m`` (m).

    Each side lies on a support line of the point set pushed out by ``offset_m``, for
    ``sides`` outward normals equally spaced in angle, so the polygon circumscribes the
    offset convex hull; it extends beyond it by at most ``(h / cos(pi / sides) - h)`` where
    ``h`` is the largest support distance from the origin of the frame.
    """
    p = np.asarray(points_m, dtype=complex).ravel()
    if p.size == 0 or sides < 3 or not offset_m >= 0:
        raise ValueError("need points, at least 3 sides and a non-negative offset")
    normals = np.exp(1j * 2.0 * np.pi * np.arange(sides) / sides)  # compass angles: clockwise
    h = np.max(
        p.real[None, :] * normals.real[:, None] + p.imag[None, :] * normals.imag[:, None], axis=1
    )
    h = h + offset_m
    n2, h2 = np.roll(normals, -1), np.roll(h, -1)
    det = normals.real * n2.imag - normals.imag * n2.real
    north = (h * n2.imag - h2 * normals.imag) / det
    east = (normals.real * h2 - n2.real * h) / det
    return north + 1j * east


def polygon_fault(polygon_m: ArrayLike) -> tuple[int, str] | None:
    """Why the vertex list is not a simple polygon: ``(vertex index, problem)``, or None.

    Problems: fewer than 3 vertices, a vertex repeated (within :data:`REPEAT_TOL_M`), two
    non-adjacent edges crossing, or no area.
    """
    a = np.asarray(polygon_m, dtype=complex).ravel()
    n = a.size
    if n < 3:
        return 0, f"expected at least 3 vertices, got {n}"
    for i in range(n):
        close = np.flatnonzero(np.abs(a[i + 1 :] - a[i]) < REPEAT_TOL_M)
        if close.size:
            j = i + 1 + int(close[0])
            return j, f"repeats vertex {i} (within {REPEAT_TOL_M:g} m)"
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # adjacent through the closing edge
            if _segments_cross(a[i], a[(i + 1) % n], a[j], a[(j + 1) % n]):
                return j, f"edge {j}-{(j + 1) % n} crosses edge {i}-{i + 1}"
    x, y = a.real, a.imag
    area = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    if area < REPEAT_TOL_M**2:
        return 0, "the polygon has no area (vertices in a line)"
    return None


def _segments_cross(p1: complex, p2: complex, q1: complex, q2: complex) -> bool:
    """Whether closed segments p1-p2 and q1-q2 intersect (touching counts)."""

    def orient(a: complex, b: complex, c: complex) -> float:
        u, v = b - a, c - a
        return u.real * v.imag - u.imag * v.real

    def on(a: complex, b: complex, c: complex) -> bool:
        return min(a.real, b.real) <= c.real <= max(a.real, b.real) and min(
            a.imag, b.imag
        ) <= c.imag <= max(a.imag, b.imag)

    d1, d2 = orient(q1, q2, p1), orient(q1, q2, p2)
    d3, d4 = orient(p1, p2, q1), orient(p1, p2, q2)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 * d2 < 0 and d3 * d4 < 0:
        return True
    eps = 1e-9
    return (
        (abs(d1) < eps and on(q1, q2, p1))
        or (abs(d2) < eps and on(q1, q2, p2))
        or (abs(d3) < eps and on(p1, p2, q1))
        or (abs(d4) < eps and on(p1, p2, q2))
    )


def first_outside(track_m: ArrayLike, polygon_m: ArrayLike) -> int | None:
    """Index of the first point of ``track_m`` (complex m) outside the polygon, or None."""
    inside = point_in_polygon(np.asarray(track_m, dtype=complex).ravel(), polygon_m)
    out = np.flatnonzero(~inside)
    return int(out[0]) if out.size else None
