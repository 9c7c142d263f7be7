"""Model-free patrol measures from true positions (docs/design.md §8): cross-track, coverage.

Pure functions: numpy in, numbers out; no files, no clocks. Positions are complex
``north + i east`` (m), times simulated seconds. Nothing here uses a course, a wind or a
time-phase: only the loop's geometry C, the sensor radius and where the aircraft really were.

* **cross-track**: an aircraft's distance from the loop C (m), computed against a dense
  polyline of C (vertices every ~1 m, so the chord error is below 2 mm on a 100 m radius).
* **passes**: points every ~10 m along C; a point is *covered* at a sample time when some
  aircraft is within the sensor radius of it; a *pass* is a maximal run of consecutive
  covered samples. The *pass interval* is start-to-start between successive passes of the
  same point; an *unseen stretch* runs from the last covered sample of one pass to the first
  of the next (or from the start of the log, or to the end of the window).
* **unseen age** of a point at time t: t minus the last covered sample at or before t (the
  start of the log if never covered). The longest unseen time over a window is the largest
  age reached at any time in the window.
* **within bounds** at a sample: every patrolling aircraft's cross-track <= ``XT_BOUND_M``
  and no point's unseen age > ``UNSEEN_BOUND_RATIO`` T/N.
* **settle time**: the start of the first stretch within bounds (alert episodes excused)
  lasting at least one loop period T. The measuring window runs from one loop period after
  the settle time to the end of the log (as the formation's "steady" figures do), if that
  leaves at least one loop period; otherwise it is the second half of the log and the run
  counts as not settled.

"Excluding alert episodes" drops pass intervals and unseen stretches that overlap an
episode (a prosecutor's tasking to its return to its slot), as the formation is then one
aircraft short by design; an aircraft's own cross-track is never counted while it is away.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

XT_BOUND_M = 10.0  # cross-track bound of "within bounds" (m)
UNSEEN_BOUND_RATIO = 1.5  # unseen-age bound of "within bounds", in units of T/N
POINT_SPACING_M = 10.0  # coverage points along C (m)
POLYLINE_SPACING_M = 1.0  # vertices of the cross-track polyline (m)
_DENSE_PER_M = 8  # phase samples per metre before resampling by arc length


def resample_closed(loop_m: np.ndarray, spacing_m: float) -> np.ndarray:
    """Points equally spaced by arc length (about ``spacing_m``, m) along a closed polyline.

    ``loop_m``: vertices of a closed curve (complex m, in order, the first not repeated).
    Returns complex vertices, the first being ``loop_m[0]``.
    """
    z = np.asarray(loop_m, dtype=complex)
    closed = np.append(z, z[0])
    s = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(closed)))])
    n = max(3, int(np.ceil(s[-1] / spacing_m)))
    st = np.arange(n) * s[-1] / n
    return np.interp(st, s, closed.real) + 1j * np.interp(st, s, closed.imag)


def loop_points(point_at_phase, length_m: float, spacing_m: float) -> np.ndarray:
    """Points of a loop every ``spacing_m`` (m) of arc length.

    ``point_at_phase``: a vectorised map from a parameter in [0, 2 pi) to loop points
    (complex m), such as ``Patrol.point_at_phase``; ``length_m``: the loop's length (m).
    """
    m = max(4096, int(np.ceil(length_m * _DENSE_PER_M)))
    dense = np.asarray(point_at_phase(np.arange(m) * 2 * np.pi / m), dtype=complex)
    return resample_closed(dense, spacing_m)


@dataclass(frozen=True)
class Polyline:
    """A closed polyline with a k-d tree of its vertices, for fast distance queries."""

    vertices_m: np.ndarray  # complex m, closed implicitly (last joins first)
    tree: cKDTree

    @classmethod
    def of(cls, vertices_m: np.ndarray) -> Polyline:
        """Index ``vertices_m`` (complex m)."""
        v = np.asarray(vertices_m, dtype=complex)
        return cls(v, cKDTree(np.column_stack([v.real, v.imag])))

    def distance_m(self, points_m: np.ndarray, k: int = 4) -> np.ndarray:
        """Distance (m) from each point (complex m, any shape) to the polyline.

        The segments on either side of the ``k`` nearest vertices are searched; the result
        is exact for the polyline except at points about equidistant from two distant parts
        of it, where it may exceed the truth by at most ``h^2 / (2 d)`` (h the vertex
        spacing, d the distance).
        """
        p = np.asarray(points_m, dtype=complex)
        flat = p.ravel()
        if flat.size == 0:
            return np.zeros(p.shape)
        v = self.vertices_m
        n = v.size
        k = min(k, n)
        _, idx = self.tree.query(np.column_stack([flat.real, flat.imag]), k=k)
        idx = np.asarray(idx).reshape(flat.size, k)
        a = np.concatenate([idx, (idx - 1) % n], axis=1)  # segment a -> a + 1
        va, vb = v[a], v[(a + 1) % n]
        d = vb - va
        q = flat[:, None] - va
        u = np.clip((q.real * d.real + q.imag * d.imag) / np.maximum(np.abs(d) ** 2, 1e-300), 0, 1)
        dist = np.min(np.abs(q - u * d), axis=1)
        return dist.reshape(p.shape)


@dataclass(frozen=True)
class Passes:
    """Sensor passes over points: run ``j`` covers point ``point[j]`` at samples
    ``start[j]..end[j]`` (inclusive indices into the sample times), sorted by point then
    time."""

    n_points: int
    point: np.ndarray
    start: np.ndarray
    end: np.ndarray


def _sorted_unique(x: np.ndarray) -> np.ndarray:
    """The distinct values of an integer array, sorted (``np.unique`` without its slow
    paths: it took 50 s for 5 million integers with numpy 2.3)."""
    x = np.sort(x)
    keep = np.ones(x.size, dtype=bool)
    keep[1:] = x[1:] != x[:-1]
    return x[keep]


def sensor_passes(points_m: np.ndarray, pos_m: np.ndarray, radius_m: float) -> Passes:
    """Passes of any aircraft's sensor disc over each point.

    ``points_m``: (P,) complex m; ``pos_m``: (A, S) complex m, aircraft x sample;
    ``radius_m``: sensor disc radius (m). A point is covered at a sample when some aircraft
    is within ``radius_m`` of it (inclusive).
    """
    pts = np.asarray(points_m, dtype=complex)
    pos = np.atleast_2d(np.asarray(pos_m, dtype=complex))
    n_s = pos.shape[1]
    empty = np.empty(0, dtype=np.int64)
    if pts.size == 0 or pos.size == 0:
        return Passes(pts.size, empty, empty, empty)
    flat = pos.ravel()
    ok = np.isfinite(flat)
    tree_p = cKDTree(np.column_stack([pts.real, pts.imag]))
    tree_a = cKDTree(np.column_stack([flat.real[ok], flat.imag[ok]]))
    pairs = tree_p.sparse_distance_matrix(tree_a, radius_m, output_type="ndarray")
    sample = np.flatnonzero(ok)[pairs["j"]] % n_s
    key = _sorted_unique(pairs["i"].astype(np.int64) * n_s + sample)
    p, s = key // n_s, key % n_s
    new = np.ones(key.size, dtype=bool)
    new[1:] = (p[1:] != p[:-1]) | (s[1:] != s[:-1] + 1)
    first = np.flatnonzero(new)
    last = np.append(first[1:] - 1, key.size - 1) if key.size else empty
    return Passes(pts.size, p[first], s[first], s[last])


def _overlaps(a: np.ndarray, b: np.ndarray, episodes: Sequence[tuple[float, float]]) -> np.ndarray:
    """Whether each closed interval [a, b] meets some episode [t0, t1]."""
    hit = np.zeros(np.shape(a), dtype=bool)
    for t0, t1 in episodes:
        hit |= (a <= t1) & (b >= t0)
    return hit


def pass_intervals(t_s: np.ndarray, passes: Passes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start-to-start intervals between successive passes of the same point.

    Returns ``(point, t_from_s, t_to_s)``: for each interval its point and the start times of
    the two passes (s).
    """
    same = passes.point[1:] == passes.point[:-1]
    t = np.asarray(t_s, dtype=float)
    return passes.point[1:][same], t[passes.start[:-1][same]], t[passes.start[1:][same]]


def unseen_stretches(t_s: np.ndarray, passes: Passes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stretches when each point was unseen: ``(point, from_s, to_s)``.

    From the last covered sample of a pass (or the first sample of the log) to the first
    covered sample of the next pass (``inf`` if not seen again before the log ends).
    """
    t = np.asarray(t_s, dtype=float)
    last_i = t.size - 1
    pts, a, b = [], [], []
    same = passes.point[1:] == passes.point[:-1]
    pts.append(passes.point[1:][same])
    a.append(t[passes.end[:-1][same]])
    b.append(t[passes.start[1:][same]])
    if passes.point.size:
        head = np.ones(passes.point.size, dtype=bool)
        head[1:] = ~same
        tail = np.ones(passes.point.size, dtype=bool)
        tail[:-1] = ~same
        lead = head & (passes.start > 0)
        pts.append(passes.point[lead])
        a.append(np.full(int(lead.sum()), t[0]))
        b.append(t[passes.start[lead]])
        trail = tail & (passes.end < last_i)
        pts.append(passes.point[trail])
        a.append(t[passes.end[trail]])
        b.append(np.full(int(trail.sum()), np.inf))
    never = np.setdiff1d(np.arange(passes.n_points), passes.point)
    if t.size:
        pts.append(never)
        a.append(np.full(never.size, t[0]))
        b.append(np.full(never.size, np.inf))
    return np.concatenate(pts), np.concatenate(a), np.concatenate(b)


def max_unseen_age_s(t_s: np.ndarray, from_s: np.ndarray, to_s: np.ndarray) -> np.ndarray:
    """At each time, the largest unseen age over the stretches ``[from_s, to_s)`` (s).

    The age at time t in a stretch is ``t - from_s``; 0 where no stretch is open.
    """
    t = np.asarray(t_s, dtype=float)
    if np.size(from_s) == 0:
        return np.zeros(t.size)
    order = np.argsort(from_s, kind="stable")
    a, b = np.asarray(from_s)[order], np.asarray(to_s)[order]
    # the earliest-starting open stretch is the first whose running-max end exceeds t
    reach = np.maximum.accumulate(b)
    i = np.searchsorted(reach, t, side="right")
    inside = i < a.size
    j = np.minimum(i, a.size - 1)
    open_ = inside & (a[j] <= t)
    return np.where(open_, t - a[j], 0.0)


def longest_unseen_s(from_s: np.ndarray, to_s: np.ndarray, w0_s: float, w1_s: float) -> float:
    """Largest unseen age reached in ``[w0_s, w1_s]`` over the stretches (s); 0 if none."""
    a, b = np.asarray(from_s, dtype=float), np.asarray(to_s, dtype=float)
    hit = (b > w0_s) & (a < w1_s)
    return float(np.max(np.minimum(b[hit], w1_s) - a[hit])) if hit.any() else 0.0


def first_stretch_start(t_s: np.ndarray, ok: np.ndarray, min_length_s: float) -> float | None:
    """Start time of the first run of True in ``ok`` lasting at least ``min_length_s`` (s)."""
    t = np.asarray(t_s, dtype=float)
    ok = np.asarray(ok, dtype=bool)
    if not ok.any():
        return None
    edge = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1) - 1
    long = t[ends] - t[starts] >= min_length_s
    return float(t[starts[long][0]]) if long.any() else None


@dataclass(frozen=True)
class PatrolMeasures:
    """The model-free measures of a run over its measuring window (see the module doc)."""

    settle_time_s: float | None
    settled: bool  # the window starts one period after settling (else: second half)
    window_start_s: float
    window_end_s: float
    cross_track_median_m: float | None
    cross_track_p95_m: float | None
    cross_track_max_m: float | None
    max_pass_interval_s: float | None
    max_pass_interval_excl_alerts_s: float | None
    mean_pass_interval_s: float | None
    coverage_revisit_ratio: float | None
    coverage_revisit_ratio_excl_alerts: float | None
    longest_unseen_s: float
    longest_unseen_excl_alerts_s: float
    longest_unseen_ratio: float
    longest_unseen_excl_alerts_ratio: float
    points_never_seen_in_window: int
    fraction_within_bounds: float
    fraction_within_bounds_excl_alerts: float
    coverage_points: int


def _stat(x: np.ndarray, f) -> float | None:
    return float(f(x)) if x.size else None


def patrol_measures(
    t_s: np.ndarray,
    pos_m: np.ndarray,
    away: np.ndarray,
    points_m: np.ndarray,
    polyline: Polyline,
    radius_m: float,
    ideal_revisit_s: float,
    period_s: float,
    episodes: Sequence[tuple[float, float]] = (),
) -> PatrolMeasures:
    """Cross-track, coverage revisit, longest unseen and time within bounds.

    Args:
        t_s: (S,) sample times, increasing (s).
        pos_m: (A, S) true positions (complex m).
        away: (A, S) True where the aircraft is away on an alert (its cross-track is not
            counted).
        points_m: (P,) coverage points along C (complex m).
        polyline: the loop C for cross-track.
        radius_m: sensor disc radius (m).
        ideal_revisit_s: T/N (s), the unit of the revisit and unseen ratios.
        period_s: loop period T (s): how long a stretch within bounds must last to settle.
        episodes: alert episodes ``(t0_s, t1_s)``, excused in the ``_excl_alerts`` figures.
    """
    t = np.asarray(t_s, dtype=float)
    pos = np.atleast_2d(np.asarray(pos_m, dtype=complex))
    away = np.atleast_2d(np.asarray(away, dtype=bool))
    xt = polyline.distance_m(pos)
    xt_max = np.max(np.where(away, 0.0, xt), axis=0) if pos.shape[0] else np.zeros(t.size)
    passes = sensor_passes(points_m, pos, radius_m)
    _, sa, sb = unseen_stretches(t, passes)
    excused = _overlaps(sa, sb, episodes)
    in_episode = _overlaps(t, t, episodes)
    bound_s = UNSEEN_BOUND_RATIO * ideal_revisit_s
    ok_all = (xt_max <= XT_BOUND_M) & (max_unseen_age_s(t, sa, sb) <= bound_s)
    ok_excl = (xt_max <= XT_BOUND_M) & (max_unseen_age_s(t, sa[~excused], sb[~excused]) <= bound_s)
    settle = first_stretch_start(t, ok_excl | in_episode, period_s)
    w1 = float(t[-1]) if t.size else 0.0
    settled = settle is not None and settle + 2 * period_s <= w1
    w0 = settle + period_s if settled else (float(t[0]) + w1) / 2 if t.size else 0.0
    win = t >= w0
    xt_win = xt[:, win][~away[:, win]]
    _, ia, ib = pass_intervals(t, passes)
    inside = (ia >= w0) & (ib <= w1)
    gaps = ib[inside] - ia[inside]
    gaps_excl = gaps[~_overlaps(ia[inside], ib[inside], episodes)]
    lu = longest_unseen_s(sa, sb, w0, w1)
    lu_excl = longest_unseen_s(sa[~excused], sb[~excused], w0, w1)
    seen = _sorted_unique(passes.point[t[passes.end] >= w0])
    outside = win & ~in_episode

    def ratio(x: float | None) -> float | None:
        return None if x is None else x / ideal_revisit_s

    return PatrolMeasures(
        settle_time_s=settle,
        settled=settled,
        window_start_s=w0,
        window_end_s=w1,
        cross_track_median_m=_stat(xt_win, np.median),
        cross_track_p95_m=_stat(xt_win, lambda x: np.percentile(x, 95)),
        cross_track_max_m=_stat(xt_win, np.max),
        max_pass_interval_s=_stat(gaps, np.max),
        max_pass_interval_excl_alerts_s=_stat(gaps_excl, np.max),
        mean_pass_interval_s=_stat(gaps, np.mean),
        coverage_revisit_ratio=ratio(_stat(gaps, np.max)),
        coverage_revisit_ratio_excl_alerts=ratio(_stat(gaps_excl, np.max)),
        longest_unseen_s=lu,
        longest_unseen_excl_alerts_s=lu_excl,
        longest_unseen_ratio=lu / ideal_revisit_s,
        longest_unseen_excl_alerts_ratio=lu_excl / ideal_revisit_s,
        points_never_seen_in_window=int(passes.n_points - seen.size),
        fraction_within_bounds=float(ok_all[win].mean()) if win.any() else 0.0,
        fraction_within_bounds_excl_alerts=float(ok_excl[outside].mean()) if outside.any() else 0.0,
        coverage_points=int(passes.n_points),
    )


class LiveCoverage:
    """Cross-track and unseen age as truth samples arrive (for a live progress line).

    Feed it samples with :meth:`update`; read :attr:`cross_track_m` (latest per aircraft)
    and :meth:`longest_unseen_now_s`.
    """

    def __init__(self, points_m: np.ndarray, polyline: Polyline, radius_m: float) -> None:
        """Coverage ``points_m`` (complex m), the loop ``polyline``, sensor ``radius_m`` (m)."""
        pts = np.asarray(points_m, dtype=complex)
        self._tree = cKDTree(np.column_stack([pts.real, pts.imag]))
        self._polyline = polyline
        self._radius_m = float(radius_m)
        self._last_seen_s = np.full(pts.size, np.nan)
        self.t_s = float("nan")
        self.cross_track_m: dict[int, float] = {}

    def update(self, t_s: np.ndarray, sysid: np.ndarray, pos_m: np.ndarray) -> None:
        """Add samples: times (s, non-decreasing), aircraft ids, true positions (complex m)."""
        t = np.asarray(t_s, dtype=float)
        pos = np.asarray(pos_m, dtype=complex)
        if t.size == 0:
            return
        if np.isnan(self.t_s):
            self._last_seen_s[:] = t[0]
        xt = self._polyline.distance_m(pos)
        for s, d in zip(np.asarray(sysid).tolist(), xt.tolist(), strict=True):
            self.cross_track_m[int(s)] = d
        near = self._tree.query_ball_point(np.column_stack([pos.real, pos.imag]), self._radius_m)
        for tj, idx in zip(t.tolist(), near, strict=True):
            if idx:
                self._last_seen_s[idx] = tj
        self.t_s = float(t[-1])

    def longest_unseen_now_s(self) -> float | None:
        """The largest unseen age of any point at the newest sample (s); None before any."""
        if np.isnan(self.t_s):
            return None
        return float(self.t_s - np.min(self._last_seen_s))
