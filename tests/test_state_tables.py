"""The alert lifecycle and the own mode as transition tables (companion/agent/alerts/lifecycle.py).

Unit tier: every legal pair of each table is accepted, every other pair of the cartesian
product raises, and the records' methods keep to the table. Contract tier: the real companion
stack in memory (:class:`companion.sim.inmemory.Engine`) answers the fast mission's decoy, and
the alert statuses and own modes each companion passed through are walks in the tables.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from companion.agent.alerts.lifecycle import (
    ALERT_TRANSITIONS,
    MODE_TRANSITIONS,
    OPEN,
    TAKEN,
    WAITING,
    AlertStatus,
    IllegalTransitionError,
    OwnMode,
    transition,
)
from companion.agent.alerts.record import AlertRecord
from companion.group.messages import Alert

Q, B, T, U, D = (
    AlertStatus.QUEUED,
    AlertStatus.BIDDING,
    AlertStatus.TASKED,
    AlertStatus.UNDER_WAY,
    AlertStatus.DONE,
)
P, X, R = OwnMode.PATROL, OwnMode.PROSECUTING, OwnMode.REJOINING

LEGAL_ALERT = sorted(ALERT_TRANSITIONS)
ILLEGAL_ALERT = sorted(set(itertools.product(AlertStatus, repeat=2)) - set(ALERT_TRANSITIONS))
LEGAL_MODE = sorted(MODE_TRANSITIONS)
ILLEGAL_MODE = sorted(set(itertools.product(OwnMode, repeat=2)) - set(MODE_TRANSITIONS))


# ---- the tables ---------------------------------------------------------------------------
def test_the_tables_are_the_documented_machines():
    """Written out once more by hand: a change to a table must change this test too."""
    assert set(ALERT_TRANSITIONS) == {
        (Q, B), (Q, T), (Q, U), (Q, D),
        (B, Q), (B, T), (B, U), (B, D),
        (T, Q), (T, U), (T, D),
        (U, Q), (U, D),
    }  # fmt: skip
    assert set(MODE_TRANSITIONS) == {(P, X), (X, R), (R, P)}
    assert len(ILLEGAL_ALERT) == 25 - 13 and len(ILLEGAL_MODE) == 9 - 3
    assert all(ALERT_TRANSITIONS.values()) and all(MODE_TRANSITIONS.values())  # causes named


def test_state_values_are_the_strings_in_use():
    """The own mode's values are AgentOutput.mode's (truth.csv, STATUSTEXT); statuses
    compare equal to their strings."""
    assert [m.value for m in OwnMode] == ["patrol", "prosecuting", "rejoining"]
    assert [s.value for s in AlertStatus] == ["queued", "bidding", "tasked", "under_way", "done"]
    assert Q == "queued" and D == "done"
    assert {Q, B, T, U} == OPEN and {Q, B} == WAITING and {T, U} == TAKEN


def test_done_is_final_and_every_status_is_reachable_from_queued():
    assert not [after for before, after in ALERT_TRANSITIONS if before is D]
    seen, frontier = {Q}, [Q]
    while frontier:
        s = frontier.pop()
        for before, after in ALERT_TRANSITIONS:
            if before is s and after not in seen:
                seen.add(after)
                frontier.append(after)
    assert seen == set(AlertStatus)


@pytest.mark.parametrize(("before", "after"), LEGAL_ALERT + LEGAL_MODE)
def test_every_legal_transition_is_accepted(before, after):
    assert transition(before, after) is after


@pytest.mark.parametrize(("before", "after"), ILLEGAL_ALERT + ILLEGAL_MODE)
def test_every_illegal_pair_raises(before, after):
    with pytest.raises(IllegalTransitionError) as info:
        transition(before, after)
    assert info.value.before is before and info.value.after is after
    assert repr(before.value) in str(info.value) and repr(after.value) in str(info.value)
    assert isinstance(info.value, RuntimeError)  # a bug, not a UserError (ValueError)
    assert not isinstance(info.value, ValueError)


@pytest.mark.parametrize(("before", "after"), [(Q, P), (P, Q), ("queued", T), (Q, "tasked")])
def test_states_of_two_machines_or_plain_strings_are_refused(before, after):
    with pytest.raises(TypeError):
        transition(before, after)


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
    rec.seen_under_way(5)  # staying under way is no transition: only the prosecutor changes
    assert rec.status is U and rec.prosecutor == 5
    rec.requeue()
    assert rec.status is Q and rec.prosecutor is None
    rec.requeue()  # a queued alert stays queued
    assert rec.status is Q
    rec.finish(20.0)
    assert rec.status is D and rec.done_t_s == 20.0


@pytest.mark.parametrize(
    "call",
    [
        lambda r: r.finish(30.0),
        lambda r: r.requeue(),
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
    site, and that UAV flies back into its slot (by 227 s). Sampled after every 50 Hz step,
    each companion's status of the alert and its own mode move only along the tables."""
    from companion.sim.inmemory import Engine, EngineConfig

    with Engine(EngineConfig(FAST, None)) as e:
        e.run(175.0)
        statuses: dict[int, list] = {s: [] for s in e.sysids}
        modes: dict[int, list] = {s: [] for s in e.sysids}
        alert_id = None
        while e.sim.t_s < 230.0:
            e.step()
            if alert_id is None:
                new = [ev for ev in e.companion_events if ev["event"] == "alert_new"]
                alert_id = new[0]["alert_id"] if new else None
            for s, r in zip(e.sysids, e.runners, strict=True):
                modes[s].append(r.agent.mode)
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
        assert all(pair in ALERT_TRANSITIONS for pair in itertools.pairwise(walk)), (s, walk)
        assert changes(modes[s]) == ([P, X, R, P] if s == prosecutor else [P]), s
    # a record is sampled after the update that made it: the reporter tasked the next UAV
    # in that update; the prosecutor took it itself (queued -> under way); the others
    # tasked it, then saw it under way
    assert walks.pop(reporter) == [T, U, D]
    assert walks.pop(prosecutor) == [Q, U, D]
    assert all(walk == [Q, T, U, D] for walk in walks.values()), walks
