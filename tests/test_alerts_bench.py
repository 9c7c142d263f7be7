"""bench/alerts.py's figures from hand-made records: which episodes each goal is judged on,
and the failures listed once; ``--remeasure`` refusing what it cannot read.

The records are written by hand (no flight), with values chosen on either side of each goal.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("alerts_bench", ROOT / "bench" / "alerts.py")
bench = importlib.util.module_from_spec(_spec)
sys.modules["alerts_bench"] = bench  # its dataclasses look their module up
_spec.loader.exec_module(bench)

TN_S = 10.0


def prosecution(off: float, back: float | None, path_back: float | None) -> dict:
    """A prosecution's record: ``off`` and ``back`` in T/N, ``path_back`` in s."""
    return {
        "sysid": 2,
        "alert_id": "1-1",
        "cover_over_plan": 0.9,
        "cover_s": 12.0,
        "off_loop_ratio": off,
        "back_on_loop_ratio": back,
        "back_on_loop_s": None if back is None else back * TN_S,
        "path_back_s": path_back,
        "max_excursion_m": 100.0,
        "rejoin_s": 20.0,
    }


def decoy(name: str, unseen: float, pros: list[dict]) -> dict:
    """A decoy's episode record, its longest unseen ``unseen`` T/N."""
    return {
        "intruder_id": name,
        "kind": "decoy",
        "crosses_loop": False,
        "detect_s": 1.0,
        "alert_s": 1.1,
        "prosecutions": pros,
        "under_track_fraction": 1.0,
        "under_track_after_detection_fraction": 1.0,
        "longest_unwatched_s": 1.0,
        "false_clears": 0,
        "episode": {"coverage_revisit_ratio": unseen, "longest_unseen_ratio": unseen},
    }


def runs() -> list[dict]:
    # decoy-1: its prosecutor off the loop 0.3 T/N, unseen 1.2 T/N (meets 1.5), back in
    # 0.8 T/N on a 6 s path; decoy-2: off 1.2 T/N, unseen 1.9 T/N, back in 1.6 T/N on a
    # 14 s path (longer than T/N = 10 s: the goal cannot be met there)
    eps = [
        decoy("decoy-1", 1.2, [prosecution(0.3, 0.8, 6.0)]),
        decoy("decoy-2", 1.9, [prosecution(1.2, 1.6, 14.0)]),
    ]
    return [{"seed": 7, "mission": {"ideal_revisit_s": TN_S}, "episodes": eps, "error": None}]


def by_name(ms: list) -> dict:
    return {m.name: m for m in ms}


def test_the_decoy_goal_is_also_judged_where_it_can_be_met_and_failures_listed_once():
    ms = by_name(bench.measures(runs()))
    everyone = ms["decoy episode longest unseen"]
    short = ms["decoy episode longest unseen, off <= T/N/2"]
    assert [s.value for s in everyone.samples] == [1.2, 1.9]
    assert [s.value for s in short.samples] == [1.2]  # decoy-2 was off the loop 1.2 T/N
    assert [s.where for s in everyone.failures()] == ["seed 7 decoy-2"]
    assert short.failures() == []  # not listed twice
    off = ms["prosecutor off the loop, a decoy's episode"]
    assert [s.value for s in off.samples] == [0.3, 1.2]


def test_back_on_the_loop_is_set_against_its_quickest_path():
    ms = by_name(bench.measures(runs()))
    ratio = ms["back on the loop / its quickest path"]
    assert [s.value for s in ratio.samples] == pytest.approx([8.0 / 6.0, 16.0 / 14.0])
    feasible = ms["back on the loop, quickest path <= T/N"]
    assert [s.value for s in feasible.samples] == [0.8]  # the 14 s path is longer than T/N
    listed = ms["prosecution end to back on the loop"]
    assert [s.where for s in listed.failures()] == ["seed 7 decoy-2 UAV 2 (1-1)"]


def test_remeasure_refuses_a_file_it_did_not_write_and_runs_it_did_not_keep(tmp_path, capsys):
    junk = tmp_path / "junk.json"
    junk.write_text("not json")
    with pytest.raises(SystemExit, match="not a file written by this bench"):
        bench.main(["--remeasure", str(junk)])
    unkept = tmp_path / "unkept.json"
    unkept.write_text(json.dumps({"args": {"out": None}, "wall_s": 1.0, "runs": []}))
    with pytest.raises(SystemExit, match="were not kept"):
        bench.main(["--remeasure", str(unkept)])


def test_combine_reports_the_pieces_as_one_and_refuses_a_seed_flown_twice(tmp_path, capsys):
    first, second = runs(), runs()
    second[0]["seed"] = 8
    for r in first + second:  # what the report's line per mission reads
        r["wall_s"] = 1.0
        r["mission"].update(
            kind="decoy", vehicles=4, loop_length_m=3000.0, wind_speed_m_s=5.0,
            duration_s=600.0, intruders=[{"id": "decoy-1", "role": "decoy", "crossing": None}],
        )  # fmt: skip
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps({"args": {}, "wall_s": 10.0, "runs": first}))
    b.write_text(json.dumps({"args": {}, "wall_s": 5.0, "runs": second}))
    both = tmp_path / "both.json"
    assert bench.main(["--combine", f"{b},{a}", "--json", str(both)]) == 0
    doc = json.loads(both.read_text())
    assert [r["seed"] for r in doc["runs"]] == [7, 8] and doc["wall_s"] == 15.0
    unseen = doc["figures"]["decoy episode longest unseen"]
    assert unseen["values"] == [1.2, 1.9, 1.2, 1.9]
    assert unseen["failures"] == ["seed 7 decoy-2", "seed 8 decoy-2"]
    with pytest.raises(SystemExit, match="seed 7 is in more than one file"):
        bench.main(["--combine", f"{a},{a}"])
    junk = tmp_path / "junk.json"
    junk.write_text("[]")
    with pytest.raises(SystemExit, match="not a file written by this bench"):
        bench.main(["--combine", f"{a},{junk}"])
