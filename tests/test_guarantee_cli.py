"""``companion guarantee``: what a mission's patrol is sure to see, and the UAVs it takes to
see a faster crossing (companion/commands/guarantee.py).

The paper's ellipse (docs/design.md §3): loop period T = 102.49 s in its 5 m/s wind, six
UAVs, sensor 50 m; so 2 r_s N / T = 100 m x 6 / 102.49 s = 5.85 m/s, and a 10 m/s crossing
needs N >= 10 x 102.49 / 100, i.e. 11.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from companion.commands.main import main

ROOT = Path(__file__).resolve().parents[1]
ELLIPSE = str(ROOT / "missions" / "ellipse_6uav.yaml")


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["guarantee", *argv])
    return status, out.getvalue(), err.getvalue()


def test_it_states_the_promise_and_the_uavs_for_a_speed():
    status, out, _ = run(ELLIPSE, "--speed", "10")
    assert status == 0
    first, promise, needed = out.splitlines()
    assert first.startswith("mission ellipse_6uav: 6 UAVs at 20 m/s on a 1.94 km loop")
    assert promise.startswith("crossings sure to be seen: up to 5.85 m/s with 6 UAVs")
    assert needed.startswith("to see a 10 m/s crossing: 11 UAVs on this loop")


def test_json_and_with_uavs_away():
    status, out, _ = run(ELLIPSE, "--speed", "2", "--away", "1", "--json")
    doc = json.loads(out)
    assert status == 0 and doc["mission"] == "ellipse_6uav" and doc["away"] == 1
    assert [g["away"] for g in doc["guarantees"]] == [0, 1, 2]
    assert abs(doc["guarantees"][0]["sure_m_s"] - 100.0 * 6 / 102.49) < 0.01
    # one away: 1.5 T / (N - 1) + 100 m / 15 m/s <= 100 m / 2 m/s from N - 1 = 4
    assert doc["vehicles_needed"] == 5


def test_a_speed_no_formation_sees_and_bad_input():
    status, out, _ = run(ELLIPSE, "--speed", "40", "--away", "1")
    assert status == 1 and "no formation of up to 1000 UAVs" in out
    status, out, err = run(ELLIPSE, "--speed", "-3")
    assert status == 2 and out == "" and "--speed must be a speed > 0 m/s" in err
