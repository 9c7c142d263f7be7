"""The records of one UAV's part in the reliefs (companion/agent/relief/records.py): each
state's and each stage's data is made by the transition that enters it and dropped by the
one that leaves it; transitions only along the tables of companion/agent/relief/states.py;
anything else raises.

Two tiers: the tables and :class:`Staged` alone (no flight), then a :class:`Duty` stepped on
a fake clock with the other members fed to a real :class:`Neighbours`, checked state by
state against the mission's figures (the base, the turnaround) worked out here.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from companion.agent.fix import Fix
from companion.agent.machine import IllegalTransitionError
from companion.agent.neighbours import Neighbours
from companion.agent.relief.duty import Duty
from companion.agent.relief.records import (
    Captured,
    Committed,
    Crossing,
    Flight,
    FullTurn,
    GoingHome,
    InLane,
    OnStation,
    OutToLane,
    Relieving,
    Riding,
    Spare,
    Staged,
    StraightHome,
    TakingOff,
    ToLane,
    ToLoop,
)
from companion.agent.relief.states import (
    DUTY_TABLE,
    HOME_TABLE,
    RELIEVING_TABLE,
    DutyEvent,
    DutyState,
    DutyStep,
    HomeEvent,
    HomeStage,
    RelievingEvent,
    RelievingStage,
)
from companion.group.messages import Energy, MemberState, Mode
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).resolve().parents[1] / "missions" / "ellipse_relief.yaml")
PATROL = MISSION.patrol
GAINS = MISSION.gains
BASE = 300j  # every spare's launch point in ellipse_relief.yaml (m)
TURNAROUND_S = 1200.0  # its spares' turnaround (s)

# every stage's record, made with its fields (a flight shared where a stage has one)
_F = Flight(0.0, BASE)
RELIEVING_RECORDS = {
    RelievingStage.COMMITTED: lambda: Committed(0.0, True, 0.0),
    RelievingStage.TAKING_OFF: lambda: TakingOff(_F, BASE, None),
    RelievingStage.TO_LANE: lambda: ToLane(_F, 100j),
    RelievingStage.TO_LOOP: lambda: ToLoop(_F),
    RelievingStage.IN_LANE: lambda: InLane(_F),
    RelievingStage.FULL_TURN: lambda: FullTurn(_F, 2.0 * math.pi, 0.0),
    RelievingStage.CAPTURED: lambda: Captured(_F, None),
}
HOME_RECORDS = {
    HomeStage.RIDING: lambda: Riding(100.0, 10),
    HomeStage.CROSSING: lambda: Crossing(100j),
    HomeStage.OUT: lambda: OutToLane(),
    HomeStage.STRAIGHT: lambda: StraightHome(),
}
DUTY_RECORDS = {
    DutyState.ON_STATION: lambda: OnStation(),
    DutyState.SPARE: lambda: Spare(True),
    DutyState.RELIEVING: lambda: Relieving.committed(5, 200.0, Committed(0.0, True, 0.0)),
    DutyState.HOME: lambda: GoingHome.starting(StraightHome()),
}
MACHINES = [
    (DUTY_TABLE, DutyState, DutyEvent, DUTY_RECORDS),
    (RELIEVING_TABLE, RelievingStage, RelievingEvent, RELIEVING_RECORDS),
    (HOME_TABLE, HomeStage, HomeEvent, HOME_RECORDS),
]


# ---- the tables alone -------------------------------------------------------------------
@pytest.mark.parametrize(
    ("table", "states", "events", "records"), MACHINES, ids=["duty", "relieving", "home"]
)
def test_every_row_of_a_table_enters_its_state_with_a_new_record_and_drops_the_old(
    table, states, events, records
):
    for (before, event), after in table.items():
        old = records[before]()
        machine = Staged(table, old)
        assert machine.state is before and machine.record is old
        new = records[after]()
        machine.go(event, new)
        assert machine.state is after and machine.record is new and machine.record is not old


@pytest.mark.parametrize(
    ("table", "states", "events", "records"), MACHINES, ids=["duty", "relieving", "home"]
)
def test_every_pair_the_table_leaves_out_raises_and_keeps_the_record(
    table, states, events, records
):
    illegal = sorted(set(itertools.product(states, events)) - set(table))
    assert illegal  # each machine has events that some state does not take
    for before, event in illegal:
        old = records[before]()
        machine = Staged(table, old)
        with pytest.raises(IllegalTransitionError):
            machine.go(event, records[before]())
        assert machine.state is before and machine.record is old


def test_a_record_of_another_state_is_refused_and_the_state_is_kept():
    on = OnStation()
    machine = Staged(DUTY_TABLE, on)
    with pytest.raises(TypeError):
        machine.go(DutyEvent.RELIEVED, Spare(True))  # relieved leads home, not to a spare
    assert machine.state is DutyState.ON_STATION and machine.record is on
    with pytest.raises(TypeError):
        Relieving.committed(5, 200.0, ToLoop(_F))  # a relief starts committed
    with pytest.raises(TypeError):
        GoingHome.starting(Crossing(100j))  # a way home starts riding or straight


def test_every_relieving_stage_is_reached_from_committed_and_the_capture_lets_go_to_fly_on():
    seen, todo = {RelievingStage.COMMITTED}, [RelievingStage.COMMITTED]
    while todo:
        s = todo.pop()
        for (before, _), after in RELIEVING_TABLE.items():
            if before is s and after not in seen:
                seen.add(after)
                todo.append(after)
    assert seen == set(RelievingStage)
    out = {
        after for (before, _), after in RELIEVING_TABLE.items() if before is RelievingStage.CAPTURED
    }
    assert out == {RelievingStage.TO_LANE, RelievingStage.TO_LOOP}
    assert not [k for k in RELIEVING_TABLE if RELIEVING_TABLE[k] is RelievingStage.COMMITTED]


def test_a_way_home_ends_straight_from_every_stage():
    for start in HomeStage:
        s = start
        for _ in range(len(HomeStage)):
            nxt = [after for (before, _), after in HOME_TABLE.items() if before is s]
            if not nxt:
                break
            s = nxt[-1]
        assert s is HomeStage.STRAIGHT, start


# ---- a duty, state by state ---------------------------------------------------------------
def _state(sysid: int, t_s: float, pos: complex, energy: Energy, mode=Mode.PATROL) -> MemberState:
    phase = float(PATROL.phase_of_point(pos))
    return MemberState(sysid, t_s, PATROL.centre_m, phase, mode, pos_m=pos, energy=energy)


def _loop_point(phase_rad: float) -> complex:
    return complex(PATROL.point_at_phase(phase_rad))


def _member_5(heard: Neighbours, t_s: float) -> None:
    """Member 5 on station, flying the loop from phase 2 rad at its nominal rate, due to
    leave at 200 s (a spare is booked for it at once)."""
    pos = _loop_point(2.0 + 2.0 * math.pi * t_s / PATROL.period_s)
    heard.hear(_state(5, t_s, pos, Energy("on_station", 30.0, 200.0, 0)), t_s)


def _step(duty: Duty, t_s: float, pos: complex, heading: float, heard: Neighbours) -> DutyStep:
    return duty.step(Fix(t_s, pos, heading, PATROL), heard, GAINS, True).step


def test_a_spare_committed_taking_off_turned_back_and_landed_has_each_states_record():
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    spare = duty.record
    assert isinstance(spare, Spare) and spare.grounded and spare.ready_t_s == 0.0
    duty.observe_battery(0.0, 100.0, 0.0, None)
    t = 0.0
    while duty.state is DutyState.SPARE:  # booked at once: committed, still on the ground
        _member_5(heard, t)
        _step(duty, t, BASE, 0.0, heard)
        t = round(t + 0.1, 6)
    rel = duty.record
    assert isinstance(rel, Relieving) and rel.member == 5 and rel.leave_of_member_s == 200.0
    assert rel.stage.state is RelievingStage.COMMITTED and rel.stage.record.grounded
    assert duty.record is not spare and duty.grounded
    while rel.stage.state is RelievingStage.COMMITTED:  # until its member's slot comes round
        _member_5(heard, t)
        step = _step(duty, t, BASE, 0.0, heard)
        t = round(t + 0.1, 6)
    assert step.command == "takeoff" and not duty.grounded
    off = rel.stage.record
    assert isinstance(off, TakingOff) and off.takeoff_pos_m == BASE
    flight = off.flight
    assert flight.launch_t_s == pytest.approx(t - 0.1) and flight.launch_pos_m == BASE
    _member_5(heard, t)
    _step(duty, t, BASE + 50.0, 0.0, heard)  # it moved: airborne, the same flight on
    assert rel.stage.state in (RelievingStage.TO_LANE, RelievingStage.TO_LOOP)
    assert rel.stage.record.flight is flight
    # UAV 12 in member 5's slot says it relieved 5: turned back, straight home
    heard.hear(_state(12, t, _loop_point(2.0), Energy("on_station", 100.0, 3000.0, 5)), t)
    _step(duty, t + 0.1, BASE + 50.0, 0.0, heard)
    home = duty.record
    assert isinstance(home, GoingHome) and home.stage.state is HomeStage.STRAIGHT
    assert duty.member is None
    _step(duty, t + 1.0, BASE + 10.0, 0.0, heard)  # within 40 m of its base: it lands
    landed = duty.record
    assert isinstance(landed, Spare) and landed.grounded and not landed.uncharged
    assert landed.ready_t_s == pytest.approx(t + 1.0 + TURNAROUND_S, abs=3.0)


def test_a_committed_spare_that_stands_down_is_a_spare_again_with_what_it_was():
    duty, heard = Duty(11, MISSION), Neighbours(11, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    t = 0.0
    while duty.state is DutyState.SPARE:
        _member_5(heard, t)
        _step(duty, t, BASE, 0.0, heard)
        t = round(t + 0.1, 6)
    committed = duty.record.stage.record
    assert isinstance(committed, Committed) and committed.since_t_s == pytest.approx(t - 0.1)
    heard.hear(_state(10, t, BASE, Energy("relieving", 100.0, None, 5), Mode.SPARE), t)
    step = _step(duty, t, BASE, 0.0, heard)  # spare 10 flies in for 5 too: 11 gives it up
    again = duty.record
    assert isinstance(again, Spare) and again.grounded and again.ready_t_s == 0.0
    assert step.hold and duty.member is None and duty.energy() == Energy("spare", 100.0, 0.0, 0)


def test_relieved_by_a_spare_it_rides_the_loop_until_its_leave_time_and_the_stint_is_dropped():
    duty, heard = Duty(3, MISSION), Neighbours(3, 3.0)
    first = duty.record
    assert isinstance(first, OnStation) and first.leave_t_s is None and first.relieved is None
    duty.observe_battery(0.0, 100.0, 0.0, 12.0)  # full: its leave time far off
    pos = _loop_point(1.0)
    _step(duty, 10.0, pos, 0.0, heard)
    leave = duty.leave_t_s
    assert leave is not None and first.leave_t_s == leave and leave > 1000.0
    heard.hear(_state(10, 11.0, BASE, Energy("relieving", 99.0, None, 3), Mode.SPARE), 11.0)
    _step(duty, 11.0, pos, 0.0, heard)
    assert first.relievers == {10}  # heard flying in for it, this stint
    heard.hear(_state(10, 12.0, pos, Energy("on_station", 98.0, 5000.0, 3)), 12.0)
    step = _step(duty, 12.0, pos, 0.0, heard)
    home = duty.record
    assert step.off_station and isinstance(home, GoingHome)
    riding = home.stage.record
    assert isinstance(riding, Riding) and riding.behind == 10
    assert riding.until_s == first.leave_t_s == pytest.approx(leave, abs=5.0)  # its last one
    assert duty.leave_t_s is None and duty.member is None  # its stint's data went with it


def test_a_relief_in_its_slot_is_on_station_with_a_new_record_naming_whom_it_relieved():
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    t, pos = 0.0, BASE
    while duty.state is not DutyState.RELIEVING or duty.grounded:  # until it takes off
        _member_5(heard, t)
        _step(duty, t, BASE, 0.0, heard)
        t = round(t + 0.1, 6)
    while duty.state is DutyState.RELIEVING and t < 120.0:  # then in member 5's slot
        ph = 2.0 + 2.0 * math.pi * t / PATROL.period_s
        _member_5(heard, t)
        pos = _loop_point(ph) + 1.0
        _step(duty, t, pos, float(PATROL.course_at_phase(ph)), heard)
        t = round(t + 0.1, 6)
    on = duty.record
    assert isinstance(on, OnStation) and on.relieved == 5 and duty.member == 5
    assert on.in_slot_t_s == pytest.approx(t - 0.1) and on.leave_t_s is None
    assert on.opening_steps == 0 and on.late_said == set() and on.relievers == set()
    # the rotation: 5's leave time + a beat (1964.6 s, by hand in tests/test_relief_duty.py)
    assert on.beat_t_s == pytest.approx(200.0 + 1964.6, abs=1.0)


def _members(heard: Neighbours, t_s: float) -> None:
    """The six members splayed, flying the loop at its nominal rate, member 5 at phase 2 rad
    at 0 s and due to leave at 200 s, the others much later."""
    for k, s in enumerate((5, 1, 2, 3, 4, 6)):
        phase = 2.0 - k * 2.0 * math.pi / 6 + 2.0 * math.pi * t_s / PATROL.period_s
        leave = 200.0 if s == 5 else 1e5
        heard.hear(_state(s, t_s, _loop_point(phase), Energy("on_station", 60.0, leave, 0)), t_s)


def _lane_far_ahead(duty: Duty, t: float) -> tuple[complex, float]:
    """Put spare 10 (just taken off) in its lane 1100 m of loop ahead of where it turns in
    behind member 5 at ``t`` (s): where a full turn pays; its position and heading."""
    phase = 2.0 + 2.0 * math.pi * t / PATROL.period_s
    phase += 2.0 * math.pi * (duty.meet_behind_m + 1100.0) / PATROL.length_m
    near = PATROL.nearest(_loop_point(phase))
    normal = complex(math.cos(near.course_rad), math.sin(near.course_rad)) * 1j
    if abs(near.point_m + normal - PATROL.centre_m) < abs(near.point_m - PATROL.centre_m):
        normal = -normal
    rel = duty.record
    flight = rel.stage.record.flight
    rel.go(RelievingEvent.NO_AIM, ToLoop(flight))  # airborne with no lane point kept,
    rel.go(RelievingEvent.REACH_LANE, InLane(flight))  # then in its lane
    flight.laned = True
    return near.point_m + duty.lane_m * normal, near.course_rad


def test_a_full_turn_in_the_lane_has_its_record_while_it_turns_and_none_after():
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    t = 0.0
    while duty.state is not DutyState.RELIEVING or duty.grounded:
        _member_5(heard, t)
        _step(duty, t, BASE, 0.0, heard)
        t = round(t + 0.1, 6)
    pos, heading = _lane_far_ahead(duty, t)  # the others heard from now on
    rel = duty.record
    stages, records, start = [], [], None
    while len(stages) < 2:
        _members(heard, t)
        step = _step(duty, t, pos, heading, heard)
        s = rel.stage.state
        if s is not (stages[-1] if stages else RelievingStage.IN_LANE):
            stages.append(s)
            records.append(rel.stage.record)
        if s is RelievingStage.FULL_TURN and start is None:  # as it starts: all of it left
            start = (rel.stage.record.left_rad, rel.stage.record.heading_rad, heading)
        heading += step.turn_rate_rad_s * 0.1
        v = step.airspeed_m_s * complex(math.cos(heading), math.sin(heading))
        pos += (v + PATROL.wind.vector) * 0.1
        t = round(t + 0.1, 6)
        assert t < 200.0, stages
    assert stages == [RelievingStage.FULL_TURN, RelievingStage.IN_LANE]
    full, after = records
    assert isinstance(full, FullTurn) and isinstance(after, InLane)
    assert start is not None and start[0] == 2.0 * math.pi and start[1] == start[2]
    # the turn counted in its record: its heading came round by 2 pi, to within a step's turn
    turned = abs(full.heading_rad - start[1])
    assert 2.0 * math.pi <= turned < 2.0 * math.pi + duty.max_u * 0.1 + 1e-9
    assert full.left_rad <= 0.0
    assert after.flight is full.flight and after.flight.turn_sign == 0.0
