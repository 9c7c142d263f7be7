"""Real intruders through the real stack in memory (issue 21): a walker on the paper's ellipse
and a walker on a generated five-sided base, judged from the truth log
(:func:`companion.report.episodes.episode_measures`: where the aircraft and the intruder
really were), and the paper's chain policy on the same walker for comparison.

Bounds are the issue's goals where they hold: the sensor over the intruder within 1.2 x the
plan made at tasking, no false clear, exactly one prosecution under policy track, under
track while inside the fence (once seen), the formation's longest unseen point within
1.5 N / (N - 1) T/N on the generated base. On the ellipse the walker is met right where it
crosses the loop and the longest unseen point reaches about 2.5 T/N: a UAV that leaves the
loop leaves the stretch ahead of it to the next UAV, T/N behind, and the airspeed's 10 %
authority closes little of that (docs/alerts.md); the test holds today's figure.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from companion.agent.config import AgentConfig
from companion.mission.generate import generate
from companion.report.episodes import episode_measures
from companion.report.rundata import load_run
from companion.sim.inmemory import Engine, EngineConfig

pytestmark = pytest.mark.contract

DATA = Path(__file__).parent / "data"
WALKER = DATA / "ellipse_walker_fast.yaml"
FIVE_SIDED_SEED = 83  # a counter-clockwise five-sided base, six UAVs, a walker crossing out
THREE_UAV_SEED = 34  # a clockwise four-sided base, three UAVs, wind 0.39 of the airspeed, a static


def fly(mission: Path, out: Path, on_confirm: str = "track") -> dict:
    """The mission in memory to its scenario's end; the walker's episode measures."""
    with Engine(EngineConfig(mission, out, agent=AgentConfig(on_confirm=on_confirm))) as e:
        e.run(e.mission.duration_s)
    (rec,) = episode_measures(load_run(out))
    return rec


@pytest.fixture(scope="module")
def ellipse_walker(tmp_path_factory) -> dict:
    return fly(WALKER, tmp_path_factory.mktemp("walker") / "run")


@pytest.fixture(scope="module")
def five_sided_walker(tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp("five")
    mission = folder / "mission.yaml"
    g = generate(FIVE_SIDED_SEED, kind="walker", max_loop_km=3)
    assert g.waypoints == 5 and not g.clockwise
    mission.write_text(g.text)
    return fly(mission, folder / "run")


@pytest.fixture(scope="module")
def three_uav_static(tmp_path_factory) -> tuple[dict, Path]:
    folder = tmp_path_factory.mktemp("three")
    mission = folder / "mission.yaml"
    g = generate(THREE_UAV_SEED, kind="static", max_loop_km=3)
    assert g.vehicles == 3 and g.waypoints == 4
    mission.write_text(g.text)
    return fly(mission, folder / "run"), folder / "run"


def one_tracker(rec: dict) -> dict:
    (pros,) = rec["prosecutions"]  # exactly one UAV answered it
    assert pros["outcome"] == "tracking" and pros["present_at_cover"]
    assert pros["cover_over_plan"] <= 1.2
    assert pros["rejoin_s"] is not None  # back in its slot once the track was lost
    return pros


def test_a_walker_on_the_ellipse_is_intercepted_and_tracked_by_one_uav(ellipse_walker):
    rec = ellipse_walker
    print("ellipse walker:", rec["episode"], rec["prosecutions"])
    one_tracker(rec)
    assert rec["false_clears"] == 0
    # watched from its first detection until it was gone: the only unwatched time is before
    assert rec["longest_unwatched_s"] <= rec["detect_s"] + 1.0
    assert rec["under_track_fraction"] >= 0.85
    assert rec["episode"]["ended"] and rec["episode"]["longest_unseen_ratio"] <= 2.6


def test_a_walker_on_a_generated_five_sided_base_keeps_its_perimeter_covered(five_sided_walker):
    rec = five_sided_walker
    print("five-sided walker:", rec["episode"], rec["prosecutions"])
    pros = one_tracker(rec)
    assert rec["false_clears"] == 0 and rec["under_track_fraction"] >= 0.9
    n = 6
    assert rec["episode"]["longest_unseen_ratio"] <= 1.5 * n / (n - 1)
    assert pros["back_on_loop_ratio"] <= 1.0


def test_the_papers_chain_hands_the_walker_on_and_starves_its_stretch(tmp_path):
    """Policy chain on the same walker: every prosecutor sees it, confirms and hands it on,
    each leaving the loop at the same stretch; the track policy's one UAV is the default
    for this reason (docs/alerts.md)."""
    rec = fly(WALKER, tmp_path / "run", on_confirm="chain")
    outcomes = [p["outcome"] for p in rec["prosecutions"]]
    print("ellipse walker, chain:", rec["episode"], outcomes)
    assert outcomes.count("confirmed") >= 3 and rec["false_clears"] == 0
    assert all(p["cover_over_plan"] <= 1.2 for p in rec["prosecutions"] if p["cover_over_plan"])
    assert rec["episode"]["longest_unseen_ratio"] > 3.0  # what the track policy avoids


def test_with_a_tracker_away_the_others_resplay_along_the_loop(three_uav_static):
    # Three UAVs, one stays over a static intruder for about 130 s: the two left re-splay as
    # two by airspeed, on the loop. Before, the steering took the third of a slot each had
    # to move off the loop at once: 217 m off it (the sensor sees 58 m) and one loop point
    # unseen 4.4 T/N, more than a whole period.
    rec, out = three_uav_static
    print("three UAVs, static:", rec["episode"], rec["prosecutions"])
    pros = one_tracker(rec)
    run = load_run(out)
    patrol = run.mission.patrol
    r_s = run.mission.sensor.footprint_radius_m
    t0, t1 = pros["tasked_t_s"] + pros["cover_s"], pros["ended_t_s"]
    worst = 0.0
    for sysid, track in run.tracks.items():
        if sysid == pros["sysid"]:
            continue
        during = (track.t_s >= t0) & (track.t_s <= t1)
        assert during.sum() > 100
        off = [patrol.phase_and_offset_of_point(complex(z))[1] for z in track.pos_m[during][::5]]
        worst = max(worst, max(off))
    print(f"the others' largest distance from the loop while it tracked: {worst:.1f} m")
    assert worst <= 0.75 * r_s  # the loop under its sensor all along (31 m measured)
    n = 3
    assert rec["episode"]["ended"]
    assert rec["episode"]["longest_unseen_ratio"] <= 1.5 * n / (n - 1)
