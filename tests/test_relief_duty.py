"""One UAV's part in the reliefs (companion/agent/relief/duty.py) on a fake clock, and the
states the plan refuses (companion/agent/relief/roster.py; docs/energy.md, "Reliefs").

The clock is the ``t_s`` each call is given: the tests step it by hand. The other members
are :class:`MemberState` records fed to a real :class:`Neighbours`, as the group delivers
them. The expected figures are computed here from the mission's numbers (the leave time by
hand from the charge, the current and the flight home worked out point by point), not with
the duty's own helpers.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.duty import (
    IN_SLOT_S,
    LAUNCH_TIMEOUT_S,
    READY_PCT,
    Duty,
)
from companion.agent.relief.records import InLane, ToLoop
from companion.agent.relief.roster import NOT_IN_MISSION, Roster, rotation_note, run_notes
from companion.agent.relief.states import DutyState, DutyStep, RelievingEvent
from companion.core.wind import groundspeed_from_course, heading_from_course
from companion.group.messages import Energy, MemberState, Mode
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).resolve().parents[1] / "missions" / "ellipse_relief.yaml")
PATROL = MISSION.patrol
GAINS = MISSION.gains
BASE = 300j  # every spare's launch point in ellipse_relief.yaml (m)
CAPACITY_MAH, RESERVE_MAH = 10000.0, 2000.0  # 20 % of 10 Ah
CRUISE_A = 10.0 * 60.0 / 50.0  # 10 Ah in 50 min: 12 A
TURNAROUND_S = 1200.0


class Log:
    """Records the duty's events, as the Agent logs them: each step's, in order."""

    def __init__(self) -> None:
        self.events: list = []

    def names(self) -> list[str]:
        return [e.name for e in self.events]


def _step(
    duty: Duty,
    log: Log | None,
    t_s: float,
    pos: complex,
    heading: float,
    heard: Neighbours,
    can_leave: bool = True,
) -> DutyStep:
    """One step of ``duty`` at ``t_s`` (s), ``pos`` (m), ``heading`` (rad) on the mission's
    loop, its events appended to ``log`` (None: not kept) right after the call."""
    done = duty.step(Fix(t_s, pos, heading, PATROL), heard, GAINS, can_leave)
    if log is not None:
        log.events.extend(done.events)
    return done.step


def _state(sysid: int, t_s: float, pos: complex, energy: Energy, mode=Mode.PATROL) -> MemberState:
    phase = float(PATROL.phase_of_point(pos))
    return MemberState(sysid, t_s, PATROL.centre_m, phase, mode, pos_m=pos, energy=energy)


def _home_by_hand() -> float:
    """The longest flight from the loop to the base (s), point by point (256 points), at
    the ground speed of the course straight to the base in the mission's wind."""
    pts = PATROL.sample_by_time(256)
    d = BASE - pts
    gs = groundspeed_from_course(PATROL.airspeed_m_s, np.arctan2(d.imag, d.real), PATROL.wind)
    return float(np.max(np.abs(d) / gs))


def _loop_point(phase_rad: float) -> complex:
    return complex(PATROL.point_at_phase(phase_rad))


# ---- on station -------------------------------------------------------------------------
def test_on_station_it_shares_the_hand_computed_leave_time_and_leaves_when_it_comes():
    log, heard = Log(), Neighbours(3, 3.0)
    duty = Duty(3, MISSION)
    assert duty.enabled and duty.state is DutyState.ON_STATION and not duty.off_station
    consumed = 7000.0  # 1000 mAh to the reserve at 12 A (3.333 mAh/s): 300 s
    duty.observe_battery(100.0, 30.0, consumed, None)  # no current yet: the mission's
    pos = _loop_point(0.0)
    step = _step(duty, log, 100.0, pos, 0.0, heard, can_leave=True)
    assert not step.off_station
    expected = 100.0 + (CAPACITY_MAH - RESERVE_MAH - consumed) / (CRUISE_A / 3.6)
    expected -= _home_by_hand() + 30.0
    e = duty.energy()
    assert e.role == "on_station" and e.battery_pct == 30.0
    assert e.t_s == pytest.approx(expected, abs=0.5)  # 64 loop points against 256
    # no spare anywhere: its relief is late, said once, before the leave time
    late = [ev for ev in log.events if ev.name == "relief_late"]
    assert len(late) == 1 and late[0].spare_sysid == 0 and late[0].t_s < e.t_s
    leave = e.t_s
    t = 101.0
    while t < leave - 0.5:  # on station up to its leave time, its battery draining at 12 A
        duty.observe_battery(t, None, consumed + (t - 100.0) * CRUISE_A / 3.6, None)
        assert not _step(duty, log, t, pos, 0.0, heard, True).off_station
        assert duty.energy().t_s == pytest.approx(leave, abs=1e-3)
        t += 10.0
    assert log.names().count("relief_late") == 1
    duty.observe_battery(leave + 0.1, None, consumed + (leave - 99.9) * CRUISE_A / 3.6, None)
    step = _step(duty, log, leave + 0.1, pos, 0.0, heard, True)
    assert step.off_station and duty.state is DutyState.HOME
    (gone,) = [ev for ev in log.events if ev.name == "relieved"]
    assert (gone.spare_sysid, gone.reason) == (0, "leave_time")
    assert duty.energy().role == "home"


def _beat_by_hand() -> float:
    """The rotation's beat (s), from the mission's figures: 40 min usable, less the plan's
    30 s lead, 2 + 1 loop periods, the slowest transit from the base to the loop's farthest
    point (256 points, at 20 - 5 m/s), the flight home and the 30 s landing margin."""
    far = float(np.max(np.abs(PATROL.sample_by_time(256) - BASE)))
    back = far / (PATROL.airspeed_m_s - abs(PATROL.wind.vector))
    return 2400.0 - 30.0 - 3.0 * PATROL.period_s - back - _home_by_hand() - 30.0


def test_the_spares_the_rotation_keeps_busy_and_the_note_when_a_mission_has_fewer():
    """Little's law by hand: each of the 6 slots comes due once a beat, and each relief keeps
    an airframe off station for the plan's lead (30 s, two loop periods, the transit), the
    flight home, the 30 s landing margin and the 20-minute turnaround: 4.68 on the ellipse
    (docs/energy.md). Its 4 spares get the note for a two-hour run, 5 do not, nor does a run
    no longer than one battery (40 min usable)."""
    far = float(np.max(np.abs(PATROL.sample_by_time(256) - BASE)))
    back = far / (PATROL.airspeed_m_s - abs(PATROL.wind.vector))
    off = 30.0 + 2.0 * PATROL.period_s + back + _home_by_hand() + 30.0 + TURNAROUND_S
    need = Roster(MISSION).spares_needed(PATROL, MISSION.vehicles.battery, 6)
    assert need == pytest.approx(6.0 * off / _beat_by_hand(), rel=2e-3)  # 64 points vs 256
    assert 4.6 < need < 4.8
    note = rotation_note(MISSION, 7200.0)
    assert note is not None and "4 spares for 6 on station" in note and "4.68" in note
    assert "5 hold it" in note
    v = MISSION.vehicles
    five = replace(MISSION, vehicles=replace(v, spares=v.spares + v.spares[:1]))
    assert rotation_note(five, 7200.0) is None
    assert rotation_note(MISSION, 2400.0) is None
    assert [n for n in run_notes(MISSION, 7200.0, True) if "4.68" in n] == [note]


def test_a_loop_too_long_for_the_batteries_beat_is_said_so():
    """A battery of three loop periods (usable): the plan books a relief two periods and more
    ahead and keeps a slack for the beat, so no beat is left and the note says why."""
    v = MISSION.vehicles
    short = replace(v.battery, endurance_min=PATROL.period_s * 3.0 / 0.8 / 60.0)
    m = replace(MISSION, vehicles=replace(v, battery=short))
    assert Roster(m).beat_s(PATROL, short) is None
    assert Roster(m).spares_needed(PATROL, short, 6) is None
    note = rotation_note(m, 7200.0)
    assert note is not None and "the rotation has no beat" in note


def test_a_staggered_opening_spaces_a_full_fleets_first_leave_times_one_beat_over_n():
    """Six UAVs full at 100 s: with ``opening: staggered`` the last in sysids order leaves
    when its battery says and each one before it one beat / 6 earlier; a UAV whose battery
    is nearly spent is not sent off before a spare booked now could be in its slot."""
    mission = replace(MISSION, vehicles=replace(MISSION.vehicles, opening="staggered"))
    battery = 100.0 + (CAPACITY_MAH - RESERVE_MAH) / (CRUISE_A / 3.6) - _home_by_hand() - 30.0
    beat = _beat_by_hand()
    assert beat == pytest.approx(1964.6, abs=1.0)  # docs/energy.md's figure
    leaves = []
    for sysid in MISSION.vehicles.sysids:
        duty = Duty(sysid, mission)
        duty.observe_battery(100.0, 100.0, 0.0, None)
        _step(duty, None, 100.0, _loop_point(0.0), 0.0, Neighbours(sysid, 3.0), True)
        leaves.append(duty.energy().t_s)
    expected = [battery - (5 - k) * beat / 6.0 for k in range(6)]
    assert leaves == pytest.approx(expected, abs=1.0)  # 64 loop points against 256
    # the default opening: every one as its battery says
    plain = Duty(1, MISSION)
    plain.observe_battery(100.0, 100.0, 0.0, None)
    _step(plain, None, 100.0, _loop_point(0.0), 0.0, Neighbours(1, 3.0), True)
    assert plain.energy().t_s == pytest.approx(battery, abs=1.0)
    # UAV 1 (five beats / 6 early) with 600 s of battery left: not before its relief's lead
    low = Duty(1, mission)
    consumed = CAPACITY_MAH - RESERVE_MAH - 600.0 * CRUISE_A / 3.6
    low.observe_battery(100.0, 30.0, consumed, None)
    _step(low, None, 100.0, _loop_point(0.0), 0.0, Neighbours(1, 3.0), True)
    far = float(np.max(np.abs(PATROL.sample_by_time(256) - BASE)))
    lead = 30.0 + 2.0 * PATROL.period_s + far / (PATROL.airspeed_m_s - abs(PATROL.wind.vector))
    assert low.energy().t_s == pytest.approx(100.0 + lead, abs=1.0)
    assert low.energy().t_s < 100.0 + 600.0 - _home_by_hand() - 30.0  # sooner than its battery


def _drain(duty: Duty, t_s: float, consumed0_mah: float = 7500.0) -> None:
    """The battery at ``t_s`` (s): ``consumed0_mah`` at 0 s, drawn at 12 A since."""
    duty.observe_battery(t_s, None, consumed0_mah + t_s * CRUISE_A / 3.6, CRUISE_A)


def test_away_on_an_alert_it_does_not_leave_even_past_its_leave_time():
    duty = Duty(3, MISSION)
    _drain(duty, 0.0)
    heard = Neighbours(3, 3.0)
    _step(duty, None, 0.0, _loop_point(0.0), 0.0, heard, can_leave=False)
    leave = duty.energy().t_s
    assert leave < 200.0
    for t in (leave + 1.0, leave + 60.0):
        _drain(duty, t)
        step = _step(duty, None, t, _loop_point(0.0), 0.0, heard, can_leave=False)
        assert not step.off_station and duty.state is DutyState.ON_STATION
    _drain(duty, leave + 61.0)
    assert _step(duty, None, leave + 61.0, _loop_point(0.0), 0.0, heard, True).off_station


def test_relieved_only_by_a_uav_it_heard_flying_in_for_it_and_then_on_patrol_in_its_slot():
    log, heard = Log(), Neighbours(3, 3.0)
    duty = Duty(3, MISSION)
    duty.observe_battery(0.0, 100.0, 0.0, 12.0)  # full: no need to leave for long
    pos = _loop_point(1.0)
    # 11 claims it has relieved 3 without ever having flown in for it: not believed
    heard.hear(_state(11, 10.0, pos, Energy("on_station", 95.0, 5000.0, 3)), 10.0)
    assert not _step(duty, log, 10.0, pos, 0.0, heard, True).off_station
    # 10 flies in for it, then shares it holds the slot on patrol: relieved
    heard.hear(_state(10, 11.0, BASE, Energy("relieving", 99.0, None, 3), Mode.SPARE), 11.0)
    assert not _step(duty, log, 11.0, pos, 0.0, heard, True).off_station
    heard.hear(_state(10, 12.0, pos, Energy("on_station", 98.0, 5000.0, 3)), 12.0)
    step = _step(duty, log, 12.0, pos, 0.0, heard, True)
    assert step.off_station and duty.state is DutyState.HOME
    (gone,) = [ev for ev in log.events if ev.name == "relieved"]
    assert (gone.spare_sysid, gone.reason) == (10, "relieved") and gone.margin_s > 0


# ---- home -------------------------------------------------------------------------------
def _home_duty(log: Log) -> tuple[Duty, Neighbours]:
    duty, heard = Duty(3, MISSION), Neighbours(3, 3.0)
    _drain(duty, 0.0)
    _step(duty, log, 0.0, _loop_point(0.0), 0.0, heard, True)
    leave = duty.energy().t_s
    _drain(duty, leave + 1.0)
    _step(duty, log, leave + 1.0, _loop_point(0.0), 0.0, heard, True)
    assert duty.state is DutyState.HOME
    return duty, heard


def test_flying_home_it_turns_towards_the_base_and_lands_within_40_m_of_it():
    log = Log()
    duty, heard = _home_duty(log)
    # 200 m north of the base, heading north (away): it turns; heading south (at it): straight
    far = BASE + 200.0
    away = _step(duty, log, 500.0, far, 0.0, heard, True)
    at = _step(duty, log, 500.1, far, math.pi, heard, True)
    assert away.off_station and abs(away.turn_rate_rad_s) == pytest.approx(
        MISSION.vehicles.max_turn_rate_rad_s
    )
    assert abs(at.turn_rate_rad_s) < 0.05 and at.command is None and not at.hold
    assert duty.state is DutyState.HOME
    land = _step(duty, log, 510.0, BASE + 39.0, math.pi, heard, True)
    assert land.command == "land" and land.hold and duty.state is DutyState.SPARE
    e = duty.energy()
    assert e.role == "spare" and e.t_s == pytest.approx(510.0 + TURNAROUND_S, abs=3.0)
    (landed,) = [ev for ev in log.events if ev.name == "relief_landed"]
    assert landed.ready_t_s == pytest.approx(e.t_s, abs=0.1)
    # on the ground until it is ready: no setpoint
    assert _step(duty, log, 600.0, BASE + 39.0, 0.0, heard, True).hold


def _passes(covered: np.ndarray) -> list[list[tuple[int, int]]]:
    """Per loop point (columns of ``covered``, samples x points), its passes as (first, last)
    sample index: maximal runs of covered samples."""
    out = []
    for col in covered.T:
        edges = np.diff(np.concatenate([[0], col.astype(int), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        out.append(list(zip(starts, ends, strict=True)))
    return out


@pytest.mark.parametrize("margin_s", [None, 70.0])
@pytest.mark.parametrize("phase0", [0.0, 1.0, 2.0, 3.0, 4.0, 4.6, 5.2, 5.8])
def test_relieved_it_leaves_no_pass_that_starts_a_point_early(phase0, margin_s):
    """UAV 3, relieved by 10 in its slot at ``phase0`` (rad), ``margin_s`` (s; None: a full
    battery) before its leave time, flown as a particle on the duty's commands at 10 Hz
    until it lands, with its relief and the other four members splayed (all flying the loop
    at its nominal rate). At every loop point (400, about 5 m apart), sensor radius 50 m: no
    pass of 3 begins before a member's pass there and runs into it (which would start that
    pass early, as the start-to-start revisit counts it)."""
    log, heard = Log(), Neighbours(3, 3.0)
    duty = Duty(3, MISSION)
    consumed0 = 0.0
    if margin_s is not None:  # the leave time by hand: margin_s from now
        flight_s = margin_s + _home_by_hand() + 30.0
        consumed0 = CAPACITY_MAH - RESERVE_MAH - flight_s * CRUISE_A / 3.6
    sensor = MISSION.sensor.footprint_radius_m
    n = MISSION.vehicles.count

    def at(t: float, behind: int = 0) -> complex:
        return _loop_point(phase0 + 2.0 * math.pi * (t / PATROL.period_s - behind / n))

    def hear(t: float, role: str) -> None:
        mode = Mode.SPARE if role == "relieving" else Mode.PATROL
        heard.hear(_state(10, t, at(t), Energy(role, 98.0, 5000.0, 3), mode), t)
        for k, sysid in enumerate((2, 1, 6, 5, 4), start=1):
            heard.hear(_state(sysid, t, at(t, k), Energy("on_station", 60.0, 5000.0, 0)), t)

    pos = at(0.0)
    course = float(PATROL.course_at_phase(phase0))
    heading = float(heading_from_course(PATROL.airspeed_m_s, course, PATROL.wind))
    duty.observe_battery(0.0, None, consumed0, CRUISE_A)
    hear(0.0, "relieving")
    _step(duty, log, 0.0, pos, heading, heard, True)
    t, dt, track = 0.1, 0.1, []
    while duty.state is DutyState.HOME or not track:
        hear(t, "on_station")
        duty.observe_battery(t, None, consumed0 + t * CRUISE_A / 3.6, CRUISE_A)
        step = _step(duty, log, t, pos, heading, heard, True)
        if duty.state is not DutyState.HOME:
            break
        track.append([pos] + [at(t, k) for k in range(n)])
        heading += step.turn_rate_rad_s * dt
        pos += (step.airspeed_m_s * complex(math.cos(heading), math.sin(heading))
                + PATROL.wind.vector) * dt  # fmt: skip
        t = round(t + dt, 6)
        assert t < 600.0, "it never got home"
    (gone,) = [ev for ev in log.events if ev.name == "relieved"]
    assert gone.spare_sysid == 10
    if margin_s is not None:
        assert gone.margin_s == pytest.approx(margin_s - 0.1, abs=1.0)
    pts = PATROL.sample_by_time(400)  # about 5 m apart
    xyz = np.array(track)  # samples x (3, then its relief and the others)
    seen = [np.abs(xyz[:, k, None] - pts[None, :]) <= sensor for k in range(n + 1)]
    mine, *members = (_passes(c) for c in seen)
    early = 0
    for p in range(len(pts)):
        theirs = [ab for m in members for ab in m[p]]
        for a, b in mine[p]:
            if any(a <= d + 1 and c <= b + 1 and a < c for c, d in theirs):  # runs into it
                early += 1
    print(f"phase {phase0} margin {margin_s}: home after {t:.1f} s, early passes {early}")
    assert early == 0
    assert len(log.events) >= 2 and log.events[-1].name == "relief_landed"


# ---- a spare ----------------------------------------------------------------------------
def _tired_member(
    heard: Neighbours, t_s: float, leave_t_s: float, sysid: int = 5, moving: bool = False
) -> complex:
    """A member on station heard at ``t_s`` (s): at phase 2 rad, or (``moving``) flying the
    loop from there at its nominal rate."""
    phase = 2.0 + (2.0 * math.pi * t_s / PATROL.period_s if moving else 0.0)
    pos = _loop_point(phase)
    heard.hear(_state(sysid, t_s, pos, Energy("on_station", 30.0, leave_t_s, 0)), t_s)
    return pos


def _phase_short_of_base(pos: complex) -> float:
    """How far (rad of time-phase) a point of the loop is short of the loop point nearest the
    base, in the sense of travel, found from 4096 points."""
    pts = PATROL.sample_by_time(4096)
    k = int(np.argmin(np.abs(pts - BASE)))
    base_phase = 2.0 * math.pi * k / 4096
    return (base_phase - float(PATROL.phase_of_point(pos))) % (2.0 * math.pi)


def _launch_t_s(t_s: float, leave_t_s: float) -> float:
    """When spare 10 at the base is booked to launch for a member leaving at ``leave_t_s``:
    its transit to the loop's farthest point at airspeed - wind, the take-over (2 T) and the
    lead (30 s) before the leave time (docs/energy.md, "Who relieves whom")."""
    pts = PATROL.sample_by_time(4096)
    transit = float(np.max(np.abs(pts - BASE))) / (PATROL.airspeed_m_s - abs(PATROL.wind.vector))
    return max(t_s, leave_t_s - 30.0 - 2.0 * PATROL.period_s - transit)


def test_a_spare_waits_on_the_ground_until_its_launch_falls_due_then_takes_off():
    log, heard = Log(), Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    assert duty.state is DutyState.SPARE and duty.grounded and duty.off_station
    duty.observe_battery(0.0, 100.0, 0.0, None)
    leave = 2000.0
    launch = _launch_t_s(0.0, leave)
    assert 1000.0 < launch < leave
    t = 0.0
    while t < launch - 2.0:  # every 10 s: holds, shares it is a spare ready now
        _tired_member(heard, t, leave)
        step = _step(duty, log, t, BASE, 0.0, heard, True)
        assert step.hold and step.command is None and duty.energy().role == "spare"
        t += 10.0
    committed = None
    for t in np.arange(launch - 2.0, launch + 1.3 * PATROL.period_s, 0.1):  # 10 Hz
        pos = _tired_member(heard, float(t), leave, moving=True)
        step = _step(duty, log, float(t), BASE, 0.0, heard, True)
        if committed is None and duty.state is DutyState.RELIEVING:
            committed = float(t)  # it shares "relieving" from its launch time: booked
            assert duty.energy() == Energy("relieving", 100.0, None, 5)
        if step.command == "takeoff":
            break
        assert step.hold  # on the ground until its member's slot comes round
    assert committed == pytest.approx(launch, abs=1.1)
    # it takes off as its member's slot comes up to the base, not wherever the slot is: the
    # slot is then less than a third of the loop short of the loop point nearest the base
    # (its turn about from the runway's heading, the wind drifting it, and its lane reached
    # two turn radii of flight early)
    assert step.command == "takeoff" and committed <= float(t) <= committed + 1.2 * PATROL.period_s
    assert 0.0 < _phase_short_of_base(pos) < 2.0 * math.pi / 3.0
    assert duty.state is DutyState.RELIEVING
    (ev,) = [e for e in log.events if e.name == "relief_launched"]
    assert ev.member_sysid == 5 and ev.leave_t_s == leave


def test_a_spare_not_charged_enough_does_not_launch():
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    duty.observe_battery(0.0, READY_PCT - 1.0, 1100.0, None)
    for t in np.arange(0.0, 4.0, 0.5):  # due at once, within the 5 s before it is passed over
        _tired_member(heard, float(t), 200.0)
        assert _step(duty, None, float(t), BASE, 0.0, heard, True).command is None
    assert duty.state is DutyState.SPARE
    duty.observe_battery(4.0, READY_PCT, 1000.0, None)
    _tired_member(heard, 4.0, 200.0)
    _step(duty, None, 4.0, BASE, 0.0, heard, True)
    assert duty.state is DutyState.RELIEVING


def test_a_spare_still_short_of_charge_past_its_ready_time_is_unavailable_and_says_so():
    # a spare whose battery was not swapped, or drained waiting: past its ready time (+ the
    # 5 s a swap's report may lag) it shares "unavailable", so no plan books it, and says so
    # once; charged again, it is a spare that can be booked
    log, heard = Log(), Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    duty.observe_battery(0.0, READY_PCT - 3.0, 1300.0, None)
    for t in np.arange(0.0, 8.0, 0.5):
        _tired_member(heard, float(t), 5000.0)
        _step(duty, log, float(t), BASE, 0.0, heard, True)
        assert duty.energy().role == ("spare" if t < 5.0 else "unavailable"), t
    assert duty.state is DutyState.SPARE
    (ev,) = [e for e in log.events if e.name == "spare_uncharged"]
    assert (ev.t_s, ev.battery_pct, ev.need_pct) == (5.0, READY_PCT - 3.0, READY_PCT)
    heard.hear(_state(10, 8.0, BASE, duty.energy()), 8.0)  # as the group carries its own
    _tired_member(heard, 8.0, 5000.0)
    _step(duty, log, 8.0, BASE, 0.0, heard, True)
    assert duty.plan.of_member(5).spare is None  # nobody to book
    duty.observe_battery(9.0, 100.0, 0.0, None)  # swapped
    heard.hear(_state(10, 9.0, BASE, Energy("spare", 100.0, 0.0, 0)), 9.0)
    _step(duty, log, 9.0, BASE, 0.0, heard, True)
    assert duty.energy().role == "spare" and duty.plan.of_member(5).spare == 10
    assert log.names().count("spare_uncharged") == 1


def _launched(log: Log) -> tuple[Duty, Neighbours, float]:
    """Spare 10 booked at once for member 5, stepped at 10 Hz until it takes off; the time."""
    duty, heard = Duty(10, MISSION), Neighbours(10, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    for t in np.arange(0.0, 1.3 * PATROL.period_s, 0.1):
        _tired_member(heard, float(t), 200.0, moving=True)
        if _step(duty, log, float(t), BASE, 0.0, heard, True).command == "takeoff":
            return duty, heard, float(t)
    raise AssertionError("no take-off")


def _committed(sysid: int, log: Log) -> tuple[Duty, Neighbours, float]:
    """Spare ``sysid`` booked at once for member 5 (leaving at 200 s), stepped at 10 Hz until
    it commits (shares ``relieving``), still on the ground; the time."""
    duty, heard = Duty(sysid, MISSION), Neighbours(sysid, 3.0)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    for t in np.arange(0.0, 10.0, 0.1):
        _tired_member(heard, float(t), 200.0)
        step = _step(duty, log, float(t), BASE, 0.0, heard, True)
        if duty.state is DutyState.RELIEVING:
            assert step.hold and step.command is None  # waiting for the slot, on the ground
            return duty, heard, float(t)
    raise AssertionError("not committed")


def test_of_two_spares_committed_to_one_member_the_higher_sysid_stands_down():
    """Two spares that planned from states a moment apart can both find themselves booked
    for member 5 (seen over UDP: both flew in, one relief was missed). Each hears the other
    within a state period: spare 11 gives it up to spare 10 and is a spare again, on the
    ground; spare 10, hearing 11 too, keeps it."""
    log = Log()
    eleven, heard, t = _committed(11, log)
    heard.hear(_state(10, t, BASE, Energy("relieving", 100.0, None, 5)), t)
    step = _step(eleven, log, t + 0.1, BASE, 0.0, heard, True)
    assert eleven.state is DutyState.SPARE and step.hold and step.command is None
    assert eleven.energy().role == "spare" and eleven.member is None
    (ev,) = [e for e in log.events if e.name == "relief_stood_down"]
    assert (ev.sysid, ev.member_sysid, ev.rival_sysid, ev.airborne) == (11, 5, 10, False)
    _step(eleven, log, t + 1.2, BASE, 0.0, heard, True)  # its next plan: 10 has 5
    assert eleven.state is DutyState.SPARE and eleven.plan.of_member(5).spare == 10
    log10 = Log()
    ten, heard10, t10 = _committed(10, log10)
    heard10.hear(_state(11, t10, BASE, Energy("relieving", 100.0, None, 5)), t10)
    _step(ten, log10, t10 + 0.1, BASE, 0.0, heard10, True)
    assert ten.state is DutyState.RELIEVING and "relief_stood_down" not in log10.names()


def test_a_spare_in_the_air_whose_member_another_has_relieved_turns_back_and_lands():
    log = Log()
    duty, heard, t0 = _launched(log)
    pos = BASE + 50.0  # it has taken off and left its launch point
    _step(duty, log, t0 + 2.0, pos, 0.0, heard, True)
    assert duty.state is DutyState.RELIEVING
    # UAV 12, in member 5's slot, says it relieved 5 (its take-over came in first)
    heard.hear(_state(12, t0 + 2.0, _loop_point(2.0), Energy("on_station", 100.0, 3000.0, 5)),
               t0 + 2.0)  # fmt: skip
    step = _step(duty, log, t0 + 2.1, pos, 0.0, heard, True)
    assert duty.state is DutyState.HOME and duty.energy().role == "home"
    assert step.off_station and not step.hold  # flying to its base
    (ev,) = [e for e in log.events if e.name == "relief_stood_down"]
    assert (ev.member_sysid, ev.rival_sysid, ev.airborne) == (5, 12, True)
    step = _step(duty, log, t0 + 3.0, BASE + 10.0, 0.0, heard, True)  # at its base
    assert step.command == "land" and duty.state is DutyState.SPARE


def test_a_spare_that_does_not_leave_the_ground_is_out_of_the_rotation():
    log = Log()
    duty, heard, t0 = _launched(log)
    t = t0
    while t <= t0 + LAUNCH_TIMEOUT_S:  # not moving, still hoping
        _tired_member(heard, t, 200.0, moving=True)
        _step(duty, log, t, BASE + 1.0, 0.0, heard, True)
        assert duty.state is DutyState.RELIEVING
        t += 1.0
    _tired_member(heard, t, 200.0, moving=True)
    step = _step(duty, log, t, BASE + 1.0, 0.0, heard, True)
    assert duty.state is DutyState.SPARE and step.hold
    assert duty.energy() == Energy("unavailable", 100.0, None, 0)
    (ev,) = [e for e in log.events if e.name == "relief_in_slot"]
    assert ev.reason == "no_takeoff" and ev.member_sysid == 5
    # never booked again: what 10 now shares gives the plan no spare
    got = Roster(MISSION).inputs(t, [(10, duty.energy(), BASE)], PATROL)
    assert got.standby == () and got.refused == ()
    _tired_member(heard, t + 5.0, 200.0)
    assert _step(duty, log, t + 5.0, BASE, 0.0, heard, True).command is None


def _along_m(a: complex, b: complex) -> float:
    """How far (m of loop, in the sense of travel) point ``a`` is ahead of point ``b``."""
    gap = float(PATROL.phase_of_point(a)) - float(PATROL.phase_of_point(b))
    return math.remainder(gap, 2.0 * math.pi) * PATROL.length_m / (2.0 * math.pi)


@pytest.mark.parametrize("member_phase", [2.0, 4.5])
def test_a_spare_flies_in_by_its_lane_and_its_sensor_meets_the_loop_just_behind_its_member(
    member_phase,
):
    """Spare 10, launched for member 5 with the other five on station (the six splayed,
    flying the loop at its nominal rate), flown as a particle on the duty's commands at
    10 Hz. While its sensor reaches the loop it is behind member 5, by less than the
    spacing less two sensor radii: its pass over a point starts after 5's and merges with
    no other member's (the coverage revisit counts from pass start to pass start). It takes
    the slot within the planned take-over."""
    log, heard = Log(), Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    spacing = 2.0 * math.pi / 6
    sensor = MISSION.sensor.footprint_radius_m

    def member_at(sysid: int, t: float) -> complex:
        k = [5, 1, 2, 3, 4, 6].index(sysid)
        return _loop_point(member_phase - k * spacing + 2.0 * math.pi * t / PATROL.period_s)

    def hear_all(t: float) -> None:
        for s in (1, 2, 3, 4, 5, 6):
            leave = 200.0 if s == 5 else 1e5
            heard.hear(_state(s, t, member_at(s, t), Energy("on_station", 60.0, leave, 0)), t)

    pos, heading = BASE, math.pi  # on its runway, facing south
    t, dt, airborne, worst_behind, worst_ahead = 0.0, 0.1, False, 0.0, 0.0
    while duty.state is not DutyState.ON_STATION and t < 6.0 * PATROL.period_s:
        hear_all(t)
        step = _step(duty, log, t, pos, heading, heard, True)
        airborne = airborne or step.command == "takeoff"
        if airborne:
            heading += step.turn_rate_rad_s * dt
            v = step.airspeed_m_s * complex(math.cos(heading), math.sin(heading))
            pos += (v + PATROL.wind.vector) * dt
            off = float(np.min(np.abs(PATROL.sample_by_time(2000) - pos)))
            if off < sensor:  # its sensor reaches the loop
                behind = _along_m(member_at(5, t), pos)
                worst_behind = max(worst_behind, behind)
                worst_ahead = max(worst_ahead, -behind)
        t = round(t + dt, 6)
    assert duty.state is DutyState.ON_STATION
    (ev,) = [e for e in log.events if e.name == "relief_in_slot"]
    assert ev.reason == "in_slot" and ev.took_s < 2.0 * PATROL.period_s
    assert worst_behind < PATROL.length_m / 6 - 2.0 * sensor
    assert worst_ahead < 5.0


def test_a_relief_holding_the_members_slot_for_3_s_is_on_station_and_says_whom_it_relieved():
    log = Log()
    duty, heard, t0 = _launched(log)
    member_phase = 2.0
    # airborne: it moved off its launch point; then it sits in the member's slot on the loop
    t = round(t0 + 1.0, 6)
    slot_since = None
    while duty.state is DutyState.RELIEVING and t < t0 + 30.0:
        ph = member_phase + 2.0 * math.pi * t / PATROL.period_s
        pos = _loop_point(ph)
        heard.hear(_state(5, t, pos, Energy("on_station", 30.0, 200.0, 0)), t)
        _step(duty, log, t, pos + 1.0, float(PATROL.course_at_phase(ph)), heard, True)
        slot_since = t if slot_since is None else slot_since
        t = round(t + 0.1, 6)
    assert duty.state is DutyState.ON_STATION
    assert t - 0.1 - slot_since == pytest.approx(IN_SLOT_S, abs=0.25)
    (ev,) = [e for e in log.events if e.name == "relief_in_slot"]
    assert ev.reason == "in_slot" and ev.member_sysid == 5
    e = duty.energy()
    assert e.role == "on_station" and e.relief_sysid == 5


# ---- refused states -----------------------------------------------------------------------
def test_the_roster_refuses_a_sysid_the_mission_does_not_list_and_plans_without_it():
    roster = Roster(MISSION)
    member = (3, Energy("on_station", 30.0, 900.0, 0), _loop_point(0.0))
    spare = (10, Energy("spare", 100.0, 0.0, 0), BASE)
    impostor = (20, Energy("spare", 100.0, 0.0, 0), _loop_point(0.1))  # nearer than 10
    got = roster.inputs(0.0, [impostor, member, spare], PATROL)
    assert [r.sysid for r in got.refused] == [20] and got.refused[0].reason == NOT_IN_MISSION
    assert [s.sysid for s in got.standby] == [10]
    # a patrol UAV sharing that it is a spare is not refused: it landed after a relief
    back = (4, Energy("spare", 100.0, 0.0, 0), BASE)
    assert roster.inputs(0.0, [back], PATROL).refused == ()


def test_a_member_whose_slot_another_member_has_taken_is_not_booked_again():
    # spare 11 holds UAV 3's slot and says so (on station, relief_sysid 3); UAV 3 has not
    # heard it yet and still shares on_station with a near leave time: no spare is booked
    # for it (one was, spare 12, which flew in and made seven on station), the others are
    roster = Roster(MISSION)
    tired = (3, Energy("on_station", 25.0, 560.0, 0), _loop_point(0.0))
    relief = (11, Energy("on_station", 98.0, 2800.0, 3), _loop_point(0.0))
    other = (4, Energy("on_station", 30.0, 900.0, 0), _loop_point(1.0))
    spare = (12, Energy("spare", 100.0, 0.0, 0), BASE)
    got = roster.inputs(404.0, [tired, relief, other, spare], PATROL)
    assert sorted(m.sysid for m in got.on_station) == [4, 11]
    # a stranger's claim does not count: it is refused, and UAV 3 is planned for
    stranger = (20, Energy("on_station", 98.0, 2800.0, 3), _loop_point(0.0))
    got = roster.inputs(404.0, [tired, stranger, spare], PATROL)
    assert [m.sysid for m in got.on_station] == [3] and [r.sysid for r in got.refused] == [20]


def test_a_spare_answering_as_another_sysid_is_refused_counted_logged_and_never_booked():
    # spare 10 is on the ground at its base; a "spare" under sysid 20 (not in the mission)
    # waits on the loop itself, so the plan would take it first (nearer) if it were heard
    log, heard = Log(), Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    for k in range(5):
        t = float(k)
        _tired_member(heard, t, 200.0)  # due at once
        heard.hear(_state(20, t, _loop_point(2.1), Energy("spare", 100.0, 0.0, 0), Mode.SPARE), t)
        _step(duty, log, t, BASE, 0.0, heard, True)
        if duty.state is DutyState.RELIEVING:
            break
    assert duty.energy().relief_sysid == 5  # 10 is booked and goes, not 20
    assert duty.refused == {NOT_IN_MISSION: 1}
    (ev,) = [e for e in log.events if e.name == "relief_refused"]
    assert (ev.member_sysid, ev.role, ev.reason) == (20, "spare", NOT_IN_MISSION)


def test_a_stranger_claiming_to_fly_in_for_a_member_does_not_hold_its_relief():
    log, heard = Log(), Neighbours(10, 3.0)
    duty = Duty(10, MISSION)
    duty.observe_battery(0.0, 100.0, 0.0, None)
    _tired_member(heard, 0.0, 200.0)
    heard.hear(_state(30, 0.0, BASE, Energy("relieving", 100.0, None, 5), Mode.SPARE), 0.0)
    _step(duty, log, 0.0, BASE, 0.0, heard, True)
    assert duty.state is DutyState.RELIEVING and duty.energy().relief_sysid == 5  # 10 goes
    (ev,) = [e for e in log.events if e.name == "relief_refused"]
    assert (ev.member_sysid, ev.role) == (30, "relieving")


def _lane_to_slot(ahead_m: float, monkeypatch, turns: bool) -> tuple[float, float, int]:
    """Spare 10 riding its lane ``ahead_m`` (m of loop) ahead of where it turns in behind
    member 5 (the six splayed, flying the loop at its nominal rate): where a climb-out left
    the spare in the fresh-clone CI of 45efd0a (635-917 m ahead on a 1.9 km loop). Flown as
    a particle on the duty's commands at 10 Hz until it is in the slot: (time s, how near
    its sensor's edge came to the loop while it turned at its turn rate ahead of member 5
    m, how many times it held its turn rate for a full turn). ``turns`` False: the full
    turn refused (riding the lane only)."""
    import companion.agent.relief.fly_in as fly_in

    if not turns:
        monkeypatch.setattr(fly_in, "full_turn_clear", lambda *a, **k: False)
    log = Log()
    duty, heard, t0 = _launched(log)
    spacing = 2.0 * math.pi / 6
    loop = PATROL.sample_by_time(4000)

    def member_at(sysid: int, t: float) -> complex:
        k = [5, 1, 2, 3, 4, 6].index(sysid)
        return _loop_point(2.0 - k * spacing + 2.0 * math.pi * t / PATROL.period_s)

    def hear_all(t: float) -> None:
        for s in (1, 2, 3, 4, 5, 6):
            leave = 1e4 if s == 5 else 1e5
            heard.hear(_state(s, t, member_at(s, t), Energy("on_station", 60.0, leave, 0)), t)

    behind = duty.meet_behind_m + ahead_m  # along the loop ahead of member 5 (m)
    phase = (
        float(PATROL.phase_of_point(member_at(5, t0))) + 2.0 * math.pi * behind / PATROL.length_m
    )
    near = PATROL.nearest(_loop_point(phase))
    normal = complex(math.cos(near.course_rad), math.sin(near.course_rad)) * 1j
    normal = (
        normal
        if abs(near.point_m + normal - PATROL.centre_m) > abs(near.point_m - PATROL.centre_m)
        else -normal
    )
    pos, heading = near.point_m + duty.lane_m * normal, near.course_rad
    rel = duty.record  # in its lane (the CI's state): airborne with no lane point kept, then
    flight = rel.stage.record.flight  # in its lane, where it has not been before
    rel.go(RelievingEvent.NO_AIM, ToLoop(flight))
    rel.go(RelievingEvent.REACH_LANE, InLane(flight))
    flight.laned = True
    t, dt, nearest_m, hard_s, full = t0, 0.1, math.inf, 0.0, 0
    turn_s = 2.0 * math.pi / duty.max_u  # a full turn at its turn rate (s)
    while duty.state is not DutyState.ON_STATION and t < t0 + 6.0 * PATROL.period_s:
        hear_all(t)
        step = _step(duty, log, t, pos, heading, heard, True)
        heading += step.turn_rate_rad_s * dt
        hard = abs(step.turn_rate_rad_s) >= duty.max_u - 1e-9  # at its turn rate
        if not hard and hard_s > 0.0:
            full += int(hard_s >= 0.95 * turn_s)  # held for a full turn
        hard_s = hard_s + dt if hard else 0.0
        v = step.airspeed_m_s * complex(math.cos(heading), math.sin(heading))
        pos += (v + PATROL.wind.vector) * dt
        if hard and _along_m(member_at(5, t), pos) < 0.0:  # turning, ahead of its member
            edge = float(np.min(np.abs(loop - pos))) - MISSION.sensor.footprint_radius_m
            nearest_m = min(nearest_m, edge)
        t = round(t + dt, 6)
    assert duty.state is DutyState.ON_STATION
    return t - t0, nearest_m, full


@pytest.mark.parametrize("ahead_m", [900.0, 1100.0, 1300.0])
def test_far_ahead_in_its_lane_it_loses_the_lead_in_full_turns_outward(ahead_m, monkeypatch):
    """A spare that reaches its lane far ahead of its slot used to fall back at the phase
    hold's 2 m/s, more than a lap (the CI failure). Now it turns full turns outward, each
    losing about 2 pi turn radii in a turn's 20 s: it is in the slot sooner than riding,
    and its sensor does not reach the loop in them."""
    took, nearest_m, full = _lane_to_slot(ahead_m, monkeypatch, turns=True)
    monkeypatch.undo()
    rode, _, rode_full = _lane_to_slot(ahead_m, monkeypatch, turns=False)
    print(f"ahead {ahead_m:.0f} m: {took:.1f} s with {full} full turns, {rode:.1f} s riding")
    assert full >= 1 and rode_full == 0
    assert took < 0.8 * rode
    assert nearest_m > 0.0
