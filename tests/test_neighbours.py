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


def test_a_state_predicted_to_the_present_matches_the_exact_particle():
    """A member flies the circle exactly (no wind: a constant turn rate, the particle's exact
    arcs, companion/core/particle.py); its state is received once, then predicted to every
    later instant. Each prediction the steering and the tasking use is where the particle
    really is, to the phase tables' accuracy, while the raw state is 2 pi age / T behind."""
    from companion.core.loops import circle
    from companion.core.particle import ParticleParams, step_one
    from companion.core.patrol import Patrol
    from companion.core.wind import Wind

    radius_m, v_m_s = 300.0, 20.0
    patrol = Patrol.build(circle(0j, radius_m), v_m_s, Wind(0.0, 0.0))  # clockwise
    params = ParticleParams(v_m_s, 1.0)
    u = v_m_s / radius_m  # clockwise: a right turn at the circle's rate
    pos, heading = complex(radius_m, 0.0) * 1j, math.pi  # east of the centre, heading south
    phase0 = patrol.phase_of_point(pos)
    heard = Neighbours(1, member_timeout_s=100.0)
    rx_t = 40.0
    heard.hear(MemberState(2, 1234.0, 0j, phase0, "patrol", "", pos_m=pos), rx_t)  # clock off
    for age in (0.5, 2.0, 7.0):
        now_pos, _ = step_one(pos, heading, u, params, 0j, age)  # one exact arc
        truth = patrol.phase_of_point(now_pos)
        assert abs(now_pos) == pytest.approx(radius_m, abs=1e-6)  # on the loop
        t = rx_t + age
        predicted = {
            "steering": heard.steering_phases(t, patrol)[0][0],
            "positions": heard.positions_phases(t, patrol)[0],
            "phases": heard.phases(t, patrol.period_s)[2],
            "others": heard.others(t, patrol.period_s)[0][0],
        }
        for name, got in predicted.items():
            assert abs(math.remainder(got - truth, 2 * math.pi)) < 1e-4, (name, age, got, truth)
        stale = abs(math.remainder(phase0 - truth, 2 * math.pi))
        assert stale == pytest.approx(2 * math.pi * age / patrol.period_s, rel=1e-3)


def test_the_members_off_the_perimeter_follow_their_last_state_in_the_tables_order():
    heard = Neighbours(1, member_timeout_s=5.0)
    for s in (4, 2, 3, 5):
        heard.hear(state(s, 0.0), 0.0)
    assert heard.away() == {} and heard.tracking() == [] and heard.prosecuting() == []
    heard.hear(state(3, 1.0, mode="prosecuting", alert_id="a"), 1.0)
    heard.hear(state(4, 1.0, mode="tracking", alert_id="b"), 1.0)
    heard.hear(state(5, 1.0, mode="spare"), 1.0)  # a spare is not away
    assert list(heard.away().items()) == [(4, ""), (3, "")]  # 4 was heard first
    assert heard.tracking() == [(4, "b")] and heard.prosecuting() == [(3, "a")]
    heard.hear(state(3, 2.0, mode="rejoining", alert_id="a"), 2.0)
    assert heard.away() == {4: "", 3: "a"} and heard.prosecuting() == []
    heard.hear(state(3, 3.0), 3.0)  # back on patrol
    assert heard.away() == {4: ""}
    heard.hear(state(2, 5.5), 5.5)
    heard.hear(state(3, 5.5), 5.5)
    heard.hear(state(5, 5.5, mode="spare"), 5.5)
    assert heard.expire(6.5).dropped == (4,)  # silent since 1 s: gone, and no longer away
    assert heard.away() == {} and heard.tracking() == []
