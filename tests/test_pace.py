"""A firmware fleet's pace (companion/sim/pace.py): the speed factor chosen from the machine's
free cores, the slow-downs when the companions starve, on fake times."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from companion.sim.pace import (
    CORES_PER_AIRCRAFT_X,
    HEADROOM,
    MIN_SPEEDUP,
    SLOW_COOLDOWN_WALL_S,
    SLOW_FACTOR,
    PaceMonitor,
    choose_speedup,
    free_cores,
)


def test_the_speed_factor_follows_the_free_cores_within_its_bounds():
    cost = CORES_PER_AIRCRAFT_X["px4"] * 6
    x, why = choose_speedup(6, "px4", 1.0, default=3.0)
    assert x == max(MIN_SPEEDUP, int(2 * HEADROOM * 1.0 / cost) / 2)
    assert "1.0 of" in why and "6" in why
    assert choose_speedup(6, "px4", 16.0, default=3.0)[0] == 3.0  # never above the default
    assert choose_speedup(6, "px4", 0.1, default=3.0)[0] == MIN_SPEEDUP  # nor below 1x
    assert choose_speedup(3, "arduplane", None, default=5.0) == (5.0, "the machine's load unknown")


def test_free_cores_reads_the_idle_ticks_of_proc_stat(tmp_path):
    stat = tmp_path / "stat"
    stat.write_text("cpu  100 0 100 800 0 0 0 0 0 0\n")

    class Later:  # the second read: 400 more ticks, 100 of them idle
        def __init__(self) -> None:
            self.n = 0

        def read_text(self) -> str:
            self.n += 1
            return (
                "cpu  100 0 100 800 0 0 0 0 0 0\n"
                if self.n == 1
                else ("cpu  250 0 250 900 0 0 0 0 0 0\n")
            )

    free = free_cores(0.0, stat=Later())
    assert free == pytest.approx((os.cpu_count() or 1) * 100 / 400)
    assert free_cores(0.0, stat=tmp_path / "missing") is None


def _stream(mon: PaceMonitor, wall0: float, t0: float, n: int, dt_wall: float, dt_s: float):
    for k in range(n):
        mon.state(wall0 + k * dt_wall, 1, t0 + k * dt_s)


def test_a_companion_that_keeps_up_is_not_slowed():
    mon = PaceMonitor(3.0)
    _stream(mon, 0.0, 0.0, 300, 0.2 / 3, 0.2)  # 5 Hz of vehicle time at 3x
    assert mon.slow_down(20.0) is None and mon.pace == 3.0 and mon.worst_hole is None


def test_a_starving_companion_slows_the_pace_once_per_cool_down():
    mon = PaceMonitor(3.0)
    wall, t = 0.0, 0.0
    for _ in range(4):  # four holes of 1.2 s of vehicle time
        _stream(mon, wall, t, 10, 0.07, 0.2)
        wall, t = wall + 1.0, t + 2.0 + 1.2
    assert mon.worst_hole == (1, pytest.approx(1.4))
    pace = mon.slow_down(wall)
    assert pace == pytest.approx(3.0 * SLOW_FACTOR)
    for _ in range(4):
        _stream(mon, wall, t, 10, 0.07, 0.2)
        wall, t = wall + 1.0, t + 2.0 + 1.2
    assert mon.slow_down(wall) is None  # within the cool-down
    for _ in range(4):
        _stream(mon, wall + SLOW_COOLDOWN_WALL_S, t, 10, 0.07, 0.2)
        wall, t = wall + 1.0, t + 2.0 + 1.2
    assert mon.slow_down(wall + SLOW_COOLDOWN_WALL_S) == pytest.approx(3.0 * SLOW_FACTOR**2)
    assert [p for _, p, _ in mon.slowed] == [pytest.approx(2.1), pytest.approx(1.47)]


def test_the_achieved_rate_is_simulated_seconds_per_wall_second():
    mon = PaceMonitor(3.0)
    for k in range(30):
        mon.truth(100.0 + k * 0.5, 10.0 + k * 1.2)  # 2.4x achieved
    assert mon.achieved() == pytest.approx(2.4)


def test_a_state_heard_far_behind_the_truth_log_is_the_groups_delay():
    mon = PaceMonitor(3.0)
    mon.truth(10.0, 100.0)
    mon.state(10.0, 4, 99.0)  # 1 s behind: within
    assert mon.worst_hole is None
    mon.state(10.1, 4, 99.2)
    mon.truth(10.2, 102.0)
    mon.state(10.2, 4, 99.4)  # 2.6 s behind the world when heard
    assert mon.worst_hole == (4, pytest.approx(2.6)) and mon.worst_lag_s == pytest.approx(2.6)


@pytest.mark.parametrize(
    ("autopilot", "link", "says"),
    [("sitl-model", "relay", "only with --autopilot px4"),
     ("sitl-model", "serial", "only with --autopilot arduplane")],
)  # fmt: skip
def test_a_cable_for_the_wrong_autopilot_is_refused_before_anything_starts(
    tmp_path, capsys, autopilot, link, says
):
    from companion.commands.main import main

    mission = Path(__file__).resolve().parent / "data" / "ellipse_3uav.yaml"
    argv = ["fleet", str(mission), "--autopilot", autopilot, "--companion-link", link]
    assert main([*argv, "--out", str(tmp_path / "run")]) == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
