"""One physics step of any length for N particles, integrated exactly over the step (pure).

:func:`advance` moves every vehicle of the particle model (:mod:`companion.core.particle`,
eq. 1) over ``h`` seconds under a turn-rate command held over the step, with what the
simulator adds around it: the turn-rate response lag, an airspeed relaxing to a demand, a
Gauss-Markov gust and the cap on the total wind. Nothing is approximated by the step's
length, so the simulator steps at the rate its companions control (0.1 s) instead of 50 Hz:

* turn rate ``u(t) = c + (u0 - c) exp(-t/tau)`` (``tau`` = ``lag_s``; 0: ``u = c``) and
  heading ``theta(t) = theta0 + c t + (u0 - c) tau (1 - exp(-t/tau))``, in closed form;
* airspeed ``s(t) = va + (s0 - va) exp(-t/tau_a)``, in closed form;
* the air-relative displacement ``int_0^h s(t) exp(i theta(t)) dt``: a constant turn rate at
  a constant airspeed flies an arc, ``s h exp(i theta0) arc_factor(c h)``
  (:func:`companion.core.particle.arc_factor`), and at a relaxing airspeed the arc plus
  ``(s0 - va) h exp(i theta0) expm1(z) / z`` with ``z = (i c - 1/tau_a) h``; under a lag,
  Gauss-Legendre quadrature (three nodes per panel, a panel per half lag time constant:
  below a micrometre on a 0.1 s step);
* the gust, a first-order Gauss-Markov process per axis (standard deviation ``sigma``,
  correlation time ``tau_g``), sampled exactly together with its integral over the step
  (:func:`gust_step`: the pair is jointly Gaussian given the gust at the start);
* the wind over the step, mean wind + mean gust, capped at ``max_wind_ratio`` of the
  step's mean airspeed (:func:`companion.core.particle.cap_wind`).

Conventions as in :mod:`companion.core.particle`: complex positions ``north + i east`` (m),
compass headings (rad), positive turn rate = right turn (rad/s), wind towards (m/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from companion.core.particle import ParticleParams, ParticleState, arc_factor, cap_wind
from companion.core.wind import wrap_pi

# Gauss-Legendre nodes on [-1, 1] and weights, three points (exact for degree-5 polynomials)
_GL_X = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
_GL_W = np.array([5.0, 8.0, 5.0]) / 9.0
PANELS_PER_LAG = 2.0  # quadrature panels per lag time constant (at least one per step)


@dataclass(frozen=True)
class Airspeed:
    """Each vehicle's airspeed over a step (arrays of shape (N,)): at the start ``start_m_s``
    (m/s), relaxing to ``demand_m_s`` (m/s) with time constant ``tau_s`` (s, > 0)."""

    start_m_s: np.ndarray
    demand_m_s: np.ndarray
    tau_s: np.ndarray

    def at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Airspeed (m/s) at ``t_s`` (s) into the step; shape (N,) or (N, K) for (K,) times."""
        t = np.asarray(t_s, dtype=float)
        if t.ndim:
            va, ds, tau = (x[:, None] for x in (self.demand_m_s, self.start_m_s, self.tau_s))
            return va + (ds - va) * np.exp(-t / tau)
        return self.demand_m_s + (self.start_m_s - self.demand_m_s) * np.exp(-t / self.tau_s)

    def mean(self, h_s: float) -> np.ndarray:
        """Mean airspeed (m/s) over the first ``h_s`` seconds (exact)."""
        x = h_s / self.tau_s
        return self.demand_m_s + (self.start_m_s - self.demand_m_s) * (-np.expm1(-x) / x)

    @property
    def steady(self) -> bool:
        """Whether every airspeed is at its demand (constant over the step)."""
        return bool(np.array_equal(self.start_m_s, self.demand_m_s))


def _integrated_ou_variance(x: float) -> float:
    """``2x - 3 + 4 exp(-x) - exp(-2x)`` (the integral's variance over ``sigma^2 tau^2``),
    by its series where the terms cancel (x < 0.1: relative error below 1e-13)."""
    if x >= 0.1:
        return 2.0 * x - 3.0 + 4.0 * math.exp(-x) - math.exp(-2.0 * x)
    total, term = 0.0, 1.0
    for n in range(1, 13):
        term *= x / n  # x^n / n!
        if n >= 3:
            total += (4.0 * (-1.0) ** n - (-2.0) ** n) * term
    return total


def gust_step(
    gust_m_s: np.ndarray, sigma_m_s: float, tau_s: float, h_s: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The gust after ``h_s`` (s) and its mean over the step, drawn exactly.

    Per axis, for ``dg = -g/tau dt + sigma sqrt(2/tau) dW`` (stationary std ``sigma``) and
    ``phi = exp(-h/tau)``: ``g(h) = phi g0 + e1`` and ``int_0^h g = tau (1 - phi) g0 + e2``
    with ``(e1, e2)`` zero-mean Gaussian, ``var e1 = sigma^2 (1 - phi^2)``,
    ``cov = sigma^2 tau (1 - phi)^2``, ``var e2 = sigma^2 tau^2 (2h/tau - 3 + 4 phi - phi^2)``.
    Draws four standard normals per vehicle from ``rng`` (shape (4, N)).

    Args:
        gust_m_s: gust now (complex m/s, shape (N,)).
        sigma_m_s: standard deviation per axis (m/s), > 0.
        tau_s: correlation time (s), > 0.
        h_s: step (s), > 0.
        rng: the simulator's generator.

    Returns:
        The gust at the end of the step and its mean over the step (complex m/s, (N,)).
    """
    x = h_s / tau_s
    one_minus_phi = -math.expm1(-x)
    phi = 1.0 - one_minus_phi
    var1 = sigma_m_s**2 * one_minus_phi * (1.0 + phi)
    a = math.sqrt(var1)
    b = sigma_m_s * tau_s * one_minus_phi**2 * sigma_m_s / a  # cov / a
    rest = _integrated_ou_variance(x) - one_minus_phi**3 / (1.0 + phi)  # var2 - b^2, scaled
    c = sigma_m_s * tau_s * math.sqrt(max(rest, 0.0))
    z = rng.standard_normal((4, np.shape(gust_m_s)[0]))
    z1 = z[0] + 1j * z[1]
    z2 = z[2] + 1j * z[3]
    g1 = phi * gust_m_s + a * z1
    integral = tau_s * one_minus_phi * gust_m_s + b * z1 + c * z2
    return g1, integral / h_s


def air_displacement(
    heading_rad: np.ndarray,
    turn_rate_rad_s: np.ndarray,
    command_rad_s: np.ndarray,
    lag_s: float,
    airspeed: Airspeed,
    h_s: float,
) -> np.ndarray:
    """``int_0^h s(t) exp(i theta(t)) dt`` (complex m, shape (N,)): the displacement through
    the air mass over the step (module docstring; the arc in closed form when it is one)."""
    if lag_s <= 0.0:  # a constant turn rate: an arc, and the airspeed's relaxation on it
        turn = np.exp(1j * heading_rad)
        if airspeed.steady:
            return airspeed.start_m_s * h_s * turn * arc_factor(command_rad_s * h_s)
        va, ds = airspeed.demand_m_s, airspeed.start_m_s - airspeed.demand_m_s
        z = (1j * command_rad_s - 1.0 / airspeed.tau_s) * h_s  # |z| >= h / tau_a > 0
        relax = np.expm1(z) / z  # int_0^h exp((i c - 1/tau_a) t) dt / h
        return h_s * turn * (va * arc_factor(command_rad_s * h_s) + ds * relax)
    panels = 1 if lag_s <= 0.0 else max(1, math.ceil(PANELS_PER_LAG * h_s / lag_s))
    width = h_s / panels
    t = ((np.arange(panels)[:, None] + 0.5 * (1.0 + _GL_X[None, :])) * width).ravel()
    w = np.tile(_GL_W, panels) * (0.5 * width)
    c, u0 = command_rad_s[:, None], turn_rate_rad_s[:, None]
    theta = heading_rad[:, None] + c * t
    if lag_s > 0.0:
        theta = theta + (u0 - c) * (-lag_s * np.expm1(-t / lag_s))
    return (airspeed.at(t) * np.exp(1j * theta)) @ w


def advance(
    state: ParticleState,
    command_rad_s: np.ndarray,
    params: ParticleParams,
    wind_m_s: complex,
    h_s: float,
    airspeed: Airspeed,
    max_wind_ratio: float,
    rng: np.random.Generator | None = None,
) -> ParticleState:
    """Advance N particles by ``h_s`` seconds under turn-rate commands held over the step.

    Args:
        state: the particles now (arrays of shape (N,)).
        command_rad_s: commanded turn rates (rad/s), clipped to +-``max_turn_rate_rad_s``;
            a non-finite one is 0 (wings level).
        params: turn-rate limit, lag, gust (``airspeed_m_s`` is not used: ``airspeed``).
        wind_m_s: mean wind over the step (complex m/s, towards).
        h_s: step (s), > 0.
        airspeed: each airspeed over the step.
        max_wind_ratio: the total wind is capped at this fraction of the step's mean
            airspeed.
        rng: the simulator's generator (required with gusts).

    Returns:
        The particles at the end of the step.

    Raises:
        ValueError: ``h_s`` not > 0, or gusts without ``rng``.
    """
    if not h_s > 0:
        raise ValueError(f"h_s must be > 0, got {h_s!r}")
    w_max = params.max_turn_rate_rad_s
    cmd = np.asarray(command_rad_s, dtype=float)
    cmd = np.minimum(np.maximum(np.where(np.isfinite(cmd), cmd, 0.0), -w_max), w_max)
    u0 = np.broadcast_to(np.asarray(state.turn_rate_rad_s, dtype=float), cmd.shape)
    theta0 = np.asarray(state.heading_rad, dtype=float)
    lag = params.lag_s
    if lag > 0:
        decay = math.exp(-h_s / lag)
        u1 = cmd + (u0 - cmd) * decay
        dtheta = cmd * h_s + (u0 - cmd) * (lag * (1.0 - decay))
    else:
        u1 = cmd.copy()
        dtheta = cmd * h_s
    air = air_displacement(theta0, u0, cmd, lag, airspeed, h_s)
    gust = np.asarray(state.gust_m_s, dtype=complex)
    if params.gust_std_m_s > 0:
        if rng is None:
            raise ValueError("gusts are enabled: pass the simulator's numpy Generator as rng")
        gust_next, gust_mean = gust_step(gust, params.gust_std_m_s, params.gust_tau_s, h_s, rng)
    else:
        gust_next, gust_mean = gust, gust
    wind = cap_wind(wind_m_s + gust_mean, max_wind_ratio * airspeed.mean(h_s))
    pos = np.asarray(state.pos_m, dtype=complex) + air + wind * h_s
    return ParticleState(pos, wrap_pi(theta0 + dtheta), u1, gust_next)
