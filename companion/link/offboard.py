"""PX4's two offboard setpoint profiles (pure): a turn-rate command -> what PX4 flies well.

PX4's fixed-wing OFFBOARD flies an attitude with thrust, or a position with velocity and
acceleration; it has no turn-rate, bank-only or course command (``docs/px4.md``).

* ``attitude`` (:meth:`OffboardSetpoints.attitude`): the roll ``phi`` of the turn-rate
  command (``atan(V u / g)``, from :class:`companion.link.shaping.Shaper`) with the pitch and
  thrust of :class:`EnergyHold`, the companion's own height and airspeed hold (TECS does not
  run in attitude offboard): two PI loops, pitch on the height error (with climb-rate
  damping and the ``1/cos phi`` lift of a bank as feed-forward), thrust on the airspeed
  error. Both start from the aircraft's own pitch and throttle (bumpless take-over).
* ``path`` (:meth:`OffboardSetpoints.path`): the look-ahead point of the arc the command
  flies: from the position, air heading ``theta``, airspeed ``V`` and wind ``w``, the point
  ``lookahead_s`` ahead on the particle's arc (``theta + u t``), the ground velocity there
  and the arc's acceleration ``i u V e^{i theta}``; PX4 follows the path through the point
  along the velocity, the acceleration's normal part as its curvature, TECS on the given
  altitude and its own FW_AIRSPD_TRIM (the speed is not PX4's to take here: the agent then
  holds the mission's airspeed).

:class:`FlightData` keeps the telemetry both need (ATTITUDE, VFR_HUD, GLOBAL_POSITION_INT).
Times are vehicle seconds, passed in; positions local ``north + i east`` (m) at the mission
origin; angles rad.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import pymap3d

from companion.core.particle import arc_factor
from companion.link.setpoints import attitude_setpoint, path_setpoint
from companion.mission.model import Origin

PATH_LOOKAHEAD_S = 0.5  # s ahead on the commanded arc (the setpoint's latency, and a little)
# PX4 (this build, SIH) turns AGAINST the acceleration's normal part: sent as the arc's
# (i u V e^{i theta}), a command turned the course at -0.45 of it (correlation -0.95 at a
# 0.5 s lag over 200 s); a circle sent as position, velocity and centripetal acceleration
# was flown 7-14 m outside for the same reason. So the acceleration is sent with this sign.
PX4_ACCEL_SIGN = -1.0
MAX_HOLD_GAP_S = 1.0  # a longer pause restarts the holds' integrators from the aircraft


@dataclass(frozen=True)
class HoldGains:
    """Gains and limits of :class:`EnergyHold` (measured on PX4 SIH: docs/px4.md).

    Attributes:
        pitch_per_m: pitch per metre of height error (rad/m).
        pitch_i_per_m_s: integral of the height error (rad per m s).
        pitch_per_climb: pitch per m/s of climb rate, subtracted (rad s/m): damping.
        pitch_bank_ff_rad: pitch added per unit of ``1/cos phi - 1`` (rad).
        thrust_per_m_s: thrust per m/s of airspeed error (1 per m/s).
        thrust_i_per_m: integral of the airspeed error (1 per m).
        pitch_min_rad, pitch_max_rad: pitch limits (rad).
        thrust_min, thrust_max: thrust limits (0..1).
    """

    pitch_per_m: float = 0.02
    pitch_i_per_m_s: float = 0.002
    pitch_per_climb: float = 0.05
    pitch_bank_ff_rad: float = 0.1
    thrust_per_m_s: float = 0.08
    thrust_i_per_m: float = 0.02
    pitch_min_rad: float = math.radians(-15.0)
    pitch_max_rad: float = math.radians(15.0)
    thrust_min: float = 0.05
    thrust_max: float = 1.0


class EnergyHold:
    """Pitch on height, thrust on airspeed: two PI loops (see :class:`HoldGains`)."""

    def __init__(self, gains: HoldGains | None = None) -> None:
        """Not started: the first :meth:`update` or :meth:`track` sets the integrators."""
        self.gains = gains or HoldGains()
        self.pitch_i_rad: float | None = None
        self.thrust_i: float | None = None
        self._last_t_s: float | None = None

    def track(self, t_s: float, pitch_rad: float, throttle: float) -> None:
        """Follow the aircraft's own pitch (rad) and throttle (0..1) at ``t_s`` (s): the
        integrators hold them, so the first command continues what it flies."""
        self.pitch_i_rad, self.thrust_i, self._last_t_s = pitch_rad, throttle, t_s

    def update(
        self,
        t_s: float,
        height_err_m: float,
        climb_m_s: float,
        airspeed_err_m_s: float,
        roll_rad: float,
        pitch_rad: float,
        throttle: float,
    ) -> tuple[float, float]:
        """Pitch (rad) and thrust (0..1) at ``t_s`` (s).

        Args:
            height_err_m: target minus actual altitude (m).
            climb_m_s: climb rate (m/s, up).
            airspeed_err_m_s: target minus actual airspeed (m/s).
            roll_rad: the roll being commanded (rad): the lift a bank needs.
            pitch_rad, throttle: the aircraft's own, where the integrators start.
        """
        g = self.gains
        last, pitch_i, thrust_i = self._last_t_s, self.pitch_i_rad, self.thrust_i
        if (
            pitch_i is None
            or thrust_i is None
            or last is None
            or not 0.0 <= t_s - last <= MAX_HOLD_GAP_S
        ):
            self.track(t_s, pitch_rad, throttle)
            last, pitch_i, thrust_i = t_s, pitch_rad, throttle
        dt = t_s - last
        self._last_t_s = t_s
        c = max(0.3, math.cos(roll_rad))
        pitch_p = g.pitch_per_m * height_err_m - g.pitch_per_climb * climb_m_s
        pitch_p += g.pitch_bank_ff_rad * (1.0 / c - 1.0)
        pitch = pitch_i + pitch_p
        # no integration further into a limit (anti-windup)
        if not _winds_up(pitch, height_err_m, g.pitch_min_rad, g.pitch_max_rad):
            pitch_i += g.pitch_i_per_m_s * height_err_m * dt
        pitch = min(g.pitch_max_rad, max(g.pitch_min_rad, pitch))
        thrust = thrust_i + g.thrust_per_m_s * airspeed_err_m_s
        if not _winds_up(thrust, airspeed_err_m_s, g.thrust_min, g.thrust_max):
            thrust_i += g.thrust_i_per_m * airspeed_err_m_s * dt
        self.pitch_i_rad = pitch_i
        self.thrust_i = min(g.thrust_max, max(g.thrust_min, thrust_i))
        thrust = min(g.thrust_max, max(g.thrust_min, thrust))
        return pitch, thrust


@dataclass
class FlightData:
    """The latest telemetry the offboard profiles use (None: not heard yet).

    Attributes:
        roll_rad, pitch_rad, yaw_rad: ATTITUDE (rad).
        airspeed_m_s: VFR_HUD airspeed (m/s).
        throttle: VFR_HUD throttle (0..1).
        alt_amsl_m: GLOBAL_POSITION_INT altitude (m above mean sea level).
        climb_m_s: GLOBAL_POSITION_INT climb rate (m/s, up).
    """

    roll_rad: float | None = None
    pitch_rad: float | None = None
    yaw_rad: float | None = None
    airspeed_m_s: float | None = None
    throttle: float | None = None
    alt_amsl_m: float | None = None
    climb_m_s: float | None = None

    def on_attitude(self, roll_rad: float, pitch_rad: float, yaw_rad: float) -> None:
        """ATTITUDE: roll, pitch, yaw (rad)."""
        self.roll_rad, self.pitch_rad, self.yaw_rad = roll_rad, pitch_rad, yaw_rad

    def on_vfr_hud(self, airspeed_m_s: float, throttle_pct: float) -> None:
        """VFR_HUD: airspeed (m/s) and throttle (percent)."""
        if math.isfinite(airspeed_m_s):
            self.airspeed_m_s = airspeed_m_s
        self.throttle = min(1.0, max(0.0, throttle_pct / 100.0))

    def on_position(self, alt_mm: int, vz_cm_s: int) -> None:
        """GLOBAL_POSITION_INT: altitude (mm AMSL) and down velocity (cm/s)."""
        self.alt_amsl_m, self.climb_m_s = alt_mm * 1e-3, -vz_cm_s * 0.01


class OffboardSetpoints:
    """Builds PX4's offboard setpoints from the shaped lateral command and :attr:`data`.

    Args:
        origin: the mission origin (local frame of the positions).
        gains: the height and airspeed hold's.
        lookahead_s: how far ahead on the commanded arc the path point is (s).

    Attributes:
        target_airspeed_m_s: the airspeed to hold (attitude profile; m/s).
        target_alt_amsl_m: the altitude to hold (m above mean sea level).
    """

    def __init__(
        self,
        origin: Origin,
        gains: HoldGains | None = None,
        lookahead_s: float = PATH_LOOKAHEAD_S,
    ) -> None:
        """No telemetry yet; the targets are set by the caller."""
        self.origin = origin
        self.hold = EnergyHold(gains)
        self.lookahead_s = lookahead_s
        self.data = FlightData()
        self.target_airspeed_m_s: float | None = None
        self.target_alt_amsl_m: float | None = None

    def track(self, t_s: float) -> None:
        """Not commanding yet (pre-stream): the holds follow the aircraft's pitch, throttle."""
        d = self.data
        if d.pitch_rad is not None and d.throttle is not None:
            self.hold.track(t_s, d.pitch_rad, d.throttle)

    def attitude(self, t_s: float, roll_rad: float, time_boot_ms: int, target_system: int):
        """SET_ATTITUDE_TARGET (0x07) with ``roll_rad`` (rad) and the holds' pitch and thrust
        at ``t_s`` (s)."""
        d = self.data
        pitch0 = d.pitch_rad if d.pitch_rad is not None else 0.0
        thr0 = d.throttle if d.throttle is not None else 0.5
        alt_err = _err(self.target_alt_amsl_m, d.alt_amsl_m)
        air_err = _err(self.target_airspeed_m_s, d.airspeed_m_s)
        pitch, thrust = self.hold.update(
            t_s, alt_err, d.climb_m_s or 0.0, air_err, roll_rad, pitch0, thr0
        )
        yaw = d.yaw_rad if d.yaw_rad is not None else 0.0
        return attitude_setpoint(roll_rad, pitch, yaw, thrust, time_boot_ms, target_system)

    def path(
        self,
        turn_rate_rad_s: float,
        pos_m: complex,
        heading_rad: float,
        airspeed_m_s: float,
        wind_m_s: complex,
        time_boot_ms: int,
        target_system: int,
    ):
        """SET_POSITION_TARGET_GLOBAL_INT (0xC00): the arc's look-ahead point.

        Args:
            turn_rate_rad_s: the commanded air turn rate (rad/s, positive right).
            pos_m: position now (local north + i east, m).
            heading_rad: air heading now (rad, compass).
            airspeed_m_s: airspeed (m/s).
            wind_m_s: the wind the air moves towards (north + i east, m/s).
        """
        t = self.lookahead_s
        u = float(turn_rate_rad_s)
        e0 = cmath.exp(1j * heading_rad)
        ahead = pos_m + wind_m_s * t + airspeed_m_s * t * e0 * complex(arc_factor(u * t))
        e1 = cmath.exp(1j * (heading_rad + u * t))
        vel = airspeed_m_s * e1 + wind_m_s
        acc = PX4_ACCEL_SIGN * 1j * u * airspeed_m_s * e1
        o = self.origin
        alt = self.target_alt_amsl_m if self.target_alt_amsl_m is not None else o.alt_m
        lat, lon, _ = pymap3d.ned2geodetic(
            ahead.real, ahead.imag, 0.0, o.lat_deg, o.lon_deg, o.alt_m
        )
        return path_setpoint(
            round(float(lat) * 1e7), round(float(lon) * 1e7), alt,
            (vel.real, vel.imag, 0.0), (acc.real, acc.imag, 0.0), time_boot_ms, target_system,
        )  # fmt: skip


def _winds_up(output: float, err: float, lo: float, hi: float) -> bool:
    """Whether integrating ``err`` would push an ``output`` at a limit further into it."""
    return (output >= hi and err > 0) or (output <= lo and err < 0)


def _err(target: float | None, actual: float | None) -> float:
    """``target - actual``, 0 while either is unknown."""
    return 0.0 if target is None or actual is None else target - actual
