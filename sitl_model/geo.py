"""Geodetic <-> local NED at a fixed origin (pymap3d, WGS-84). Positions north/east in m."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d

# ArduPilot SITL's default home (CMAC, Canberra), used when no mission gives an origin.
DEFAULT_ORIGIN = (-35.363261, 149.165230, 584.0)


@dataclass(frozen=True)
class LocalFrame:
    """Tangent plane at ``lat_deg, lon_deg`` (deg) and ``alt_m`` (m above the ellipsoid)."""

    lat_deg: float
    lon_deg: float
    alt_m: float

    def to_geodetic(
        self, north_m: np.ndarray, east_m: np.ndarray, up_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Latitude (deg), longitude (deg), altitude (m) of local points (m above origin)."""
        lat, lon, alt = pymap3d.ned2geodetic(
            north_m, east_m, -np.asarray(up_m, dtype=float), self.lat_deg, self.lon_deg, self.alt_m
        )
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)

    def to_local(self, lat_deg: float, lon_deg: float) -> complex:
        """Local position ``north + i east`` (m) of a geodetic point (deg)."""
        n, e, _ = pymap3d.geodetic2ned(
            lat_deg, lon_deg, self.alt_m, self.lat_deg, self.lon_deg, self.alt_m
        )
        return complex(float(n), float(e))
