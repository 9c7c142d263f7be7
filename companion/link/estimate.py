"""State estimate from telemetry (pure): position, ground course, air heading, turn rate.

Input: GLOBAL_POSITION_INT fields (lat/lon degE7, AMSL altitude mm, ground velocity
north/east cm/s, heading cdeg) and the vehicle time of the message (s, from
:class:`companion.link.clock.VehicleClock`). Output: a :class:`StateEstimate` in the
mission's local frame (pymap3d ``geodetic2ned`` at the mission origin).

The air heading the Agent wants is derived from the measured ground course and the known
wind (``heading_from_course``), so the centre/phase the Agent computes from it reproduce the
measured course exactly. Below ``MIN_GROUNDSPEED_M_S`` the course is taken from the
autopilot's heading field instead. The achieved air turn rate is the course change between
successive estimates converted through the wind triangle (DESIGN 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pymap3d

from companion.core.wind import (
    Wind,
    course_from_heading,
    heading_from_course,
    turn_rate_from_course_rate,
    wrap_pi,
)
from companion.mission.model import Origin

MIN_GROUNDSPEED_M_S = 1.0
MAX_RATE_GAP_S = 0.5  # no turn-rate measurement across a longer gap


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
    """

    t_s: float
    time_boot_ms: int
    pos_m: complex
    alt_m: float
    course_rad: float
    groundspeed_m_s: float
    heading_rad: float
    turn_rate_rad_s: float | None


class Estimator:
    """Builds :class:`StateEstimate` from successive GLOBAL_POSITION_INT messages.

    Args:
        origin: the mission origin (local frame reference).
        airspeed_m_s: the vehicle's airspeed (m/s).
        wind: the wind (from the mission).
    """

    def __init__(self, origin: Origin, airspeed_m_s: float, wind: Wind) -> None:
        """No estimate yet."""
        self.origin = origin
        self.airspeed_m_s = float(airspeed_m_s)
        self.wind = wind
        self.last: StateEstimate | None = None

    def reset(self) -> None:
        """Forget the previous estimate (after a link loss or reboot)."""
        self.last = None

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
        o = self.origin
        n, e, d = pymap3d.geodetic2ned(
            lat_e7 * 1e-7, lon_e7 * 1e-7, alt_mm * 1e-3, o.lat_deg, o.lon_deg, o.alt_m
        )
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
        heading = float(heading_from_course(self.airspeed_m_s, course, self.wind))
        rate = None
        if prev is not None and 0 < t_s - prev.t_s <= MAX_RATE_GAP_S:
            nu = float(wrap_pi(course - prev.course_rad)) / (t_s - prev.t_s)
            mid = prev.heading_rad + 0.5 * float(wrap_pi(heading - prev.heading_rad))
            rate = float(turn_rate_from_course_rate(self.airspeed_m_s, mid, nu, self.wind))
        est = StateEstimate(
            t_s=t_s,
            time_boot_ms=int(time_boot_ms),
            pos_m=complex(float(n), float(e)),
            alt_m=-float(d),
            course_rad=course,
            groundspeed_m_s=speed,
            heading_rad=heading,
            turn_rate_rad_s=rate,
        )
        self.last = est
        return est

    def site_from_geodetic(self, lat_e7: int, lon_e7: int) -> complex:
        """A detected object's position (local north + i east, m) from lat/lon degE7."""
        o = self.origin
        n, e, _ = pymap3d.geodetic2ned(
            lat_e7 * 1e-7, lon_e7 * 1e-7, o.alt_m, o.lat_deg, o.lon_deg, o.alt_m
        )
        return complex(float(n), float(e))
