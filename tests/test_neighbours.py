"""Who is in the formation as one companion hears it (companion/agent/neighbours.py, pure)."""

from __future__ import annotations

import math

import pytest

from companion.agent.neighbours import Neighbours
from companion.group.messages import MemberState


def state(sysid: int, t_s: float, phase: float = 0.0, mode: str = "patrol", alert_id: str = ""):
    return MemberState(sysid, t_s, 0j, phase, mode, alert_id)  # type: ignore[arg-type]


def test_own_state_is_ignored_and_a_silent_member_leaves_after_the_timeout():
    heard = Neighbours(2, member_timeout_s=3.0)
    assert not heard.hear(state(2, 0.0), 0.0)
    assert heard.hear(state(3, 0.0), 0.0) and heard.hear(state(1, 0.0), 0.5)
    change = heard.expire(1.0)
    assert change.joined == (1, 3) and change.lost == () and change.dropped == ()
    assert heard.expire(3.0).joined == ()  # reported once
    change = heard.expire(3.2)  # 3 silent for 3.2 s (> 3 s), 1 for 2.7 s
    assert change.dropped == (3,) and change.lost == (3,) and set(heard.table) == {1}
    # heard and gone between two calls: dropped, but it never joined, so it is not lost
    heard.hear(state(5, 3.3), 3.3)
    change = heard.expire(7.0)
    assert change.dropped == (1, 5) and change.lost == (1,) and change.joined == ()


def test_phases_are_extrapolated_at_the_nominal_rate_from_the_receipt_time():
    heard = Neighbours(1, member_timeout_s=10.0)
    period = 100.0
    heard.hear(state(2, 50.0, phase=1.0), 40.0)  # its clock 10 s ahead of ours: no matter
    heard.hear(state(3, 40.0, phase=2.0, mode="prosecuting", alert_id="a"), 40.0)
    heard.hear(state(4, 40.0, phase=3.0, mode="rejoining", alert_id="b"), 40.0)
    rate = 2 * math.pi / period
    ph = heard.phases(45.0, period)
    assert ph[2] == pytest.approx(state(2, 50.0, 1.0).phase_at(55.0, period))
    assert set(heard.phases(45.0, period, on_patrol=True)) == {2}
    assert abs(ph[3] - 2.0) == pytest.approx(5.0 * rate)
    assert [p for p, _ in heard.others(45.0, period)] == list(ph.values())
    assert heard.away() == {3: "", 4: "b"}
    assert heard.prosecuting() == [(3, "a")]


def test_a_spare_is_out_of_the_formation_and_not_away():
    # a spare waiting, flying in or flying home: the others splay without it, and it does
    # not count as a UAV away on an alert (tasking's max_prosecutors)
    heard = Neighbours(1, member_timeout_s=10.0)
    heard.hear(state(2, 0.0, phase=1.0), 0.0)
    heard.hear(state(10, 0.0, phase=2.0, mode="spare"), 0.0)
    heard.hear(state(3, 0.0, phase=3.0, mode="prosecuting", alert_id="a"), 0.0)
    assert set(heard.phases(0.0, 100.0)) == {2, 3}
    assert [p for p, _ in heard.others(0.0, 100.0)] == [1.0, 3.0]
    assert heard.in_formation() == 2
    assert heard.away() == {3: ""}
