"""Mission files: the shipped missions load; every bad mission gives one clear error."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.cli import main
from companion.mission import MissionError, load_mission

ROOT = Path(__file__).resolve().parents[1]
BAD = sorted((ROOT / "tests" / "data" / "bad_missions").glob("*.yaml"))

# file -> (field named in the message, or "" when the problem is the whole file; words)
EXPECTED = {
    "absurd_count.yaml": ("vehicles.count", "whole number from 1 to 250"),
    "absurd_size.yaml": ("perimeter.ellipse.semi_major_m", "<= 100000"),
    "airspeed_string.yaml": ("vehicles.airspeed_m_s", "expected an airspeed"),
    "alias_bomb.yaml": ("", "aliases are not allowed"),
    "binary_garbage.yaml": ("", "not UTF-8"),
    "bool_turn_rate.yaml": ("vehicles.max_turn_rate_deg_s", "got bool"),
    "collinear_waypoints.yaml": ("perimeter.waypoints", "collinear"),
    "corner_radius_unflyable.yaml": ("perimeter.corner_radius_m", "corner radius of at least"),
    "duplicate_key.yaml": ("vehicles.count", "duplicate key"),
    "duplicate_sysids.yaml": ("vehicles.sysids", "distinct"),
    "ellipse_and_waypoints.yaml": ("perimeter", "exactly one of 'ellipse' or 'waypoints'"),
    "ellipse_too_tight.yaml": ("perimeter.ellipse", "turn rates up to"),
    "empty.yaml": ("", "empty"),
    "huge_file.yaml": ("", "larger than"),
    "inf_axis.yaml": ("perimeter.ellipse.semi_minor_m", "finite"),
    "latitude_out_of_range.yaml": ("origin.lat_deg", "latitude"),
    "missing_airspeed.yaml": ("vehicles.airspeed_m_s", "missing required field"),
    "nan_axis.yaml": ("perimeter.ellipse.semi_major_m", "finite"),
    "python_tag.yaml": ("", "tag"),
    "syntax_error.yaml": ("", "YAML syntax error"),
    "too_few_sysids.yaml": ("vehicles.sysids", "expected 6 system ids"),
    "top_level_list.yaml": ("(top level)", "expected a mapping"),
    "two_waypoints.yaml": ("perimeter.waypoints", "at least 3 waypoints"),
    "unknown_intruder_kind.yaml": ("scenario.intruders[0].kind", "one of static, moving, decoy"),
    "unknown_top_key.yaml": ("colour", "unknown field"),
    "unknown_wind_key.yaml": ("wind.gusty", "unknown field"),
    "wind_above_airspeed.yaml": ("wind", "below the airspeed"),
    "wind_equals_airspeed.yaml": ("wind", "below the airspeed"),
    "wrong_version.yaml": ("version", "unsupported mission version 2"),
    "zero_vehicles.yaml": ("vehicles.count", "whole number from 1"),
}


def test_corpus_is_complete():
    assert len(BAD) >= 25
    assert {p.name for p in BAD} == set(EXPECTED)


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


@pytest.mark.parametrize("path", BAD, ids=[p.name for p in BAD])
def test_bad_mission_gives_one_clear_error(path):
    field, words = EXPECTED[path.name]
    with pytest.raises(MissionError) as info:
        load_mission(path)
    msg = str(info.value)
    assert str(path) in msg and words in msg
    assert "\n" not in msg
    if field:
        assert f" {field}:" in msg
    if path.name not in ("empty.yaml", "huge_file.yaml", "binary_garbage.yaml"):
        assert info.value.line is not None and f"{path}:{info.value.line}:" in msg


@pytest.mark.parametrize("path", BAD, ids=[p.name for p in BAD])
def test_simulate_exits_2_with_one_line(path, tmp_path, capsys):
    assert main(["simulate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err
    assert not (tmp_path / "out").exists()


def test_no_code_runs_from_a_mission(tmp_path):
    marker = Path("/tmp/pwned")
    marker.unlink(missing_ok=True)
    with pytest.raises(MissionError):
        load_mission(ROOT / "tests" / "data" / "bad_missions" / "python_tag.yaml")
    assert not marker.exists()


def test_cli_process_prints_no_traceback(tmp_path):
    bad = ROOT / "tests" / "data" / "bad_missions" / "wind_above_airspeed.yaml"
    proc = subprocess.run(
        [sys.executable, "-m", "companion", "simulate", str(bad), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert "wind speed 25 m/s must be below the airspeed 20 m/s" in proc.stderr


def test_lat_lon_waypoints_are_converted_to_local_metres():
    wpafb = load_mission(ROOT / "missions" / "wpafb_4uav.yaml")
    museum = wpafb.perimeter.shape.waypoints[0]
    # independent flat-earth check: 1 deg latitude ~ 111.0 km, longitude scaled by cos(lat)
    lat0, lon0 = wpafb.origin.lat_deg, wpafb.origin.lon_deg
    north = (museum.lat_deg - lat0) * 111_034.0
    east = (museum.lon_deg - lon0) * 111_320.0 * np.cos(np.radians(lat0))
    assert museum.north_m == pytest.approx(north, abs=15.0)
    assert museum.east_m == pytest.approx(east, abs=15.0)
