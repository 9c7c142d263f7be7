"""The time-splay steering law in wind (eq. 17-21, with docs/design.md §4's corrections).

For each steered vehicle k, from its own state and the time-phases of all N members:

    c_k       = r_k - rho(gamma_k)
    nu_k      = kappa(gamma_k) s_k [ 1 + K ( s_k <e^{i gamma_k}, c_k - c_ref> - dU/dpsi_k ) ]
    dU/dpsi_k = sum_{m=1..N} K_m < p_m , i e^{i m psi_k} >,  p_m = (1/(m N)) sum_j e^{i m psi_j}
    u_k       = nu_k s_k^2 / (s0 (s0 + beta cos(theta_k - theta_w))),  clipped to +-omega_max

``<a, b> = Re(conj(a) b)``. ``c_ref`` is the fixed centre ``c0`` (default) or, in the paper's
form, the mean of the members' centres. All of it is computed in the patrol's canonical
(clockwise) frame; inputs and the returned turn rate are world quantities (rad/s, positive
= right). The phase-gradient term is passed in, so the same law serves the splay formation
and the tracking of one target phase (the rejoin after a prosecution).

Gain scaling: with ``l = s0 L / (2 pi)`` (m^2/s), ``K = centre_gain / l`` (s/m^2) and
``|K_m| = phase_gain * l / N`` (m^2/s) make both terms dimensionless and scale-free.
"""

from __future__ import annotations

import cmath
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, cast, overload

import numpy as np
from numpy.typing import ArrayLike

from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI

CentreForm = Literal["fixed", "mean"]


@dataclass(frozen=True)
class Gains:
    """Steering gains.

    Attributes:
        centre_gain: dimensionless ``K l`` (default 2).
        phase_gain: dimensionless ``|K_m| N / l`` (default 1).
        centre_form: "fixed" steers every centre to ``c0``; "mean" is the paper's ``P c``.
        track_gain: dimensionless gain of the single-phase tracking potential used to bring a
            returning prosecutor back into its slot (``K_track = track_gain * l``).
        xtrack_bw_rad_s: natural frequency (rad/s) of the cross-track hold added to the law
            (:func:`xtrack_course_rate`; fixed-centre form only); 0 = the paper's law alone.
        xtrack_damping: damping ratio of the hold.
        speed_authority_m_s: most the airspeed may differ from the mission's to hold the
            time-phase (m/s, :func:`phase_speed_offset`); 0 = a fixed airspeed (the paper).
        speed_tau_s: time constant (s) of that phase hold, in along-track slot error per
            airspeed change.
    """

    centre_gain: float = 2.0
    phase_gain: float = 1.0
    centre_form: CentreForm = "fixed"
    track_gain: float = 0.5
    xtrack_bw_rad_s: float = 0.3
    xtrack_damping: float = 0.8
    speed_authority_m_s: float = 2.0
    speed_tau_s: float = 8.0

    def __post_init__(self) -> None:
        """Validate: finite positive gains and a known centre form."""
        for name in ("centre_gain", "phase_gain", "track_gain", "xtrack_damping"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        if not (np.isfinite(self.xtrack_bw_rad_s) and 0 <= self.xtrack_bw_rad_s <= 2.0):
            raise ValueError(f"xtrack_bw_rad_s must be in [0, 2] rad/s, got {self.xtrack_bw_rad_s}")
        if not (np.isfinite(self.speed_authority_m_s) and 0 <= self.speed_authority_m_s <= 10):
            raise ValueError(
                f"speed_authority_m_s must be in [0, 10] m/s, got {self.speed_authority_m_s}"
            )
        if not (np.isfinite(self.speed_tau_s) and 1.0 <= self.speed_tau_s <= 600.0):
            raise ValueError(f"speed_tau_s must be in [1, 600] s, got {self.speed_tau_s}")
        if self.centre_form not in ("fixed", "mean"):
            raise ValueError(f"centre_form must be 'fixed' or 'mean', got {self.centre_form!r}")


def speed_holds_phase(gains: Gains) -> bool:
    """Whether the airspeed holds the time-phase (:func:`phase_speed_offset`): with an
    authority, and in the fixed-centre form only, where the loop a UAV should be on, and so
    where along it each one is, is known; the mean form lets the loop float."""
    return gains.speed_authority_m_s > 0 and gains.centre_form == "fixed"


def length_scale_m2_s(patrol: Patrol) -> float:
    """``l = s0 L / (2 pi)`` (m^2/s), the natural scale of the gains."""
    return patrol.airspeed_m_s * patrol.length_m / TWO_PI


def centre_gain_s_m2(patrol: Patrol, gains: Gains) -> float:
    """``K`` (s/m^2)."""
    return gains.centre_gain / length_scale_m2_s(patrol)


def phase_gains_m2_s(patrol: Patrol, gains: Gains, n: int) -> np.ndarray:
    """``K_1..K_N`` (m^2/s): positive for m < N, negative for m = N (time-splay, eq. 20)."""
    if n < 1:
        raise ValueError(f"need at least one member, got {n}")
    k = np.full(n, gains.phase_gain * length_scale_m2_s(patrol) / n)
    k[-1] = -k[-1]
    return k


# From this many members the gradient is read from a table of the splay's pair function
# (:func:`_pair_table`): O(N) per steered member instead of N harmonics of N members, to
# about 1e-10 of the gradient's scale; smaller fleets sum the harmonics exactly (the
# one-member form, :func:`splay_gradient_of`, in Python scalars: N^2 products)
TABLE_FROM_N = 16
TABLE_POINTS_PER_HARMONIC = 128  # grid points per period of the highest harmonic (N)


def splay_gradient_of(psi_k: float, others: Sequence[float], k_m2_s: float) -> float:
    """``dU/dpsi_k`` (m^2/s) of one member of the time-splay (:func:`splay_gradient` with
    the gains of :func:`phase_gains_m2_s`: ``K_m = k`` for ``m < N``, ``K_N = -k``).

    Args:
        psi_k: the member's phase (rad).
        others: the other ``N - 1`` members' phases (rad).
        k_m2_s: ``k`` (m^2/s).

    The same sum as :func:`splay_gradient`, over the pairs: ``-(1/N) sum_j G(psi_k - psi_j)``
    with ``G(theta) = sum_m (K_m / m) sin(m theta)`` (the member's own pair is 0), the
    harmonics ``e^{i m theta}`` by repeated products, in Python scalars; from
    :data:`TABLE_FROM_N` members by :func:`splay_gradient`'s table.
    """
    n = len(others) + 1
    if n >= TABLE_FROM_N:
        k_m = np.full(n, k_m2_s)
        k_m[-1] = -k_m2_s
        return float(
            _gradient_from_table(np.asarray(float(psi_k)), np.array([psi_k, *others]), k_m)
        )
    weights = _inverse_harmonics(n)
    total = 0.0
    for psi_j in others:
        z = cmath.exp(1j * (psi_k - psi_j))
        zm = z
        for w in weights:  # m = 1 .. N - 1
            total += zm.imag * w
            zm *= z
        total -= zm.imag / n  # m = N: K_N = -k
    return -(k_m2_s / n) * total


@functools.lru_cache(maxsize=64)
def _inverse_harmonics(n: int) -> tuple[float, ...]:
    """``1 / m`` for ``m = 1 .. n - 1``."""
    return tuple(1.0 / m for m in range(1, n))


def splay_gradient(psi_k: ArrayLike, psi_all: ArrayLike, k_m: np.ndarray) -> np.ndarray:
    """``dU/dpsi_k`` of the (N, N) time-splay potential (m^2/s).

    Args:
        psi_k: phases of the steered members (rad), shape (M,) or scalar.
        psi_all: phases of all N members, the steered ones included (rad), shape (N,).
        k_m: ``K_1..K_N`` (m^2/s), shape (N,).

    The sum over harmonics, ``sum_m K_m <p_m, i e^{i m psi_k}>``, is a sum over members of
    one pair function, ``-(1/N) sum_j G(psi_k - psi_j)`` with ``G(theta) = sum_m (K_m / m)
    sin(m theta)``: from :data:`TABLE_FROM_N` members ``G`` is interpolated from a table
    (:func:`_pair_table`), so a member's gradient costs O(N), not O(N^2).
    """
    psi_all = np.asarray(psi_all, dtype=float)
    n = psi_all.size
    if n >= TABLE_FROM_N:
        return _gradient_from_table(np.asarray(psi_k, dtype=float), psi_all, k_m)
    m, mn = _harmonics(n)
    p = np.exp(1j * (m[:, None] * psi_all)).sum(axis=1) / mn  # p_m, shape (N,)
    e = 1j * np.exp(1j * np.multiply.outer(np.asarray(psi_k, dtype=float), m))  # (..., N)
    return (p.conj() * e).real @ k_m


def _gradient_from_table(psi_k: np.ndarray, psi_all: np.ndarray, k_m: np.ndarray) -> np.ndarray:
    """:func:`splay_gradient` as ``-(1/N) sum_j G(psi_k - psi_j)``, ``G`` by cubic Hermite
    interpolation of its table (values and slopes)."""
    n = psi_all.size
    k_m = np.asarray(k_m, dtype=float)
    # the table is of the gains' shape (K_m / K_1): a re-timed loop scales K, not the table
    scale = float(k_m[0]) or 1.0
    g, dg = _pair_table(n, (k_m / scale).tobytes())
    points = g.size - 1
    h = TWO_PI / points
    x = np.mod(psi_k[..., None] - psi_all, TWO_PI) / h  # (..., N), grid units
    i = np.minimum(x.astype(np.intp), points - 1)
    t = x - i
    u = 1.0 - t
    tt = t * t
    pair = (
        (1.0 + 2.0 * t) * u * u * g[i]
        + t * u * u * h * dg[i]
        + tt * (3.0 - 2.0 * t) * g[i + 1]
        - tt * u * h * dg[i + 1]
    )
    return -(scale / n) * pair.sum(axis=-1)


@functools.lru_cache(maxsize=8)
def _pair_table(n: int, shape: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``G(theta) = sum_m (K_m / m) sin(m theta)`` and ``G'(theta) = sum_m K_m cos(m theta)``
    on ``points + 1`` equal steps of ``[0, 2 pi]`` (read-only), for gains ``K_m`` given as
    the bytes of a float array of ``n`` (one FFT each; ``points`` a multiple of ``n``, so an
    even splay's phase differences fall on grid points)."""
    k_m = np.frombuffer(shape, dtype=float)
    points = TABLE_POINTS_PER_HARMONIC * n
    coef = np.zeros(points, dtype=complex)
    m = np.arange(1, n + 1)
    coef[m] = k_m
    series = np.fft.ifft(coef) * points  # sum_m K_m e^{i m theta_p}
    coef[m] = k_m / m
    g = (np.fft.ifft(coef) * points).imag
    g, dg = np.append(g, g[0]), np.append(series.real, series.real[0])
    g.flags.writeable = dg.flags.writeable = False
    return g, dg


@functools.lru_cache(maxsize=64)
def _harmonics(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``m = 1..n`` and ``m n`` (read-only arrays), for the splay potential of ``n`` members."""
    m = np.arange(1, n + 1)
    mn = m * n
    m.flags.writeable = mn.flags.writeable = False
    return m, mn


def splay_potential(psi_all: ArrayLike, k_m: np.ndarray) -> float:
    """``U = sum_m K_m (N/2) |p_m|^2`` (m^2/s)."""
    psi_all = np.asarray(psi_all, dtype=float)
    n = psi_all.size
    m = np.arange(1, n + 1)
    p = np.exp(1j * np.outer(m, psi_all)).sum(axis=1) / (m * n)
    return float(np.sum(k_m * 0.5 * n * np.abs(p) ** 2))


def splay_curvature_m2_s(patrol: Patrol, gains: Gains, n: int) -> float:
    """``d^2 U / d psi_k^2`` at a perfect splay of ``n`` members, the others held (m^2/s).

    Moving one phase by ``delta`` from a perfect splay adds ``delta^2 / N^2`` to
    ``|p_m|^2`` for every ``m < N`` and takes ``(N - 1) delta^2 / N^2`` from ``|p_N|^2``;
    with ``U = sum_m K_m (N/2) |p_m|^2``, ``K_m = k`` for ``m < N`` and ``K_N = -k``, the
    second derivative is ``2 k (N - 1) / N``. Zero for one member (nothing to splay against).
    """
    if n < 2:
        return 0.0
    k = gains.phase_gain * length_scale_m2_s(patrol) / n
    return 2.0 * k * (n - 1) / n


def phase_speed_offset(
    patrol: Patrol, gains: Gains, phase_gradient: float, curvature_m2_s: float
) -> float:
    """Airspeed change (m/s) that holds this UAV's time-phase: fast when behind, slow ahead.

    The phase error is read from the potential's gradient, ``delta = dU/dpsi / curvature``
    (rad; exact near the splay, :func:`splay_curvature_m2_s`, or ``K_track`` for the
    single-phase potential), as the along-track slot error ``e = delta L / (2 pi)`` (m). On
    the loop a change ``dv`` of airspeed moves the slot error at about ``dv``, so
    ``dv = -e / tau`` closes it with time constant ``speed_tau_s``, smoothly saturated at
    ``+-speed_authority_m_s``. Steering alone can change a phase only by flying a longer or
    shorter path, i.e. off the loop; the airspeed keeps the splay along the loop instead
    (docs/robustness.md, "Gusts"). 0 when the authority or the curvature is 0, and in the
    mean-centre form (:func:`speed_holds_phase`).
    """
    if not speed_holds_phase(gains) or curvature_m2_s <= 0.0:
        return 0.0
    return slot_speed_offset(patrol, gains, float(phase_gradient) / curvature_m2_s)


def slot_speed_offset(patrol: Patrol, gains: Gains, phase_error_rad: float) -> float:
    """Airspeed change (m/s) for a time-phase error ``phase_error_rad`` (rad, positive =
    ahead of the slot): ``-e / tau`` of the along-track error ``e = delta L / (2 pi)`` (m),
    smoothly saturated at ``+-speed_authority_m_s``; 0 where the airspeed does not hold the
    phase (:func:`speed_holds_phase`)."""
    a = gains.speed_authority_m_s
    if not speed_holds_phase(gains):
        return 0.0
    err_m = phase_error_rad * patrol.length_m / TWO_PI
    return a * math.tanh(-err_m / gains.speed_tau_s / a)


@overload
def tracking_gradient(patrol: Patrol, gains: Gains, psi_k: float, psi_target: float) -> float: ...
@overload
def tracking_gradient(
    patrol: Patrol, gains: Gains, psi_k: ArrayLike, psi_target: ArrayLike
) -> np.ndarray: ...
def tracking_gradient(
    patrol: Patrol, gains: Gains, psi_k: ArrayLike, psi_target: ArrayLike
) -> np.ndarray | float:
    """``dU/dpsi_k`` of ``U = K_track (1 - cos(psi_k - psi_target))`` (m^2/s)."""
    k_track = gains.track_gain * length_scale_m2_s(patrol)
    if isinstance(psi_k, float) and isinstance(psi_target, float):
        return k_track * math.sin(psi_k - psi_target)
    return k_track * np.sin(np.asarray(psi_k) - np.asarray(psi_target))


def reference_centre(patrol: Patrol, gains: Gains, centres_all: ArrayLike | None = None) -> complex:
    """``c0`` (fixed form) or the mean of the members' centres (mean form), world m."""
    if gains.centre_form == "fixed":
        return patrol.centre_m
    if centres_all is None or np.size(centres_all) == 0:
        raise ValueError("the mean-centre form needs the members' centres")
    return complex(np.mean(np.asarray(centres_all, dtype=complex)))


XTRACK_SAT_M = 40.0  # the hold acts on offsets up to about this (m)
XTRACK_MAX_ANGLE_RAD = 0.5  # and on course errors up to this (rad)


def xtrack_course_rate(
    gains: Gains,
    groundspeed_m_s: ArrayLike,
    d_out_m: ArrayLike,
    course_error_rad: ArrayLike,
    law_course_gain_1_s: ArrayLike,
) -> np.ndarray:
    """Course-rate correction (rad/s, canonical) of the cross-track hold.

    The paper's law feeds back only ``<e^{i gamma}, c - c0>``, the along-track part of the
    centre error: an offset across a nearly straight edge (``c - c0`` normal to the course)
    is invisible to it until the loop curves, so gusts push aircraft tens of metres off the
    long edges. The hold adds ``k_d d - k_e eta`` on the offset ``d`` from the nearest loop
    point (outward positive) and the course error ``eta`` against its tangent: with
    ``d' = -s eta`` the offset obeys ``d'' + k_e d' + s k_d d = 0``, natural frequency ``w``
    and damping ``z`` for ``k_d = w^2 / s`` and ``k_e = 2 z w`` less the law's own course
    feedback ``K s^2`` (a course error moves the centre by ``R eta`` along the course, which
    the law answers with ``K s^2 eta``). Offsets saturate smoothly at ``XTRACK_SAT_M`` and
    course errors at ``XTRACK_MAX_ANGLE_RAD``: far from the loop the paper's law alone
    brings the aircraft in.
    """
    w, z = gains.xtrack_bw_rad_s, gains.xtrack_damping
    if w <= 0:
        return np.zeros(np.shape(d_out_m))
    if isinstance(d_out_m, float) and isinstance(course_error_rad, float):
        return xtrack_course_rate_of(  # a float for floats
            gains, float(groundspeed_m_s), d_out_m, course_error_rad, float(law_course_gain_1_s)
        )
    k_d = w * w / np.asarray(groundspeed_m_s)
    k_e = np.maximum(2.0 * z * w - np.asarray(law_course_gain_1_s), 0.0)
    d = XTRACK_SAT_M * np.tanh(np.asarray(d_out_m) / XTRACK_SAT_M)
    eta = np.clip(course_error_rad, -XTRACK_MAX_ANGLE_RAD, XTRACK_MAX_ANGLE_RAD)
    return k_d * d - k_e * eta


def xtrack_course_rate_of(
    gains: Gains,
    groundspeed_m_s: float,
    d_out_m: float,
    course_error_rad: float,
    law_course_gain_1_s: float,
) -> float:
    """:func:`xtrack_course_rate` of one aircraft (rad/s; the same arguments, floats)."""
    w, z = gains.xtrack_bw_rad_s, gains.xtrack_damping
    if w <= 0:
        return 0.0
    k_e = max(2.0 * z * w - law_course_gain_1_s, 0.0)
    d = XTRACK_SAT_M * math.tanh(d_out_m / XTRACK_SAT_M)
    eta = min(max(course_error_rad, -XTRACK_MAX_ANGLE_RAD), XTRACK_MAX_ANGLE_RAD)
    return w * w / groundspeed_m_s * d - k_e * eta


MAX_PHASE_BOOST = 25.0


def phase_boost(gains: Gains, patrol: Patrol) -> float:
    """Factor on the phase term with the cross-track hold on: ``1 + (w R / s0)^2`` with
    ``R = L / 2 pi`` the loop's mean radius, at most ``MAX_PHASE_BOOST`` (1 without the hold).

    A boost by the local radius of curvature instead was measured worse: on the ellipse the
    others' centre error during the paper's alert episode rose from 1.5 m to 3.6 m (the
    paper's bound is 2 m), since the flanks (R 800 m) got 25 and the tips (100 m) 1.1."""
    w = gains.xtrack_bw_rad_s
    if w <= 0:
        return 1.0
    r_mean = patrol.length_m / TWO_PI
    return float(min(MAX_PHASE_BOOST, 1.0 + (w * r_mean / patrol.airspeed_m_s) ** 2))


def hold_applies(gains: Gains, patrol: Patrol) -> bool:
    """Whether the cross-track hold is added to the law for this loop.

    Only in the fixed-centre form (the hold is relative to the base's loop; the mean form
    lets the loop float). With a fixed airspeed, only where the phase boost it needs at the
    loop's mean radius stays within ``MAX_PHASE_BOOST``: on a large loop (WPAFB, 24.7 km,
    would need about 870) the splay could not be kept by steering, and the paper's law alone
    holds it (measured: 17 m p95 with the hold off, an aircraft thrown off the loop with it
    on). With the airspeed free to hold the phase (``speed_authority_m_s`` > 0) the hold
    applies on any loop: the airspeed keeps the splay along the loop."""
    if gains.xtrack_bw_rad_s <= 0 or gains.centre_form != "fixed":
        return False
    if speed_holds_phase(gains):
        return True
    r_mean = patrol.length_m / TWO_PI
    return 1.0 + (gains.xtrack_bw_rad_s * r_mean / patrol.airspeed_m_s) ** 2 <= MAX_PHASE_BOOST


def cross_track(patrol: Patrol, pos_m: complex, heading_rad: float) -> tuple[float, float]:
    """Outward offset (m) from the nearest loop point and the course error against its
    tangent (rad, canonical sense: positive = turned further than the tangent)."""
    v = patrol.airspeed_m_s * np.exp(1j * patrol.angle_to_canon(heading_rad))
    g = float(np.angle(v + patrol.wind_canon.vector))
    g_t, d_out = patrol.nearest_canon(complex(patrol.to_canon(pos_m)))
    return d_out, float(np.angle(np.exp(1j * (g - g_t))))


def steering_turn_rate(
    patrol: Patrol,
    gains: Gains,
    pos_m: complex,
    heading_rad: float,
    phase_gradient: float,
    centre_ref_m: complex,
    max_turn_rate_rad_s: float,
) -> float:
    """Turn-rate command (rad/s, world, positive = right) of one aircraft from the steering
    law (eq. 19), with the cross-track hold where it applies.

    Args:
        patrol: loop, airspeed and wind.
        gains: steering gains.
        pos_m: position of the steered aircraft (world, complex m).
        heading_rad: its air heading (rad, world).
        phase_gradient: its ``dU/dpsi_k`` (m^2/s), e.g. from :func:`splay_gradient`.
        centre_ref_m: the centre the loop centres are steered to (world, complex m).
        max_turn_rate_rad_s: saturation (rad/s).

    Python scalars throughout (numpy's per-call cost is most of a control step's); the
    gains' constants on this loop (:func:`centre_gain_s_m2`, :func:`phase_boost`,
    :func:`hold_applies`) are worked out once per loop and gains.
    """
    s0 = patrol.airspeed_m_s
    wind = patrol.wind_canon
    pos_m, heading_rad = complex(pos_m), float(heading_rad)
    if patrol.clockwise:
        r, th, c_ref = pos_m, heading_rad, complex(centre_ref_m)
    else:
        r, th, c_ref = pos_m.conjugate(), -heading_rad, complex(centre_ref_m).conjugate()
    v = s0 * cmath.exp(1j * th) + wind.vector
    s2 = v.real * v.real + v.imag * v.imag
    s = math.sqrt(s2)
    g = math.atan2(v.imag, v.real)
    off, radius = patrol.shape.offset_and_radius(g)
    align = (complex(math.cos(g), -math.sin(g)) * (r - off - c_ref)).real
    big_k, boost, hold = _law_constants(patrol, gains)
    nu = s / radius * (1.0 + big_k * (s * align - phase_gradient))
    if hold:
        # The hold pins the aircraft to the loop, and an aircraft on the loop cannot change
        # its time-phase: the law corrects phases by flying off the loop (inside to catch up).
        # Held to an offset d, the phase rate changes by about d / R where the paper's law
        # changed it by (R / s) times its course rate: the phase term is boosted by the ratio
        # (w R / s)^2 at the loop's mean radius (capped) so the splay converges as before.
        nu = nu - s / radius * big_k * (boost - 1.0) * phase_gradient
        g_t, d_out = patrol.nearest_canon(r, g)
        eta = math.remainder(g - g_t, TWO_PI)
        nu = nu + xtrack_course_rate_of(gains, s, d_out, eta, big_k * s2)
    # u = nu s^2 / (s0 (s0 + beta cos(theta - theta_w))): turn_rate_from_course_rate
    u = nu * s2 / (s0 * (s0 + wind.speed_m_s * math.cos(th - wind.towards_rad)))
    u = u if patrol.clockwise else -u
    return min(max(u, -max_turn_rate_rad_s), max_turn_rate_rad_s)


def _law_constants(patrol: Patrol, gains: Gains) -> tuple[float, float, bool]:
    """``K`` (s/m^2), the phase boost and whether the hold applies, for ``gains`` on
    ``patrol``: computed once per (loop, gains) and kept on the patrol."""
    memo = patrol.derived
    key = ("steering", id(gains))
    got = cast("tuple[Gains, tuple[float, float, bool]] | None", memo.get(key))
    if got is None or got[0] is not gains:  # the gains are kept: their id is not reused
        consts = (
            centre_gain_s_m2(patrol, gains),
            phase_boost(gains, patrol),
            hold_applies(gains, patrol),
        )
        memo[key] = got = (gains, consts)
    return got[1]


def lyapunov(patrol: Patrol, gains: Gains, pos_m: ArrayLike, heading_rad: ArrayLike) -> float:
    """``V = S + (T / 2 pi) U`` for the whole fleet (m^2), fixed-centre or mean form."""
    c, psi = patrol.centre_and_phase(pos_m, heading_rad)
    c_ref = reference_centre(patrol, gains, c)
    s_pot = 0.5 * float(np.sum(np.abs(c - c_ref) ** 2))
    k_m = phase_gains_m2_s(patrol, gains, np.size(psi))
    return s_pot + patrol.period_s / TWO_PI * splay_potential(psi, k_m)
