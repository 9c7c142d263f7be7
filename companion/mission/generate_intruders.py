"""One generated intruder (pure): where it appears, how it moves, when it is gone, and what
it is meant to be (:class:`IntruderPlan`), for :func:`companion.mission.generate.generate`.

A static intruder or a decoy lies within ``NEAR_LOOP`` footprint radii of the loop; a walker
or a vehicle crosses the loop on a straight path, inward or outward, at most
``CROSS_ANGLE_DEG`` off its normal; an intruder on a path is drawn by
:mod:`companion.mission.generate_paths`. Conventions as in :mod:`companion.mission.generate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from companion.core.fence import point_in_polygon
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.mission.generate_paths import PATH_ROLES, Crossing, PathRole, draw_path
from companion.mission.model import Intruder, Leg

IntruderRole = Literal[
    "static", "decoy", "walker", "vehicle", "turning_vehicle", "stop_and_go", "crosses_back"
]

STRAIGHT_ROLES: tuple[IntruderRole, ...] = ("static", "decoy", "walker", "vehicle")
INTRUDER_ROLES: tuple[IntruderRole, ...] = STRAIGHT_ROLES + PATH_ROLES
WALKER_M_S = (0.5, 2.0)
VEHICLE_M_S = (3.0, 10.0)
STATIC_STAY_PERIODS = (0.75, 1.5)
MOVING_LIFE_PERIODS = (0.75, 1.5)
MIN_LIFE_S = 90.0  # shortest life of a static or moving intruder (s)
NEAR_LOOP = 0.8  # a static intruder or decoy lies within this many footprint radii of C
CROSS_ANGLE_DEG = 60.0  # a crossing path is at most this far off the loop's normal
INSIDE_SHARE = 0.8  # a crossing path uses at most this share of the chord inside the loop


@dataclass(frozen=True)
class IntruderPlan:
    """What one generated intruder is meant to be (the YAML says only static/moving/decoy/path).

    Attributes:
        id: its id in the scenario.
        role: "static", "decoy", "walker", "vehicle", or on a path "turning_vehicle",
            "stop_and_go" or "crosses_back".
        crossing: "inward" or "outward" for a walker, a vehicle or a path that crosses the
            loop once, "in_and_out" for one that crosses it and comes back out, else None.
        speed_m_s: ground speed (m/s; a path's fastest leg), 0 for static ones and decoys.
        appear_t_s: when it appears (s, simulated).
        vanish_t_s: when it vanishes (s), None for a decoy (a few seconds after its first
            detection, :attr:`vanish_after_detection_s`).
        vanish_after_detection_s: a decoy's life once detected (s), else None.
        cross_t_s: when a crossing intruder is on the loop (s; the first time), else None.
        legs: the legs of a path (0 for the others).
        turns_deg: a path's turns between its legs (deg, right positive).
        stops_s: a path's waits (s), in order.
    """

    id: str
    role: IntruderRole
    crossing: Crossing | None
    speed_m_s: float
    appear_t_s: float
    vanish_t_s: float | None
    vanish_after_detection_s: float | None = None
    cross_t_s: float | None = None
    legs: int = 0
    turns_deg: tuple[float, ...] = ()
    stops_s: tuple[float, ...] = ()


@dataclass(frozen=True)
class DrawnIntruder:
    """One intruder as written to the YAML (local m, m/s, s)."""

    plan: IntruderPlan
    start_m: complex
    velocity_m_s: complex = 0j
    legs: tuple[Leg, ...] = ()


def loop_point(rng: np.random.Generator, patrol: Patrol) -> tuple[complex, complex]:
    """A loop point drawn uniformly by arc length, and the outward unit normal there."""
    grid = np.linspace(0.0, TWO_PI, 4097)
    pts = patrol.point_at_phase(grid)
    arc = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(pts)))])
    psi = float(np.interp(rng.uniform(0.0, arc[-1]), arc, grid))
    p = complex(patrol.point_at_phase(psi))
    normal = 1j * np.exp(1j * float(patrol.course_at_phase(psi)))
    if (np.conj(normal) * (p - patrol.centre_m)).real < 0:
        normal = -normal
    return p, complex(normal)


def inside_chord_m(patrol: Patrol, p_m: complex, u: complex) -> float:
    """How far (m) a ray from loop point ``p_m`` going in along unit ``u`` runs inside."""
    poly = patrol.point_at_phase(np.linspace(0.0, TWO_PI, 1440, endpoint=False))
    a, b = poly, np.roll(poly, -1)
    d = b - a
    den = (np.conj(u) * d).imag  # cross(u, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.conj(a - p_m) * d).imag / den  # along the ray (m)
        s = (np.conj(a - p_m) * u).imag / den  # along the segment (0-1)
    hit = np.isfinite(t) & (s >= 0) & (s <= 1)
    return float(np.max(t[hit], initial=0.0))


def draw_intruder(
    rng: np.random.Generator,
    ident: str,
    role: IntruderRole,
    patrol: Patrol,
    footprint_m: float,
    settle_s: float,
    n: int,
) -> DrawnIntruder:
    """One intruder of ``role``, appearing within a revisit interval after the settle."""
    period = patrol.period_s
    appear = round(settle_s + float(rng.uniform(0.0, period / n)), 1)
    p, out = loop_point(rng, patrol)
    on_path = next((r for r in PATH_ROLES if r == role), None)
    if on_path is not None:
        return path_intruder(rng, ident, on_path, patrol, footprint_m, appear, p, out)
    if role in ("static", "decoy"):
        site = p + out * float(rng.uniform(-NEAR_LOOP, NEAR_LOOP)) * footprint_m
        if role == "decoy":
            after = round(float(rng.uniform(3.0, 8.0)), 1)
            plan = IntruderPlan(ident, "decoy", None, 0.0, appear, None, after)
        else:
            stay = max(MIN_LIFE_S, float(rng.uniform(*STATIC_STAY_PERIODS)) * period)
            plan = IntruderPlan(ident, "static", None, 0.0, appear, round(appear + stay, 1))
        return DrawnIntruder(plan, complex(round(site.real, 2), round(site.imag, 2)))
    speed = float(rng.uniform(*(WALKER_M_S if role == "walker" else VEHICLE_M_S)))
    crossing: Crossing = "inward" if rng.random() < 0.5 else "outward"
    off = np.exp(1j * math.radians(float(rng.uniform(-CROSS_ANGLE_DEG, CROSS_ANGLE_DEG))))
    inward = complex(-out * off)  # unit, into the loop
    life = max(MIN_LIFE_S, float(rng.uniform(*MOVING_LIFE_PERIODS)) * period)
    before = float(rng.uniform(0.2, 0.6))  # share of its life before it is on the loop
    inside_s = (1.0 - before) * life if crossing == "inward" else before * life
    room_s = INSIDE_SHARE * inside_chord_m(patrol, p, inward) / speed
    if inside_s > room_s:  # it would come out on the far side: shorten its life
        life *= room_s / inside_s
    v = speed * (inward if crossing == "inward" else -inward)
    v = complex(round(v.real, 3), round(v.imag, 3))
    start = p - v * before * life
    start = complex(round(start.real, 2), round(start.imag, 2))
    plan = IntruderPlan(
        ident,
        role,
        crossing,
        abs(v),
        appear,
        round(appear + life, 1),
        cross_t_s=round(appear + before * life, 1),
    )
    return DrawnIntruder(plan, start, v)


def path_intruder(
    rng: np.random.Generator,
    ident: str,
    role: PathRole,
    patrol: Patrol,
    footprint_m: float,
    appear_s: float,
    p_m: complex,
    out: complex,
) -> DrawnIntruder:
    """An intruder on a path of ``role`` through loop point ``p_m`` (complex m; ``out`` the
    outward normal), appearing at ``appear_s`` (s) and gone at the end of its last leg."""
    walk_s = max(MIN_LIFE_S, float(rng.uniform(*MOVING_LIFE_PERIODS)) * patrol.period_s)
    loop = patrol.point_at_phase(np.linspace(0.0, TWO_PI, 1440, endpoint=False))
    drawn = draw_path(rng, role, p_m, out, footprint_m, loop, walk_s)
    it = Intruder(ident, "path", appear_s, drawn.start_m.real, drawn.start_m.imag, path=drawn.legs)
    end = it.path_end_t_s
    t = np.arange(appear_s, end + 0.5, 0.5)
    inside = point_in_polygon(it.positions_m(t), loop)
    flips = np.flatnonzero(inside != inside[0])
    plan = IntruderPlan(
        ident,
        role,
        drawn.crossing,
        round(it.max_speed_m_s, 3),
        appear_s,
        math.ceil(10.0 * end + 1.0) / 10.0,  # 0.1-0.2 s after its last point
        cross_t_s=round(float(t[flips[0]]), 1) if flips.size else None,
        legs=len(drawn.legs),
        turns_deg=drawn.turns_deg,
        stops_s=tuple(leg.wait_s for leg in drawn.legs if leg.wait_s > 0),
    )
    return DrawnIntruder(plan, drawn.start_m, legs=drawn.legs)


def gone_by_s(plan: IntruderPlan, revisit_s: float) -> float:
    """When the intruder will be gone (s): a decoy is allowed two revisit intervals
    (``revisit_s``, s) to be seen."""
    if plan.vanish_t_s is not None:
        return plan.vanish_t_s
    return plan.appear_t_s + 2 * revisit_s + (plan.vanish_after_detection_s or 0.0)
