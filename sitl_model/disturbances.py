"""The world and sensors as they are: changing wind, GPS errors, an EKF-like wind estimate.

Pure and vectorised over vehicles (arrays of shape (N,)); randomness only from the
generators passed in; no clocks. Conventions as in the whole package: complex vectors
``north + i east``, wind vectors point where the air moves TOWARDS, wind directions in
parameters and messages are where it blows FROM (compass degrees).

Wind at simulated time ``t`` (s), before gusts (:func:`mean_wind_m_s`)::

    speed(t) = max(0, S + A_s sin(2 pi t / T + pi/4) + [t >= t_step] dS)
    from(t)  = D + A_d cos(2 pi t / T + pi/4) + [t >= t_step] dD

``S, D`` = ``SIM_WIND_SPD, SIM_WIND_DIR``; ``A_s, A_d, T`` = ``SIM_WDRIFT_SPD,
SIM_WDRIFT_DIR, SIM_WDRIFT_T``; ``t_step, dS, dD`` = ``SIM_WSTEP_T, SIM_WSTEP_SPD,
SIM_WSTEP_DIR`` (``t_step = 0``: no step). The speed and direction drifts are in quadrature
and both start at ``+0.71`` of their amplitude, so at no moment are both zero and the world
differs from the forecast from t = 0. Each vehicle adds its own gust, and the total is
capped at :data:`MAX_WIND_RATIO` of the airspeed (:func:`companion.core.particle.cap_wind`):
the wind never reaches the airspeed, whatever the parameters.

Sensor errors (:class:`SensorErrors`), one state per vehicle shared by every message, updated
at the GPS's 10 Hz: GPS position error = first-order Gauss-Markov per axis (sigma ``SIM_GPS_NOISE``,
correlation ``SIM_GPS_TAU``); GPS velocity error = white noise per axis
(``SIM_GPS_VNOISE``); the autopilot's wind estimate = the true wind at the vehicle low-passed
with time constant ``SIM_WEST_TAU`` plus a Gauss-Markov error (sigma ``SIM_WEST_ERR``,
correlation :data:`WIND_EST_ERR_TAU_S`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from companion.core.wind import Wind
from sitl_model.params import Params

MAX_WIND_RATIO = 0.9  # the total wind (mean + gust) is capped at this fraction of the airspeed
WIND_EST_ERR_TAU_S = 60.0  # correlation time (s) of the wind estimate's error
_DRIFT_PHASE_RAD = math.pi / 4.0


@dataclass(frozen=True)
class WindProfile:
    """Mean wind over a run: steady, sinusoidal drift and one step (m/s, deg, s)."""

    speed_m_s: float
    from_deg: float
    drift_speed_m_s: float = 0.0
    drift_dir_deg: float = 0.0
    drift_period_s: float = 600.0
    step_t_s: float = 0.0
    step_speed_m_s: float = 0.0
    step_dir_deg: float = 0.0

    @classmethod
    def from_params(cls, p: Params) -> WindProfile:
        """The profile set by the ``SIM_WIND_*``, ``SIM_WDRIFT_*`` and ``SIM_WSTEP_*`` knobs."""
        return cls(
            p["SIM_WIND_SPD"],
            p["SIM_WIND_DIR"],
            p["SIM_WDRIFT_SPD"],
            p["SIM_WDRIFT_DIR"],
            p["SIM_WDRIFT_T"],
            p["SIM_WSTEP_T"],
            p["SIM_WSTEP_SPD"],
            p["SIM_WSTEP_DIR"],
        )

    @property
    def varies(self) -> bool:
        """True if the mean wind changes with time (a drift or a step is set)."""
        drift = self.drift_speed_m_s != 0.0 or self.drift_dir_deg != 0.0
        step = self.step_t_s > 0.0 and (self.step_speed_m_s != 0.0 or self.step_dir_deg != 0.0)
        return drift or step


def wind_speed_from(t_s: float, w: WindProfile) -> tuple[float, float]:
    """Mean wind at time ``t_s`` (s): speed (m/s, >= 0) and direction FROM (deg, [0, 360))."""
    arg = 2.0 * math.pi * t_s / w.drift_period_s + _DRIFT_PHASE_RAD
    speed = w.speed_m_s + w.drift_speed_m_s * math.sin(arg)
    from_deg = w.from_deg + w.drift_dir_deg * math.cos(arg)
    if w.step_t_s > 0.0 and t_s >= w.step_t_s:
        speed += w.step_speed_m_s
        from_deg += w.step_dir_deg
    return max(0.0, speed), from_deg % 360.0


def mean_wind_m_s(t_s: float, w: WindProfile) -> complex:
    """Mean wind vector at time ``t_s`` (s): m/s, complex, direction blown towards."""
    return Wind.from_meteo(*wind_speed_from(t_s, w)).vector


def complex_normal(rng: np.random.Generator, sigma: float, n: int) -> np.ndarray:
    """``n`` complex samples with independent N(0, sigma^2) north and east parts."""
    z = rng.normal(0.0, sigma, (2, n))
    return z[0] + 1j * z[1]


def gauss_markov_step(
    x: np.ndarray, sigma: float, tau_s: float, dt_s: float, rng: np.random.Generator
) -> np.ndarray:
    """One exact step of a first-order Gauss-Markov process per axis.

    ``x' = phi x + sigma sqrt(1 - phi^2) n`` with ``phi = exp(-dt/tau)``: the stationary
    standard deviation is ``sigma`` (units of ``x``) and the autocorrelation
    ``exp(-|lag| / tau)``. ``x`` complex (north + i east), shape (N,).
    """
    phi = math.exp(-dt_s / tau_s)
    return x * phi + complex_normal(rng, sigma * math.sqrt(1.0 - phi * phi), x.shape[0])


def lag_step(x: np.ndarray, target: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag towards ``target`` over ``dt_s`` (s), exact for a held target.

    ``tau_s`` (s) = 0 follows the target at once.
    """
    if tau_s <= 0.0:
        return np.array(target, dtype=complex)
    return x + (target - x) * (1.0 - math.exp(-dt_s / tau_s))


@dataclass(frozen=True)
class ErrorParams:
    """Sensor-error settings: sigmas (m, m/s) and time constants (s)."""

    gps_sigma_m: float = 0.0
    gps_tau_s: float = 30.0
    gps_vel_sigma_m_s: float = 0.0
    wind_est_tau_s: float = 10.0
    wind_est_sigma_m_s: float = 0.0
    wind_est_err_tau_s: float = WIND_EST_ERR_TAU_S

    @classmethod
    def from_params(cls, p: Params) -> ErrorParams:
        """The settings of the ``SIM_GPS_*`` and ``SIM_WEST_*`` knobs."""
        return cls(
            p["SIM_GPS_NOISE"],
            p["SIM_GPS_TAU"],
            p["SIM_GPS_VNOISE"],
            p["SIM_WEST_TAU"],
            p["SIM_WEST_ERR"],
        )


class SensorErrors:
    """Per-vehicle GPS errors and wind estimate, advanced once per GPS epoch (0.1 s).

    Attributes (complex arrays of shape (N,)):
        gps_pos_m: GPS position error (m), added to every position the vehicle reports.
        gps_vel_m_s: GPS velocity error (m/s), added to every velocity it reports.
        wind_est_m_s: the autopilot's lagged estimate of the wind at the vehicle (m/s).
        wind_err_m_s: slowly varying error of that estimate (m/s).
    """

    def __init__(
        self,
        cfg: ErrorParams,
        wind_m_s: np.ndarray,
        gps_rng: np.random.Generator,
        wind_rng: np.random.Generator,
    ) -> None:
        """Errors drawn from their stationary distributions; the estimate starts converged
        on ``wind_m_s`` (complex m/s per vehicle, the true wind at t = 0)."""
        n = len(wind_m_s)
        self._gps_rng = gps_rng
        self._wind_rng = wind_rng
        zeros = np.zeros(n, dtype=complex)
        self.gps_pos_m = zeros.copy()
        self.gps_vel_m_s = zeros.copy()
        self.wind_err_m_s = zeros.copy()
        self.wind_est_m_s = np.array(wind_m_s, dtype=complex)
        if cfg.gps_sigma_m > 0:
            self.gps_pos_m = complex_normal(gps_rng, cfg.gps_sigma_m, n)
        if cfg.gps_vel_sigma_m_s > 0:
            self.gps_vel_m_s = complex_normal(gps_rng, cfg.gps_vel_sigma_m_s, n)
        if cfg.wind_est_sigma_m_s > 0:
            self.wind_err_m_s = complex_normal(wind_rng, cfg.wind_est_sigma_m_s, n)
        self._gps_pos_on = cfg.gps_sigma_m > 0
        self._gps_vel_on = cfg.gps_vel_sigma_m_s > 0
        self._wind_err_on = cfg.wind_est_sigma_m_s > 0

    def step(self, cfg: ErrorParams, wind_m_s: np.ndarray, dt_s: float) -> None:
        """Advance every error by ``dt_s`` (s), one GPS epoch.

        ``wind_m_s`` (complex m/s) is the true wind at the start of the interval, held over
        it (exact for a wind that changed at the previous epoch).
        """
        n = len(wind_m_s)
        if cfg.gps_sigma_m > 0:
            self.gps_pos_m = gauss_markov_step(
                self.gps_pos_m, cfg.gps_sigma_m, cfg.gps_tau_s, dt_s, self._gps_rng
            )
        elif self._gps_pos_on:
            self.gps_pos_m = np.zeros(n, dtype=complex)
        self._gps_pos_on = cfg.gps_sigma_m > 0
        if cfg.gps_vel_sigma_m_s > 0:
            self.gps_vel_m_s = complex_normal(self._gps_rng, cfg.gps_vel_sigma_m_s, n)
        elif self._gps_vel_on:
            self.gps_vel_m_s = np.zeros(n, dtype=complex)
        self._gps_vel_on = cfg.gps_vel_sigma_m_s > 0
        self.wind_est_m_s = lag_step(self.wind_est_m_s, wind_m_s, cfg.wind_est_tau_s, dt_s)
        if cfg.wind_est_sigma_m_s > 0:
            self.wind_err_m_s = gauss_markov_step(
                self.wind_err_m_s,
                cfg.wind_est_sigma_m_s,
                cfg.wind_est_err_tau_s,
                dt_s,
                self._wind_rng,
            )
        elif self._wind_err_on:
            self.wind_err_m_s = np.zeros(n, dtype=complex)
        self._wind_err_on = cfg.wind_est_sigma_m_s > 0

    @property
    def wind_reported_m_s(self) -> np.ndarray:
        """What WIND reports (complex m/s, direction blown towards): estimate + error."""
        return self.wind_est_m_s + self.wind_err_m_s
