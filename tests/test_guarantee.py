"""The crossing guarantee (companion/core/guarantee.py): a table of known values, the UAVs
needed for a speed, and the promise against a brute-force simulation of crossings.

The brute force knows nothing of the derivation: on a generated base (corners, wind and all)
N UAVs fly the loop in even time splay (time-phase ``psi0 + 2 pi t / T + 2 pi k / N``); an
intruder crosses the sensor band at a loop point drawn by arc length, at a time, angle and
side drawn at random, on a straight line or on a random path with turns and stops; it is seen
when some UAV comes within the footprint radius of it while it is in the band (the distance
over each 0.2 s step taken at its closest approach, the motions linear over the step). Every
crossing no faster than the promise must be seen, and some a little faster must be missed
(the promise is the best there is, not merely safe).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from companion.core.guarantee import (
    AWAY_UNSEEN_REVISITS,
    crossing_guarantee,
    describe,
    revisit_gap_s,
    vehicles_needed,
)
from companion.core.wind import groundspeed_from_course
from companion.mission import parse_mission
from companion.mission.generate import generate

DT_S = 0.2
TABLE = 1 << 15  # loop points by time-phase


def test_known_values():
    # r_s 50 m, T 120 s, 6 UAVs: a gap of 20 s, so 100 m / 20 s = 5 m/s at any angle
    g = crossing_guarantee(120.0, 6, 50.0, 20.0, 0.0)
    assert g.gap_s == 20.0 and g.sure_m_s == 5.0 and not g.continuous
    # straight across, at 20 m/s: 1 / sqrt((20 / 100)^2 - (1 / 20)^2)
    assert g.across_m_s == pytest.approx(1.0 / math.sqrt(0.04 - 0.0025))
    assert g.worst_angle_deg == pytest.approx(math.degrees(math.acos(100.0 / 400.0)))
    # wind 5 m/s: the same speed (the patrol's speed drops out), the worst angle at 15 m/s
    w = crossing_guarantee(120.0, 6, 50.0, 20.0, 5.0)
    assert w.sure_m_s == 5.0 and w.slowest_ground_speed_m_s == 15.0
    assert w.worst_angle_deg == pytest.approx(math.degrees(math.acos(100.0 / 300.0)))
    # one away: 1.5 T / (N - 1) unseen plus a pass over a point, 2 r_s / 15 s
    a = crossing_guarantee(120.0, 6, 50.0, 20.0, 5.0, away=1)
    assert AWAY_UNSEEN_REVISITS == 1.5
    assert a.gap_s == pytest.approx(1.5 * 120.0 / 5 + 100.0 / 15.0)
    assert a.sure_m_s == pytest.approx(100.0 / a.gap_s)
    # 30 UAVs, 4 s apart: discs 80 m apart at 20 m/s, 100 m wide: every crossing is seen
    c = crossing_guarantee(120.0, 30, 50.0, 20.0, 0.0)
    assert c.continuous and c.sure_m_s == math.inf and c.as_dict()["sure_m_s"] is None
    assert revisit_gap_s(120.0, 6) == 20.0


def test_the_uavs_needed_for_a_speed():
    # 100 m / (120 s / N) >= 10 m/s from N = 12
    assert vehicles_needed(10.0, 120.0, 50.0, 20.0, 0.0) == 12
    assert vehicles_needed(10.01, 120.0, 50.0, 20.0, 0.0) == 13
    # one away: 100 / (180 / (N - 1) + 100 / 20) >= 10 from N - 1 = 36
    assert vehicles_needed(10.0, 120.0, 50.0, 20.0, 0.0, away=1) == 37
    # with one away the gap is never below 100 m / 20 m/s: 20 m/s is never promised
    assert vehicles_needed(20.0, 120.0, 50.0, 20.0, 0.0, away=1) is None


@pytest.mark.parametrize(
    "args",
    [(120.0, 6, 50.0, 20.0, 0.0, 6), (120.0, 6, 50.0, 20.0, 20.0, 0), (120.0, 6, 0.0, 20, 0, 0),
     (0.0, 6, 50.0, 20.0, 0.0, 0), (120.0, 6, 50.0, 20.0, -1.0, 0)],
)  # fmt: skip
def test_bad_arguments_are_refused(args):
    *head, away = args
    with pytest.raises(ValueError):
        crossing_guarantee(*head, away=away)


def test_the_line_for_an_operator():
    recs = [crossing_guarantee(120.0, 6, 50.0, 20.0, 0.0, away=k).as_dict() for k in range(3)]
    line = describe(recs)
    assert line.startswith("crossings sure to be seen: up to 5.00 m/s with 6 UAVs on the loop")
    # one away: 100 m / (1.5 x 120 s / 5 + 100 m / 20 m/s) = 100 / 41
    assert "band 2 r_s = 100 m" in line and "1 away 2.44 m/s" in line


# ---- the brute force -----------------------------------------------------------------------------
class Base:
    """A generated base flown by its N UAVs in even time splay (see the module doc)."""

    def __init__(self, seed: int, max_loop_km: float = 3.0) -> None:
        g = generate(seed, max_loop_km=max_loop_km)
        self.mission = m = parse_mission(g.text, f"{g.name}.yaml")
        self.patrol = p = m.patrol
        self.n, self.r_s, self.period_s = m.vehicles.count, m.sensor.footprint_radius_m, p.period_s
        self.promise = m.crossing_guarantee()
        self.grid = np.linspace(0.0, 2 * np.pi, TABLE + 1)
        pts = p.point_at_phase(self.grid[:-1])
        self.pts = np.append(pts, pts[0])
        self.tree = cKDTree(np.c_[self.pts.real, self.pts.imag])
        self.arc = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(self.pts)))])

    def uavs(self, t_s: np.ndarray, psi0: float) -> np.ndarray:
        """(S, N) positions (complex m) at the times ``t_s``."""
        ph = psi0 + 2 * np.pi * t_s[:, None] / self.period_s
        ph = np.mod(ph + 2 * np.pi * np.arange(self.n)[None, :] / self.n, 2 * np.pi)
        return np.interp(ph, self.grid, self.pts.real) + 1j * np.interp(
            ph, self.grid, self.pts.imag
        )

    def loop_point(self, rng: np.random.Generator) -> tuple[complex, complex, float]:
        """A loop point drawn by arc length, the unit tangent in the sense of travel there,
        and the patrol's ground speed there (m/s)."""
        psi = float(np.interp(rng.uniform(0.0, self.arc[-1]), self.arc, self.grid))
        course = float(self.patrol.course_at_phase(psi))
        speed = float(groundspeed_from_course(self.patrol.airspeed_m_s, course, self.patrol.wind))
        return complex(self.patrol.point_at_phase(psi)), complex(np.exp(1j * course)), speed

    def seen(
        self, t_s: np.ndarray, x_m: np.ndarray, psi0: float, j: int | None = None
    ) -> bool | None:
        """Whether the intruder at ``x_m`` (complex m) at the times ``t_s`` is seen during its
        passage through the band that contains sample ``j`` (default the middle one; None:
        not in the band there)."""
        dist = self.tree.query(np.c_[x_m.real, x_m.imag])[0]
        inb = dist <= self.r_s
        j = int(np.argmin(dist)) if j == -1 else (x_m.size // 2 if j is None else j)
        if not inb[j]:
            return None
        a = j - int(np.argmin(inb[j::-1])) if not inb[: j + 1].all() else 0
        b = j + int(np.argmin(inb[j:])) if not inb[j:].all() else x_m.size - 1
        d = self.uavs(t_s[a : b + 1], psi0) - x_m[a : b + 1, None]
        e = d[1:] - d[:-1]  # closest approach over each step
        den = np.abs(e) ** 2
        u = np.clip(-(np.conj(e) * d[:-1]).real / np.where(den > 0, den, 1.0), 0.0, 1.0)
        return bool(np.abs(d[:-1] + u * e).min() <= self.r_s)


def straight(base: Base, rng, factor: float, angle: str | None = None) -> bool | None:
    """A straight crossing at ``factor`` times the promise: at a random angle (5-175 deg from
    the tangent), or at the local worst angle (``angle="worst"``: the tangent to two discs,
    ``acos(v / s)``), either side, at a random time."""
    q, tangent, s = base.loop_point(rng)
    v = factor * base.promise.sure_m_s
    worst = math.acos(min(0.99, v / s))  # (as fast as the UAVs there: nearly along the loop)
    alpha = worst if angle == "worst" else math.radians(rng.uniform(5, 175))
    normal = 1j * tangent * (1 if rng.random() < 0.5 else -1)
    vel = v * (math.cos(alpha) * tangent + math.sin(alpha) * normal)
    span = 1.5 * base.r_s / (v * math.sin(alpha)) + 2 * DT_S
    t = rng.uniform(0.0, base.period_s) + np.arange(-span, span + DT_S / 2, DT_S)
    return base.seen(t, q + vel * (t - t[t.size // 2]), rng.uniform(0.0, 2 * np.pi))


def winding(base: Base, rng, factor: float) -> bool | None:
    """A path across the band at up to ``factor`` times the promise: a new heading and speed
    every 2-10 s (the heading within 80 deg of straight across), a stop of 5-30 s now and
    then, from 1.2 r_s on one side to 1.2 r_s on the other."""
    q, tangent, _ = base.loop_point(rng)
    normal = 1j * tangent * (1 if rng.random() < 0.5 else -1)
    vmax = factor * base.promise.sure_m_s
    pos, t, xs, ts = q - 1.2 * base.r_s * normal, 0.0, [], []
    while ((np.conj(normal) * (pos - q)).real < 1.2 * base.r_s) and t < 4000.0:
        hold = rng.uniform(2.0, 10.0)
        if rng.random() < 0.15:
            v = 0.0
            hold = rng.uniform(5.0, 30.0)
        else:
            v = vmax * rng.uniform(0.3, 1.0)
        heading = normal * np.exp(1j * math.radians(rng.uniform(-80, 80)))
        for _ in range(int(hold / DT_S)):
            xs.append(pos)
            ts.append(t)
            pos, t = pos + v * DT_S * heading, t + DT_S
    x, tt = np.array(xs), np.array(ts) + rng.uniform(0.0, base.period_s)
    return base.seen(tt, x, rng.uniform(0.0, 2 * np.pi), j=-1)  # through the nearest sample


def counts(results: list[bool | None]) -> tuple[int, int]:
    """(seen, missed) among the crossings that were in the band."""
    return sum(r is True for r in results), sum(r is False for r in results)


def test_every_crossing_slower_than_the_promise_is_seen_and_faster_ones_can_be_missed():
    base, rng = Base(1), np.random.default_rng(7)
    below = [straight(base, rng, rng.uniform(0.5, 1.0)) for _ in range(150)]
    edge = [straight(base, rng, rng.uniform(0.95, 0.999), "worst") for _ in range(100)]
    above = [straight(base, rng, rng.uniform(1.05, 1.3), "worst") for _ in range(100)]
    assert counts(below)[1] == 0 and counts(below)[0] > 100
    assert counts(edge)[1] == 0 and counts(edge)[0] > 60
    assert counts(above)[1] >= 5  # the promise is the best there is


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "km"), [(0, 3.0), (22, 3.0), (4, 3.0), (12, 10.0), (21, 25.0), (53, 25.0)]
)  # winds of 0.46, 0.49, 0.19, 0.12, 0.49, 0.33 of the airspeed; loops 1.8-25 km
def test_on_more_bases_and_along_paths_that_turn_and_stop(seed: int, km: float):
    base, rng = Base(seed, km), np.random.default_rng(seed)
    below = [straight(base, rng, rng.uniform(0.3, 1.0)) for _ in range(150)]
    edge = [straight(base, rng, rng.uniform(0.97, 0.999), "worst") for _ in range(100)]
    paths = [winding(base, rng, 1.0) for _ in range(40)]
    above = [straight(base, rng, rng.uniform(1.05, 1.5), "worst") for _ in range(100)]
    assert counts(below)[1] == 0 and counts(edge)[1] == 0 and counts(paths)[1] == 0
    assert counts(paths)[0] >= 30
    assert counts(above)[1] >= 3
