"""A relieving spare's way in after ArduPlane's own take-off (docs/energy.md, "On real
ArduPlane"): TAKEOFF climbs out along the runway and loiters until the companion asks for
GUIDED, so the spare starts its way in from wherever and heading however the climb-out left
it, not from the runway where it chose its lane point. Flown as a particle on
``tests/data/ellipse_3uav_relief.yaml`` (the ArduPlane relief test's mission): three on
station, spare 10 on a runway 100 m east of the loop taking off south, relieving UAV 1.
Judged by when the duty says it is in the slot (held 3 s within 20 m of it); how deep its
sensor reached over the loop ahead of UAV 1 is measured against 4000 sampled loop points, not
the duty's own geometry, and printed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.duty import Duty
from companion.agent.relief.states import DutyState
from companion.group.messages import Energy, MemberState, Mode
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).resolve().parent / "data" / "ellipse_3uav_relief.yaml")
PATROL, GAINS = MISSION.patrol, MISSION.gains
RUNWAY, RUNWAY_HEADING = 300j, math.pi  # spare 10's, as the mission has it (m, rad: south)
LOOP = PATROL.sample_by_time(4000)
SENSOR_M = MISSION.sensor.footprint_radius_m
DT = 0.1  # the companion's step (s)


def _member_at(sysid: int, t_s: float, phase0: float) -> complex:
    """Members 1, 2, 3 splayed, 1 at ``phase0`` (rad) at 0 s, on the loop at its rate."""
    k = (sysid - 1) * 2.0 * math.pi / 3.0
    return complex(PATROL.point_at_phase(phase0 - k + 2.0 * math.pi * t_s / PATROL.period_s))


def _hear(heard: Neighbours, t_s: float, phase0: float) -> None:
    for s in (1, 2, 3):
        pos = _member_at(s, t_s, phase0)
        leave = 400.0 if s == 1 else 1e5
        st = MemberState(s, t_s, PATROL.centre_m, float(PATROL.phase_of_point(pos)),
                         Mode.PATROL, pos_m=pos,
                         energy=Energy("on_station", 60.0, leave, 0))  # fmt: skip
        heard.hear(st, t_s)


def _ahead_m(a: complex, b: complex) -> float:
    """How far (m of loop, in the sense of travel) point ``a`` is ahead of point ``b``."""
    gap = float(PATROL.phase_of_point(a)) - float(PATROL.phase_of_point(b))
    return math.remainder(gap, 2.0 * math.pi) * PATROL.length_m / (2.0 * math.pi)


def _fly(phase0: float, climb_s: float, loiter_s: float) -> tuple[float, float]:
    """Spare 10 booked for UAV 1 and stepped on its runway until it takes off; its take-off
    flown as TAKEOFF does, deaf to the duty: straight along the runway for ``climb_s``, then
    a loiter circle to the left at its turn rate for ``loiter_s`` (s); then told it climbed
    out and flown on the duty's commands until it is in the slot. (How far m its sensor
    reached over the loop ahead of UAV 1 at worst, 0 if never; launch to slot, s)."""
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    t = 0.0
    while True:
        _hear(heard, t, phase0)
        done = duty.step(Fix(t, RUNWAY, RUNWAY_HEADING, PATROL), heard, GAINS, True)
        if done.step.command == "takeoff":
            break
        t = round(t + DT, 6)
        assert t < 3.0 * PATROL.period_s, "no take-off"
    t0, pos, heading, worst = t, RUNWAY, RUNWAY_HEADING, 0.0

    def fly(turn_rate: float, airspeed: float) -> None:
        nonlocal pos, heading, worst
        heading += turn_rate * DT
        v = airspeed * complex(math.cos(heading), math.sin(heading))
        pos += (v + PATROL.wind.vector) * DT
        over = SENSOR_M - float(np.min(np.abs(LOOP - pos)))
        if over > 0.0 and _ahead_m(_member_at(1, t, phase0), pos) < 0.0:
            worst = max(worst, over)

    while t < t0 + climb_s + loiter_s:  # TAKEOFF: the duty's commands go nowhere
        _hear(heard, t, phase0)
        duty.step(Fix(t, pos, heading, PATROL), heard, GAINS, True)
        fly(0.0 if t < t0 + climb_s else -duty.max_u, PATROL.airspeed_m_s)
        t = round(t + DT, 6)
    duty.climbed_out()
    while duty.state is not DutyState.ON_STATION:
        _hear(heard, t, phase0)
        step = duty.step(Fix(t, pos, heading, PATROL), heard, GAINS, True).step
        fly(step.turn_rate_rad_s, step.airspeed_m_s)
        t = round(t + DT, 6)
        assert t < t0 + 8.0 * PATROL.period_s, "not in the slot"
    return worst, t - t0


@pytest.mark.parametrize("phase0", [0.0, 2.0])
@pytest.mark.parametrize("climb_s", [20.0, 35.0])
@pytest.mark.parametrize("loiter_s", [0.0, 30.0, 45.0])
def test_after_its_climb_out_a_spare_is_in_its_slot_within_3_loop_periods(
    phase0, climb_s, loiter_s
):
    """Wherever ArduPlane's climb-out (20 or 35 s along the runway, then up to 45 s of
    loiter while its companion is slow to see GUIDED) leaves it, the spare is in its slot
    within 3 loop periods (307 s) of its launch. A spare that reached its lane far ahead
    of its slot used to fall back at the phase hold's 2 m/s: in a sweep of 48 such
    climb-outs (6 slot phases x 2 climbs x 4 loiters) up to 410 s, median 268 s. It now
    loses the lead in full turns outward (``FlyIn._hold_turn``): up to 259 s, median 164
    s, none slower. In the fresh-clone CI of 45efd0a such a spare was not in its slot by
    its member's leave time, 258 s after its launch. Printed, not asserted: how deep its
    sensor reached over the loop while it was ahead of UAV 1 (m; docs/energy.md, "Not
    yet")."""
    over, took = _fly(phase0, climb_s, loiter_s)
    print(f"climb {climb_s:.0f} s, loiter {loiter_s:.0f} s: slot {took:.1f} s, over {over:.1f} m")
    assert took < 3.0 * PATROL.period_s
