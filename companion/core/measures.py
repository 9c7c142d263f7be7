"""Formation measures of docs/design.md §8 (pure; arrays in, floats out).

* splay error: max over phase-adjacent pairs of ``|delta psi - 2 pi / N|`` (deg);
* centre error: ``max_k |c_k - c0|`` (m);
* convergence time: first time after which splay error < 2 deg and centre error < 5 m hold.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from companion.core.wind import TWO_PI

SPLAY_TOL_DEG = 2.0
CENTRE_TOL_M = 5.0


def splay_error_deg(phases_rad: ArrayLike) -> float:
    """Largest deviation of adjacent phase gaps from ``2 pi / N`` (deg); 0 for N <= 1: one
    column of :func:`splay_errors_deg`."""
    column = np.asarray(phases_rad, dtype=float).ravel()[:, np.newaxis]
    return float(splay_errors_deg(column)[0])


def splay_errors_deg(phases_rad: ArrayLike) -> np.ndarray:
    """The splay error of every column of an (N members, T times) array of phases (rad):
    per column, the largest deviation of adjacent phase gaps from ``2 pi / N`` (deg, shape
    (T,)); 0 for N <= 1."""
    psi = np.sort(np.mod(np.asarray(phases_rad, dtype=float), TWO_PI), axis=0)
    n = psi.shape[0]
    if n <= 1:
        return np.zeros(psi.shape[1])
    gaps = np.diff(np.vstack([psi, psi[:1] + TWO_PI]), axis=0)
    return np.degrees(np.max(np.abs(gaps - TWO_PI / n), axis=0))


def centre_error_m(centres_m: ArrayLike, centre_ref_m: complex) -> float:
    """Largest distance of the members' loop centres from the reference centre (m)."""
    c = np.asarray(centres_m, dtype=complex).ravel()
    return float(np.max(np.abs(c - centre_ref_m))) if c.size else 0.0


def convergence_time_s(
    t_s: ArrayLike,
    splay_deg: ArrayLike,
    centre_m: ArrayLike,
    splay_tol_deg: float = SPLAY_TOL_DEG,
    centre_tol_m: float = CENTRE_TOL_M,
) -> float | None:
    """First sample time after which both errors stay below tolerance (s); None if never."""
    t = np.asarray(t_s, dtype=float)
    ok = (np.asarray(splay_deg) < splay_tol_deg) & (np.asarray(centre_m) < centre_tol_m)
    if t.size == 0 or not ok[-1]:
        return None
    bad = np.flatnonzero(~ok)
    return float(t[0] if bad.size == 0 else t[bad[-1] + 1])
