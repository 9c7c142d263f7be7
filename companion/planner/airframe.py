"""All path families, solved in the frame that moves with the air mass.

Conventions: complex positions ``north + i east`` (m), compass angles (rad), positive turn
rate = right turn, turn sense ``delta = +1`` (R) or ``-1`` (L), turn radius
``rho = s0 / omega``. A point moving at heading ``h`` on a circle of sense ``delta`` has its
centre at ``p + delta rho i exp(i h)``.

In the air frame (origin at the start, t = 0) the aircraft flies an ordinary Dubins-type
path at speed ``s0`` and the goal drifts: it is at ``g - d t`` with ``d = w - v_goal``. A
word is feasible at time ``T`` when its air-frame length to the goal at ``T`` equals
``s0 T``. Three ways to solve that, whichever is simplest for the family:

* same-sense turn-straight-turn (RSR, LSL): the total turn ``A`` is fixed by the headings
  (mod 2 pi), the straight runs between two circle centres, so ``s0 T - rho A = |D - d T|``
  is a quadratic in ``T`` (closed form; this is the paper's eq. 29 seen from the air);
* opposite-sense turn-straight-turn (RSL, LSR) and turn-straight to a point (RS, LS):
  parametrise by the first arc ``a1``; the straight of length ``l`` along
  ``u = exp(i psi) + d / s0`` must close the gap, so ``Im(conj(u) R(a1)) = 0`` is a smooth
  1-D equation on at most two known sub-intervals of ``[0, 2 pi]``;
* turn-turn-turn (RLR, LRL) and turn-turn to a point (RL, LR): parametrise by ``T``; the
  middle circle is where the Dubins construction puts it (both intersection choices), so
  ``F(T) = rho (a1 + a2 [+ a3]) - s0 T`` on the bounded interval where the circles touch.

The 1-D equations are scanned on a grid (numpy) and each sign change is refined with
``scipy.optimize.brentq`` on the same formula evaluated with Python scalars; a sign change
that is an arc wrap-around (a jump, not a root) fails the residual check and is dropped.
"""

from __future__ import annotations

import cmath
import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

# at start, not at the first plan: imported there it stalled a companion at its first alert
# (0.3-0.5 s of CPU, 0.4-1.0 s of wall time: scipy.optimize and what it pulls in): at 5x the
# detector and its prosecutor fell silent for 3 s and two UAVs took the alert (test_arduplane)
from scipy.optimize import brentq

from companion.core.wind import TWO_PI
from companion.planner.paper import Candidate

_N_ARC = 33  # grid points per arc sub-interval
_N_TIME = 97  # grid points per time interval
_WORD = {1.0: "R", -1.0: "L"}
_LOOPS = (0.0, TWO_PI)  # extra full loops tried in the root-found families


ArrayOrFloat = Any
"""What the kernels below take and give: a float (the root refinement) or a numpy array of
them (the scan); each kernel is written once for both, its backend picks the functions."""


def _sqrt0_array(x: ArrayOrFloat) -> ArrayOrFloat:
    """``sqrt(max(x, 0))`` elementwise."""
    return np.sqrt(np.maximum(x, 0.0))


def _sqrt0_scalar(x: ArrayOrFloat) -> ArrayOrFloat:
    """``sqrt(max(x, 0))`` of a float."""
    return math.sqrt(max(x, 0.0))


@dataclass(frozen=True)
class _Backend:
    """The three functions a kernel calls: ``exp`` of a complex, its ``phase`` (rad) and
    ``sqrt0`` (``sqrt(max(x, 0))``), on arrays (:data:`_VEC`) or scalars (:data:`_SCA`)."""

    exp: Callable[[ArrayOrFloat], ArrayOrFloat]
    phase: Callable[[ArrayOrFloat], ArrayOrFloat]
    sqrt0: Callable[[ArrayOrFloat], ArrayOrFloat]


_VEC = _Backend(np.exp, np.angle, _sqrt0_array)
"""numpy backend: the kernels below run on arrays for the scan."""
_SCA = _Backend(cmath.exp, cmath.phase, _sqrt0_scalar)
"""Scalar backend: the same kernels on Python numbers for the root refinement."""


@dataclass(frozen=True)
class Problem:
    """One planning problem in the air frame (SI units, radians).

    Attributes:
        goal_m: goal relative to the start at t = 0 (m, complex).
        drift_m_s: ``d = w - v_goal`` (m/s, complex); the air-frame goal is at ``goal - d t``.
        theta0_rad: start air heading (rad).
        thetaf_rad: final air heading (rad), or None for a free final heading.
        airspeed_m_s: ``s0`` (m/s).
        turn_rate_rad_s: ``omega`` (rad/s).
    """

    goal_m: complex
    drift_m_s: complex
    theta0_rad: float
    thetaf_rad: float | None
    airspeed_m_s: float
    turn_rate_rad_s: float

    @property
    def final_heading_rad(self) -> float:
        """``thetaf_rad`` for the families that end on a heading (rad).

        Raises:
            ValueError: the final heading is free (the caller picked the wrong family).
        """
        if self.thetaf_rad is None:
            raise ValueError("this path family needs a final heading; it is free")
        return self.thetaf_rad

    @property
    def rho(self) -> float:
        """Turn radius in the air (m)."""
        return self.airspeed_m_s / self.turn_rate_rad_s

    def centre1(self, delta: float) -> complex:
        """Air-frame centre of the first turn circle of sense ``delta`` (m)."""
        return delta * self.rho * 1j * cmath.exp(1j * self.theta0_rad)


def same_sense(p: Problem) -> list[Candidate]:
    """RSR and LSL in closed form (quadratic in T), total turn ``A`` and ``A + 2 pi``.

    With ``A + 2 pi`` a full loop is added to the first turn when the geometry needs only
    ``A``: that path always exists when ``|d| < s0``, so the search below is bounded.
    """
    s0, rho, om, d = p.airspeed_m_s, p.rho, p.turn_rate_rad_s, p.drift_m_s
    thetaf = p.final_heading_rad
    out: list[Candidate] = []
    for delta in (1.0, -1.0):
        c1 = p.centre1(delta)
        big_d = p.goal_m + delta * rho * 1j * cmath.exp(1j * thetaf) - c1
        turn = (delta * (thetaf - p.theta0_rad)) % TWO_PI
        for total in (turn, turn + TWO_PI):
            a = total / om
            qa = s0 * s0 - abs(d) ** 2
            qb = -2.0 * (s0 * s0 * a - (big_d.conjugate() * d).real)
            qc = (s0 * a) ** 2 - abs(big_d) ** 2
            for t in _quadratic_roots(qa, qb, qc):
                if t < a - 1e-12:
                    continue
                line = big_d - d * t
                length = abs(line)
                arcs: tuple[float, float]
                if length < 1e-9:
                    arcs = (total, 0.0)
                else:
                    psi = cmath.phase(line)
                    a1 = (delta * (psi - p.theta0_rad)) % TWO_PI
                    a2 = (delta * (thetaf - psi)) % TWO_PI
                    a1 = 0.0 if a1 > TWO_PI - 1e-9 else a1
                    a2 = 0.0 if a2 > TWO_PI - 1e-9 else a2
                    extra = total - (a1 + a2)
                    if extra < -1e-7:
                        continue
                    arcs = (a1 + max(extra, 0.0), a2)
                word = _WORD[delta] + "S" + _WORD[delta]
                out.append((t, word, (arcs[0] / om, length / s0, arcs[1] / om)))
    return out


def _quadratic_roots(a: float, b: float, c: float) -> list[float]:
    """Real roots of ``a t^2 + b t + c`` (any of a, b may vanish)."""
    if abs(a) < 1e-12 * (abs(b) + abs(c) + 1e-300):
        return [-c / b] if b != 0 else []
    disc = b * b - 4.0 * a * c
    if disc < 0:
        if disc < -1e-12 * b * b:
            return []
        disc = 0.0  # a double root lost to rounding
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    roots = [q / a]
    if q != 0:
        roots.append(c / q)
    return roots


# ---------------------------------------------------------------- arc-parametrised families


def _arc_kernel(
    p: Problem, delta: float, mixed: bool, split: float, xp: _Backend
) -> Callable[[ArrayOrFloat], tuple[ArrayOrFloat, ArrayOrFloat, ArrayOrFloat]]:
    """Residual ``Im(conj(u) R)`` as a function of the first arc ``a1`` (rad).

    ``mixed``: opposite-sense final turn to ``thetaf`` (RSL/LSR); else turn-straight to a
    point (RS/LS). ``split`` is added to the turning (0, 2 pi or 4 pi: the final arc's
    wrap-around, see :func:`opposite_sense`, plus an extra full loop).
    Returns ``(residual, straight_m, arcs_total_rad)`` as functions of ``a1``.
    """
    s0, rho, d = p.airspeed_m_s, p.rho, p.drift_m_s
    c1 = p.centre1(delta)
    base = p.goal_m - c1
    arc2_0 = 0.0  # the final arc at a1 = 0 (mixed only)
    if mixed:
        thetaf = p.final_heading_rad
        base -= delta * rho * 1j * cmath.exp(1j * thetaf)
        arc2_0 = split - (delta * (thetaf - p.theta0_rad)) % TWO_PI
    k_turn = 2.0 if mixed else 1.0

    def parts(a1: ArrayOrFloat) -> tuple[ArrayOrFloat, ArrayOrFloat, ArrayOrFloat]:
        e = xp.exp(1j * (p.theta0_rad + delta * a1))
        arcs = (2.0 * a1 + arc2_0) if mixed else (a1 + split)
        r = base + k_turn * delta * rho * 1j * e - d * (rho * arcs / s0)
        u = e + d / s0
        prod = u.conjugate() * r
        return prod.imag, prod.real / (abs(u) ** 2), arcs

    return parts


def opposite_sense(p: Problem) -> list[Candidate]:
    """RSL and LSR: roots in the first arc of the straight-closing condition."""
    out: list[Candidate] = []
    for delta in (1.0, -1.0):
        # the final arc a2 = (a1 - s*) mod 2 pi wraps at a1 = s*: two smooth pieces
        s_star = (delta * (p.final_heading_rad - p.theta0_rad)) % TWO_PI
        for loop in _LOOPS:
            for lo, hi, split in ((0.0, s_star, TWO_PI), (s_star, TWO_PI, 0.0)):
                if hi - lo < 1e-12:
                    continue
                word = _WORD[delta] + "S" + _WORD[-delta]
                out += _arc_roots(p, delta, True, split + loop, lo, hi, word)
    return out


def turn_straight(p: Problem) -> list[Candidate]:
    """RS and LS to a point (free final heading)."""
    out: list[Candidate] = []
    for delta in (1.0, -1.0):
        for loop in _LOOPS:
            out += _arc_roots(p, delta, False, loop, 0.0, TWO_PI, _WORD[delta] + "S")
    return out


def _arc_roots(
    p: Problem, delta: float, mixed: bool, split: float, lo: float, hi: float, word: str
) -> list[Candidate]:
    vec = _arc_kernel(p, delta, mixed, split, _VEC)
    sca = _arc_kernel(p, delta, mixed, split, _SCA)
    grid = np.linspace(lo, hi, _N_ARC)
    with np.errstate(all="ignore"):
        res = vec(grid)[0]
    out: list[Candidate] = []
    s0, om = p.airspeed_m_s, p.turn_rate_rad_s
    for a1 in _refine(lambda x: sca(x)[0], grid, res, 1e-7 * (1.0 + abs(p.goal_m))):
        _, straight, arcs = sca(a1)
        if not straight >= -1e-7:
            continue
        straight = max(straight, 0.0)
        t = (p.rho * arcs + straight) / s0
        durs: tuple[float, ...]
        if mixed:  # any extra loop is flown in the final turn
            durs = (a1 / om, straight / s0, (arcs - a1) / om)
        else:
            durs = (arcs / om, straight / s0)
        out.append((t, word, durs))
    return out


# ---------------------------------------------------------------- time-parametrised families


def _time_kernel(
    p: Problem, delta: float, sigma: float, to_point: bool, xp: _Backend
) -> tuple[Callable[[ArrayOrFloat], tuple[ArrayOrFloat, ...]], complex]:
    """Arc angles (rad, each in [0, 2 pi)) of RLR/LRL, or RL/LR to a point, at time ``T``.

    The middle circle touches the first circle and the last one (or passes through the
    goal point, ``to_point``); ``sigma`` picks one of the two such circles.
    Returns ``(arcs_of_T, v0)`` where the circles exist while ``|v0 - d T|`` is in range.
    """
    rho, d, th0 = p.rho, p.drift_m_s, p.theta0_rad
    c1 = p.centre1(delta)
    v0 = p.goal_m - c1
    thetaf = 0.0  # unused to a point: the final heading is free
    if not to_point:
        thetaf = p.final_heading_rad
        v0 += delta * rho * 1j * cmath.exp(1j * thetaf)

    def arcs_at(t: ArrayOrFloat) -> tuple[ArrayOrFloat, ...]:  # float or array
        v = v0 - d * t
        q = abs(v)
        unit = v / q
        if to_point:
            x = (3.0 * rho * rho + q * q) / (2.0 * q)
            cm = c1 + unit * (x + sigma * 1j * xp.sqrt0(4.0 * rho * rho - x * x))
            psi1 = xp.phase(1j * delta * (cm - c1))
            psi2 = xp.phase(-1j * delta * (c1 + v - cm))
            return ((delta * (psi1 - th0)) % TWO_PI, (delta * (psi1 - psi2)) % TWO_PI)
        cm = c1 + 0.5 * v + sigma * 1j * unit * xp.sqrt0(4.0 * rho * rho - 0.25 * q * q)
        psi1 = xp.phase(1j * delta * (cm - c1))
        psi2 = xp.phase(1j * delta * (cm - c1 - v))
        return (
            (delta * (psi1 - th0)) % TWO_PI,
            (delta * (psi1 - psi2)) % TWO_PI,
            (delta * (thetaf - psi2)) % TWO_PI,
        )

    return arcs_at, v0


def turn_turn(p: Problem, t_max: float, to_point: bool) -> list[Candidate]:
    """RLR/LRL (``to_point`` False) or RL/LR to a point, for ``0 <= T <= t_max``.

    ``F(T) = rho (sum of arcs + loop) - s0 T`` is scanned on a grid. An arc that wraps
    between 2 pi and 0 inside a grid cell makes ``F`` jump by ``2 pi rho``; such a cell is
    searched on both sides of the wrap, each with its arcs continued (unwrapped) from its
    own end, and a root counts only if its arcs are still within [0, 2 pi] there.
    """
    rho, d, om = p.rho, p.drift_m_s, p.turn_rate_rad_s
    out: list[Candidate] = []
    for delta, sigma in itertools.product((1.0, -1.0), (1.0, -1.0)):
        vec, v0 = _time_kernel(p, delta, sigma, to_point, _VEC)
        sca, _ = _time_kernel(p, delta, sigma, to_point, _SCA)
        pieces = _disc_interval(v0, d, (3.0 if to_point else 4.0) * rho, t_max)
        if to_point and pieces:
            pieces = _minus(pieces[0], _disc_interval(v0, d, rho, t_max))
        letters = _WORD[delta] + _WORD[-delta] + ("" if to_point else _WORD[delta])
        for lo, hi in pieces:
            grid = np.linspace(lo, hi, _N_TIME)
            with np.errstate(all="ignore"):
                arcs = np.stack(vec(grid))
            jumps = np.round(np.diff(arcs, axis=1) / TWO_PI).sum(axis=0)
            for loop in _LOOPS:
                found = _first_time_root(sca, grid, arcs, jumps, rho * loop, p)
                if found is not None:
                    t, arc_values = found
                    arc_values[0] += loop
                    out.append((t, letters, tuple(a / om for a in arc_values)))
    return out


def _first_time_root(
    sca: Callable, grid: np.ndarray, arcs: np.ndarray, jumps: np.ndarray, extra_m: float,
    p: Problem,
) -> tuple[float, list[float]] | None:  # fmt: skip
    """Earliest valid root of ``rho * sum(arcs) + extra_m - s0 T`` on the scanned grid."""
    rho, s0 = p.rho, p.airspeed_m_s
    f = rho * arcs.sum(axis=0) + extra_m - s0 * grid
    wrap_m = TWO_PI * rho * jumps
    left_next = f[1:] - wrap_m  # the left branch continued to the cell's right end
    right_prev = f[:-1] + wrap_m  # the right branch continued to the cell's left end
    fin = np.isfinite(f[:-1]) & np.isfinite(f[1:])
    down_left = fin & (f[:-1] > 0) & (left_next <= 0)
    down_right = fin & (jumps != 0) & (right_prev > 0) & (f[1:] <= 0)
    for j in np.nonzero(down_left | down_right)[0]:
        for side, ok in ((j, down_left[j]), (j + 1, down_right[j])):
            if not ok:
                continue
            ref = [float(a) for a in arcs[:, side]]

            def unwrapped(t: float, ref: list[float] = ref) -> list[float]:
                return [
                    r + (a - r + math.pi) % TWO_PI - math.pi
                    for a, r in zip(sca(t), ref, strict=True)
                ]

            def g(t: float, unwrapped: Callable = unwrapped) -> float:
                return rho * sum(unwrapped(t)) + extra_m - s0 * t

            a, b = float(grid[j]), float(grid[j + 1])
            if g(a) * g(b) > 0:
                continue
            t = brentq(g, a, b, xtol=1e-13, rtol=1e-15)
            values = unwrapped(t)
            if abs(g(t)) < 1e-7 * (1.0 + rho) and all(-1e-9 <= v <= TWO_PI + 1e-9 for v in values):
                return t, [min(max(v, 0.0), TWO_PI) for v in values]
    return None


def _disc_interval(v0: complex, d: complex, r: float, t_max: float) -> list[tuple[float, float]]:
    """``[lo, hi]`` within ``[0, t_max]`` where ``|v0 - d t| <= r`` (empty list if none)."""
    dd = abs(d) ** 2
    if dd == 0.0:
        return [(0.0, t_max)] if abs(v0) <= r else []
    mid = (v0.conjugate() * d).real / dd
    disc = mid * mid - (abs(v0) ** 2 - r * r) / dd
    if disc < 0:
        return []
    half = math.sqrt(disc)
    lo, hi = max(mid - half, 0.0), min(mid + half, t_max)
    return [(lo, hi)] if hi > lo else []


def _minus(
    piece: tuple[float, float], holes: list[tuple[float, float]]
) -> list[tuple[float, float]]:
    """``piece`` with the (at most one) interval in ``holes`` removed."""
    if not holes:
        return [piece]
    (lo, hi), (h_lo, h_hi) = piece, holes[0]
    return [(a, b) for a, b in ((lo, min(hi, h_lo)), (max(lo, h_hi), hi)) if b > a]


def _refine(
    f: Callable[[float], float], grid: np.ndarray, values: np.ndarray, tol: float
) -> Iterator[float]:
    """Roots of ``f`` at the sign changes of ``values`` on ``grid``, in grid order (lazily).

    A sign change whose refined point does not make ``|f| < tol`` is a jump and is dropped.
    """
    finite = np.isfinite(values)
    neg = np.signbit(values)
    idx = np.nonzero(finite[:-1] & finite[1:] & (neg[:-1] != neg[1:]))[0]
    for i in idx:
        a, b = float(grid[i]), float(grid[i + 1])
        fa, fb = f(a), f(b)
        if fa * fb > 0:  # scalar and vector rounding disagree at an end: not a real change
            continue
        x = brentq(f, a, b, xtol=1e-13, rtol=1e-15)
        if abs(f(x)) < tol:
            yield x
