"""Wind kinematics for a constant-airspeed particle in steady, uniform wind (docs/design.md §2).

Conventions: compass angles in radians (0 = North, pi/2 = East), complex positions and
velocities ``north + i east``, positive turn rate = right turn. ``Wind`` holds the wind
vector ``w = beta exp(i theta_w)`` (the direction it blows TOWARDS); build it from the
meteorological "from" direction with :meth:`Wind.from_meteo`.

All functions accept scalars or numpy arrays and broadcast.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass
from functools import cached_property
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

TWO_PI = 2.0 * np.pi


@overload
def wrap_pi(angle_rad: float) -> float: ...
@overload
def wrap_pi(angle_rad: ArrayLike) -> np.ndarray: ...
def wrap_pi(angle_rad: ArrayLike) -> np.ndarray | float:
    """Wrap an angle to [-pi, pi) radians (a float for a float)."""
    if isinstance(angle_rad, float):  # the control step's case: same values as numpy
        return (angle_rad + math.pi) % TWO_PI - math.pi
    return (np.asarray(angle_rad) + np.pi) % TWO_PI - np.pi


@overload
def wrap_2pi(angle_rad: float) -> float: ...
@overload
def wrap_2pi(angle_rad: ArrayLike) -> np.ndarray: ...
def wrap_2pi(angle_rad: ArrayLike) -> np.ndarray | float:
    """Wrap an angle to [0, 2 pi) radians (a float for a float)."""
    if isinstance(angle_rad, float):  # the control step's case: same values as numpy
        return angle_rad % TWO_PI
    return np.asarray(angle_rad) % TWO_PI


@dataclass(frozen=True)
class Wind:
    """Steady uniform wind.

    Attributes:
        speed_m_s: wind speed ``beta`` (m/s), >= 0.
        towards_rad: direction the air moves towards, ``theta_w`` (rad, compass).
    """

    speed_m_s: float
    towards_rad: float

    @classmethod
    def from_meteo(cls, speed_m_s: float, from_deg: float) -> Wind:
        """Wind of ``speed_m_s`` (m/s) blowing FROM compass bearing ``from_deg`` (deg)."""
        return cls(float(speed_m_s), float(wrap_2pi(np.radians(from_deg) + np.pi)))

    @classmethod
    def from_vector(cls, wind_m_s: complex) -> Wind:
        """Wind whose velocity (m/s, towards, ``north + i east``) is ``wind_m_s``."""
        w = complex(wind_m_s)
        return cls(abs(w), float(wrap_2pi(np.arctan2(w.imag, w.real))))

    @classmethod
    def calm(cls) -> Wind:
        """No wind."""
        return cls(0.0, 0.0)

    @cached_property
    def vector(self) -> complex:
        """Wind velocity ``w`` (m/s) as ``north + i east`` (computed once)."""
        return complex(self.speed_m_s * np.exp(1j * self.towards_rad))

    @property
    def from_deg(self) -> float:
        """Meteorological direction the wind blows from (deg, [0, 360))."""
        return float(np.degrees(wrap_2pi(self.towards_rad + np.pi)))

    def check_against(self, airspeed_m_s: float) -> None:
        """Raise ``ValueError`` unless the wind is slower than ``airspeed_m_s`` (m/s)."""
        if not (0.0 <= self.speed_m_s < airspeed_m_s):
            raise ValueError(
                f"wind speed {self.speed_m_s} m/s must be >= 0 and below the airspeed "
                f"{airspeed_m_s} m/s"
            )


def ground_velocity(airspeed_m_s: float, heading_rad: ArrayLike, wind: Wind) -> np.ndarray:
    """Ground velocity ``s0 exp(i theta) + w`` (m/s, complex north + i east); a complex for
    a float heading."""
    if isinstance(heading_rad, float):  # the control step's case: same values as numpy
        return airspeed_m_s * cmath.exp(1j * heading_rad) + wind.vector
    return airspeed_m_s * np.exp(1j * np.asarray(heading_rad)) + wind.vector


def course_from_heading(airspeed_m_s: float, heading_rad: ArrayLike, wind: Wind) -> np.ndarray:
    """Ground course ``gamma`` (rad, [-pi, pi)) flown with air heading ``heading_rad``; a
    float for a float."""
    if isinstance(heading_rad, float):  # one heading: math
        v = airspeed_m_s * cmath.exp(1j * heading_rad) + wind.vector
        return math.atan2(v.imag, v.real)
    return np.angle(ground_velocity(airspeed_m_s, heading_rad, wind))


def groundspeed_from_heading(airspeed_m_s: float, heading_rad: ArrayLike, wind: Wind) -> np.ndarray:
    """Ground speed ``s`` (m/s) flown with air heading ``heading_rad``."""
    return np.abs(ground_velocity(airspeed_m_s, heading_rad, wind))


def groundspeed_from_course(airspeed_m_s: float, course_rad: ArrayLike, wind: Wind) -> np.ndarray:
    """Ground speed ``s(gamma)`` (m/s) along course ``course_rad``.

    ``s = beta cos(gamma - theta_w) + sqrt(s0^2 - beta^2 sin^2(gamma - theta_w))``.
    """
    d = np.asarray(course_rad) - wind.towards_rad
    b = wind.speed_m_s
    return b * np.cos(d) + np.sqrt(airspeed_m_s**2 - (b * np.sin(d)) ** 2)


def heading_from_course(airspeed_m_s: float, course_rad: ArrayLike, wind: Wind) -> np.ndarray:
    """Air heading ``theta`` (rad) that makes good ground course ``course_rad`` (wind triangle).

    ``theta = gamma - asin((beta / s0) sin(theta_w - gamma))``. A float for a float.
    """
    if isinstance(course_rad, float):  # one course: math
        ratio = wind.speed_m_s / airspeed_m_s * math.sin(wind.towards_rad - course_rad)
        return course_rad - math.asin(ratio)
    g = np.asarray(course_rad)
    return g - np.arcsin(wind.speed_m_s / airspeed_m_s * np.sin(wind.towards_rad - g))


def course_rate_from_turn_rate(
    airspeed_m_s: float, heading_rad: ArrayLike, turn_rate_rad_s: ArrayLike, wind: Wind
) -> np.ndarray:
    """Course rate ``nu`` (rad/s) produced by air turn rate ``u`` (rad/s) at heading ``theta``.

    ``nu = u s0 (s0 + beta cos(theta - theta_w)) / s^2``.
    """
    th = np.asarray(heading_rad)
    s0 = airspeed_m_s
    s2 = np.abs(ground_velocity(s0, th, wind)) ** 2
    return (
        np.asarray(turn_rate_rad_s)
        * s0
        * (s0 + wind.speed_m_s * np.cos(th - wind.towards_rad))
        / s2
    )


def turn_rate_from_course_rate(
    airspeed_m_s: float, heading_rad: ArrayLike, course_rate_rad_s: ArrayLike, wind: Wind
) -> np.ndarray:
    """Air turn rate ``u`` (rad/s) needed for course rate ``nu`` (rad/s) at heading ``theta``.

    Inverse of :func:`course_rate_from_turn_rate`:
    ``u = nu s^2 / (s0 (s0 + beta cos(theta - theta_w)))``. A float for floats.
    """
    if isinstance(heading_rad, float) and isinstance(course_rate_rad_s, float):
        s0, b = airspeed_m_s, wind.speed_m_s
        v = s0 * cmath.exp(1j * heading_rad) + wind.vector
        s2 = v.real * v.real + v.imag * v.imag
        return course_rate_rad_s * s2 / (s0 * (s0 + b * math.cos(heading_rad - wind.towards_rad)))
    th = np.asarray(heading_rad)
    s0 = airspeed_m_s
    s2 = np.abs(ground_velocity(s0, th, wind)) ** 2
    return (
        np.asarray(course_rate_rad_s)
        * s2
        / (s0 * (s0 + wind.speed_m_s * np.cos(th - wind.towards_rad)))
    )


MAX_WIND_FRACTION = 0.9  # a wind at or above this fraction of the airspeed is refused


def valid_wind(wind_m_s: complex | None, airspeed_m_s: float) -> bool:
    """True for a finite wind vector (m/s) clearly below the airspeed (m/s)."""
    if wind_m_s is None:
        return False
    w = complex(wind_m_s)
    if not (math.isfinite(w.real) and math.isfinite(w.imag)):
        return False
    return abs(w) < MAX_WIND_FRACTION * airspeed_m_s
