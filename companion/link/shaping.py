"""Closing the loop on the achieved turn (pure): a turn-rate command -> a profile setpoint.

Real autopilots do not fly what an open-loop conversion promises (docs/design.md §7):
ArduPlane achieves about 0.75 of ``g tan(phi) / V`` for a bank setpoint, and its course hold
lags a moving target. Each profile here has one scalar *gain*: achieved air turn rate (rad/s)
per unit of the setpoint's nominal quantity ``x``:

* turn-rate: ``x`` = body yaw rate sent (rad/s); nominal gain 1.
* bank: ``x = g tan(phi) / V`` of the bank sent (rad/s); nominal gain 1 (ArduPlane ~0.75).
* attitude (PX4): as bank; the pitch and thrust come from the companion's own holds
  (:mod:`companion.link.offboard`).
* path (PX4): ``x`` = the turn rate of the arc whose look-ahead point is sent (rad/s);
  nominal gain 1, adapted (PX4 flew 1.28 of the curvature sent: docs/px4.md).
* heading: ``x`` = the turn rate asked for through the lateral-acceleration limit (rad/s):
  the target course leads the aircraft by 90 deg on the side of the turn and param3 =
  ``V |x|`` (m/s^2, at least ``MIN_ACCEL_M_S2``) caps the turn, so the aircraft keeps turning
  at that rate between setpoints (and through a stalled link, for 90 deg) instead of
  stopping on a near target; nominal gain 1.

The gain is estimated online by exponentially forgotten least squares on pairs (``x`` in
force over a telemetry interval, achieved turn rate measured over it), and the setpoint sent
is ``x = u / gain``. Samples near the turn-rate limit, after gaps or with little excitation
do not update it. Time is the vehicle's (s), passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from companion.core.wind import wrap_pi
from companion.link.offboard import OffboardSetpoints
from companion.link.setpoints import (
    G_M_S2,
    MAX_BANK_RAD,
    Profile,
    bank_setpoint,
    heading_setpoint,
    turn_rate_setpoint,
)

GAIN_BOUNDS: dict[str, tuple[float, float]] = {
    "turn-rate": (0.5, 1.5),
    "bank": (0.4, 1.5),
    "heading": (0.4, 1.5),
    "attitude": (0.4, 1.5),
    "path": (0.5, 1.5),
}
MAX_LEAD_RAD = math.radians(90.0)  # a course target further ahead would be ambiguous
MIN_ACCEL_M_S2 = 0.05  # param3 must stay > 0 (0 means "no limit" to some autopilots)
MAX_SAMPLE_GAP_S = 0.5
AUTOPILOT_LAG_S = 0.3  # assumed first-order lag of the achieved turn rate (ArduPlane: 0.3-0.6)
PAIR_LP_S = 1.5  # low-pass of the (command, achieved) pairs (s)
MAX_RESIDUAL_RAD_S = 0.05  # a sample this far from the model is something else (a loiter,
# a stalled link, a gust): it does not update the gain


@dataclass
class GainEstimate:
    """Forgetting least squares of ``y = gain * x`` (one parameter).

    Attributes:
        gain: current estimate (prior until there is enough excitation).
        prior: the nominal gain.
        lo, hi: bounds of the estimate.
        tau_s: forgetting time constant (s of vehicle time).
        min_info: least weighted sum of ``x^2`` before the data overrule the prior.
    """

    prior: float
    lo: float
    hi: float
    tau_s: float = 20.0
    min_info: float = 0.02
    gain: float = 0.0
    sxx: float = 0.0
    sxy: float = 0.0
    samples: int = 0

    def __post_init__(self) -> None:
        """Start at the prior."""
        self.gain = self.prior

    def update(self, x: float, y: float, dt_s: float) -> float:
        """Add one pair observed over ``dt_s`` (s); returns the new estimate."""
        lam = math.exp(-dt_s / self.tau_s)
        self.sxx = lam * self.sxx + x * x
        self.sxy = lam * self.sxy + x * y
        self.samples += 1
        if self.sxx >= self.min_info:
            # blend with the prior as if it were min_info worth of data
            est = (self.sxy + self.prior * self.min_info) / (self.sxx + self.min_info)
            self.gain = min(self.hi, max(self.lo, est))
        return self.gain


class Shaper:
    """Turns turn-rate commands into setpoints of one profile, correcting the gain online.

    Args:
        profile: "turn-rate", "bank" or "heading".
        airspeed_m_s: airspeed ``V`` (m/s) for the bank conversion.
        max_turn_rate_rad_s: the vehicle's turn-rate limit (rad/s).
        adapt: estimate the gain online (False: open loop at the nominal gain). The turn-rate
            profile is flown exactly by rate-controlled autopilots, so it never adapts.
        heading_gain_1_s: prior gain for the heading profile (achieved / asked turn rate).
        offboard: PX4's setpoint builder, needed by the ``attitude`` and ``path`` profiles.
    """

    def __init__(
        self,
        profile: Profile,
        airspeed_m_s: float,
        max_turn_rate_rad_s: float,
        *,
        adapt: bool = True,
        heading_gain_1_s: float = 1.0,
        offboard: OffboardSetpoints | None = None,
    ) -> None:
        """Start at the nominal gain."""
        if profile not in GAIN_BOUNDS:
            raise ValueError(f"unknown profile {profile!r}")
        if profile in ("attitude", "path") and offboard is None:
            raise ValueError(f"the {profile} profile needs an OffboardSetpoints")
        self.profile = profile
        self.offboard = offboard
        self.airspeed_m_s = float(airspeed_m_s)
        self.max_u = float(max_turn_rate_rad_s)
        self.adapt = adapt and profile != "turn-rate"
        lo, hi = GAIN_BOUNDS[profile]
        prior = heading_gain_1_s if profile == "heading" else 1.0
        self.estimate = GainEstimate(prior, lo, hi)
        # the bank the autopilot flies at most (rad): its own limit where it said it (ArduPlane
        # clips a bank setpoint to ROLL_LIMIT_DEG), so the gain is learnt from the bank flown
        self.bank_limit_rad = MAX_BANK_RAD
        self._last_x: float | None = None
        self._x_lag: float | None = None  # the command through the autopilot's lag
        self._pair: tuple[float, float] | None = None  # low-passed (command, achieved)
        self._last_t_s = 0.0

    @property
    def gain(self) -> float:
        """Current achieved-turn-rate gain (see the module docstring for its unit)."""
        return self.estimate.gain

    @property
    def x_in_force(self) -> float | None:
        """Nominal turn rate (rad/s) of the setpoint in force (None: none sent since the
        last :meth:`observe` or :meth:`reset_sample`)."""
        return self._last_x

    def observe(self, t_s: float, achieved_turn_rate_rad_s: float | None) -> None:
        """The turn rate (rad/s) achieved since the last setpoint, measured at ``t_s`` (s)."""
        x, self._last_x = self._last_x, None
        if not self.adapt or x is None:
            self._x_lag = self._pair = None
            return
        dt = t_s - self._last_t_s
        if not 0 < dt <= MAX_SAMPLE_GAP_S:
            self._x_lag = self._pair = None
            return
        # The autopilot answers a setpoint with a lag (roll dynamics): the turn rate achieved
        # over the interval answers the recent commands, not only the last one. Pair it with
        # the command passed through a first-order lag of AUTOPILOT_LAG_S, averaged over the
        # interval; pairing it with the last command alone biases the gain low whenever the
        # commands vary (gusts), down to the floor on ArduPlane.
        # Both then go through the same low-pass (PAIR_LP_S), which keeps the slow content
        # (where a lag, assumed or real, shifts little) and drops the fast (gust-driven).
        x0 = x if self._x_lag is None else self._x_lag
        decay = math.exp(-dt / AUTOPILOT_LAG_S)
        x_avg = x + (x0 - x) * AUTOPILOT_LAG_S / dt * (1.0 - decay)
        self._x_lag = x + (x0 - x) * decay
        y = achieved_turn_rate_rad_s
        if y is None or abs(y) > 0.9 * self.max_u:
            self._pair = None  # saturated by the autopilot's limit: says nothing of the gain
            return
        a = 1.0 - math.exp(-dt / PAIR_LP_S)
        if self._pair is None:
            self._pair = (x_avg, y)
            return
        xf, yf = self._pair
        xf, yf = xf + a * (x_avg - xf), yf + a * (y - yf)
        self._pair = (xf, yf)
        if abs(yf - self.gain * xf) > MAX_RESIDUAL_RAD_S + 0.6 * abs(xf):
            return
        self.estimate.update(xf, yf, dt)

    def reset_sample(self) -> None:
        """Forget the setpoint in force (no setpoint was sent, e.g. the pilot took over)."""
        self._last_x = None
        self._x_lag = self._pair = None

    def setpoint(
        self,
        t_s: float,
        turn_rate_rad_s: float,
        course_rad: float,
        time_boot_ms: int,
        target_system: int,
        *,
        pos_m: complex = 0j,
        heading_rad: float = 0.0,
        wind_m_s: complex = 0j,
    ) -> Any:
        """The setpoint flying ``turn_rate_rad_s`` (rad/s) from ground course ``course_rad``.

        The path profile also takes the position ``pos_m`` (local north + i east, m), the air
        heading ``heading_rad`` (rad, compass) and the wind ``wind_m_s`` (towards, m/s).
        """
        u = max(-self.max_u, min(self.max_u, float(turn_rate_rad_s)))
        x = u / self.gain
        if self.profile == "turn-rate":
            msg = turn_rate_setpoint(x, time_boot_ms, target_system)
        elif self.profile in ("bank", "attitude"):
            phi = math.atan(self.airspeed_m_s * x / G_M_S2)
            phi = max(-self.bank_limit_rad, min(self.bank_limit_rad, phi))
            x = G_M_S2 * math.tan(phi) / self.airspeed_m_s
            if self.profile == "bank":
                msg = bank_setpoint(phi, time_boot_ms, target_system)
            else:
                assert self.offboard is not None  # PX4's profiles are made with their offboard
                msg = self.offboard.attitude(t_s, phi, time_boot_ms, target_system)
        elif self.profile == "path":
            assert self.offboard is not None
            msg = self.offboard.path(
                x, pos_m, heading_rad, self.airspeed_m_s, wind_m_s, time_boot_ms, target_system
            )
        else:
            x = max(-self.max_u, min(self.max_u, x))
            target = float(wrap_pi(course_rad + math.copysign(MAX_LEAD_RAD, x)))
            accel = max(MIN_ACCEL_M_S2, self.airspeed_m_s * abs(x))
            x = math.copysign(accel / self.airspeed_m_s, x)
            msg = heading_setpoint(target, accel, target_system)
        self._last_x, self._last_t_s = x, t_s
        return msg
