"""Geodetic <-> local NED at a fixed origin (pymap3d, WGS-84). Positions north/east in m.

:meth:`LocalFrame.to_geodetic` (every vehicle's position, each time telemetry is built) is
pymap3d's ``ned2geodetic`` (``enu2ecef`` then You's ``ecef2geodetic``) with the origin's
terms computed once: the same numpy operations in the same order, so the same bits
(``tests/test_sitl_geo.py``), at a tenth of the cost of its per-call set-up.
"""

from __future__ import annotations

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
        object.__setattr__(self, "_origin", (*ecef, *terms))

    def to_geodetic(
        self, north_m: np.ndarray, east_m: np.ndarray, up_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude (deg), longitude (deg), altitude (m) of local points (m above origin).

        The values of ``pymap3d.ned2geodetic`` bit for bit (see the module docstring).
        """
        north = np.asarray(north_m, dtype=float)
        east = np.asarray(east_m, dtype=float)
        up = np.asarray(up_m, dtype=float)  # ned2geodetic's -(-up) is up, bit for bit
        if north.ndim != 1:
            lat, lon, alt = pymap3d.ned2geodetic(
                north, east, -up, self.lat_deg, self.lon_deg, self.alt_m
            )
            return np.asarray(lat), np.asarray(lon), np.asarray(alt)
        x0, y0, z0, clat, slat, clon, slon = self._origin
        # enu2uvw, then the origin added (enu2ecef)
        t = clat * up - slat * north
        w = slat * up + clat * north
        x = x0 + (clon * t - slon * east)
        y = y0 + (slon * t + clon * east)
        z = z0 + w
        return _ecef2geodetic(x, y, z, (self.lat_deg, self.lon_deg, self.alt_m))

    def to_local(self, lat_deg: float, lon_deg: float) -> complex:
        """Local position ``north + i east`` (m) of a geodetic point (deg)."""
        n, e, _ = pymap3d.geodetic2ned(
            lat_deg, lon_deg, self.alt_m, self.lat_deg, self.lon_deg, self.alt_m
        )
        return complex(float(n), float(e))


def _ecef2geodetic(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """pymap3d's ``ecef2geodetic`` (WGS-84, degrees; You 2000) for arrays of shape (N,), its
    operations in its order; a point at the pole axis or the centre goes to pymap3d."""
    r = np.sqrt(x**2 + y**2 + z**2)
    u = np.sqrt(0.5 * (r**2 - _E**2) + 0.5 * np.hypot(r**2 - _E**2, 2 * _E * z))
    hxy = np.hypot(x, y)
    if (np.abs(u) <= 1e-8).any() or (np.abs(hxy) <= 1e-8).any():  # np.isclose(., 0)
        lat, lon, alt = pymap3d.ecef2geodetic(x, y, z)
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)
    huE = np.hypot(u, _E)
    beta = np.arctan(huE / u * z / hxy)
    beta += ((_B * u - _A * huE + _E**2) * np.sin(beta)) / (
        _A * huE * 1 / np.cos(beta) - _E**2 * np.cos(beta)
    )
    lat = np.arctan(_A / _B * np.tan(beta))
    cos_beta = np.cos(beta)
    if np.abs(beta).max() >= _LIM_PI2:  # pymap3d's float32 patch, a no-op elsewhere
        lat = np.where(beta >= _LIM_PI2, pi / 2, lat)
        lat = np.where(beta <= -_LIM_PI2, -pi / 2, lat)
        cos_beta = np.where(beta >= _LIM_PI2, 0, cos_beta)
        cos_beta = np.where(beta <= -_LIM_PI2, 0, cos_beta)
    lon = np.arctan2(y, x)
    alt = np.hypot(z - _B * np.sin(beta), hxy - _A * cos_beta)
    inside = x**2 / _A**2 + y**2 / _A**2 + z**2 / _B**2 < 1
    if inside.any():
        alt[inside] = -alt[inside]
    return np.degrees(lat), np.degrees(lon), alt
