"""Is a waypoint list the outline of a convex perimeter? (pure geometry, docs/design.md §3)

The patrol loop around waypoints is their rounded convex hull, so a waypoint that is not a
corner of that hull would be silently skipped by the loop, and a list that does not go
round the hull in order describes a different (self-crossing) shape than the one flown.
:func:`outline_fault` finds the first such waypoint so the caller can name it: a repeat of
an earlier waypoint, a dent (strictly inside the hull of the others), or a waypoint out of
order around the hull (the outline as listed crosses itself). Either sense of listing is
fine; the sense of travel is set separately.

Positions are complex ``north + i east`` (m). "No fault" is a result (``None``), not an
exception; too few or collinear points are left to :func:`companion.core.loops.rounded_hull`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

OUTLINE_TOL_M = 1.0  # closer than this (m) is "the same point" / "on the hull"


@dataclass(frozen=True)
class OutlineFault:
    """The first waypoint that keeps a list from being a convex outline.

    Attributes:
        index: 0-based index of the offending waypoint.
        kind: "repeat", "dent" or "order".
        other: for a repeat, the index of the earlier waypoint it repeats; else None.
        depth_m: for a dent, how far inside the hull of the others it lies (m); else 0.
    """

    index: int
    kind: str
    other: int | None = None
    depth_m: float = 0.0


def outline_fault(points_m: ArrayLike, tol_m: float = OUTLINE_TOL_M) -> OutlineFault | None:
    """The first waypoint that is a repeat, a dent or out of order, or None if all are fine.

    Args:
        points_m: waypoints in the order given, complex ``north + i east`` (m).
        tol_m: points closer than this are repeats, and a waypoint within this distance of
            the hull's boundary counts as on it (m), > 0.

    Returns:
        None when the waypoints, as listed, go once round their convex hull with each on
        its boundary; None too for fewer than 3 points or a hull without area (the loop
        builder refuses those with its own message).
    """
    pts = np.asarray(points_m, dtype=complex).ravel()
    n = len(pts)
    if n < 3 or not np.all(np.isfinite(pts)):
        return None
    gap = np.abs(pts[:, None] - pts[None, :])
    for j in range(1, n):
        close = np.flatnonzero(gap[j, :j] <= tol_m)
        if close.size:
            return OutlineFault(j, "repeat", other=int(close[0]))
    xy = np.column_stack([pts.real, pts.imag])
    from scipy.spatial import ConvexHull, QhullError  # loaded only here (0.27 s of start-up)

    try:
        hull = ConvexHull(xy)
    except QhullError:
        return None
    if hull.volume <= 1e-6 * max(1.0, float(np.ptp(xy, axis=0).max()) ** 2):
        return None
    # hull.equations: unit outward normal (a, b) and offset c, a x + b y + c <= 0 inside
    depth = -np.max(xy @ hull.equations[:, :2].T + hull.equations[:, 2], axis=1)
    for i in range(n):
        if depth[i] > tol_m:
            return OutlineFault(i, "dent", depth_m=float(depth[i]))
    # every point is on the boundary: their angles about an interior point order them
    # round the hull; the list must visit them in that cyclic order, one way or the other
    inner = xy[hull.vertices].mean(axis=0)
    rank = np.argsort(np.argsort(np.angle(pts - complex(*inner))))
    steps = (np.roll(rank, -1) - rank) % n
    counts = Counter(steps.tolist())
    forward = 1 if counts[1] >= counts[n - 1] else n - 1
    bad = np.flatnonzero(steps != forward)
    if bad.size:
        return OutlineFault(int((bad[0] + 1) % n), "order")
    return None
