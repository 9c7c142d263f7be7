"""The particle-in-wind vehicle of eq. 1 as a pure, vectorised step function.

    dr/dt = s0 exp(i theta) + w + g(t)       dtheta/dt = u,   |u| <= omega_max

``r`` is the complex position ``north + i east`` (m), ``theta`` the air heading (rad,
compass), ``u`` the turn rate (rad/s, positive = right), ``w`` the steady wind and ``g`` an
optional gust (first-order Gauss-Markov, drawn only from the generator passed in).

Integration is exact for a constant turn rate over the step: the particle flies a circular
arc in the air mass while the air mass drifts by ``(w + g) dt``. With a first-order response
lag ``tau`` the achieved turn rate relaxes towards the command exactly
(``u <- u_c + (u - u_c) exp(-dt/tau)``); the heading change over the step is then exact and
the position follows the arc of the step's mean turn rate (error O(dt^2 |du/dt|)).
Arrays of shape (N,) step N vehicles at once; scalars work too.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from companion.core.wind import wrap_pi


@dataclass(frozen=True)
class ParticleParams:
    """Vehicle parameters.

    Attributes:
        airspeed_m_s: constant airspeed ``s0`` (m/s), > 0.
        max_turn_rate_rad_s: turn-rate limit ``omega_max`` (rad/s), > 0.
        lag_s: first-order time constant of the turn-rate response (s); 0 = instant.
        gust_std_m_s: standard deviation of each horizontal gust component (m/s); 0 = none.
        gust_tau_s: correlation time of the gust process (s), > 0.
    """

    airspeed_m_s: float
    max_turn_rate_rad_s: float
    lag_s: float = 0.0
    gust_std_m_s: float = 0.0
    gust_tau_s: float = 5.0

    def __post_init__(self) -> None:
        """Validate: positive airspeed and turn-rate limit, non-negative lag and gust."""
        for name in ("airspeed_m_s", "max_turn_rate_rad_s", "gust_tau_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        for name in ("lag_s", "gust_std_m_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True)
class ParticleState:
    """State of one or more particles (arrays of equal shape, or scalars).

    Attributes:
        pos_m: complex position ``north + i east`` (m).
        heading_rad: air heading ``theta`` (rad, compass).
        turn_rate_rad_s: achieved turn rate ``u`` (rad/s), used by the lag model.
        gust_m_s: current gust velocity (m/s, complex north + i east).
    """

    pos_m: np.ndarray
    heading_rad: np.ndarray
    turn_rate_rad_s: np.ndarray
    gust_m_s: np.ndarray

    @classmethod
    def at(cls, north_m: ArrayLike, east_m: ArrayLike, heading_rad: ArrayLike) -> ParticleState:
        """Particles at rest in turn (u = 0) and without gust at the given poses."""
        n = np.asarray(north_m, dtype=float)
        e = np.asarray(east_m, dtype=float)
        h = np.asarray(heading_rad, dtype=float)
        n, e, h = np.broadcast_arrays(n, e, h)
        zeros = np.zeros(n.shape)
        return cls(n + 1j * e, h.copy(), zeros, zeros.astype(complex))


def cap_wind(wind_m_s: ArrayLike, max_m_s: ArrayLike) -> np.ndarray:
    """``wind_m_s`` (complex m/s) scaled down to ``max_m_s`` (m/s) where it is stronger."""
    w = np.asarray(wind_m_s, dtype=complex)
    mag = np.abs(w)
    over = mag > max_m_s
    if not over.any():
        return w
    return np.where(over, w * (max_m_s / np.where(over, mag, 1.0)), w)


def arc_factor(x: ArrayLike) -> np.ndarray:
    """``(exp(i x) - 1) / (i x)``, stable at x = 0: the chord of an arc turned by ``x`` (rad)
    over the length of the arc, as a complex factor."""
    x = np.asarray(x, dtype=float)
    return np.exp(0.5j * x) * np.sinc(x / (2.0 * np.pi))


def step(
    state: ParticleState,
    turn_rate_cmd_rad_s: ArrayLike,
    params: ParticleParams,
    wind_m_s: complex,
    dt_s: float,
    rng: np.random.Generator | None = None,
    airspeed_m_s: ArrayLike | None = None,
    max_wind_m_s: ArrayLike | None = None,
) -> ParticleState:
    """Advance the particles by ``dt_s`` seconds under a turn-rate command held over the step.

    Args:
        state: current state.
        turn_rate_cmd_rad_s: commanded turn rate (rad/s); clipped to +-omega_max, non-finite
            values are treated as 0 (wings level).
        params: vehicle parameters.
        wind_m_s: steady wind vector (m/s, complex north + i east, direction blown towards).
        dt_s: step length (s), > 0.
        rng: the one random generator; required only when gusts are enabled.
        airspeed_m_s: each particle's airspeed over the step (m/s), overriding
            ``params.airspeed_m_s`` (e.g. an autopilot whose airspeed decays); None: the
            constant ``params.airspeed_m_s``.
        max_wind_m_s: cap on the magnitude of each particle's total wind (steady + gust, m/s;
            :func:`cap_wind`); None: no cap.

    Returns:
        The new state.
    """
    if not dt_s > 0:
        raise ValueError(f"dt_s must be > 0, got {dt_s!r}")
    w_max = params.max_turn_rate_rad_s
    cmd = np.asarray(turn_rate_cmd_rad_s, dtype=float)
    if cmd.ndim:  # the same values as below, without nan_to_num's and clip's overhead
        cmd = np.minimum(np.maximum(np.where(np.isfinite(cmd), cmd, 0.0), -w_max), w_max)
    else:
        cmd = np.clip(np.nan_to_num(cmd, nan=0.0, posinf=0.0, neginf=0.0), -w_max, w_max)
    u0 = np.asarray(state.turn_rate_rad_s, dtype=float)
    if params.lag_s > 0:
        a = np.exp(-dt_s / params.lag_s)
        u1 = cmd + (u0 - cmd) * a
        dtheta = cmd * dt_s + (u0 - cmd) * params.lag_s * (1.0 - a)
    else:
        if not np.shape(u0):
            u1 = cmd
        elif cmd.shape == u0.shape:
            u1 = cmd.copy()
        else:
            u1 = np.broadcast_to(cmd, u0.shape).astype(float)
        dtheta = cmd * dt_s
    gust = np.asarray(state.gust_m_s, dtype=complex)
    if params.gust_std_m_s > 0:
        if rng is None:
            raise ValueError("gusts are enabled: pass the simulator's numpy Generator as rng")
        phi = np.exp(-dt_s / params.gust_tau_s)
        sigma = params.gust_std_m_s * np.sqrt(1.0 - phi**2)
        shape = np.shape(gust)
        noise = rng.normal(0.0, sigma, shape) + 1j * rng.normal(0.0, sigma, shape)
        gust_next = gust * phi + noise
        drift = 0.5 * (gust + gust_next)
    else:
        gust_next = gust
        drift = gust
    theta0 = np.asarray(state.heading_rad, dtype=float)
    s0 = params.airspeed_m_s if airspeed_m_s is None else np.asarray(airspeed_m_s, dtype=float)
    air = s0 * dt_s * np.exp(1j * theta0) * arc_factor(dtheta)
    wind = wind_m_s + drift
    if max_wind_m_s is not None:
        wind = cap_wind(wind, max_wind_m_s)
    pos = np.asarray(state.pos_m, dtype=complex) + air + wind * dt_s
    heading = wrap_pi(theta0 + dtheta)
    return ParticleState(pos, heading, u1, gust_next)


def step_one(
    pos_m: complex,
    heading_rad: float,
    turn_rate_cmd_rad_s: float,
    params: ParticleParams,
    wind_m_s: complex,
    dt_s: float,
) -> tuple[complex, float]:
    """:func:`step` of one particle at rest in turn and without gust (as
    ``step(ParticleState.at(north, east, heading), ...)`` with no gust process, airspeed
    override or wind cap): the same arithmetic in the same order on Python scalars, so the
    same values, at a fraction of numpy's per-call cost (a companion's prediction each step).

    Args:
        pos_m: position (complex north + i east, m).
        heading_rad: air heading (rad, compass).
        turn_rate_cmd_rad_s: commanded turn rate (rad/s); clipped to +-omega_max, a
            non-finite value is treated as 0.
        params: vehicle parameters (``gust_std_m_s`` is not used).
        wind_m_s: steady wind vector (m/s, complex, towards).
        dt_s: step length (s), > 0.

    Returns:
        The new position (complex m) and air heading (rad, [-pi, pi)).
    """
    if not dt_s > 0:
        raise ValueError(f"dt_s must be > 0, got {dt_s!r}")
    w_max = params.max_turn_rate_rad_s
    cmd = float(turn_rate_cmd_rad_s)
    cmd = min(max(cmd if math.isfinite(cmd) else 0.0, -w_max), w_max)
    if params.lag_s > 0:
        a = float(np.exp(-dt_s / params.lag_s))  # numpy's exp, as step's (math's may differ)
        dtheta = cmd * dt_s + (0.0 - cmd) * params.lag_s * (1.0 - a)
    else:
        dtheta = cmd * dt_s
    x = math.pi * (dtheta / (2.0 * math.pi) if dtheta != 0 else 1.0e-20)  # np.sinc's
    arc = cmath.exp(0.5j * dtheta) * (math.sin(x) / x)
    air = params.airspeed_m_s * dt_s * cmath.exp(1j * float(heading_rad)) * arc
    pos = complex(pos_m) + air + (wind_m_s + 0j) * dt_s
    return pos, wrap_pi(float(heading_rad) + dtheta)
