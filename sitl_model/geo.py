"""Geodetic <-> local NED at a fixed origin (pymap3d, WGS-84). Positions north/east in m.

:meth:`LocalFrame.to_geodetic` (every vehicle's position, each time telemetry is built) is
pymap3d's ``ned2geodetic`` (``enu2ecef`` then You's ``ecef2geodetic``) with the origin's
terms computed once, worked point by point in Python scalars (``math``): a fleet's handful
of points costs less so than numpy's per-operation overhead. Its values are pymap3d's to a
few ulps, not bit for bit (``math`` and numpy may round a function differently): within
1e-11 deg and 1e-6 m of ``pymap3d.ned2geodetic`` (``tests/test_sitl_geo.py``), where the
telemetry rounds to 1e-7 deg and 1 mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from math import pi

import numpy as np
import pymap3d
from pymap3d.ellipsoid import Ellipsoid

_WGS84 = Ellipsoid.from_name("wgs84")
_A = _WGS84.semimajor_axis
_B = _WGS84.semiminor_axis
_E = np.sqrt(_A**2 - _B**2)
_LIM_PI2 = pi / 2 - np.finfo(np.float64).eps
_EF, _E2 = float(_E), float(_E**2)
_A_OVER_B = _A / _B

# ArduPilot SITL's default home (CMAC, Canberra), used when no mission gives an origin.
DEFAULT_ORIGIN = (-35.363261, 149.165230, 584.0)


@dataclass(frozen=True)
class LocalFrame:
    """Tangent plane at ``lat_deg, lon_deg`` (deg) and ``alt_m`` (m above the ellipsoid)."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    _origin: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        """The origin's ECEF position and the ENU rotation's terms, as pymap3d makes them."""
        lat0, lon0 = np.radians(self.lat_deg), np.radians(self.lon_deg)
        ecef = pymap3d.geodetic2ecef(self.lat_deg, self.lon_deg, self.alt_m)
        terms = (np.cos(lat0), np.sin(lat0), np.cos(lon0), np.sin(lon0))
        object.__setattr__(self, "_origin", tuple(float(v) for v in (*ecef, *terms)))

    def to_geodetic(
        self, north_m: np.ndarray, east_m: np.ndarray, up_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude (deg), longitude (deg), altitude (m) of local points (m above origin).

        The values of ``pymap3d.ned2geodetic`` to a few ulps (see the module docstring).
        """
        north = np.asarray(north_m, dtype=float)
        east = np.asarray(east_m, dtype=float)
        up = np.asarray(up_m, dtype=float)  # ned2geodetic's -(-up) is up, bit for bit
        if north.ndim != 1 or north.shape != east.shape or north.shape != up.shape:
            lat, lon, alt = pymap3d.ned2geodetic(
                north, east, -up, self.lat_deg, self.lon_deg, self.alt_m
            )
            return np.asarray(lat), np.asarray(lon), np.asarray(alt)
        rows = self.geodetic_rows(north.tolist(), east.tolist(), up.tolist())
        lat, lon, alt = zip(*rows, strict=True) if rows else ((), (), ())
        return np.array(lat, dtype=float), np.array(lon, dtype=float), np.array(alt, dtype=float)

    def geodetic_rows(
        self, north_m: list[float], east_m: list[float], up_m: list[float]
    ) -> list[tuple[float, float, float]]:
        """:meth:`to_geodetic` of points given as lists (m): (latitude deg, longitude deg,
        altitude m) of each, as Python floats (the telemetry's every step)."""
        x0, y0, z0, clat, slat, clon, slon = self._origin
        rows = []
        for n, e, u in zip(north_m, east_m, up_m, strict=True):
            # enu2uvw, then the origin added (enu2ecef)
            t = clat * u - slat * n
            x, y = x0 + (clon * t - slon * e), y0 + (slon * t + clon * e)
            rows.append(_ecef2geodetic(x, y, z0 + (slat * u + clat * n)))
        return rows

    def to_local(self, lat_deg: float, lon_deg: float) -> complex:
        """Local position ``north + i east`` (m) of a geodetic point (deg)."""
        n, e, _ = pymap3d.geodetic2ned(
            lat_deg, lon_deg, self.alt_m, self.lat_deg, self.lon_deg, self.alt_m
        )
        return complex(float(n), float(e))


def _ecef2geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """Latitude (deg), longitude (deg), altitude (m) of one ECEF point (m): pymap3d's
    ``ecef2geodetic`` (WGS-84, You 2000: eqs. 4a-4c, 13 and 7) in ``math``; a point at the
    pole axis or the centre goes to pymap3d."""
    r2 = x * x + y * y + z * z
    q = r2 - _E2
    u = math.sqrt(0.5 * q + 0.5 * math.hypot(q, 2 * _EF * z))
    hxy = math.hypot(x, y)
    if u <= 1e-8 or hxy <= 1e-8:  # np.isclose(., 0): pymap3d's special cases
        lat, lon, alt = pymap3d.ecef2geodetic(x, y, z)
        return float(lat), float(lon), float(alt)
    hue = math.hypot(u, _EF)
    beta = math.atan(hue / u * z / hxy)
    beta += ((_B * u - _A * hue + _E2) * math.sin(beta)) / (
        _A * hue / math.cos(beta) - _E2 * math.cos(beta)
    )
    if abs(beta) >= _LIM_PI2:  # pymap3d's patch at the poles
        lat, lon, alt = pymap3d.ecef2geodetic(x, y, z)
        return float(lat), float(lon), float(alt)
    lat = math.atan(_A_OVER_B * math.tan(beta))
    alt = math.hypot(z - _B * math.sin(beta), hxy - _A * math.cos(beta))
    if (x * x + y * y) / (_A * _A) + z * z / (_B * _B) < 1:  # inside the ellipsoid
        alt = -alt
    return math.degrees(lat), math.degrees(math.atan2(y, x)), alt
