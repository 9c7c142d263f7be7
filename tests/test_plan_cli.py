"""``companion plan`` as a real subprocess: batch JSON Lines and single-case flags."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from companion.core.wind import Wind
from companion.planner import Aircraft, Goal, Pose, plan_path

ROOT = Path(__file__).resolve().parents[1]

GOOD = {
    "start_north_m": 0, "start_east_m": 0, "start_heading_deg": 0, "goal_north_m": 500,
    "goal_east_m": 300, "airspeed_m_s": 20, "max_turn_rate_deg_s": 15, "wind_speed_m_s": 8,
    "wind_from_deg": 200, "goal_course_deg": 90,
}  # fmt: skip


def run_cli(*args: str, stdin: str = "") -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "companion", "plan", *args],
        input=stdin, capture_output=True, text=True, cwd=ROOT, env=env, timeout=60,
    )  # fmt: skip


def with_(**changes: object) -> str:
    case = {**GOOD, **changes}
    return json.dumps({k: v for k, v in case.items() if v is not None})


def test_batch_mixes_good_and_bad_lines_in_order() -> None:
    lines = [
        json.dumps(GOOD),
        "{not json",
        with_(wind_speed_m_s=25),  # wind >= airspeed
        with_(max_turn_rate_deg_s=0),
        with_(goal_north_m=0, goal_east_m=0),  # goal == start
        with_(colour="red"),
        with_(airspeed_m_s=None),  # missing key
        with_(airspeed_m_s="20"),  # wrong type
        with_(goal_course_deg=None, goal_heading_deg=45.0),
        with_(goal_course_deg=None),  # free final heading
        "[1, 2]",
    ]
    proc = run_cli("--batch", "-", stdin="\n".join(lines) + "\n")
    assert proc.returncode == 0, proc.stderr
    out = [json.loads(x) for x in proc.stdout.splitlines()]
    assert len(out) == len(lines)
    bad = {2: "bad JSON", 3: "below the airspeed", 4: "must be > 0", 5: "equals",
           6: "unknown key 'colour'", 7: "missing key 'airspeed_m_s'",
           8: "airspeed_m_s must be a number", 11: "JSON object"}  # fmt: skip
    for n, answer in enumerate(out, start=1):
        if n in bad:
            assert answer["line"] == n and bad[n] in answer["error"], answer
        else:
            assert set(answer) == {"time_s", "path_type", "segments"}, answer
    first = plan_path(
        Pose(0j, 0.0), Goal(500 + 300j, course_rad=math.radians(90)),
        Aircraft(20.0, math.radians(15)), Wind.from_meteo(8, 200),
    )  # fmt: skip
    assert out[0]["time_s"] == pytest.approx(first.time_s)
    assert out[0]["path_type"] == first.family
    assert [s["duration_s"] for s in out[0]["segments"]] == pytest.approx(
        [s.duration_s for s in first.segments]
    )
    assert {round(abs(s["turn_rate_deg_s"]), 9) for s in out[0]["segments"]} <= {0.0, 15.0}
    assert len(out[9]["path_type"]) <= 2  # free final heading: a two-piece word at most
    assert out[8]["time_s"] > 0


def test_batch_from_file(tmp_path: Path) -> None:
    path = tmp_path / "cases.jsonl"
    path.write_text(json.dumps(GOOD) + "\n" + with_(goal_north_m=-800) + "\n")
    proc = run_cli("--batch", str(path))
    out = [json.loads(x) for x in proc.stdout.splitlines()]
    assert proc.returncode == 0 and len(out) == 2 and all("time_s" in x for x in out)


def flags(case: dict) -> list[str]:
    return [a for k, v in case.items() for a in ("--" + k.replace("_", "-"), str(v))]


def test_single_case_from_flags() -> None:
    proc = run_cli(*flags(GOOD))
    assert proc.returncode == 0, proc.stderr
    answer = json.loads(proc.stdout)
    batch = json.loads(run_cli("--batch", "-", stdin=json.dumps(GOOD)).stdout)
    assert answer == batch


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"airspeed_m_s": "fast"}, "not a number"),
        ({"wind_speed_m_s": 30}, "below the airspeed"),
        ({"goal_north_m": 0, "goal_east_m": 0}, "equals"),
        ({"goal_heading_deg": 10}, "not both"),
    ],
)
def test_bad_flags_exit_2_with_one_line(changes: dict, message: str) -> None:
    proc = run_cli(*flags({**GOOD, **changes}))
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert len(proc.stderr.strip().splitlines()) == 1
    assert message in proc.stderr and "Traceback" not in proc.stderr


def test_missing_flag_exits_2() -> None:
    case = dict(GOOD)
    del case["airspeed_m_s"]
    proc = run_cli(*flags(case))
    assert proc.returncode == 2
    assert "--airspeed-m-s" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
