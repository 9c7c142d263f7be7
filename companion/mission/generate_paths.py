"""Seeded intruder paths for the mission generator (pure): vehicles on roads that turn,
walkers that stop and go, intruders that cross the perimeter and come back out.

Each role is drawn through the generator's one ``numpy.random.Generator`` as the legs of a
``kind: path`` intruder (:class:`companion.mission.model.Leg`), round one point of the loop
it crosses there (``p_m``, with the loop's outward normal ``out``). Conventions as in
:mod:`companion.mission.generate`: complex ``north + i east`` metres, m/s, s, compass angles;
a turn is the change of direction between two legs (deg, either way).

* **turning vehicle** (:data:`TURNING_M_S`, 5-15 m/s, each leg within 20 % of its own
  speed): a road-like polyline, 1-2 legs outside the loop and up to :data:`MAX_ROAD_LEGS`
  inside, turns of :data:`TURN_DEG` (30-120 deg) at its junctions; the leg that crosses the
  loop goes within 60 deg of its normal, and its first junction inside is 0.3-1.5 footprint
  radii in (so in about half of them the vehicle turns inside the sensor band). It drives
  as long as a straight vehicle lives (0.75-1.5 loop periods), 40-80 % of it inside, less
  where the loop leaves no room. Crosses inward or outward; it vanishes at its last point.
* **stop and go** (a walker, 0.5-2 m/s): a straight-ish crossing (bends of at most 25 deg)
  as long as a straight walker's (0.75-1.5 loop periods of walking), with 1-3 stops of
  :data:`STOP_S` (20-90 s) at its bends; in half of them the first stop is in the band (it
  waits under cover at the fence line). Inward or outward.
* **crosses back** (1-8 m/s): from outside, in across the loop 1.5-4 footprint radii, maybe
  a wait there, a turn of 120-180 deg and out again across the loop, ending 1.5-3 footprint
  radii beyond it ("in_and_out").

Every drawn path is checked against the loop: the part before the crossing on one side, the
part after on the other (for "crosses back", inside between its two crossings), its start and
its end more than :data:`CLEAR_RADII` footprint radii from the loop (so that it crosses the
whole sensor band); a draw that fails is drawn again smaller, and after :data:`TRIES` the
path is a straight crossing with one bend half a radius in.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from companion.core.fence import point_in_polygon
from companion.mission.model import Leg

PathRole = Literal["turning_vehicle", "stop_and_go", "crosses_back"]
PATH_ROLES: tuple[PathRole, ...] = ("turning_vehicle", "stop_and_go", "crosses_back")

TURNING_M_S = (5.0, 15.0)
TURN_DEG = (30.0, 120.0)
WALKER_M_S = (0.5, 2.0)
BEND_DEG = 25.0  # a stop-and-go walker's bends, at most (deg, either way)
STOP_S = (20.0, 90.0)
BACK_M_S = (1.0, 8.0)
BACK_TURN_DEG = (120.0, 180.0)
CROSS_ANGLE_DEG = 60.0  # the crossing leg is at most this far off the loop's normal
INSIDE_SHARE = 0.8  # the part inside uses at most this share of the room along its way
TRIES = 30
MAX_ROAD_LEGS = 6  # legs of a turning vehicle's road inside the loop
CLEAR_RADII = 1.2  # a path starts and ends this many footprint radii from the loop, or more
_SAMPLE_M = 5.0  # spacing of the points that check a path against the loop (m)


@dataclass(frozen=True)
class DrawnPath:
    """A drawn path: where it starts (complex m), its legs, how it crosses the loop
    ("inward", "outward" or "in_and_out") and the turns between its legs (deg, signed,
    positive to the right), all as the YAML writes them."""

    start_m: complex
    legs: tuple[Leg, ...]
    crossing: str
    turns_deg: tuple[float, ...]


def draw_path(
    rng: np.random.Generator,
    role: PathRole,
    p_m: complex,
    out: complex,
    footprint_m: float,
    loop_m: np.ndarray,
    walk_s: float,
) -> DrawnPath:
    """A path of ``role`` crossing the loop at ``p_m`` (complex m; ``out`` the outward unit
    normal there); ``loop_m``: the loop as a closed polygon (complex m); ``walk_s``: how long
    a walker walks or a vehicle drives, waits apart (s; shortened to fit inside the loop)."""
    if role == "turning_vehicle":
        return _turning_vehicle(rng, p_m, out, footprint_m, loop_m, walk_s)
    if role == "stop_and_go":
        return _stop_and_go(rng, p_m, out, footprint_m, loop_m, walk_s)
    return _crosses_back(rng, p_m, out, footprint_m, loop_m)


# ---- geometry ---------------------------------------------------------------------------------
def _walk(
    start_m: complex, direction: complex, lengths_m: list[float], turns_deg: list[float]
) -> list[complex]:
    """The points after ``start_m`` of legs of ``lengths_m`` (m), the first along the unit
    ``direction``, each next one turned by the next of ``turns_deg`` (deg, right positive)."""
    points, here, d = [], start_m, direction
    for j, length in enumerate(lengths_m):
        if j > 0:
            d = _turned(d, turns_deg[j - 1])
        here = here + length * d
        points.append(here)
    return points


def _turned(direction: complex, turn_deg: float) -> complex:
    """``direction`` turned by ``turn_deg`` (deg) to the right (clockwise on a north-up map:
    a compass angle grows, so in ``north + i east`` it is ``exp(+i turn)``)."""
    return direction * complex(math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg)))


def _room_m(loop_m: np.ndarray, from_m: complex, u: complex) -> float:
    """How far (m) a ray from ``from_m`` along unit ``u`` runs before it last meets the loop
    polygon (from a point inside: to where it leaves)."""
    a, b = loop_m, np.roll(loop_m, -1)
    d = b - a
    den = (np.conj(u) * d).imag
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.conj(a - from_m) * d).imag / den
        s = (np.conj(a - from_m) * u).imag / den
    hit = np.isfinite(t) & (s >= 0) & (s <= 1) & (t > 0)
    return float(np.max(t[hit], initial=0.0))


def _samples(points_m: list[complex]) -> np.ndarray:
    """Points every :data:`_SAMPLE_M` m or closer along the polyline (complex m)."""
    out = [np.array([points_m[0]])]
    for a, b in itertools.pairwise(points_m):
        k = max(1, math.ceil(abs(b - a) / _SAMPLE_M))
        out.append(a + (b - a) * np.arange(1, k + 1) / k)
    return np.concatenate(out)


def _all(points_m: list[complex], loop_m: np.ndarray, inside: bool) -> bool:
    """Whether the polyline stays inside (or outside) the loop at every sample."""
    inn = point_in_polygon(_samples(points_m), loop_m)
    return bool(np.all(inn) if inside else not np.any(inn))


def _clear_of_band(points_m: list[complex], loop_m: np.ndarray, r_s: float) -> bool:
    """Whether every one of ``points_m`` (complex m) is farther than :data:`CLEAR_RADII`
    footprint radii ``r_s`` (m) from the loop polygon (its ends: a whole crossing)."""
    a, b = loop_m, np.roll(loop_m, -1)
    d = b - a
    for z in points_m:
        u = np.clip((np.conj(d) * (z - a)).real / np.abs(d) ** 2, 0.0, 1.0)
        if float(np.min(np.abs(z - a - u * d))) <= CLEAR_RADII * r_s:
            return False
    return True


def _legs(
    points_m: list[complex], speeds_m_s: list[float], waits_s: list[float]
) -> tuple[Leg, ...]:
    """Legs to ``points_m`` (rounded as the YAML writes them: 0.01 m, 0.01 m/s, 0.1 s)."""
    return tuple(
        Leg(round(z.real, 2), round(z.imag, 2), round(v, 2), round(w, 1))
        for z, v, w in zip(points_m, speeds_m_s, waits_s, strict=True)
    )


def _start(z: complex) -> complex:
    """``z`` rounded as the YAML writes it (0.01 m)."""
    return complex(round(z.real, 2), round(z.imag, 2))


def _through(
    p_m: complex, before: list[complex], after: list[complex], outward: bool
) -> tuple[complex, list[complex]]:
    """The start and the points in time order of a crossing through ``p_m``: ``before`` are
    the points outside walked back from ``p_m``, ``after`` the points inside walked from it;
    ``outward`` runs it the other way (from the last inside point out)."""
    order = before[::-1][1:] + after
    start = before[-1]
    if outward:
        order = after[::-1][1:] + before
        start = after[-1]
    return start, order


# ---- the roles ----------------------------------------------------------------------------------
def _turning_vehicle(
    rng: np.random.Generator,
    p_m: complex,
    out: complex,
    r_s: float,
    loop_m: np.ndarray,
    drive_s: float,
) -> DrawnPath:
    speed = float(rng.uniform(*TURNING_M_S))
    outward = bool(rng.random() < 0.5)
    share_in = float(rng.uniform(0.4, 0.8))  # of its drive, inside the loop
    scale = 1.0
    for _ in range(TRIES):
        off = math.radians(float(rng.uniform(-CROSS_ANGLE_DEG, CROSS_ANGLE_DEG)))
        inward = -out * complex(math.cos(off), math.sin(off))
        room = _room_m(loop_m, p_m - 0.01 * inward, inward)
        first_in = float(rng.uniform(0.3, 1.5)) * r_s
        after = _road_inside(rng, p_m, inward, first_in, share_in * drive_s * speed, loop_m)
        n_out = int(rng.integers(1, 3))
        total_out = max(2.0 * r_s, (1.0 - share_in) * drive_s * speed * scale)
        out_len = list(total_out * rng.dirichlet(np.ones(n_out)))
        out_len[0] = max(out_len[0], 1.5 * r_s)
        before = _walk(p_m, -inward, out_len, [_turn(rng, TURN_DEG) for _ in out_len[1:]])
        if (
            first_in < INSIDE_SHARE * room
            and len(after) >= 2
            and _sides_ok(p_m, before, after, loop_m)
            and _clear_of_band([before[-1], after[-1]], loop_m, r_s)
        ):
            break
        scale *= 0.8
    else:  # a straight crossing with one turn half a radius in
        inward = -out
        after = _walk(p_m, inward, [0.5 * r_s, 1.5 * r_s], [TURN_DEG[0]])
        before = _walk(p_m, -inward, [2.0 * r_s], [])
    start, order = _through(p_m, before, after, outward)
    speeds = [float(np.clip(speed * rng.uniform(0.8, 1.2), *TURNING_M_S)) for _ in order]
    return _drawn(start, order, speeds, [0.0] * len(order), "outward" if outward else "inward")


def _road_inside(
    rng: np.random.Generator,
    p_m: complex,
    inward: complex,
    first_m: float,
    length_m: float,
    loop_m: np.ndarray,
) -> list[complex]:
    """A road inside the loop from ``p_m``: ``first_m`` (m) along ``inward``, then legs
    turned by :data:`TURN_DEG` (the side with room), each at most :data:`INSIDE_SHARE` of
    the room ahead, until ``length_m`` (m) in all or :data:`MAX_ROAD_LEGS` legs."""
    here, d = p_m + first_m * inward, inward
    points, left = [here], length_m - first_m
    while left > 1.0 and len(points) < MAX_ROAD_LEGS:
        turn = _turn(rng, TURN_DEG)
        rooms = [(_room_m(loop_m, here, _turned(d, t)), t) for t in (turn, -turn)]
        room, turn = max(rooms)
        if room < 2.0:
            break
        d = _turned(d, turn)
        leg = min(left, float(rng.uniform(0.3, INSIDE_SHARE)) * room)
        here = here + leg * d
        points.append(here)
        left -= leg
    return points


def _drawn(
    start_m: complex,
    points_m: list[complex],
    speeds_m_s: list[float],
    waits_s: list[float],
    how: str,
) -> DrawnPath:
    """The drawn path, rounded as the YAML writes it, its turns measured on the rounded
    points."""
    legs = _legs(points_m, speeds_m_s, waits_s)
    start = _start(start_m)
    turns = _turns_of(start, [leg.point_m for leg in legs])
    return DrawnPath(start, legs, how, tuple(round(t, 1) for t in turns))


def _turn(rng: np.random.Generator, range_deg: tuple[float, float]) -> float:
    """A turn of ``range_deg`` (deg), to either side."""
    return float(rng.uniform(*range_deg)) * (1.0 if rng.random() < 0.5 else -1.0)


def _sides_ok(
    p_m: complex, before: list[complex], after: list[complex], loop_m: np.ndarray
) -> bool:
    """The points walked back from ``p_m`` stay outside the loop, those walked on inside
    (the first metre either side of the loop is not judged)."""
    a0 = after[0] - p_m
    b0 = before[0] - p_m
    return _all([p_m + a0 / abs(a0), *after], loop_m, True) and _all(
        [p_m + b0 / abs(b0), *before], loop_m, False
    )


def _stop_and_go(
    rng: np.random.Generator,
    p_m: complex,
    out: complex,
    r_s: float,
    loop_m: np.ndarray,
    walk_s: float,
) -> DrawnPath:
    speed = float(rng.uniform(*WALKER_M_S))
    outward = bool(rng.random() < 0.5)
    before_share = float(rng.uniform(0.2, 0.6))  # of its walk, before it reaches the loop
    stop_in_band = bool(rng.random() < 0.5)
    scale = 1.0
    for _ in range(TRIES):
        off = math.radians(float(rng.uniform(-CROSS_ANGLE_DEG, CROSS_ANGLE_DEG)))
        inward = -out * complex(math.cos(off), math.sin(off))
        room = _room_m(loop_m, p_m - 0.01 * inward, inward)
        share_in = (1.0 - before_share) if not outward else before_share
        d_in = min(share_in * walk_s * speed, INSIDE_SHARE * room) * scale
        d_in = max(d_in, min(2.0 * r_s, INSIDE_SHARE * room))
        d_out = max((1.0 - share_in) * walk_s * speed * scale, 2.0 * r_s)
        n_in, n_out = int(rng.integers(1, 4)), int(rng.integers(1, 3))
        in_len = list(d_in * rng.dirichlet(np.ones(n_in)))
        if stop_in_band and n_in > 1:  # the first bend (and its stop) in the band
            first = float(rng.uniform(0.2, 0.9)) * r_s
            in_len = [first, *list((d_in - first) * rng.dirichlet(np.ones(n_in - 1)))]
        out_len = list(d_out * rng.dirichlet(np.ones(n_out)))
        turns_in = [float(rng.uniform(-BEND_DEG, BEND_DEG)) for _ in range(n_in - 1)]
        turns_out = [float(rng.uniform(-BEND_DEG, BEND_DEG)) for _ in range(n_out - 1)]
        after = _walk(p_m, inward, in_len, turns_in)
        before = _walk(p_m, -inward, out_len, turns_out)
        if (
            min(in_len + out_len) > 1.0
            and _sides_ok(p_m, before, after, loop_m)
            and _clear_of_band([before[-1], after[-1]], loop_m, r_s)
        ):
            break
        scale *= 0.8
    else:
        inward = -out
        after = _walk(p_m, inward, [0.5 * r_s, 1.5 * r_s], [0.0])
        before = _walk(p_m, -inward, [2.0 * r_s], [])
    start, order = _through(p_m, before, after, outward)
    # 1-3 stops at its bends (the last point is where it ends), one at the bend nearest the
    # loop inside (in the band) when drawn so; a walk with no bend stops at its end
    bends = len(order) - 1
    count = min(bends, int(rng.integers(1, 4)))
    stops = set(rng.choice(bends, size=count, replace=False).tolist()) if bends else set()
    if stop_in_band and len(after) > 1:
        stops.add(len(before) - 1 if not outward else len(after) - 2)
    stops = stops or {len(order) - 1}
    waits = [float(rng.uniform(*STOP_S)) if j in stops else 0.0 for j in range(len(order))]
    how = "outward" if outward else "inward"
    return _drawn(start, order, [speed] * len(order), waits, how)


def _turns_of(start_m: complex, points_m: list[complex]) -> list[float]:
    """The signed turns (deg, right positive) at each inner point of the polyline."""
    pts = [start_m, *points_m]
    d = [b - a for a, b in itertools.pairwise(pts)]
    return [math.degrees(float(np.angle(b / a))) for a, b in itertools.pairwise(d)]


def _crosses_back(
    rng: np.random.Generator, p_m: complex, out: complex, r_s: float, loop_m: np.ndarray
) -> DrawnPath:
    speed = float(rng.uniform(*BACK_M_S))
    scale = 1.0
    for _ in range(TRIES):
        off = math.radians(float(rng.uniform(-45.0, 45.0)))
        inward = -out * complex(math.cos(off), math.sin(off))
        room = _room_m(loop_m, p_m - 0.01 * inward, inward)
        depth = min(float(rng.uniform(1.5, 4.0)) * r_s, 0.5 * room) * scale
        approach = float(rng.uniform(1.5, 4.0)) * r_s
        turn = _turn(rng, BACK_TURN_DEG)
        start = p_m - approach * inward
        q = p_m + depth * inward
        back = _turned(inward, turn)
        exit_m = _room_m(loop_m, q, back)
        end = q + (exit_m + float(rng.uniform(1.5, 3.0)) * r_s) * back
        if (
            exit_m > 0
            and exit_m < 3.0 * depth + 4.0 * r_s
            and _all([p_m + inward, q], loop_m, True)
            and _all([q + back, q + max(exit_m - 1.0, 0.0) * back], loop_m, True)
            and not point_in_polygon(np.array([start, end]), loop_m).any()
            and _clear_of_band([start, end], loop_m, r_s)
        ):
            break
        scale *= 0.8
    else:
        inward = -out
        start, q, end = p_m - 2.0 * r_s * inward, p_m + 1.5 * r_s * inward, p_m - 2 * r_s * inward
    wait = float(rng.uniform(0.0, 60.0)) if rng.random() < 0.5 else 0.0
    return _drawn(start, [q, end], [speed, speed], [wait, 0.0], "in_and_out")
