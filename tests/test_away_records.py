"""A UAV's own mode and its record (companion.agent.away), as transitions of the mode table.

Every row of ``MODE_TABLE`` is taken from a state holding the source mode's record: the
transition holds the entered mode's record, made by the constructor that carries over what
the next mode needs, and the left mode's record is dropped (nothing refers to it any more).
Every pair the table does not list raises and leaves the state as it was, and so does a
record that is not the entered mode's. Then the same through an Agent: an operator's alert
makes it a prosecutor holding a ``Prosecuting`` record; the operator's cancel drops it for a
``Rejoining`` one.
"""

from __future__ import annotations

import gc
import weakref
from collections.abc import Callable
from pathlib import Path

import pytest

from companion.agent.agent import Agent
from companion.agent.alerts.search import Search
from companion.agent.away import (
    RECORD_OF,
    AwayRecord,
    LeftLoop,
    OwnState,
    Prosecuting,
    Rejoining,
    Searching,
    ToLoop,
    Tracking,
)
from companion.agent.fix import Fix
from companion.agent.machine import IllegalTransitionError
from companion.agent.modes import MODE_TABLE, ModeEvent, OwnMode
from companion.core.wind import heading_from_course
from companion.group.messages import Alert, Track
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
P = MISSION.patrol
T_S = 100.0
SLOT = VirtualParticle(0.5, 90.0, P.period_s)
SEARCH = Search(Track(T_S, 300 + 0j, 0j, 20.0, 0.2, 5), T_S, 50.0, 80.0)


def record_in(mode: OwnMode) -> AwayRecord | None:
    """A record of ``mode``, for the alert "2-1", built by hand (not by the constructors under
    test)."""
    left = LeftLoop(t_s=80.0, phase_rad=0.4)
    return {
        OwnMode.PATROL: None,
        OwnMode.PROSECUTING: Prosecuting(
            "2-1", 300 + 0j, SLOT, 60.0, planned_time_s=12.5, left=left
        ),
        OwnMode.SEARCHING: Searching("2-1", 300 + 0j, SLOT, SEARCH, 12.5, True, left),
        OwnMode.TRACKING: Tracking("2-1", 95.0),
        OwnMode.REJOIN_TO_LOOP: Rejoining("2-1", SLOT, 98.0, ToLoop(left)),
        OwnMode.REJOIN_ALONG_LOOP: Rejoining("2-1", SLOT, 98.0, None),
    }[mode]


# what each transition hands on, made from the left mode's record (the Pilot's calls)
ENTER: dict[ModeEvent, Callable[[AwayRecord | None], AwayRecord | None]] = {
    ModeEvent.TASKED: lambda _: Prosecuting("2-1", 300 + 0j, SLOT, 60.0),
    ModeEvent.PATH_FLOWN: lambda old: Searching.begin(old, SEARCH),
    ModeEvent.ENDED: lambda old: Rejoining.after(old, T_S),
    ModeEvent.TRACKER: lambda old: Tracking.begin(old, T_S),
    ModeEvent.TRACK_ENDED: lambda old: Rejoining.after_tracking(old, 1.25, T_S, P.period_s),
    ModeEvent.ON_LOOP: lambda old: old.on_loop(),
    ModeEvent.IN_SLOT: lambda _: None,
    ModeEvent.TIMED_OUT: lambda _: None,
    ModeEvent.HANDED_BACK: lambda _: None,
}


@pytest.mark.parametrize(("mode", "event"), list(MODE_TABLE), ids=lambda x: x.value)
def test_entering_a_mode_holds_its_new_record_and_leaving_drops_the_old(mode, event):
    state = OwnState(mode, record_in(mode))
    old = weakref.ref(state.record) if state.record is not None else None
    new = ENTER[event](state.record)
    state.change(event, new)
    assert state.mode is MODE_TABLE[(mode, event)]
    assert state.record is new
    assert type(new) is RECORD_OF[state.mode] or (new is None and RECORD_OF[state.mode] is None)
    if new is not None:
        assert new.alert_id == "2-1"  # the alert carries over (or is the one tasked)
    gc.collect()
    assert old is None or old() is None  # nothing holds the left mode's record any more


def test_what_each_transition_carries_over():
    prosecuting = record_in(OwnMode.PROSECUTING)
    searching = Searching.begin(prosecuting, SEARCH)
    assert (searching.virtual, searching.left, searching.search) == (SLOT, prosecuting.left, SEARCH)
    assert (searching.planned_time_s, searching.covered, searching.plan) == (12.5, False, None)
    back = Rejoining.after(searching, T_S)
    assert (back.virtual, back.t0_s, back.to_loop.left) == (SLOT, T_S, prosecuting.left)
    assert back.to_loop.plan is None
    tracking = Tracking.begin(searching, T_S)
    assert (tracking.t0_s, tracking.plan) == (T_S, None)  # no slot: out of the formation
    after = Rejoining.after_tracking(tracking, 1.25, T_S + 30.0, P.period_s)
    assert after.virtual.phase(T_S + 30.0) == pytest.approx(1.25)  # its slot where it joins
    assert after.to_loop.left.t_s is None  # the formation re-splayed: nowhere to go back to
    along = back.on_loop()
    assert along.to_loop is None and (along.virtual, along.t0_s) == (SLOT, T_S)


ILLEGAL = [(m, e) for m in OwnMode for e in ModeEvent if (m, e) not in MODE_TABLE]


@pytest.mark.parametrize(("mode", "event"), ILLEGAL, ids=lambda x: x.value)
def test_a_transition_the_table_does_not_list_raises_and_changes_nothing(mode, event):
    record = record_in(mode)
    state = OwnState(mode, record)
    with pytest.raises(IllegalTransitionError):
        state.change(event, record_in(OwnMode.PROSECUTING))
    assert state.mode is mode and state.record is record


@pytest.mark.parametrize(
    ("mode", "event", "wrong"),
    [
        (OwnMode.PATROL, ModeEvent.TASKED, Tracking("2-1", T_S)),  # not a Prosecuting
        (OwnMode.PATROL, ModeEvent.TASKED, None),  # prosecuting without its record
        (OwnMode.PROSECUTING, ModeEvent.ENDED, None),
        (OwnMode.REJOIN_TO_LOOP, ModeEvent.IN_SLOT, Rejoining("2-1", SLOT, T_S, None)),
        # on the loop, the first stage's record must be dropped
        (
            OwnMode.REJOIN_TO_LOOP,
            ModeEvent.ON_LOOP,
            Rejoining("2-1", SLOT, T_S, ToLoop(LeftLoop())),
        ),
        (OwnMode.PROSECUTING, ModeEvent.ENDED, Rejoining("2-1", SLOT, T_S, None)),
    ],
)
def test_a_record_that_is_not_the_entered_modes_raises(mode, event, wrong):
    record = record_in(mode)
    state = OwnState(mode, record)
    with pytest.raises(TypeError):
        state.change(event, wrong)
    assert state.mode is mode and state.record is record


def on_loop(phase_rad: float) -> tuple[complex, float]:
    course = float(P.course_at_phase(phase_rad))
    return complex(P.point_at_phase(phase_rad)), float(
        heading_from_course(P.airspeed_m_s, course, P.wind)
    )


def test_an_agent_tasked_holds_a_prosecuting_record_and_a_cancel_swaps_it_for_a_rejoin():
    agent = Agent(1, MISSION)
    assert agent.own_mode is OwnMode.PATROL and agent.away is None
    site = 1.3 * complex(P.point_at_phase(1.0))  # outside the loop, ahead
    agent.receive_alert(Alert("255-1", site, 255, T_S, "new"), T_S)
    agent.update(Fix(T_S + 0.1, *on_loop(0.0), agent.patrol))
    assert agent.own_mode is OwnMode.PROSECUTING
    prosecuting = agent.away
    assert isinstance(prosecuting, Prosecuting) and prosecuting.alert_id == "255-1"
    assert prosecuting.plan is not None
    shared = agent.update(Fix(T_S + 0.2, *on_loop(0.01), agent.patrol)).broadcast
    assert shared.mode == "prosecuting" and shared.alert_id == "255-1"
    assert shared.phase_rad == prosecuting.virtual.phase(T_S + 0.2)  # its slot, not its place
    left = weakref.ref(prosecuting)
    agent.receive_alert(Alert("255-1", site, 255, T_S + 1.0, "cleared"), T_S + 1.0)
    pos, heading = on_loop(0.05)
    inside = pos + 100.0 * (P.centre_m - pos) / abs(P.centre_m - pos)  # off the loop: a path back
    out = agent.update(Fix(T_S + 1.1, inside, heading, agent.patrol))
    assert [e["outcome"] for e in out.events if e["event"] == "prosecution_end"] == ["cancelled"]
    assert agent.own_mode is OwnMode.REJOIN_TO_LOOP and isinstance(agent.away, Rejoining)
    assert agent.away.virtual is prosecuting.virtual and agent.away.t0_s == T_S + 1.1
    del prosecuting
    gc.collect()
    assert left() is None  # the Agent no longer holds the prosecution's record
