"""One companion's own wind estimate from its telemetry (pure).

Two sources, fused when both are fresh:

* the autopilot's estimate, where it streams one (ArduPilot's WIND: ``direction`` where the
  wind comes FROM, deg; ``speed`` m/s; PX4's WIND_COV: ``wind_x``, ``wind_y`` the air's
  velocity north and east, m/s, NaN when unknown);
* the air-data triangle ``w = v_ground - V_air e^{i theta}``: ground velocity from
  GLOBAL_POSITION_INT, air heading ``theta`` from ATTITUDE yaw (extrapolated to the velocity's
  time with the yaw rate between the last two attitudes) and airspeed ``V_air`` from VFR_HUD
  (the mission's airspeed until one arrives). Each sample is noisy (gusts, GPS velocity
  noise, attitude/velocity timing); an exponential average over ``tau_s`` of vehicle time
  removes some of it. The default (5 s) is short on purpose: the fleet takes the median of
  its members' estimates and the agreement's hysteresis absorbs the scatter, while a lagging
  wind costs cross-track (drifting wind on the ellipse, robustness bench, agreement at
  0.2 m/s: 30 s read 17.6 m p95 with the former 0.5 m/s agreement, 10 s 11.4 m, 5 s 9.8 m).
  Timing biases that rotate with the heading are not averaged out over a loop at 5 s; an
  autopilot with such biases may want a longer ``tau_s``.

Bad input (NaN, a negative speed, a wind at or above the airspeed) is ignored and counted in
:attr:`WindEstimator.counts`. Times are the autopilot's boot time (ms) or vehicle seconds,
passed in; wind vectors are ``north + i east`` (m/s) towards which the air moves.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field

from companion.core.wind import valid_wind, wrap_pi

MAX_ATTITUDE_AGE_S = 0.3  # an attitude older than this is not paired with a velocity
MAX_AP_WIND_AGE_S = 5.0  # the autopilot's estimate is fresh for this long
MIN_OWN_WEIGHT = 0.9  # own estimate used once the average holds this much weight (0..1)


def wind_from_meteo(speed_m_s: float, from_deg: float) -> complex:
    """Wind vector (m/s, towards) from speed and the direction it blows FROM (deg)."""
    return speed_m_s * cmath.exp(1j * (math.radians(from_deg) + math.pi))


@dataclass
class WindEstimator:
    """Online wind estimate of one vehicle.

    Args:
        airspeed_m_s: the mission's airspeed (m/s), until VFR_HUD reports one.
        tau_s: averaging time of the air-data triangle (s).
    """

    airspeed_m_s: float
    tau_s: float = 5.0
    counts: dict[str, int] = field(
        default_factory=lambda: {"bad_autopilot": 0, "bad_airdata": 0, "samples": 0}
    )
    _ap: tuple[complex, float] | None = None  # (wind, vehicle s)
    _att: list[tuple[float, float]] = field(default_factory=list)  # (boot s, yaw rad)
    _air_m_s: float | None = None
    _sum: complex = 0j
    _weight: float = 0.0
    _last_t_s: float | None = None

    # ---- inputs -------------------------------------------------------------------------
    def on_autopilot_wind(self, t_s: float, speed_m_s: float, from_deg: float) -> bool:
        """The autopilot's WIND at vehicle time ``t_s`` (s); False (counted) if refused."""
        ok = math.isfinite(speed_m_s) and math.isfinite(from_deg) and speed_m_s >= 0.0
        w = wind_from_meteo(speed_m_s, from_deg) if ok else None
        if w is None or not valid_wind(w, self.airspeed_now):  # (None: not ok)
            self.counts["bad_autopilot"] += 1
            return False
        self._ap = (w, float(t_s))
        return True

    def on_autopilot_wind_vector(self, t_s: float, north_m_s: float, east_m_s: float) -> bool:
        """The autopilot's wind as the velocity of the air (m/s north, east: PX4's WIND_COV)
        at vehicle time ``t_s`` (s); False (counted) if refused (NaN: PX4 has none)."""
        ok = math.isfinite(north_m_s) and math.isfinite(east_m_s)
        w = complex(north_m_s, east_m_s) if ok else None
        if w is None or not valid_wind(w, self.airspeed_now):
            self.counts["bad_autopilot"] += 1
            return False
        self._ap = (w, float(t_s))
        return True

    def on_attitude(self, boot_s: float, yaw_rad: float) -> None:
        """ATTITUDE yaw (rad, compass heading) at autopilot boot time ``boot_s`` (s)."""
        if not math.isfinite(yaw_rad):
            self.counts["bad_airdata"] += 1
            return
        if self._att and boot_s <= self._att[-1][0]:
            self._att = []  # reordered or rebooted: start over
        self._att = [*self._att[-1:], (float(boot_s), float(yaw_rad))]

    def on_airspeed(self, airspeed_m_s: float) -> None:
        """VFR_HUD airspeed (m/s)."""
        if not (math.isfinite(airspeed_m_s) and airspeed_m_s > 1.0):
            self.counts["bad_airdata"] += 1
            return
        self._air_m_s = float(airspeed_m_s)

    def on_ground_velocity(self, t_s: float, boot_s: float, vel_m_s: complex) -> None:
        """Ground velocity (m/s) at vehicle time ``t_s`` / boot time ``boot_s`` (s)."""
        yaw = self.heading_at(boot_s)
        if yaw is None:
            return
        w = complex(vel_m_s) - self.airspeed_now * cmath.exp(1j * yaw)
        if not valid_wind(w, self.airspeed_now * 1.5):  # a sample may be gusty; not absurd
            self.counts["bad_airdata"] += 1
            return
        dt = 0.1 if self._last_t_s is None else t_s - self._last_t_s
        if dt <= 0:
            return  # not newer
        if dt > 10 * self.tau_s:
            self._sum, self._weight = 0j, 0.0  # a long gap: forget
        lam = math.exp(-dt / self.tau_s)
        # exponentially forgotten mean: weight -> 1 after a few tau of samples
        self._sum = lam * self._sum + (1.0 - lam) * w
        self._weight = lam * self._weight + (1.0 - lam)
        self._last_t_s = float(t_s)
        self.counts["samples"] += 1

    # ---- outputs ------------------------------------------------------------------------
    @property
    def airspeed_now(self) -> float:
        """The latest measured airspeed (m/s), else the mission's."""
        return self._air_m_s if self._air_m_s is not None else self.airspeed_m_s

    def heading_at(self, boot_s: float) -> float | None:
        """Air heading (rad) extrapolated to boot time ``boot_s`` (s), None if stale."""
        if not self._att:
            return None
        t1, y1 = self._att[-1]
        if abs(boot_s - t1) > MAX_ATTITUDE_AGE_S:
            return None
        rate = 0.0
        if len(self._att) == 2:
            t0, y0 = self._att[0]
            if 0 < t1 - t0 <= 1.0:
                rate = float(wrap_pi(y1 - y0)) / (t1 - t0)
        return y1 + rate * (boot_s - t1)

    def own(self) -> complex | None:
        """The air-data estimate (m/s) once it has settled, else None."""
        return self._sum / self._weight if self._weight >= MIN_OWN_WEIGHT else None

    def autopilot(self, t_s: float) -> complex | None:
        """The autopilot's latest estimate (m/s) if fresh at ``t_s`` (s)."""
        if self._ap is None or t_s - self._ap[1] > MAX_AP_WIND_AGE_S:
            return None
        return self._ap[0]

    def estimate(self, t_s: float) -> complex | None:
        """The fused estimate at ``t_s`` (s): the mean of the fresh sources, None if none."""
        sources = [w for w in (self.own(), self.autopilot(t_s)) if w is not None]
        if not sources:
            return None
        return sum(sources) / len(sources)
