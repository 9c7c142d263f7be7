"""State estimate from telemetry (pure): position, ground course, air heading, turn rate.

Input: GLOBAL_POSITION_INT fields (lat/lon degE7, AMSL altitude mm, ground velocity
north/east cm/s, heading cdeg) and the vehicle time of the message (s, from
:class:`companion.link.clock.VehicleClock`); ATTITUDE yaw, VFR_HUD airspeed and the
autopilot's WIND where it streams them. Output: a :class:`StateEstimate` in the mission's
local frame (pymap3d's ``geodetic2ned`` at the mission origin, its WGS-84 formulas in Python
scalars), and the vehicle's own wind estimate
(:class:`companion.link.wind_estimate.WindEstimator`).

The air heading the Agent steers from is *filtered*: the course-derived heading
``heading_from_course(measured course, agreed wind)`` is noisy where it matters most (a gust
or 0.1 m/s of GPS velocity noise turns the course by 0.3 deg, and 1 cm/s of velocity
resolution by 0.03 deg; on an edge of radius R a course error d gamma is R d gamma of loop
centre: 25 m on a 50 km edge). So the heading is propagated with the attitude's yaw changes
(an AHRS heading is smooth and precise, but may carry a bias) and pulled towards the
course-derived heading with time constant ``HEADING_TAU_S`` (a complementary filter: the
attitude's high frequencies, the course's low frequencies). Without attitude telemetry the
course-derived heading is used as it is. Below ``MIN_GROUNDSPEED_M_S`` the course is taken
from the autopilot's heading field instead. The achieved air turn rate is the attitude yaw's
change between successive estimates (the filtered heading's without attitude telemetry): the
filter's pull towards the course-derived heading carries the gusts' turning of the course,
which the setpoint did not cause, and it biased the shaper's gain estimate low (1.5 m/s gusts
on the ellipse, guidance lab: 0.92-1.03 against the true 1.0; from the yaw, 0.99-1.02).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.core.wind import (
    Wind,
    course_from_heading,
    heading_from_course,
    wrap_pi,
)
from companion.link.wind_estimate import WindEstimator
from companion.mission.model import Origin

WGS84_A_M = 6378137.0  # semi-major axis (m), as pymap3d's "wgs84"
WGS84_B_M = 6356752.31424518  # semi-minor axis (m)
MIN_GROUNDSPEED_M_S = 1.0
MAX_RATE_GAP_S = 0.5  # no turn-rate measurement across a longer gap
HEADING_TAU_S = 3.0  # complementary filter: course-derived heading weight (s); gusts (5 s) pass


@dataclass(frozen=True)
class StateEstimate:
    """One state estimate.

    Attributes:
        t_s: vehicle time (unix s).
        time_boot_ms: the autopilot's stamp of the telemetry (ms).
        pos_m: position, local north + i east from the mission origin (m).
        alt_m: altitude above the origin (m).
        course_rad: ground course (rad, compass).
        groundspeed_m_s: ground speed (m/s).
        heading_rad: air heading (rad, compass) consistent with the course and the wind.
        turn_rate_rad_s: achieved air turn rate since the previous estimate (rad/s), or None.
        measured_course_rad: the ground course of the telemetry's velocity (rad, compass), which
            ``course_rad`` filters; their difference is the gusts' (and wind error's) doing.
    """

    t_s: float
    time_boot_ms: int
    pos_m: complex
    alt_m: float
    course_rad: float
    groundspeed_m_s: float
    heading_rad: float
    turn_rate_rad_s: float | None
    measured_course_rad: float | None = None


class Estimator:
    """Builds :class:`StateEstimate` from successive GLOBAL_POSITION_INT messages.

    Args:
        origin: the mission origin (local frame reference).
        airspeed_m_s: the vehicle's airspeed (m/s).
        wind: the wind the fleet flies by (the mission's until the fleet agrees on one;
            :meth:`set_wind`).
        heading_tau_s: time constant of the heading filter (s); 0 = course-derived only.
    """

    def __init__(
        self,
        origin: Origin,
        airspeed_m_s: float,
        wind: Wind,
        *,
        heading_tau_s: float = HEADING_TAU_S,
    ) -> None:
        """No estimate yet."""
        self.origin = origin
        self.airspeed_m_s = float(airspeed_m_s)
        self.wind = wind
        self.heading_tau_s = float(heading_tau_s)
        self.wind_estimator = WindEstimator(self.airspeed_m_s)
        self.last: StateEstimate | None = None
        self._att_yaw: float | None = None  # attitude yaw at the last estimate (rad)
        # the origin, its ECEF position (m) and the sines and cosines of its latitude and
        # longitude, worked out once
        self._frame: tuple[Origin, tuple[float, ...]] | None = None

    def reset(self) -> None:
        """Forget the previous estimate (after a link loss or reboot)."""
        self.last = None
        self._att_yaw = None

    def set_wind(self, wind: Wind) -> None:
        """The wind the fleet now flies by (the agreed wind)."""
        self.wind = wind

    def on_attitude(self, time_boot_ms: int, yaw_rad: float) -> None:
        """ATTITUDE: yaw (rad) at the autopilot's boot time (ms)."""
        self.wind_estimator.on_attitude(time_boot_ms * 1e-3, yaw_rad)

    def on_airspeed(self, airspeed_m_s: float) -> None:
        """VFR_HUD: airspeed (m/s)."""
        self.wind_estimator.on_airspeed(airspeed_m_s)

    def on_autopilot_wind(self, t_s: float, speed_m_s: float, from_deg: float) -> None:
        """WIND (ArduPilot): speed (m/s), direction it blows FROM (deg), at vehicle time (s)."""
        self.wind_estimator.on_autopilot_wind(t_s, speed_m_s, from_deg)

    def on_autopilot_wind_vector(self, t_s: float, north_m_s: float, east_m_s: float) -> None:
        """WIND_COV (PX4): the air's velocity north and east (m/s) at vehicle time (s)."""
        self.wind_estimator.on_autopilot_wind_vector(t_s, north_m_s, east_m_s)

    def from_global_position(
        self,
        t_s: float,
        time_boot_ms: int,
        lat_e7: int,
        lon_e7: int,
        alt_mm: int,
        vx_cm_s: int,
        vy_cm_s: int,
        hdg_cdeg: int,
    ) -> StateEstimate | None:
        """The estimate for one GLOBAL_POSITION_INT at vehicle time ``t_s`` (s).

        Returns None for a message not newer than the previous one (duplicate, reordered).
        """
        prev = self.last
        if prev is not None and time_boot_ms <= prev.time_boot_ms:
            if prev.time_boot_ms - time_boot_ms < 5_000:
                return None
            prev = None  # the autopilot rebooted
        n, e, d = self.ned_of(lat_e7 * 1e-7, lon_e7 * 1e-7, alt_mm * 1e-3)
        vel = complex(vx_cm_s, vy_cm_s) * 0.01
        speed = abs(vel)
        if speed >= MIN_GROUNDSPEED_M_S:
            course = math.atan2(vel.imag, vel.real)
        elif hdg_cdeg != 65535:
            course = float(
                course_from_heading(self.airspeed_m_s, math.radians(hdg_cdeg * 0.01), self.wind)
            )
        elif prev is not None:
            course = prev.course_rad
        else:
            course = 0.0
        measured = course
        heading = float(heading_from_course(self.airspeed_m_s, course, self.wind))
        if speed >= MIN_GROUNDSPEED_M_S:
            self.wind_estimator.on_ground_velocity(t_s, time_boot_ms * 1e-3, vel)
        yaw = self.wind_estimator.heading_at(time_boot_ms * 1e-3)
        dt = t_s - prev.t_s if prev is not None else 0.0
        if yaw is not None and prev is not None and self._att_yaw is not None and 0 < dt <= 1:
            # propagate with the attitude, pull towards the course-derived heading
            pred = prev.heading_rad + float(wrap_pi(yaw - self._att_yaw))
            k = min(1.0, dt / self.heading_tau_s) if self.heading_tau_s > 0 else 1.0
            heading = float(wrap_pi(pred + k * float(wrap_pi(heading - pred))))
            course = float(course_from_heading(self.airspeed_m_s, heading, self.wind))
        rate = None
        if prev is not None and 0 < dt <= MAX_RATE_GAP_S:
            if yaw is not None and self._att_yaw is not None:
                rate = float(wrap_pi(yaw - self._att_yaw)) / dt
            else:
                rate = float(wrap_pi(heading - prev.heading_rad)) / dt
        self._att_yaw = yaw
        est = StateEstimate(
            t_s=t_s,
            time_boot_ms=int(time_boot_ms),
            pos_m=complex(float(n), float(e)),
            alt_m=-float(d),
            course_rad=course,
            groundspeed_m_s=speed,
            heading_rad=heading,
            turn_rate_rad_s=rate,
            measured_course_rad=measured,
        )
        self.last = est
        return est

    def site_from_geodetic(self, lat_e7: int, lon_e7: int) -> complex:
        """A detected object's position (local north + i east, m) from lat/lon degE7."""
        n, e, _ = self.ned_of(lat_e7 * 1e-7, lon_e7 * 1e-7, self.origin.alt_m)
        return complex(float(n), float(e))

    def ned_of(self, lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
        """North, east, down (m) from the origin of a geodetic point (deg, deg, m): pymap3d's
        ``geodetic2ned`` on WGS-84 (the point's ECEF position, less the origin's, turned into
        the origin's local frame) in Python scalars, the origin's terms worked out once."""
        o = self.origin
        frame = self._frame
        if frame is None or frame[0] is not o:
            lat0, lon0 = math.radians(o.lat_deg), math.radians(o.lon_deg)
            x0, y0, z0 = _ecef(lat0, lon0, o.alt_m)
            sines = (math.sin(lat0), math.cos(lat0), math.sin(lon0), math.cos(lon0))
            frame = self._frame = (o, (x0, y0, z0, *sines))
        x0, y0, z0, sin_lat0, cos_lat0, sin_lon0, cos_lon0 = frame[1]
        x, y, z = _ecef(math.radians(lat_deg), math.radians(lon_deg), alt_m)
        u, v, w = x - x0, y - y0, z - z0
        t = cos_lon0 * u + sin_lon0 * v
        east = -sin_lon0 * u + cos_lon0 * v
        up = cos_lat0 * t + sin_lat0 * w
        north = -sin_lat0 * t + cos_lat0 * w
        return north, east, -up


def _ecef(lat_rad: float, lon_rad: float, alt_m: float) -> tuple[float, float, float]:
    """ECEF position (m) of a WGS-84 geodetic point (rad, rad, m above the ellipsoid)."""
    a, b = WGS84_A_M, WGS84_B_M
    cos_lat, sin_lat = math.cos(lat_rad), math.sin(lat_rad)
    n = a * a / math.hypot(a * cos_lat, b * sin_lat)  # prime vertical radius of curvature
    return (
        (n + alt_m) * cos_lat * math.cos(lon_rad),
        (n + alt_m) * cos_lat * math.sin(lon_rad),
        (n * (b / a) ** 2 + alt_m) * sin_lat,
    )
