"""The geofence (issue 14): polygon geometry, the mission's fence, and the companions'
refusal of alerts the fence rules out (the real companion stack in memory,
``companion.sim.inmemory``: an operator's signed alert heard by six ``Runner``s)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from companion.agent.agent import Agent
from companion.agent.alerts.paths import fence_refusal
from companion.core.fence import (
    Fence,
    first_outside,
    point_in_polygon,
    polygon_fault,
    signed_distance_m,
    support_polygon,
)
from companion.mission import MissionError, load_mission, parse_mission
from companion.sim.inmemory import Engine, EngineConfig
from tests.fleet_harness import quiet_mission

PAPER = "missions/ellipse_6uav.yaml"


def _mission_text(fence: str) -> str:
    with open(PAPER, encoding="utf-8") as f:
        return f.read() + fence


# ---- geometry ---------------------------------------------------------------------------
def test_point_in_polygon_matches_an_independent_implementation():
    rng = np.random.default_rng(3)
    # a non-convex (star-shaped) polygon and random points around it
    k = np.arange(14)
    radius = np.where(k % 2 == 0, 500.0, 180.0) * (1 + 0.2 * rng.random(14))
    poly = radius * np.exp(1j * 2 * np.pi * k / 14) + (30 - 70j)
    pts = (rng.random(4000) - 0.5) * 1400 + 1j * (rng.random(4000) - 0.5) * 1400
    ours = point_in_polygon(pts, poly)
    ref = MplPath(np.c_[poly.real, poly.imag]).contains_points(np.c_[pts.real, pts.imag])
    assert ours.sum() > 300 and (~ours).sum() > 300
    assert np.array_equal(ours, ref)


def test_signed_distance_of_a_square():
    sq = np.array([0, 100, 100 + 100j, 100j])  # north 0..100, east 0..100
    d = signed_distance_m(np.array([50 + 50j, 10 + 50j, -30 + 50j, 130 + 140j]), sq)
    assert d == pytest.approx([50.0, 10.0, -30.0, -50.0])


def test_support_polygon_contains_the_grown_set_closely():
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    ellipse = 400 * np.cos(t) + 1j * 200 * np.sin(t)
    poly = support_polygon(ellipse, 150.0)
    assert polygon_fault(poly) is None
    room = signed_distance_m(ellipse, poly)
    assert room.min() >= 150.0 - 1e-6  # every point at least the offset inside
    assert room.min() <= 150.0 * 1.01 + 600 * (1 / math.cos(math.pi / 32) - 1)


@pytest.mark.parametrize(
    ("poly", "index", "words"),
    [
        ([0, 100], 0, "at least 3 vertices"),
        ([0, 100, 100 + 100j, 0.5j], 3, "repeats vertex 0"),
        ([0, 100, 100j, 100 + 100j], 3, "crosses edge"),
        ([0, 100, 200], 0, "no area"),
    ],
)
def test_polygon_faults(poly, index, words):
    fault = polygon_fault(np.array(poly, dtype=complex))
    assert fault is not None and fault[0] == index and words in fault[1]


def test_first_outside():
    sq = [0, 100, 100 + 100j, 100j]
    assert first_outside([50 + 50j, 60 + 50j], sq) is None
    assert first_outside([50 + 50j, 60 + 50j, 160 + 50j, 50 + 50j], sq) == 2


# ---- the mission's fence ----------------------------------------------------------------
def test_default_fence_surrounds_the_loop_with_turn_room():
    m = load_mission(PAPER)
    f = m.fence
    assert not f.explicit and f.margin_m == 150.0
    assert (f.min_alt_m, f.max_alt_m) == (50.0, 200.0)  # 100..150 m -/+ 50 m
    loop = m.patrol.point_at_phase(np.linspace(0, 2 * np.pi, 500, endpoint=False))
    turn_r = (20.0 + 5.0) / math.radians(18.0)
    room = signed_distance_m(loop, np.array(f.fence.polygon_m))
    assert room.min() >= 2 * turn_r + 150.0 - 0.1  # 720 loop samples: chords sag < 0.1 m
    assert room.min() <= 2 * turn_r + 150.0 + 15.0


def test_explicit_fence_in_lat_lon_and_metres():
    text = _mission_text(
        """fence:
  min_alt_m: 80
  max_alt_m: 400
  polygon:
    - {north_m: -700, east_m: -500}
    - {lat_deg: 39.8063, lon_deg: -84.0058}
    - {north_m: 700, east_m: 500}
    - {north_m: -700, east_m: 500}
"""
    )
    m = parse_mission(text, "x.yaml")
    f = m.fence
    assert f.explicit and (f.min_alt_m, f.max_alt_m) == (80.0, 400.0)
    assert f.vertices[1].lat_deg == 39.8063
    assert f.vertices[1].north_m == pytest.approx(700, abs=2)
    assert f.vertices[1].east_m == pytest.approx(-500, abs=5)  # 0.0001 deg of lon: 8.5 m


def test_fence_that_cuts_the_loop_names_the_line():
    text = _mission_text(
        """fence:
  polygon:
    - {north_m: -700, east_m: -500}
    - {north_m: 350, east_m: -500}
    - {north_m: 350, east_m: 500}
    - {north_m: -700, east_m: 500}
"""
    )
    with pytest.raises(MissionError) as err:
        parse_mission(text, "x.yaml")
    e = err.value
    assert e.field == "fence.polygon" and "passes" in str(e) and "outside the fence" in str(e)
    assert e.line == text.splitlines().index("  polygon:") + 2  # the list starts there


# ---- alerts the fence rules out ----------------------------------------------------------
def test_fence_refusal_site_room_and_path():
    m = load_mission(PAPER)
    u = m.vehicles.max_turn_rate_rad_s
    f = m.fence.fence
    assert fence_refusal(m.patrol, f, -450 + 0j, u) is None  # 50 m outside the loop
    assert "outside the fence" in fence_refusal(m.patrol, f, -900 + 0j, u)
    assert "a turn past it needs 80 m" in fence_refusal(m.patrol, f, -660 + 0j, u)
    # a fence with a notch cutting in from the east almost to the site: the site is well
    # inside, but the paths from the east side of the loop cross the notch
    notch = Fence(
        (-800 - 800j, 800 - 800j, 800 + 800j, 40 + 800j, 40 + 60j, -40 + 60j, -40 + 800j,
         -800 + 800j),
        0.0,
        500.0,
    )  # fmt: skip
    why = fence_refusal(m.patrol, notch, 0 - 100j, u)
    assert why is not None and "path from the loop leaves the fence" in why
    assert (
        fence_refusal(m.patrol, dataclasses.replace(notch, polygon_m=f.polygon_m), -100j, u) is None
    )


@dataclasses.dataclass
class AlertRun:
    """What an in-memory run did with an operator's alert: the companions' events, their
    agents and their own modes at the end."""

    events: list[dict]
    agents: list[Agent]
    modes: list[str]


def _run_with_operator_alert(folder: Path, site: complex, alert_id: str) -> AlertRun:
    """The paper's patrol alone, 30 s, then an operator's alert at ``site`` (m), to 60 s."""
    path = quiet_mission(folder, 900.0, source=Path(PAPER))
    with Engine(EngineConfig(path)) as sim:
        sim.run(30.0)
        sim.operator_alert(alert_id, site.real, site.imag)
        sim.run(60.0)
        return AlertRun(
            list(sim.companion_events),
            [r.agent for r in sim.runners],
            [r.agent_mode for r in sim.runners],
        )


@pytest.mark.contract
def test_an_alert_outside_the_fence_is_refused_by_every_companion_and_moves_no_uav(tmp_path):
    sim = _run_with_operator_alert(tmp_path, -900 + 0j, "255-1")
    refused = [e for e in sim.events if e["event"] == "alert_refused"]
    assert sorted(e["sysid"] for e in refused) == [1, 2, 3, 4, 5, 6]
    assert {(e["alert_id"], e["reason"]) for e in refused} == {("255-1", "fence")}
    assert not [e for e in sim.events if e["event"] in ("alert_tasked", "plan")]
    assert all(a.away is None for a in sim.agents) and sim.modes == ["patrol"] * 6


@pytest.mark.contract
def test_an_alert_inside_the_fence_is_still_flown(tmp_path):
    sim = _run_with_operator_alert(tmp_path, -450 + 0j, "255-2")
    assert not [e for e in sim.events if e["event"] == "alert_refused"]
    tasked = [e for e in sim.events if e["event"] == "alert_tasked"]
    assert len(tasked) == 6 and len({e["prosecutor_sysid"] for e in tasked}) == 1
