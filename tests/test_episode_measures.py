"""Alert episode measures (companion/report/episodes.py) on hand-built runs.

A 300 m circle flown at 20 m/s in calm air by two UAVs (T = 2 pi 300 / 20 = 94.25 s,
T/N = 47.12 s), a sensor of 40 m, a square fence 500 m about the centre, truth sampled every
second. The tracks are made up (a UAV may sit still or jump) so that every expected figure
below can be worked out by hand from the positions; none comes from the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.agent.events import (
    AlertCleared,
    AlertLost,
    AlertNew,
    AlertTasked,
    PlanMade,
    ProsecutionEnd,
    Rejoined,
    RejoinPath,
)
from companion.mission import parse_mission
from companion.report.episodes import (
    FALSE_CLEAR_RADII,
    ON_LOOP_FRACTION,
    ON_LOOP_HOLD_S,
    UNSEEN_GOAL_REVISITS,
    WATCH_S,
    episode_measures,
    format_episode,
    most_away_at_once,
)
from companion.report.rundata import Away, RunData, Track

R_M, S0, N, RS = 300.0, 20.0, 2, 40.0
IDEAL_S = 2 * math.pi * R_M / S0 / N  # T/N
TIMES = np.arange(0.0, 201.0)  # one sample a second, 0..200 s
FAR = 2000 + 0j  # a place from which no sensor sees the loop or any intruder


def mission(intruders: str):
    """The circle mission with these scenario intruder lines (YAML flow mappings)."""
    text = f"""\
version: 1
name: episodes
origin: {{lat_deg: 39.8, lon_deg: -84.0, alt_m: 200}}
perimeter:
  ellipse: {{semi_major_m: {R_M}, semi_minor_m: {R_M}}}
wind: {{speed_m_s: 0, from_deg: 0}}
vehicles:
  count: {N}
  airspeed_m_s: {S0}
  max_turn_rate_deg_s: 18
  initial: {{line: {{from: {{north_m: 0, east_m: -300}}, to: {{north_m: 0, east_m: 300}},
    heading_deg: 0}}}}
sensor: {{footprint_radius_m: {RS}}}
fence:
  polygon:
    - {{north_m: 500, east_m: -500}}
    - {{north_m: 500, east_m: 500}}
    - {{north_m: -500, east_m: 500}}
    - {{north_m: -500, east_m: -500}}
scenario:
  duration_s: 200
  intruders:
{intruders}
"""
    return parse_mission(text, "episodes.yaml")


def track(sysid: int, pos_m: np.ndarray) -> Track:
    zeros = np.zeros(TIMES.size)
    return Track(sysid, TIMES, np.asarray(pos_m, dtype=complex), zeros, np.array(["GUIDED"] * 201))


def run_of(intruders: str, pos1: np.ndarray, pos2: np.ndarray, events: list) -> RunData:
    recs = [e.to_record() if hasattr(e, "to_record") else e for e in events]
    return RunData(None, mission(intruders), {1: track(1, pos1), 2: track(2, pos2)}, recs)


def by_id(records: list[dict]) -> dict[str, dict]:
    return {r["intruder_id"]: r for r in records}


def test_time_under_track_and_the_longest_unwatched_interval():
    # a static intruder at the centre from 20 s to 120 s (samples 20..119: 100 s, all inside
    # the fence); UAV 1 sits on it at 30-40 s and 100-105 s, else far away
    pos1 = np.full(TIMES.size, FAR)
    pos1[(TIMES >= 30) & (TIMES <= 40)] = 0
    pos1[(TIMES >= 100) & (TIMES <= 105)] = 0
    # a walker from north 250 m going north at 2 m/s from 0 to 100 s: it crosses the loop
    # (north 300) at 25 s, never leaves the fence, and no sensor ever covers it
    intruders = (
        "    - {id: stay, kind: static, appear_t_s: 20, north_m: 0, east_m: 0, vanish_t_s: 120}\n"
        "    - {id: walk, kind: moving, appear_t_s: 0, north_m: 250, east_m: 0,"
        " velocity_north_m_s: 2.0, velocity_east_m_s: 0.0, vanish_t_s: 100}"
    )
    seen = AlertNew(
        t_s=30.5, sysid=1, alert_id="1-1", detector_sysid=1, north_m=5.0, east_m=0.0, own=True
    )
    recs = by_id(episode_measures(run_of(intruders, pos1, np.full(TIMES.size, FAR), [seen])))
    stay = recs["stay"]
    assert WATCH_S == 30.0  # the hand count below uses it
    # covered at 30..40 and 100..105; watched while the last cover is at most 30 s old:
    # 30..70 (41 s) and 100..119 (20 s) of the 100 s present
    assert stay["inside_fence_s"] == pytest.approx(100.0)
    assert stay["under_track_fraction"] == pytest.approx(61 / 100)
    assert stay["longest_unwatched_s"] == pytest.approx(29.0)  # 71..99
    # from its first detection at 30 s: 90 s inside, 30..70 and 100..119 watched (61 s)
    assert stay["under_track_after_detection_fraction"] == pytest.approx(61 / 90, abs=1e-4)
    assert stay["longest_uncovered_s"] == pytest.approx(59.0)  # 41..99
    assert stay["detect_s"] == pytest.approx(10.0) and stay["alert_s"] == pytest.approx(10.5)
    assert stay["alert_ids"] == ["1-1"] and not stay["crosses_loop"]
    assert stay["vanish_source"] == "mission" and stay["vanish_t_s"] == 120.0
    assert stay["prosecutions"] == [] and stay["episode"] is None  # nobody was tasked
    walk = recs["walk"]
    assert walk["crosses_loop"] and walk["detect_s"] is None and walk["alert_ids"] == []
    assert walk["inside_fence_s"] == pytest.approx(100.0)
    assert walk["under_track_fraction"] == 0.0 and walk["longest_unwatched_s"] == 100.0
    assert walk["under_track_after_detection_fraction"] is None  # never detected
    # the band is within r_s = 40 m of the loop (radius 300): the static one at the centre
    # never enters it; the walker does at north 260 m (5 s) and is never seen until it ends
    assert stay["band_to_detect_s"] is None
    assert walk["band_to_detect_s"] == pytest.approx(100.0 - 5.0)


def test_band_to_detection_counts_from_reaching_the_loops_band():
    # a walker from north -200 m (100 m inside the loop) going south at 2 m/s: in the band
    # (north <= -260 m) from 30 s; UAV 2 waits at north -290 m from 42 s and sees it at once
    # (the walker at -284 m); UAV 1 is far away throughout
    intruders = (
        "    - {id: edge, kind: moving, appear_t_s: 0, north_m: -200, east_m: 0,"
        " velocity_north_m_s: -2.0, velocity_east_m_s: 0.0, vanish_t_s: 60}"
    )
    pos2 = np.full(TIMES.size, FAR)
    pos2[TIMES >= 42] = -290 + 0j
    (edge,) = episode_measures(run_of(intruders, np.full(TIMES.size, FAR), pos2, []))
    assert edge["detect_s"] == pytest.approx(42.0)
    assert edge["band_to_detect_s"] == pytest.approx(42.0 - 30.0)


def test_a_clear_with_the_intruder_under_the_uav_is_false_and_one_after_it_left_is_not():
    assert FALSE_CLEAR_RADII * RS == 120.0  # the hand distances below straddle it
    intruders = (
        "    - {id: near, kind: static, appear_t_s: 0, north_m: 300, east_m: 0, vanish_t_s: 100}\n"
        "    - {id: gone, kind: static, appear_t_s: 0, north_m: -300, east_m: 0, vanish_t_s: 50}\n"
        "    - {id: decoy, kind: decoy, appear_t_s: 0, north_m: 0, east_m: 300}"
    )
    pos1 = np.full(TIMES.size, 300 + 100j)  # UAV 1 100 m from "near"
    pos2 = np.full(TIMES.size, -300 + 0j)  # UAV 2 on top of "gone"
    pos2[TIMES >= 45] = 300j  # ... then on the decoy's site
    pos2[TIMES >= 70] = 300 + 130j  # ... then 130 m from "near"
    events = [
        # UAV 1 clears "a" at 60 s with "near" 100 m away: false; the others hear it (once)
        ProsecutionEnd(t_s=60.0, sysid=1, alert_id="a", outcome="cleared", planned_time_s=9.0),
        AlertCleared(t_s=60.0, sysid=1, alert_id="a", detector_sysid=1),
        AlertCleared(t_s=60.05, sysid=2, alert_id="a", detector_sysid=1),
        # UAV 2 clears "b" at 60 s over the decoy's site: "gone" vanished at 50 s, the decoy
        # at 40 s
        ProsecutionEnd(t_s=60.0, sysid=2, alert_id="b", outcome="cleared", planned_time_s=9.0),
        # the decoy vanished at 40 s (the simulator says so; without that it would be there
        # to the end) and UAV 2 clears "c" on top of it at 46 s
        {"t_s": 40.0, "event": "intruder_vanished", "intruder": "decoy", "source": "sim"},
        AlertCleared(t_s=46.0, sysid=1, alert_id="c", detector_sysid=2),
        # UAV 2 clears "d" at 75 s, 130 m from "near": not false
        {"t_s": 75.0, "event": "some_future_clear", "sysid": 2, "alert_id": "d",
         "outcome": "cleared"},
        # a confirmation is no clear
        ProsecutionEnd(t_s=80.0, sysid=1, alert_id="e", outcome="confirmed", planned_time_s=9.0),
    ]  # fmt: skip
    recs = by_id(episode_measures(run_of(intruders, pos1, pos2, events)))
    assert recs["near"]["false_clears"] == 1
    assert recs["near"]["false_clear_events"] == [{"t_s": 60.0, "sysid": 1, "alert_id": "a"}]
    assert recs["gone"]["false_clears"] == 0
    assert recs["decoy"]["false_clears"] == 0
    assert recs["decoy"]["vanish_source"] == "sim" and recs["decoy"]["vanish_t_s"] == 40.0


def test_a_clear_of_another_intruders_alert_is_not_a_false_clear_of_this_one():
    # generated mission 2: a decoy gone, a walker 40 m from it under its own open alert; the
    # decoy's clear is the decoy's answer, not a clear of the walker
    intruders = (
        "    - {id: decoy, kind: static, appear_t_s: 0, north_m: 300, east_m: 0, vanish_t_s: 50}\n"
        "    - {id: walker, kind: static, appear_t_s: 0, north_m: 300, east_m: 40, vanish_t_s: 150}"
    )
    pos1 = np.full(TIMES.size, 300 + 0j)  # UAV 1 over the decoy's site, the walker 40 m off
    pos2 = np.full(TIMES.size, FAR)
    events = [
        AlertNew(
            t_s=10.0, sysid=1, alert_id="d", detector_sysid=1, north_m=300.0, east_m=0.0, own=True
        ),
        AlertNew(
            t_s=12.0, sysid=1, alert_id="w", detector_sysid=1, north_m=300.0, east_m=40.0, own=True
        ),
        ProsecutionEnd(t_s=60.0, sysid=1, alert_id="d", outcome="cleared", planned_time_s=9.0),
        AlertCleared(t_s=60.0, sysid=1, alert_id="d", detector_sysid=1),
        ProsecutionEnd(t_s=90.0, sysid=1, alert_id="w", outcome="cleared", planned_time_s=9.0),
    ]  # fmt: skip
    recs = by_id(episode_measures(run_of(intruders, pos1, pos2, events)))
    assert recs["decoy"]["false_clears"] == 0  # gone at 50 s
    assert recs["walker"]["false_clear_events"] == [{"t_s": 90.0, "sysid": 1, "alert_id": "w"}]


def test_a_prosecution_that_lost_its_intruder_near_is_counted_apart_from_false_clears():
    # a vehicle's prosecutor ends "lost" with the intruder 100 m away (within 3 r_s): not a
    # clear (it claims nothing is there), but the same near miss, counted as lost near; the
    # alert_lost every member logs is no clear either
    intruders = (
        "    - {id: car, kind: static, appear_t_s: 0, north_m: 300, east_m: 0, vanish_t_s: 150}"
    )
    pos1 = np.full(TIMES.size, 300 + 100j)  # UAV 1 100 m from the car
    pos2 = np.full(TIMES.size, FAR)
    pos2[TIMES >= 90] = 300 + 130j  # UAV 2 130 m from it at its loss at 95 s
    events = [
        ProsecutionEnd(t_s=60.0, sysid=1, alert_id="a", outcome="lost", planned_time_s=9.0),
        AlertLost(t_s=60.0, sysid=1, alert_id="a", detector_sysid=1),
        AlertLost(t_s=60.05, sysid=2, alert_id="a", detector_sysid=1),
        ProsecutionEnd(t_s=95.0, sysid=2, alert_id="b", outcome="lost", planned_time_s=9.0),
    ]  # fmt: skip
    (car,) = episode_measures(run_of(intruders, pos1, pos2, events))
    assert car["false_clears"] == 0
    assert car["lost_near"] == 1
    assert car["lost_near_events"] == [{"t_s": 60.0, "sysid": 1, "alert_id": "a"}]


def test_a_prosecution_is_timed_against_its_plan_and_its_excursion_and_return_measured():
    # a static intruder 128 m outside the loop at north 428 m, from 40 s to 150 s; UAV 2
    # passes over it at 44-45 s and reports it at 45 s; UAV 1, on the loop at north 300 m,
    # is tasked at 50 s, flies out at 5 m/s to north 400 m (70 s: confirmed), hovers there,
    # jumps back onto the loop at 80 s, blips 20 m off at 83 s and rejoins at 95 s
    intruders = (
        "    - {id: it, kind: static, appear_t_s: 40, north_m: 428, east_m: 0, vanish_t_s: 150}"
    )
    x = np.full(TIMES.size, 300.0)
    out = (TIMES > 50) & (TIMES <= 70)
    x[out] = 300 + 5 * (TIMES[out] - 50)
    x[(TIMES > 70) & (TIMES < 80)] = 400.0
    x[TIMES == 83] = 320.0
    pos1 = x + 0j
    pos2 = np.zeros(TIMES.size, dtype=complex)  # the centre: 300 m from the loop
    pos2[(TIMES >= 44) & (TIMES <= 45)] = 428
    site = {"north_m": 428.0, "east_m": 0.0}
    events = [
        AlertNew(t_s=45.0, sysid=2, alert_id="2-1", detector_sysid=2, own=True, **site),
        AlertNew(t_s=45.1, sysid=1, alert_id="2-1", detector_sysid=2, own=False, **site),
        AlertTasked(t_s=50.0, sysid=2, alert_id="2-1", prosecutor_sysid=1, policy="next"),
        AlertTasked(t_s=50.0, sysid=1, alert_id="2-1", prosecutor_sysid=1, policy="next"),
        PlanMade(t_s=50.0, sysid=1, alert_id="2-1", planned_time_s=15.0, path_type="LSL"),
        ProsecutionEnd(t_s=70.0, sysid=1, alert_id="2-1", outcome="confirmed",
                       planned_time_s=15.0),
        RejoinPath(t_s=70.0, sysid=1, alert_id="2-1", planned_time_s=6.5, path_type="RSL"),
        Rejoined(t_s=95.0, sysid=1, alert_id="2-1", in_slot=True, rejoin_s=25.0),
    ]  # fmt: skip
    (rec,) = episode_measures(run_of(intruders, pos1, pos2, events))
    assert rec["detect_s"] == pytest.approx(4.0) and rec["alert_s"] == pytest.approx(5.0)
    assert rec["prosecutions"][0]["path_back_s"] == 6.5
    (p,) = rec["prosecutions"]
    # the sensor is over it once north >= 428 - 40 = 388 m: the first sample is 68 s (390 m)
    assert p["sysid"] == 1 and p["tasked_t_s"] == 50.0 and p["planned_time_s"] == 15.0
    assert p["cover_s"] == pytest.approx(18.0) and p["cover_over_plan"] == pytest.approx(1.2)
    assert p["present_at_cover"] and p["outcome"] == "confirmed" and p["ended_t_s"] == 70.0
    assert p["max_excursion_m"] == pytest.approx(100.0, abs=0.05)
    # more than r_s = 40 m off once north > 340 m: 59..79 s, 21 samples of 1 s, and 58 s
    # (340 m) sits on the boundary (the loop's polyline is a hair inside the circle)
    assert 21.0 <= p["off_loop_s"] <= 22.0
    assert p["off_loop_ratio"] == pytest.approx(p["off_loop_s"] / IDEAL_S, abs=1e-4)
    # within r_s / 4 = 10 m of the loop from 80 s, but 20 m off at 83 s: it holds 5 s from 84 s
    assert ON_LOOP_FRACTION * RS == 10.0 and ON_LOOP_HOLD_S == 5.0
    assert p["back_on_loop_s"] == pytest.approx(14.0)
    assert p["back_on_loop_ratio"] == pytest.approx(14.0 / IDEAL_S, abs=1e-4)
    assert p["rejoin_s"] == 25.0 and p["rejoined_t_s"] == 95.0
    ep = rec["episode"]
    assert ep["t0_s"] == 45.0 and ep["t1_s"] == 95.0 and ep["ended"]
    # the loop points near north 300 m were covered from 0 s until UAV 1 left, and again at
    # 80 s when it came back: 80 s start to start; the rest of the loop was never seen, so at
    # the episode's end (95 s) it has been unseen for 95 s
    assert ep["max_pass_interval_s"] == pytest.approx(80.0)
    assert ep["coverage_revisit_ratio"] == pytest.approx(80.0 / IDEAL_S, abs=1e-4)
    assert ep["longest_unseen_s"] == pytest.approx(95.0)
    assert ep["longest_unseen_ratio"] == pytest.approx(95.0 / IDEAL_S, abs=1e-4)
    # under track: covered at 44-45 s (UAV 2) and 68-79 s (UAV 1 at 390-400 m), so watched
    # from 44 to 109 s of its 110 s; unwatched 40-43 s and 110-149 s
    assert rec["under_track_fraction"] == pytest.approx(66 / 110)
    assert rec["longest_unwatched_s"] == pytest.approx(40.0)
    line = format_episode(rec)
    assert line.startswith("it (static)") and "1 prosecution(s)" in line and "1.20" in line


def test_a_prosecution_still_away_at_the_end_leaves_the_episode_open():
    intruders = "    - {id: it, kind: static, appear_t_s: 10, north_m: 300, east_m: 0}"
    pos = np.full(TIMES.size, 300 + 0j)
    site = {"north_m": 300.0, "east_m": 0.0}
    events = [
        AlertNew(t_s=20.0, sysid=2, alert_id="2-1", detector_sysid=2, own=True, **site),
        AlertTasked(t_s=30.0, sysid=1, alert_id="2-1", prosecutor_sysid=1, policy="next"),
    ]
    (rec,) = episode_measures(run_of(intruders, pos, pos, events))
    (p,) = rec["prosecutions"]
    assert p["cover_s"] == 0.0 and p["planned_time_s"] is None and p["cover_over_plan"] is None
    assert p["outcome"] is None and p["back_on_loop_s"] is None and p["rejoin_s"] is None
    assert rec["vanish_source"] == "end" and not rec["episode"]["ended"]
    assert rec["episode"]["t1_s"] == pytest.approx(200.0, abs=0.01)
    assert "(open)" in format_episode(rec)


def test_a_pass_over_the_intruder_after_the_prosecution_ended_is_not_its_cover():
    # tasked at 50 s, UAV 1 clears at 60 s far from the intruder (so not a false clear), then
    # passes over it at 70-75 s on its way back: the prosecution never had it under its sensor
    intruders = (
        "    - {id: it, kind: static, appear_t_s: 40, north_m: 428, east_m: 0, vanish_t_s: 150}"
    )
    pos1 = np.full(TIMES.size, FAR)
    pos1[(TIMES >= 70) & (TIMES <= 75)] = 428
    site = {"north_m": 428.0, "east_m": 0.0}
    events = [
        AlertNew(t_s=45.0, sysid=2, alert_id="2-1", detector_sysid=2, own=True, **site),
        AlertTasked(t_s=50.0, sysid=1, alert_id="2-1", prosecutor_sysid=1, policy="next"),
        PlanMade(t_s=50.0, sysid=1, alert_id="2-1", planned_time_s=15.0, path_type="LSL"),
        ProsecutionEnd(t_s=60.0, sysid=1, alert_id="2-1", outcome="cleared",
                       planned_time_s=15.0),
        Rejoined(t_s=90.0, sysid=1, alert_id="2-1", in_slot=True, rejoin_s=30.0),
    ]  # fmt: skip
    (rec,) = episode_measures(run_of(intruders, pos1, np.full(TIMES.size, FAR), events))
    (p,) = rec["prosecutions"]
    assert p["outcome"] == "cleared" and p["cover_s"] is None and p["cover_over_plan"] is None
    assert rec["false_clears"] == 0 and rec["detect_s"] == pytest.approx(30.0)


@pytest.mark.parametrize(
    ("spans", "expected"),
    [
        ([], 0),
        ([(0.0, 10.0)], 1),
        ([(0.0, 10.0), (10.0, 20.0)], 2),  # one ends as the other begins: both at 10 s
        ([(0.0, 9.0), (10.0, 20.0)], 1),
        ([(0.0, 30.0), (5.0, 8.0), (7.0, 12.0)], 3),
        ([(-50.0, -1.0), (101.0, 200.0)], 0),  # outside the window [0, 100]
    ],
)
def test_most_away_at_once_counts_the_overlapping_windows(spans, expected):
    wins = [Away(k + 1, f"a{k}", a, b) for k, (a, b) in enumerate(spans)]
    assert most_away_at_once(wins, 0.0, 100.0) == expected


def _two_alerts(other_t0_s: float, other_t1_s: float) -> list:
    """UAV 1 answers the decoy (alert "d", 60-90 s); UAV 2 is away for the walker (alert
    "w") from ``other_t0_s`` to ``other_t1_s`` (a tracker, say)."""
    d = {"north_m": 300.0, "east_m": 0.0}
    w = {"north_m": -300.0, "east_m": 0.0}
    return [
        AlertNew(t_s=50.0, sysid=2, alert_id="w", detector_sysid=2, own=True, **w),
        AlertNew(t_s=55.0, sysid=1, alert_id="d", detector_sysid=1, own=True, **d),
        AlertTasked(t_s=other_t0_s, sysid=2, alert_id="w", prosecutor_sysid=2, policy="next"),
        AlertTasked(t_s=60.0, sysid=1, alert_id="d", prosecutor_sysid=1, policy="next"),
        Rejoined(t_s=90.0, sysid=1, alert_id="d", in_slot=True, rejoin_s=5.0),
        Rejoined(t_s=other_t1_s, sysid=2, alert_id="w", in_slot=True, rejoin_s=5.0),
    ]  # fmt: skip


@pytest.mark.parametrize(("other", "k"), [((52.0, 150.0), 1), ((95.0, 150.0), 0)])
def test_a_decoys_goal_is_the_revisit_of_the_uavs_left_on_the_loop(other, k):
    """With the other UAV away during the decoy's episode (55-90 s), one of two patrols:
    the goal is 1.5 N / (N - 1) = 3 T/N; away only after the episode, 1.5 T/N."""
    intruders = (
        "    - {id: decoy, kind: static, appear_t_s: 40, north_m: 300, east_m: 0,"
        " vanish_t_s: 58}\n"
        "    - {id: walker, kind: static, appear_t_s: 40, north_m: -300, east_m: 0}"
    )
    pos = np.full(TIMES.size, 300 + 0j)
    recs = by_id(episode_measures(run_of(intruders, pos, pos, _two_alerts(*other))))
    ep = recs["decoy"]["episode"]
    assert (ep["t0_s"], ep["t1_s"]) == (55.0, 90.0)
    assert ep["others_away"] == k
    assert ep["revisit_left_ratio"] == pytest.approx(N / (N - k))
    assert ep["unseen_goal_ratio"] == pytest.approx(UNSEEN_GOAL_REVISITS * N / (N - k))
    # the walker's own episode counts the decoy's prosecutor as the other one away
    assert recs["walker"]["episode"]["others_away"] == 1


@pytest.mark.parametrize("off_at_retask", [False, True])
def test_a_prosecutor_tasked_again_is_back_if_on_the_loop_then_else_unmeasured(off_at_retask):
    # generated mission 2: UAV 1 checks a decoy from the loop (north 300 m, on the circle),
    # clears it at 60 s and is tasked to a second intruder 0.1 s later, which it tracks
    # 100 m off the loop for the rest of the run. It never left the loop for the first: back
    # at once (0 s), though the new tasking cut its 5 s hold short; the hold must not run
    # on into the second prosecution. Had it been off the loop when tasked again (from 55 s),
    # the first is not measured (None), and says why.
    intruders = (
        "    - {id: a, kind: static, appear_t_s: 40, north_m: 310, east_m: 0, vanish_t_s: 55}\n"
        "    - {id: b, kind: static, appear_t_s: 40, north_m: 0, east_m: 400, vanish_t_s: 200}"
    )
    pos1 = np.full(TIMES.size, 300 + 0j)
    pos1[(55.0 if off_at_retask else 61.0) <= TIMES] = 0 + 400j  # 100 m outside the loop
    pos2 = np.full(TIMES.size, FAR)
    events = [
        AlertNew(t_s=45.0, sysid=1, alert_id="1-1", detector_sysid=1, own=True,
                 north_m=310.0, east_m=0.0),
        AlertTasked(t_s=50.0, sysid=1, alert_id="1-1", prosecutor_sysid=1, policy="next"),
        ProsecutionEnd(t_s=60.0, sysid=1, alert_id="1-1", outcome="cleared",
                       planned_time_s=5.0),
        Rejoined(t_s=60.0, sysid=1, alert_id="1-1", in_slot=True, rejoin_s=0.0),
        AlertNew(t_s=60.05, sysid=1, alert_id="1-2", detector_sysid=1, own=True,
                 north_m=0.0, east_m=400.0),
        AlertTasked(t_s=60.1, sysid=1, alert_id="1-2", prosecutor_sysid=1, policy="next"),
        ProsecutionEnd(t_s=60.2, sysid=1, alert_id="1-2", outcome="tracking",
                       planned_time_s=1.0),
    ]  # fmt: skip
    recs = by_id(episode_measures(run_of(intruders, pos1, pos2, events)))
    (p,) = recs["a"]["prosecutions"]
    if off_at_retask:
        assert p["back_on_loop_s"] is None and p["retasked_before_back"] is True
    else:
        assert p["back_on_loop_s"] == 0.0 and p["retasked_before_back"] is False
    (q,) = recs["b"]["prosecutions"]  # tracking to the end: never back, and not re-tasked
    assert q["back_on_loop_s"] is None and q["retasked_before_back"] is False
