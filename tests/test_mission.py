"""Mission files: the shipped missions load (bad ones: tests/test_bad_missions.py)."""

from pathlib import Path

import numpy as np
import pytest

from companion.mission import load_mission

ROOT = Path(__file__).resolve().parents[1]
# The corpus of bad missions (tests/data/bad_missions/) is checked through every command
# that reads a mission in tests/test_bad_missions.py.


def test_shipped_missions_load():
    ellipse = load_mission(ROOT / "missions" / "ellipse_6uav.yaml")
    assert ellipse.vehicles.count == 6
    assert ellipse.patrol.period_s == pytest.approx(102.49, abs=0.01)
    assert [p.east_m for p in ellipse.vehicles.initial] == [0.0] * 6
    assert ellipse.intruders[0].position_m(700.0) == complex(230.0, -200.0)
    wpafb = load_mission(ROOT / "missions" / "wpafb_4uav.yaml")
    assert len(wpafb.perimeter.shape.waypoints) == 7
    assert len(wpafb.perimeter.loop().vertices_m) == 7  # every landmark is on the hull
    near = wpafb.patrol.nearest(complex(1300.0, -1250.0))
    assert near.distance_m < wpafb.sensor.footprint_radius_m  # a patrol pass can see it


def test_lat_lon_waypoints_are_converted_to_local_metres():
    wpafb = load_mission(ROOT / "missions" / "wpafb_4uav.yaml")
    museum = wpafb.perimeter.shape.waypoints[0]
    # independent flat-earth check: 1 deg latitude ~ 111.0 km, longitude scaled by cos(lat)
    lat0, lon0 = wpafb.origin.lat_deg, wpafb.origin.lon_deg
    north = (museum.lat_deg - lat0) * 111_034.0
    east = (museum.lon_deg - lon0) * 111_320.0 * np.cos(np.radians(lat0))
    assert museum.north_m == pytest.approx(north, abs=15.0)
    assert museum.east_m == pytest.approx(east, abs=15.0)


def test_a_mission_error_crosses_to_another_process_whole():
    """A pool's or a Dask worker's refusal reaches its parent pickled: the message, the file,
    the field and the line survive (the default pickling passed only the message to a
    four-argument constructor, and the pool's result thread died on it)."""
    import pickle

    from companion.mission.errors import MissionError

    err = MissionError("m.yaml", "vehicles.spares", "the patrol cannot be kept up", 36)
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is MissionError and str(back) == str(err)
    assert (back.file, back.field, back.line, back.problem) == (
        "m.yaml",
        "vehicles.spares",
        36,
        "the patrol cannot be kept up",
    )
    bare = pickle.loads(pickle.dumps(MissionError("m.yaml", "", "not YAML")))
    assert str(bare) == "m.yaml: not YAML" and bare.line is None
