"""Reliefs on a loop much longer than a spare's flight to it, from an airfield inside it:
the paper's Wright-Patterson loop all day (``missions/wpafb_all_day.yaml``; a period of
25.5 min, spares at the origin; docs/energy.md, "The Wright-Patterson loop all day").

Checked without the module's formulas: inside or outside by counting crossings of a ray
with 20,000 sampled loop points; the plan's figures from the mission's numbers by hand; the
spare's flight as a particle on the duty's commands.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.duty import Duty
from companion.agent.relief.join import inside
from companion.agent.relief.roster import Roster, rotation_note
from companion.agent.relief.states import DutyState
from companion.group.messages import Energy, MemberState, Mode
from companion.mission import load_mission

MISSIONS = Path(__file__).resolve().parents[1] / "missions"
MISSION = load_mission(MISSIONS / "wpafb_all_day.yaml")
PATROL = MISSION.patrol
GAINS = MISSION.gains
LOOP = PATROL.sample_by_time(20000)
SENSOR_M = MISSION.sensor.footprint_radius_m


def _inside_by_ray(p: complex) -> bool:
    """Point in polygon by the crossings of the ray east from ``p`` with the sampled loop."""
    a, b = LOOP, np.roll(LOOP, -1)
    straddles = (a.real > p.real) != (b.real > p.real)
    with np.errstate(divide="ignore", invalid="ignore"):
        east = a.imag + (p.real - a.real) * (b.imag - a.imag) / (b.real - a.real)
    return int(np.count_nonzero(straddles & (east > p.imag))) % 2 == 1


def test_inside_the_loop_as_a_ray_counts_it():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-7000, 7000, 300) + 1j * rng.uniform(-7000, 7000, 300)
    pts = [p for p in pts if float(np.min(np.abs(LOOP - p))) > 5.0]  # not on the line
    assert [inside(p, PATROL) for p in pts] == [_inside_by_ray(p) for p in pts]
    assert inside(0j, PATROL)  # the airfield


def test_from_the_airfield_inside_the_take_over_is_the_capture_not_two_periods():
    """The spares wait inside a loop whose period (1,531 s) is longer than their flight to its
    farthest point (537 s into the wind): the plan gives a relief its transit and 120 s to
    settle, not two periods (51 min, longer than the 40 usable minutes of a battery). The
    ellipse's spares wait outside its loop: two periods there, as before."""
    roster = Roster(MISSION)
    far = float(np.max(np.abs(PATROL.sample_by_time(256))))
    back = far / (PATROL.airspeed_m_s - abs(PATROL.wind.vector))
    assert 500.0 < back < 560.0 and PATROL.period_s > 1500.0
    assert roster.takeover_s(PATROL) == 120.0
    assert roster.relief_lead_s(PATROL) == pytest.approx(30.0 + 120.0 + back, rel=2e-3)
    # the beat keeps 5 % of the battery (120 s) for a higher current, not a 25-minute period
    beat = roster.beat_s(PATROL, MISSION.vehicles.battery)
    assert beat == pytest.approx(
        2400.0 - (30.0 + 120.0 + back) - 120.0 - roster.home_s(PATROL) - 30.0, rel=1e-9
    )
    assert 8.0 < roster.spares_needed(PATROL, MISSION.vehicles.battery, 4) <= 9.0
    assert rotation_note(MISSION, 21600.0) is None  # its nine hold it
    ellipse = load_mission(MISSIONS / "ellipse_relief.yaml")
    assert Roster(ellipse).takeover_s(ellipse.patrol) == 2.0 * ellipse.patrol.period_s


def _along_m(a: complex, b: complex) -> float:
    """How far (m of loop, in the sense of travel) point ``a`` is ahead of point ``b``."""
    gap = float(PATROL.phase_of_point(a)) - float(PATROL.phase_of_point(b))
    return math.remainder(gap, 2.0 * math.pi) * PATROL.length_m / (2.0 * math.pi)


@pytest.mark.parametrize("member_phase", [0.5, 2.5, 4.5])
def test_a_spare_from_the_airfield_takes_off_at_once_and_meets_its_slot_behind_its_member(
    member_phase,
):
    """Spare 10 on the airfield, booked for member 1 with the other three on station (the
    four splayed, flying the loop at its nominal rate), flown as a particle on the duty's
    commands at 10 Hz. It takes off within 2 s of committing (no wait for the slot to come
    round), is in the slot within its transit and the plan's 120 s, and while its sensor
    reaches the loop it is behind member 1 (by less than the spacing less two sensor radii,
    never ahead by 5 m): its pass over a point starts after 1's and merges with no other's."""
    events: list = []
    heard = Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    spacing = 2.0 * math.pi / 4
    roster = Roster(MISSION)

    def member_at(sysid: int, t: float) -> complex:
        phase = member_phase - (sysid - 1) * spacing + 2.0 * math.pi * t / PATROL.period_s
        return complex(PATROL.point_at_phase(phase))

    def hear_all(t: float) -> None:
        for s in (1, 2, 3, 4):
            pos = member_at(s, t)
            leave = 700.0 if s == 1 else 1e5
            e = Energy("on_station", 60.0, leave, 0)
            phase = float(PATROL.phase_of_point(pos))
            heard.hear(MemberState(s, t, PATROL.centre_m, phase, Mode.PATROL, pos_m=pos,
                                   energy=e), t)  # fmt: skip

    pos, heading = 0j, math.radians(230.0)  # on its runway
    t, dt, committed, took_off = 0.0, 0.1, None, None
    worst_behind, worst_ahead = 0.0, 0.0
    while duty.state is not DutyState.ON_STATION and t < 1500.0:
        hear_all(t)
        done = duty.step(Fix(t, pos, heading, PATROL), heard, GAINS, True)
        events.extend(done.events)
        step = done.step
        if committed is None and duty.state is DutyState.RELIEVING:
            committed = t
        if step.command == "takeoff":
            took_off = t
        if took_off is not None:
            heading += step.turn_rate_rad_s * dt
            v = step.airspeed_m_s * complex(math.cos(heading), math.sin(heading))
            pos += (v + PATROL.wind.vector) * dt
            if float(np.min(np.abs(LOOP - pos))) < SENSOR_M:  # its sensor reaches the loop
                behind = _along_m(member_at(1, t), pos)
                worst_behind = max(worst_behind, behind)
                worst_ahead = max(worst_ahead, -behind)
        t = round(t + dt, 6)
    assert duty.state is DutyState.ON_STATION
    assert committed is not None and took_off is not None and took_off - committed <= 2.0
    (ev,) = [e for e in events if e.name == "relief_in_slot"]
    assert ev.reason == "in_slot" and ev.member_sysid == 1
    assert ev.took_s <= roster.back_s(PATROL) + roster.takeover_s(PATROL)
    assert worst_behind < PATROL.length_m / 4 - 2.0 * SENSOR_M
    assert worst_ahead < 5.0


def test_the_all_day_mission_is_case_v_b_evenly_splayed_with_batteries_and_nine_spares():
    """``wpafb_all_day.yaml``: ``wpafb_4uav.yaml``'s loop, wind, airframe and sensor; the four
    start on the loop a quarter of a period apart; nine spares on the airfield (more than
    the companions' 8.2, the loader's ideal rotation needs 7)."""
    paper = load_mission(MISSIONS / "wpafb_4uav.yaml")
    assert (PATROL.period_s, PATROL.length_m) == (paper.patrol.period_s, paper.patrol.length_m)
    assert (MISSION.wind, MISSION.sensor, MISSION.gains) == (paper.wind, paper.sensor, paper.gains)
    v = MISSION.vehicles
    assert (v.sysids, v.airspeed_m_s, v.max_turn_rate_rad_s) == (
        paper.vehicles.sysids,
        paper.vehicles.airspeed_m_s,
        paper.vehicles.max_turn_rate_rad_s,
    )
    starts = [complex(p.north_m, p.east_m) for p in v.initial]
    assert max(float(np.min(np.abs(LOOP - s))) for s in starts) < 10.0
    k = [int(np.argmin(np.abs(LOOP - s))) for s in starts]  # samples equally spaced in time
    quarter = len(LOOP) / 4
    assert [round(((kk - k[0]) % len(LOOP)) / quarter, 2) for kk in k] == [0.0, 1.0, 2.0, 3.0]
    assert len(v.spares) == 9 and all(sp.base_m == 0j for sp in v.spares)
    assert v.opening == "staggered"
