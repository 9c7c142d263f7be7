"""The world's wind on real firmware: what the truth log carries and what the report says.

``companion fleet --autopilot arduplane --sim-param SIM_WIND_SPD=7.5 --sim-param
SIM_WIND_DIR=215`` flies the instances in a wind the mission does not know (issue 23's real
day). The world process writes that wind, not the mission's, into the truth log's wind
columns (the report's T/N is timed in it) and into ``run_info.json`` with where it came
from; the report's headline names it beside the mission's. Checked by hand: 7.5 m/s from
215 deg blows towards 35 deg, north 7.5 cos 35 = 6.144 m/s, east 7.5 sin 35 = 4.302 m/s.
"""

from __future__ import annotations

import argparse

import pytest

from companion.mission import load_mission
from companion.report.summary import headline
from companion.sim.arduplane.world import ArduPlaneWorld
from companion.sim.firmware.world import parser
from companion.sim.px4.world import Px4World
from sitl_model.testing import REPO

MISSION = REPO / "tests" / "data" / "ellipse_3uav.yaml"  # 5 m/s from 180 deg
ARGS = ["--mission", str(MISSION), "--sysids", "1", "--ports", "1", "--epoch", "0",
        "--speedup", "1", "--duration", "1", "--truth-log", "t", "--events-log", "e",
        "--clock-log", "c"]  # fmt: skip


def _world(cls: type, *extra: str):
    """A world process's wind, without its connections (its constructor opens them)."""
    w = cls.__new__(cls)
    w.args = parser("world", "ports", "SIM_SPEEDUP").parse_args([*ARGS, *extra])
    w.mission = load_mission(MISSION)
    return w


def test_the_wind_set_on_arduplane_is_the_truths_and_says_where_it_came_from():
    w = _world(ArduPlaneWorld, "--world-wind", "7.5,215")
    v = w.true_wind_m_s()
    assert v.real == pytest.approx(6.144, abs=1e-3) and v.imag == pytest.approx(4.302, abs=1e-3)
    ww = w.world_wind()
    assert ww["speed_m_s"] == pytest.approx(7.5) and ww["from_deg"] == pytest.approx(215.0)
    assert ww["source"] == "set on the firmware's simulation"
    assert (ww["mission_speed_m_s"], ww["mission_from_deg"]) == (5.0, 180.0)


def test_without_it_the_mission_wind_and_px4_still_air():
    w = _world(ArduPlaneWorld)
    assert w.true_wind_m_s() == pytest.approx(complex(5.0, 0.0), abs=1e-9)  # towards north
    assert w.world_wind()["source"].startswith("the mission's")
    sih = _world(Px4World).world_wind()
    assert sih["speed_m_s"] == 0.0 and sih["source"].startswith("still air")


@pytest.mark.parametrize("bad", ["7.5", "x,215", "-1,215", "nan,10", "7.5,215,3"])
def test_a_bad_world_wind_is_refused(bad: str):
    with pytest.raises(SystemExit):
        parser("world", "ports", "SIM_SPEEDUP").parse_args([*ARGS, "--world-wind", bad])


def test_the_headline_names_the_worlds_wind_beside_the_missions():
    ww = _world(ArduPlaneWorld, "--world-wind", "7.5,215").world_wind()
    m = dict.fromkeys(
        ["cross_track_median_m", "cross_track_p95_m", "cross_track_max_m",
         "coverage_revisit_ratio", "longest_unseen_s", "longest_unseen_ratio",
         "fraction_within_bounds", "coverage_revisit_ratio_excl_alerts",
         "longest_unseen_excl_alerts_s", "longest_unseen_excl_alerts_ratio",
         "fraction_within_bounds_excl_alerts"], 1.0,
    )  # fmt: skip
    m |= {
        "reference_rule": "true wind: mean of the truth log's wind",
        "reference_wind_speed_m_s": 7.5,
        "reference_wind_from_deg": 215.0,
        "settled": False,
        "window_start_s": 100.0,
        "window_end_s": 500.0,
        "reference_ideal_revisit_s": 16.0,
        "world_wind": ww,
    }
    text = "\n".join(headline(m))
    assert (
        "true wind (7.5 m/s from 215 deg: set on the firmware's simulation; the mission says "
        "5.0 m/s from 180 deg)" in text
    ), text
    del m["world_wind"]  # our own simulator: its truth log has the wind, nothing to add
    assert "true wind (7.5 m/s from 215 deg)" in "\n".join(headline(m))


def test_argparse_type_is_what_the_fleet_passes():
    # the fleet passes f"{speed:g},{from:g}": integers and decimals alike
    ns = parser("world", "ports", "SIM_SPEEDUP").parse_args([*ARGS, "--world-wind", "8,225"])
    assert isinstance(ns, argparse.Namespace) and ns.world_wind == (8.0, 225.0)
