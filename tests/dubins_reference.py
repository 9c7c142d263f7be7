"""Independent reference for the planner tests: classic Dubins lengths and the air-frame scan.

Written from the classic six-word Dubins formulas (normalised distance ``d = D / rho``,
angles ``alpha``, ``beta`` relative to the start-goal line), with nothing shared with the
planner's trochoid or air-frame code. Works on the complex plane ``x + i y`` with angles
from the x axis towards y; a path's length does not care whether that is the compass frame
(north + i east) or its mirror image, because all six words are taken.

Minimum time in wind (docs/design.md §6): in the frame moving with the air the aircraft flies
a plain Dubins path of radius ``s0 / omega`` to the drifting goal ``g - w t``. A path of some word
arrives at ``t`` only if its length is exactly ``s0 t``; so

* :func:`first_time_below` (docs/design.md §6 literally): the first ``t`` with
  ``DubinsLength(t) <= s0 t``, a lower bound on the minimum time; and
* :func:`min_time_in_wind`: the first ``t`` where some word's length (optionally plus one
  or two full loops) crosses ``s0 t`` *continuously*. Near the start the Dubins length
  jumps (a word appears when two circles separate, or an arc wraps from 2 pi to 0); a jump
  below ``s0 t`` is not an arrival, because the path that appears is too short to fill the
  time and the words cannot be stretched continuously.
"""

from __future__ import annotations

import numpy as np

TAU = 2.0 * np.pi


def _mod(x: np.ndarray) -> np.ndarray:
    return np.mod(x, TAU)


def dubins_words(q0: complex, th0: float, q1, th1: float, rho: float) -> dict[str, tuple]:
    """Normalised ``(t, p, q)`` of the six words (nan where a word does not exist).

    ``q1`` may be an array of goal points. Lengths are ``rho * (t + p + q)``. The words
    are named in the mathematical sense (L = towards increasing angle).
    """
    delta = np.asarray(q1) - q0
    d = np.abs(delta) / rho
    phi = np.angle(delta)
    a = _mod(th0 - phi)
    b = _mod(th1 - phi)
    sa, sb, ca, cb = np.sin(a), np.sin(b), np.cos(a), np.cos(b)
    cab = np.cos(a - b)
    out = {}
    with np.errstate(invalid="ignore"):
        p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)
        tmp = np.arctan2(cb - ca, d + sa - sb)
        out["LSL"] = (_mod(tmp - a), np.sqrt(np.where(p2 >= 0, p2, np.nan)), _mod(b - tmp))
        p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)
        tmp = np.arctan2(ca - cb, d - sa + sb)
        out["RSR"] = (_mod(a - tmp), np.sqrt(np.where(p2 >= 0, p2, np.nan)), _mod(tmp - b))
        p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)
        p = np.sqrt(np.where(p2 >= 0, p2, np.nan))
        tmp = np.arctan2(-ca - cb, d + sa + sb) - np.arctan2(-2.0, p)
        out["LSR"] = (_mod(tmp - a), p, _mod(tmp - b))
        p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)
        p = np.sqrt(np.where(p2 >= 0, p2, np.nan))
        tmp = np.arctan2(ca + cb, d - sa - sb) - np.arctan2(2.0, p)
        out["RSL"] = (_mod(a - tmp), p, _mod(b - tmp))
        c = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8
        p = _mod(TAU - np.arccos(np.where(np.abs(c) <= 1, c, np.nan)))
        t = _mod(a - np.arctan2(ca - cb, d - sa + sb) + p / 2)
        out["RLR"] = (t, p, _mod(a - b - t + p))
        c = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8
        p = _mod(TAU - np.arccos(np.where(np.abs(c) <= 1, c, np.nan)))
        t = _mod(-a - np.arctan2(ca - cb, d + sa - sb) + p / 2)
        out["LRL"] = (t, p, _mod(b - a - t + p))
    return out


def dubins_length(q0: complex, th0: float, q1, th1: float, rho: float) -> np.ndarray:
    """Shortest Dubins length (m) from ``(q0, th0)`` to ``(q1, th1)``; ``q1`` may be an array."""
    words = dubins_words(q0, th0, q1, th1, rho)
    lengths = np.stack([t + p + q for t, p, q in words.values()])
    return rho * np.nanmin(lengths, axis=0)


def fly_word(q0: complex, th0: float, word: str, tpq: tuple, rho: float) -> tuple[complex, float]:
    """End pose of a normalised Dubins word (math sense: L increases the angle)."""
    pos, th = complex(q0), float(th0)
    for letter, x in zip(word, tpq, strict=True):
        if letter == "S":
            pos += rho * x * np.exp(1j * th)
            continue
        sense = 1.0 if letter == "L" else -1.0
        centre = pos + sense * 1j * rho * np.exp(1j * th)
        th += sense * x
        pos = centre - sense * 1j * rho * np.exp(1j * th)
    return pos, th


def _bisect_sign(gap, lo: float, hi: float, steps: int = 24) -> tuple[float, float]:
    """Shrink ``[lo, hi]`` (gap(lo) > 0 >= gap(hi)) by bisection on the sign of ``gap``."""
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if gap(mid) <= 0:
            hi = mid
        else:
            lo = mid
    return lo, hi


def first_time_below(
    goal: complex, th0: float, thf: float, s0: float, omega: float, wind: complex,
    t_hi: float, step_s: float = 0.02,
) -> float:  # fmt: skip
    """First ``t`` in ``[0, t_hi]`` with ``DubinsLength(t) <= s0 t`` (start at 0), or inf."""
    rho = s0 / omega

    def gap(t):
        return dubins_length(0j, th0, goal - wind * t, thf, rho) - s0 * t

    ts = np.arange(0.0, t_hi + step_s, step_s)
    below = np.nonzero(gap(ts) <= 0)[0]
    if below.size == 0:
        return np.inf
    j = below[0]
    return 0.0 if j == 0 else _bisect_sign(gap, ts[j - 1], ts[j])[1]


def min_time_in_wind(
    goal: complex, th0: float, thf: float, s0: float, omega: float, wind: complex,
    t_hi: float, step_s: float = 0.02, loops: tuple[int, ...] = (0, 1),
) -> float:  # fmt: skip
    """First continuous crossing of ``s0 t`` by any word's length (+ ``loops`` full circles).

    Scans ``[0, t_hi]`` every ``step_s`` seconds per word; a sign change between two scan
    points where the word exists is bisected on the sign of ``length - s0 t`` and kept only
    if the length is continuous there (jump below 1 mm across the final bracket).
    """
    rho = s0 / omega
    ts = np.arange(0.0, t_hi + step_s, step_s)
    words = dubins_words(0j, th0, goal - wind * ts, thf, rho)
    best = np.inf
    for name, (t_, p_, q_) in words.items():

        def length(t: float, name: str = name) -> float:
            a, b, c = dubins_words(0j, th0, goal - wind * t, thf, rho)[name]
            return float(rho * (a + b + c))

        for n in loops:
            gaps = rho * (t_ + p_ + q_ + n * TAU) - s0 * ts
            ok = np.isfinite(gaps[:-1]) & np.isfinite(gaps[1:])
            for j in np.nonzero(ok & (gaps[:-1] > 0) & (gaps[1:] <= 0))[0]:
                if ts[j] >= best:
                    break

                def gap(t: float, n: int = n, length=length) -> float:
                    value = length(t) + n * TAU * rho - s0 * t
                    return value if np.isfinite(value) else np.inf

                lo, hi = _bisect_sign(gap, ts[j], ts[j + 1])
                if abs(length(hi) - length(lo)) < 1e-3:
                    best = min(best, hi)
                    break
    return best
