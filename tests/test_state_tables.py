"""The alert lifecycle and the own mode as tables keyed by (state, event)
(companion/agent/alerts/lifecycle.py, companion/agent/modes.py, companion/agent/machine.py).

Unit tier: every row of each table is accepted, every other (state, event) pair of the
cartesian product raises, and the records' methods keep to the table. Contract tier: the real
companion stack in memory (:class:`companion.sim.inmemory.Engine`) answers the fast mission's
decoy, and the alert statuses and own modes each companion passed through are walks in the
tables.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from companion.agent.alerts.lifecycle import (
    ALERT_TABLE,
    OPEN,
    TAKEN,
    WAITING,
    AlertEvent,
    AlertStatus,
    next_status,
)
from companion.agent.alerts.record import AlertRecord
from companion.agent.machine import IllegalTransitionError
from companion.agent.modes import MODE_TABLE, ModeEvent, OwnMode, next_mode
from companion.group.messages import Alert, Mode

Q, B, T, U, K, D = (
    AlertStatus.QUEUED,
    AlertStatus.BIDDING,
    AlertStatus.TASKED,
    AlertStatus.UNDER_WAY,
    AlertStatus.TRACKED,
    AlertStatus.DONE,
)
A = AlertEvent
P, X, S, K_ = OwnMode.PATROL, OwnMode.PROSECUTING, OwnMode.SEARCHING, OwnMode.TRACKING
RL, RA = OwnMode.REJOIN_TO_LOOP, OwnMode.REJOIN_ALONG_LOOP
M = ModeEvent

LEGAL_ALERT = sorted(ALERT_TABLE)
ILLEGAL_ALERT = sorted(set(itertools.product(AlertStatus, AlertEvent)) - set(ALERT_TABLE))
LEGAL_MODE = sorted(MODE_TABLE)
ILLEGAL_MODE = sorted(set(itertools.product(OwnMode, ModeEvent)) - set(MODE_TABLE))


# ---- the tables ---------------------------------------------------------------------------
def test_the_tables_are_the_documented_machines():
    """Written out once more by hand, as the modules' docstrings draw them: a change to a
    table must change this test too."""
    open_ = (Q, B, T, U, K)
    assert {
        (Q, A.AUCTION_OPENED): B,
        (Q, A.TASKED): T, (B, A.TASKED): T,
        (Q, A.TASKED_SELF): U, (B, A.TASKED_SELF): U,
        (Q, A.SEEN_UNDER_WAY): U, (B, A.SEEN_UNDER_WAY): U, (T, A.SEEN_UNDER_WAY): U,
        (U, A.SEEN_UNDER_WAY): U,
        (Q, A.TAKEN_OVER_TASKED): T, (Q, A.TAKEN_OVER_AWAY): U,
        (Q, A.CONFIRMED): Q, (B, A.CONFIRMED): Q, (T, A.CONFIRMED): Q, (U, A.CONFIRMED): Q,
        (T, A.TASK_LAPSED): Q,
        (T, A.PROSECUTOR_LOST): Q, (U, A.PROSECUTOR_LOST): Q, (K, A.PROSECUTOR_LOST): Q,
        **{(s, A.TRACKING_SEEN): K for s in open_},
        **{(s, A.CLEARED): D for s in open_},
        **{(s, A.LOST): D for s in open_},
        (Q, A.REFUSED): D, (B, A.REFUSED): D,
    } == ALERT_TABLE  # fmt: skip
    assert MODE_TABLE == {
        (P, M.TASKED): X,
        (X, M.PATH_FLOWN): S,
        (X, M.ENDED): RL, (S, M.ENDED): RL,
        (X, M.TRACKER): K_, (S, M.TRACKER): K_,
        (K_, M.TRACK_ENDED): RL,
        (RL, M.ON_LOOP): RA,
        (RL, M.IN_SLOT): P, (RA, M.IN_SLOT): P,
        (RL, M.TIMED_OUT): P, (RA, M.TIMED_OUT): P,
        (RL, M.HANDED_BACK): P,
    }  # fmt: skip
    assert len(ILLEGAL_ALERT) == 6 * 13 - 36 and len(ILLEGAL_MODE) == 6 * 9 - 13


def test_state_values_are_the_strings_in_use():
    """The own mode is shared as the group's vocabulary (MemberState.mode, AgentOutput.mode,
    truth.csv, STATUSTEXT, the page); statuses compare equal to their strings."""
    assert [m.value for m in Mode] == [
        "patrol",
        "prosecuting",
        "rejoining",
        "tracking",
        "searching",
        "spare",  # the reliefs' (companion/agent/relief/duty.py), not an OwnMode
        "overridden",  # its autopilot took it from the companion (companion/link/failsafe.py)
    ]
    assert {m: m.shared for m in OwnMode} == {
        P: Mode.PATROL, X: Mode.PROSECUTING, S: Mode.SEARCHING, K_: Mode.TRACKING,
        RL: Mode.REJOINING, RA: Mode.REJOINING,
    }  # fmt: skip
    assert [m for m in OwnMode if m.rejoining] == [RL, RA]
    assert [m for m in OwnMode if m.prosecuting] == [X, S]
    assert [s.value for s in AlertStatus] == [
        "queued", "bidding", "tasked", "under_way", "tracked", "done"
    ]  # fmt: skip
    assert Q == "queued" and D == "done"
    assert {Q, B, T, U, K} == OPEN and {Q, B} == WAITING and {T, U, K} == TAKEN


def _reachable(table: dict, start) -> set:
    seen, frontier = {start}, [start]
    while frontier:
        s = frontier.pop()
        for (before, _), after in table.items():
            if before is s and after not in seen:
                seen.add(after)
                frontier.append(after)
    return seen


def test_done_is_final_every_status_is_reachable_and_every_mode_returns_to_patrol():
    assert not [key for key in ALERT_TABLE if key[0] is D]
    assert _reachable(ALERT_TABLE, Q) == set(AlertStatus)
    assert _reachable(MODE_TABLE, P) == set(OwnMode)
    assert all(P in _reachable(MODE_TABLE, m) for m in OwnMode)


@pytest.mark.parametrize(("state", "event"), LEGAL_ALERT)
def test_every_alert_row_is_accepted(state, event):
    assert next_status(state, event) is ALERT_TABLE[(state, event)]


@pytest.mark.parametrize(("state", "event"), LEGAL_MODE)
def test_every_mode_row_is_accepted(state, event):
    assert next_mode(state, event) is MODE_TABLE[(state, event)]


@pytest.mark.parametrize(
    ("step", "state", "event"),
    [(next_status, s, e) for s, e in ILLEGAL_ALERT] + [(next_mode, s, e) for s, e in ILLEGAL_MODE],
)
def test_every_other_pair_raises(step, state, event):
    with pytest.raises(IllegalTransitionError) as info:
        step(state, event)
    assert info.value.state is state and info.value.event is event
    assert repr(state.value) in str(info.value) and repr(event.value) in str(info.value)
    assert isinstance(info.value, RuntimeError)  # a bug, not a UserError (ValueError)
    assert not isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    ("step", "state", "event"),
    [
        (next_status, "queued", A.TASKED),
        (next_status, Q, "tasked"),
        (next_status, P, A.TASKED),
        (next_mode, Mode.PATROL, M.TASKED),  # the wire's mode is not the own mode
        (next_mode, P, A.TASKED),
    ],
)
def test_plain_strings_and_another_machines_values_are_refused(step, state, event):
    with pytest.raises(TypeError):
        step(state, event)


# ---- the record keeps to the table --------------------------------------------------------
def record() -> AlertRecord:
    return AlertRecord(Alert("1-1", 100 + 50j, 1, 10.0), t0_s=10.0)


def test_a_record_moves_only_by_its_methods():
    rec = record()
    assert rec.status is Q and not rec.taken and not rec.started
    with pytest.raises(AttributeError):
        rec.status = D  # type: ignore[misc]
    rec.open_bidding(11.0)
    assert rec.status is B and rec.bid_deadline_s == 11.0 and rec.bids == {}
    rec.task(3, 11.5, started=False)
    assert rec.status is T and rec.taken and not rec.started and rec.prosecutor == 3
    rec.seen_under_way(4)
    assert rec.status is U and rec.started and rec.prosecutor == 4
    rec.seen_under_way(5)  # staying under way is a row of its own: the prosecutor changes
    assert rec.status is U and rec.prosecutor == 5
    rec.requeue(A.CONFIRMED)
    assert rec.status is Q and rec.prosecutor is None
    rec.requeue(A.CONFIRMED)  # a queued alert confirmed stays queued
    assert rec.status is Q
    with pytest.raises(IllegalTransitionError):
        rec.requeue(A.TASK_LAPSED)  # only a tasked alert's tasking lapses
    rec.finish(20.0)
    assert rec.status is D and rec.done_t_s == 20.0


@pytest.mark.parametrize(
    "call",
    [
        lambda r: r.finish(30.0),
        lambda r: r.requeue(A.CONFIRMED),
        lambda r: r.open_bidding(31.0),
        lambda r: r.task(2, 31.0, started=True),
        lambda r: r.seen_under_way(2),
    ],
)
def test_a_done_record_refuses_every_change(call):
    rec = record()
    rec.finish(20.0)
    with pytest.raises(IllegalTransitionError):
        call(rec)
    assert rec.status is D


@pytest.mark.parametrize(
    ("end", "status"),
    [
        (lambda r: r.finish(40.0, A.LOST), D),  # its tracker lost it
        (lambda r: r.finish(40.0), D),  # the operator released it (cleared)
        (lambda r: r.requeue(A.PROSECUTOR_LOST), Q),  # the tracker left the formation
    ],
    ids=["lost", "released", "tracker lost"],
)
def test_a_tracked_alert_is_handed_to_its_tracker_and_released(end, status):
    """Under way, then seen tracking: the tracker holds it (no one else is tasked) until
    it is lost, released, or the tracker leaves the formation (back to the queue)."""
    rec = record()
    rec.task(3, 11.0, started=True)
    rec.tracked_by(3)
    assert rec.status is K and rec.taken and rec.prosecutor == 3
    rec.tracked_by(3)  # seen tracking again: a row of its own
    with pytest.raises(IllegalTransitionError):
        rec.seen_under_way(4)  # a stale "prosecuting" state never takes it back
    end(rec)
    assert rec.status is status


def test_only_a_queued_alert_opens_bidding_and_only_a_waiting_one_is_tasked():
    rec = record()
    rec.task(2, 11.0, started=False)
    with pytest.raises(IllegalTransitionError):
        rec.open_bidding(12.0)
    with pytest.raises(IllegalTransitionError):
        rec.task(3, 12.0, started=False)


@pytest.mark.parametrize("status", [Q, B, T, U])
def test_an_earlier_report_inherits_the_tasking_but_not_the_auction(status):
    other = record()
    if status is B:
        other.open_bidding(12.0)
    elif status in TAKEN:
        other.task(4, 11.0, started=status is U)
    rec = AlertRecord(Alert("2-1", 100 + 40j, 2, 9.0), t0_s=9.0)
    rec.inherit(other)
    assert rec.status is (Q if status is B else status)
    assert rec.prosecutor == other.prosecutor and rec.bids == {}


# ---- contract: a real alert through the real stack, in memory ---------------------------
FAST = Path(__file__).resolve().parents[1] / "tests" / "data" / "companion_ellipse_fast.yaml"


def changes(values: list) -> list:
    """``values`` with consecutive repeats dropped."""
    return [v for k, v in enumerate(values) if k == 0 or v != values[k - 1]]


@pytest.mark.contract
def test_a_decoy_alert_walks_the_tables_in_every_companion():
    """The decoy (fast mission, 180 s) is reported, taken by the next UAV, cleared at its
    site, and that UAV flies back into its slot (by 231 s: back onto the loop first). Sampled after
    every 50 Hz step,
    each companion's status of the alert and its own mode move only along the tables."""
    from companion.sim.inmemory import Engine, EngineConfig

    # 20 ms engine steps (physics_every=1), so that a status held for less than a control
    # period (queued until the prosecutor's next position report) is sampled
    with Engine(EngineConfig(FAST, None, physics_every=1)) as e:
        e.run(175.0)
        statuses: dict[int, list] = {s: [] for s in e.sysids}
        modes: dict[int, list] = {s: [] for s in e.sysids}
        alert_id = None
        while e.sim.t_s < 245.0:
            e.step()
            if alert_id is None:
                new = [ev for ev in e.companion_events if ev["event"] == "alert_new"]
                alert_id = new[0]["alert_id"] if new else None
            for s, r in zip(e.sysids, e.runners, strict=True):
                modes[s].append(r.agent.own_mode)
                rec = r.agent.alerts.get(alert_id) if alert_id else None
                if rec is not None:  # pruned some 11 s after it is done
                    statuses[s].append(rec.status)
        log = list(e.companion_events)
    (reported,) = [ev for ev in log if ev["event"] == "alert_new" and ev["own"]]
    (end,) = [ev for ev in log if ev["event"] == "prosecution_end"]
    assert end["alert_id"] == reported["alert_id"] == alert_id and end["outcome"] == "cleared"
    reporter, prosecutor = reported["sysid"], end["sysid"]
    assert reporter != prosecutor
    assert [ev["sysid"] for ev in log if ev["event"] == "rejoined"] == [prosecutor]
    walks = {s: changes(statuses[s]) for s in e.sysids}
    for s, walk in walks.items():
        rows = {(before, after) for (before, _), after in ALERT_TABLE.items()}
        assert all(pair in rows for pair in itertools.pairwise(walk)), (s, walk)
        if s != prosecutor:
            assert changes(modes[s]) == [P], s
    # the prosecutor's own mode walked the mode table, its rejoin stage by stage (one update
    # may take two rows: the prosecution ends and a path to the slot is found at once)
    walk = changes(modes[prosecutor])
    assert walk[:2] == [P, X] and walk[-1] == P and all(m.rejoining for m in walk[2:-1]), walk
    # the decoy is within the sensor's reach of the loop, so it is checked from the loop
    # (plan "loop"): the prosecutor never leaves it, and its rejoin ends in the update it
    # begins (rejoin_to_loop, then in its slot: two rows at once)
    (plan,) = [ev for ev in log if ev["event"] == "plan"]
    assert plan["path_type"] == "loop" and walk == [P, X, P], (plan, walk)
    rows = {(before, after) for (before, _), after in MODE_TABLE.items()}
    rows |= {(a, c) for a, b in rows for b2, c in rows if b2 is b}
    assert all(pair in rows for pair in itertools.pairwise(walk)), walk
    # a record is sampled after the update that made it: the reporter tasked the next UAV
    # in that update; the prosecutor took it itself (queued -> under way); the others
    # tasked it, then saw it under way
    assert walks.pop(reporter) == [T, U, D]
    assert walks.pop(prosecutor) == [Q, U, D]
    assert all(walk == [Q, T, U, D] for walk in walks.values()), walks
