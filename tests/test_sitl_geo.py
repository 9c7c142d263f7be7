"""The simulator's local frame: its fast geodetic conversion is pymap3d's to a few ulps."""

from __future__ import annotations

import numpy as np
import pymap3d

from sitl_model.geo import LocalFrame


def test_to_geodetic_gives_pymap3d_ned2geodetic_to_well_under_a_millimetre() -> None:
    rng = np.random.default_rng(46)
    for _ in range(400):
        lat0, lon0 = rng.uniform(-75.0, 75.0), rng.uniform(-180.0, 180.0)
        alt0 = rng.uniform(-400.0, 4000.0)  # below the ellipsoid too (the sign of "inside")
        frame = LocalFrame(lat0, lon0, alt0)
        n = int(rng.integers(1, 120))
        scale = rng.choice([5.0, 1e3, 3e4, 2e5])
        north, east = rng.normal(0.0, scale, n), rng.normal(0.0, scale, n)
        up = rng.uniform(-600.0, 500.0, n)
        lat, lon, alt = frame.to_geodetic(north, east, up)
        want_lat, want_lon, want_alt = pymap3d.ned2geodetic(north, east, -up, lat0, lon0, alt0)
        # 1e-11 deg is 1.1 um of latitude; the telemetry rounds to 1e-7 deg and 1 mm
        assert np.max(np.abs(lat - want_lat)) < 1e-11, (lat0, lon0, alt0)
        assert np.max(np.abs(lon - want_lon)) < 1e-11, (lat0, lon0, alt0)
        assert np.max(np.abs(alt - want_alt)) < 1e-6, (lat0, lon0, alt0)
        rows = frame.geodetic_rows(north.tolist(), east.tolist(), up.tolist())
        assert rows == list(zip(lat.tolist(), lon.tolist(), alt.tolist(), strict=True))


def test_to_geodetic_of_the_origin_is_the_origin_and_a_scalar_works() -> None:
    frame = LocalFrame(39.8, -84.0, 250.0)
    lat, lon, alt = frame.to_geodetic(np.zeros(1), np.zeros(1), np.zeros(1))
    assert abs(lat[0] - 39.8) < 1e-12 and abs(lon[0] + 84.0) < 1e-12
    assert abs(alt[0] - 250.0) < 1e-6
    lat, lon, alt = frame.to_geodetic(np.float64(100.0), np.float64(0.0), np.float64(0.0))
    assert lat > 39.8 and abs(lon + 84.0) < 1e-12  # 100 m north: further north, same meridian
