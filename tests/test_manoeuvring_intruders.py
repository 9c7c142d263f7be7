"""Intruders that manoeuvre, through the real stack in memory (issue 47): a truck that turns at
a junction inside the sensor band and a walker that stops 60 s under cover and goes on, on a
generated base, judged from the truth log (:func:`companion.report.episodes.episode_measures`).

The base, fleet and wind are the generator's (``generate(SEED, kind="walker")``); the intruder
is written here from the loop's own geometry, so the turn and the stop fall where the test
says: a truck driving in along the loop's normal at 8 m/s turns 90 deg at a junction half a
footprint inside the loop and drives on along it; a walker crossing at 2 m/s stops for
60 s half a footprint inside the loop and walks on inward, on a base of three UAVs whose
prosecutor comes late (T/N 35 s), so a prediction that walks on is far from where it stands.

Bounds are the issue's goals: the sensor over the intruder within 1.2 x the plan made at
tasking, no false clear, no loss near it, and the walker under track at least 90 % of its
time in the fence after its detection.
"""

from __future__ import annotations

import cmath
import re
from pathlib import Path

import pytest

from companion.agent.config import AgentConfig
from companion.mission import load_mission
from companion.mission.generate import generate
from companion.report.episodes import episode_measures
from companion.report.rundata import load_run
from companion.sim.inmemory import Engine, EngineConfig

pytestmark = pytest.mark.contract

SEED = 83  # a counter-clockwise five-sided base, six UAVs (tests/test_real_intruders.py)
WALKER_SEED = 3  # three UAVs on a 2.2 km loop, T/N 35 s: a prosecutor comes late
APPEAR_S = 200.0
PHASE_RAD = 2.0  # where on the loop the intruder crosses


def _leg(p: complex, speed: float, wait: float = 0.0) -> str:
    w = f", wait_s: {wait:.1f}" if wait else ""
    return f"        - {{north_m: {p.real:.2f}, east_m: {p.imag:.2f}, speed_m_s: {speed:.2f}{w}}}"


def mission_with(folder: Path, kind: str) -> tuple[Path, float]:
    """The generated base with one intruder of ``kind`` ("truck" or "walker"); the mission
    file and its duration (s)."""
    g = generate(SEED if kind == "truck" else WALKER_SEED, kind="walker", max_loop_km=3)
    base = folder / "base.yaml"
    base.write_text(g.text)
    m = load_mission(base)
    patrol, r_s = m.patrol, m.sensor.footprint_radius_m
    on_loop = complex(patrol.point_at_phase(PHASE_RAD))
    along = cmath.exp(1j * float(patrol.course_at_phase(PHASE_RAD)))  # the loop's direction
    centroid = complex(sum(complex(patrol.point_at_phase(k * 0.1)) for k in range(63)) / 63)
    inward = 1j * along if ((centroid - on_loop) / (1j * along)).real > 0 else -1j * along
    junction = on_loop + 0.5 * r_s * inward
    if kind == "truck":
        start = junction - 250.0 * inward
        legs = [_leg(junction, 8.0), _leg(junction + 250.0 * along, 8.0)]
        dur = 250.0 / 8.0 * 2
    else:
        start = junction - 60.0 * inward
        legs = [_leg(junction, 2.0, wait=60.0), _leg(junction + 120.0 * inward, 2.0)]
        dur = (60.0 + 0.5 * r_s) / 2.0 + 60.0 + 120.0 / 2.0
    intruder = "\n".join(
        [
            "  intruders:",
            f"    - id: {kind}",
            "      kind: path",
            f"      appear_t_s: {APPEAR_S:.1f}",
            f"      north_m: {start.real:.2f}",
            f"      east_m: {start.imag:.2f}",
            "      path:",
            *legs,
            f"      vanish_t_s: {APPEAR_S + dur + 5.0:.1f}",
        ]
    )
    duration = APPEAR_S + dur + 120.0
    text = re.sub(r"  intruders:\n(?:    .*\n|      .*\n)*", intruder + "\n", g.text)
    text = re.sub(r"duration_s: [0-9.]+", f"duration_s: {duration:.1f}", text)
    path = folder / f"{kind}.yaml"
    path.write_text(text)
    load_mission(path)  # valid
    return path, duration


def fly(mission: Path, out: Path, duration: float) -> dict:
    with Engine(EngineConfig(mission, out, agent=AgentConfig(on_confirm="track"))) as e:
        e.run(duration)
    (rec,) = episode_measures(load_run(out))
    return rec


@pytest.fixture(scope="module")
def truck(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("truck")
    mission, duration = mission_with(folder, "truck")
    return fly(mission, folder / "run", duration)


@pytest.fixture(scope="module")
def walker(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("walker")
    mission, duration = mission_with(folder, "walker")
    return fly(mission, folder / "run", duration)


def test_a_truck_turning_at_a_junction_in_the_band_is_met_and_not_cleared(truck):
    rec = truck
    print("truck:", rec["prosecutions"], rec["under_track_after_detection_fraction"])
    assert rec["detect_s"] is not None
    assert rec["false_clears"] == 0 and rec["lost_near"] == 0
    pros = rec["prosecutions"]
    assert pros and pros[0]["present_at_cover"] and pros[0]["cover_over_plan"] <= 1.2


def test_a_walker_that_stops_sixty_seconds_and_goes_on_stays_under_track(walker):
    rec = walker
    print("walker:", rec["prosecutions"], rec["under_track_after_detection_fraction"])
    assert rec["detect_s"] is not None
    assert rec["false_clears"] == 0 and rec["lost_near"] == 0
    assert rec["under_track_after_detection_fraction"] >= 0.9


TURNED_SEED = 28  # generate(28, kind="turning_vehicle"): 11 UAVs, a 15 m/s vehicle that turns
# 60 deg at a junction 1 s before its first pass ends (bench/alerts.py, docs/alerts.md)


@pytest.fixture(scope="module")
def turned(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("turned")
    g = generate(TURNED_SEED, kind="turning_vehicle", max_loop_km=3)
    mission = folder / "turned.yaml"
    mission.write_text(g.text)
    cfg = EngineConfig(
        mission, folder / "run", seed=TURNED_SEED, agent=AgentConfig(on_confirm="track")
    )  # as bench/alerts.py flies it
    with Engine(cfg) as e:
        e.run(g.duration_s)
    (rec,) = episode_measures(load_run(folder / "run"))
    return rec


def test_a_vehicle_that_turned_after_its_pass_is_its_prosecutors_intruder(turned):
    """Its prosecutor flies over it 19-34 m off the straight prediction: that sighting ends
    the prosecution, it raises no second alert (which another UAV was tasked to after the
    vehicle was gone) and does not search on for the old prediction."""
    rec = turned
    print("turned:", rec["prosecutions"])
    assert rec["false_clears"] == 0 and rec["lost_near"] == 0
    pros = rec["prosecutions"]
    assert len(pros) == 1, pros
    assert pros[0]["present_at_cover"] and pros[0]["cover_over_plan"] <= 1.2
    assert pros[0]["outcome"] in ("tracking", "confirmed")
