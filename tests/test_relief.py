"""The relief schedule and the time to leave (companion/agent/relief/, docs/energy.md)."""

from __future__ import annotations

import itertools
import math
import random

import pytest

from companion.agent.relief.energy import Drain, home_time_s, leave_time_s
from companion.agent.relief.schedule import (
    LEAD_S,
    NoLaunchWatch,
    OnStation,
    Standby,
    plan,
)
from companion.core.wind import Wind

SOUTH_5 = Wind.from_meteo(5.0, 180.0)  # 5 m/s from the South: blows towards North


# ---- energy -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("base", "expected_s"),
    [
        (1500 + 0j, 1500 / 25.0),  # downwind: 20 + 5 m/s
        (-1500 + 0j, 1500 / 15.0),  # upwind: 20 - 5 m/s
        (1500j, 1500 / math.sqrt(20.0**2 - 5.0**2)),  # crosswind: crab, sqrt(s0^2 - w^2)
        (0j, 0.0),
    ],
)
def test_home_time_is_the_distance_over_the_ground_speed_towards_home(base, expected_s):
    assert home_time_s(0j, base, 20.0, SOUTH_5) == pytest.approx(expected_s, rel=1e-9)


def test_home_time_flown_by_the_wind_triangle_reaches_home():
    # independent check: fly the heading that holds the course, integrate, and land at home
    base = 900 - 1200j
    t = home_time_s(0j, base, 20.0, SOUTH_5)
    course = math.atan2(base.imag, base.real)
    w = SOUTH_5.vector
    # heading whose air vector plus the wind points along the course (solved numerically)
    lo, hi = course - 1.0, course + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        v = 20.0 * complex(math.cos(mid), math.sin(mid)) + w
        cross = (v * complex(math.cos(course), -math.sin(course))).imag
        lo, hi = (mid, hi) if cross < 0 else (lo, mid)
    v = 20.0 * complex(math.cos(lo), math.sin(lo)) + w
    assert abs(v * t - base) < 1e-6


def test_leave_time_by_hand():
    # 10 Ah, 20 % reserve (2000 mAh), 3000 mAh drawn, 12 A = 3.333 mAh/s: 5000 mAh to the
    # reserve last 1500 s; 100 s home and 20 s margin: leave 1380 s from now
    t = leave_time_s(600.0, 3000.0, 10000.0, 2000.0, 12.0, 100.0, 20.0)
    assert t == pytest.approx(600.0 + 1380.0, abs=1e-9)


def test_leave_time_refuses_a_current_that_is_not_positive():
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError):
            leave_time_s(0.0, 0.0, 1000.0, 100.0, bad, 0.0)


def test_drain_smooths_a_step_of_current_with_its_time_constant():
    d = Drain(tau_s=30.0)
    d.add(0.0, 10.0)
    for k in range(1, 31):
        d.add(float(k), 20.0)
    assert d.current_a == pytest.approx(20.0 - 10.0 * math.exp(-1.0), rel=1e-9)
    d.add(30.0, 1000.0)  # a repeat of the same time is ignored
    assert d.current_a == pytest.approx(20.0 - 10.0 * math.exp(-1.0), rel=1e-9)


# ---- the schedule -------------------------------------------------------------------------
def _fleet(rng: random.Random, n: int, s: int):
    members = [OnStation(1 + k, rng.uniform(100.0, 3000.0)) for k in range(n)]
    spares = [
        Standby(10 + k, rng.choice([0.0, rng.uniform(0.0, 2500.0)]), rng.uniform(20.0, 120.0))
        for k in range(s)
    ]
    return members, spares


def test_the_plan_does_not_depend_on_the_order_the_states_were_heard():
    rng = random.Random(1)
    for _ in range(200):
        members, spares = _fleet(rng, rng.randint(1, 6), rng.randint(0, 4))
        ref = plan(50.0, members, spares, 20.0)
        for _ in range(5):
            rng.shuffle(members)
            rng.shuffle(spares)
            assert plan(50.0, members, spares, 20.0) == ref


def test_every_member_computes_the_same_plan_from_what_it_hears():
    # each member knows its own leave time exactly and hears the others' as shared (the
    # wire carries microseconds): the views are the same set, so the plans are equal
    rng = random.Random(2)
    members, spares = _fleet(rng, 6, 3)
    shared = [OnStation(m.sysid, round(m.leave_t_s * 1e6) / 1e6) for m in members]
    plans = []
    for me in members:
        own = OnStation(me.sysid, round(me.leave_t_s * 1e6) / 1e6)
        view = [own] + [m for m in shared if m.sysid != me.sysid]
        rng.shuffle(view)
        plans.append(plan(80.0, view, list(reversed(spares)), 20.0))
    plans += [plan(80.0, shared, spares, 20.0) for _ in spares]  # the spares compute it too
    assert all(p == plans[0] for p in plans)


def test_no_spare_is_booked_twice_and_no_member_relieved_twice():
    rng = random.Random(3)
    for _ in range(500):
        members, spares = _fleet(rng, rng.randint(1, 8), rng.randint(0, 5))
        under_way = {}
        if spares and rng.random() < 0.5:  # one spare already flying in for a member
            sp = spares.pop(rng.randrange(len(spares)))
            under_way[sp.sysid] = members[rng.randrange(len(members))].sysid
        p = plan(rng.uniform(0.0, 100.0), members, spares, 20.0, under_way)
        booked = [r.spare for r in p.reliefs if r.spare is not None]
        assert len(booked) == len(set(booked))
        assert sorted(r.member for r in p.reliefs) == sorted(m.sysid for m in members)
        assert set(booked) <= {s.sysid for s in spares} | set(under_way)
        assert sum(r.spare is not None for r in p.reliefs) == min(
            len(members), len(spares) + len(under_way)
        )


def test_as_many_reliefs_are_on_time_as_any_assignment_allows():
    # independent check by brute force: every injective assignment of spares to members;
    # a spare is on time for a member iff it can be in the slot LEAD_S before it must leave
    rng = random.Random(4)
    for _ in range(300):
        members, spares = _fleet(rng, rng.randint(1, 4), rng.randint(1, 4))
        t, tk = 0.0, 20.0
        p = plan(t, members, spares, tk)
        on_time = sum(not r.late for r in p.reliefs)

        def ok(m, s, t=t, tk=tk):
            return max(s.ready_t_s, t) + s.transit_s + tk <= m.leave_t_s

        best = 0
        k = min(len(members), len(spares))
        for ms in itertools.permutations(members, k):
            for ss in itertools.permutations(spares, k):
                best = max(best, sum(ok(m, s) for m, s in zip(ms, ss, strict=True)))
        assert on_time == best


def test_a_spare_launches_its_transit_and_take_over_and_lead_before_the_member_must_leave():
    p = plan(0.0, [OnStation(1, 2000.0)], [Standby(10, 0.0, 60.0)], 20.0)
    (r,) = p.reliefs
    assert (r.member, r.spare, r.late) == (1, 10, False)
    assert r.launch_t_s == pytest.approx(2000.0 - 60.0 - 20.0 - LEAD_S)
    assert r.on_station_t_s <= r.leave_t_s


def test_a_late_relief_is_announced_before_it_is_late():
    # the only spare is charging until 1900 s, 60 s of transit, 20 s of take-over: it can
    # be in the slot at 1980 s, 30 s after member 2 must leave at 1950 s. The plan says so
    # at 1000 s, long before.
    p = plan(1000.0, [OnStation(2, 1950.0)], [Standby(10, 1900.0, 60.0)], 20.0)
    (r,) = p.reliefs
    assert r.spare == 10 and r.late and r.late_s == pytest.approx(30.0)
    assert r.leave_t_s > 1000.0


def test_a_spare_goes_where_it_is_on_time_and_the_member_it_cannot_save_is_late():
    # the same spare is on time for member 1 (3000 s) but not for member 2 (1950 s):
    # it relieves 1, and 2 is announced late with no spare at all
    p = plan(1000.0, [OnStation(2, 1950.0), OnStation(1, 3000.0)], [Standby(10, 1900.0, 60.0)], 20)
    assert p.of_member(1).spare == 10 and not p.of_member(1).late
    r2 = p.of_member(2)
    assert r2.spare is None and r2.late_s == math.inf


def test_a_relief_under_way_stays_booked_when_another_member_becomes_more_urgent():
    # spare 10 flies in for member 1; member 2's battery turns out worse: 10 is not taken
    # away from 1 (that would leave both half-done), spare 11 goes for 2
    p = plan(
        100.0,
        [OnStation(1, 900.0), OnStation(2, 500.0)],
        [Standby(11, 0.0, 50.0)],
        20.0,
        under_way={10: 1},
    )
    assert p.of_member(1).spare == 10 and p.of_member(1).under_way
    assert p.of_member(2).spare == 11


def test_a_spare_that_does_not_launch_is_passed_over_and_the_next_goes():
    members = [OnStation(1, 1000.0)]
    spares = [Standby(10, 0.0, 60.0), Standby(11, 0.0, 90.0)]
    watch = NoLaunchWatch(grace_s=5.0)
    first = plan(880.0, members, spares, 20.0)
    assert first.of_member(1).spare == 10  # the nearer one
    due = first.of_member(1).launch_t_s
    for t in (due, due + 3.0, due + 6.0):  # 10 keeps sharing that it waits
        p = plan(t, members, spares, 20.0, passed_over=watch.passed_over)
        passed = watch.see(t, p, waiting={10, 11})
    assert passed == (10,) and watch.passed_over == {10}
    p = plan(due + 6.0, members, spares, 20.0, passed_over=watch.passed_over)
    assert p.of_member(1).spare == 11 and p.passed_over == (10,)
    # it launched late after all (no longer waiting): it is no longer passed over
    watch.see(due + 7.0, p, waiting={11})
    assert watch.passed_over == frozenset()


def test_a_sysid_given_twice_is_refused():
    with pytest.raises(ValueError):
        plan(0.0, [OnStation(1, 10.0)], [Standby(1, 0.0, 1.0)], 1.0)


def test_the_duty_table_is_one_cycle_and_anything_else_raises():
    from companion.agent.machine import IllegalTransitionError, advance
    from companion.agent.relief.states import DUTY_TABLE, DutyEvent, DutyState

    s, seen = DutyState.ON_STATION, []
    for ev in (DutyEvent.RELIEVED, DutyEvent.LANDED, DutyEvent.LAUNCHED, DutyEvent.IN_SLOT):
        s = advance(DUTY_TABLE, s, ev)
        seen.append(s)
    assert seen == [DutyState.HOME, DutyState.SPARE, DutyState.RELIEVING, DutyState.ON_STATION]
    with pytest.raises(IllegalTransitionError):
        advance(DUTY_TABLE, DutyState.SPARE, DutyEvent.RELIEVED)  # a spare is not relieved
    with pytest.raises(IllegalTransitionError):
        advance(DUTY_TABLE, DutyState.HOME, DutyEvent.IN_SLOT)  # nor takes a slot from home


def test_with_the_rotation_a_member_relieved_first_is_the_spare_of_a_later_one():
    # one spare, two members; member 1 leaves at 1000 s and is a spare again 1500 s later
    members = [OnStation(1, 1000.0), OnStation(2, 5000.0)]
    alone = plan(0.0, members, [Standby(10, 0.0, 60.0)], 20.0)
    assert alone.of_member(2).spare is None and alone.of_member(2).late  # counted now only
    rot = plan(0.0, members, [Standby(10, 0.0, 60.0)], 20.0, returns_s=1500.0, return_transit_s=60)
    assert rot.of_member(1).spare == 10 and not rot.of_member(1).late
    r2 = rot.of_member(2)
    assert r2.spare == 1 and not r2.late and r2.launch_t_s >= 1000.0 + 1500.0
    # too slow a turnaround: member 2 is late, by how much its returning spare misses
    slow = plan(0.0, members, [Standby(10, 0.0, 60.0)], 20.0, returns_s=4000.0, return_transit_s=60)
    assert slow.of_member(2).spare == 1
    assert slow.of_member(2).late_s == pytest.approx(1000.0 + 4000.0 + 60.0 + 20.0 - 5000.0)


def test_a_member_is_never_booked_as_its_own_relief():
    # no spare at all: the only candidate for member 2 would be its own return
    p = plan(0.0, [OnStation(2, 100.0)], [], 20.0, returns_s=10.0, return_transit_s=5.0)
    assert p.of_member(2).spare is None and p.of_member(2).late_s == math.inf


def test_a_lost_member_gets_the_first_spare_now_before_the_members_on_time():
    # member 3 fell silent on station at 400 s; 1 and 2 must leave much later. Without
    # rule 1a, 3 is late anyway, so rule 2 would give both spares to 1 and 2 and 3 would
    # wait for a returning member: here 3 gets spare 10 at once, 1 gets 11, 2 nobody yet
    members = [OnStation(1, 3000.0), OnStation(2, 3100.0), OnStation(3, 400.0, lost=True)]
    spares = [Standby(10, 0.0, 60.0), Standby(11, 0.0, 60.0)]
    for order in itertools.permutations(members):
        p = plan(410.0, list(order), spares, 200.0, returns_s=1500.0, return_transit_s=60.0)
        r3 = p.of_member(3)
        assert (r3.spare, r3.launch_t_s) == (10, 410.0)  # now
        assert r3.late_s == pytest.approx(410.0 + 60.0 + 200.0 - 400.0)
        assert p.of_member(1).spare == 11 and not p.of_member(1).late
        # the rotation: 2's relief is member 1 coming back, never 3 (lost for good)
        assert p.of_member(2).spare == 1
        assert all(r.spare != 3 for r in p.reliefs)
    # the same fleet with 3 not lost, only late: rule 3 gives 3 the first spare too, since 1
    # and 2 stay on time (2 with 3 coming back at 1900 s); before rule 3, 1 and 2 took both
    # spares and 3 waited for member 1's return at 4500 s
    late = plan(410.0, [m if m.sysid != 3 else OnStation(3, 400.0) for m in members], spares,
                200.0, returns_s=1500.0, return_transit_s=60.0)  # fmt: skip
    assert (late.of_member(3).spare, late.of_member(3).launch_t_s) == (10, 410.0)
    assert late.of_member(1).spare == 11 and not late.of_member(1).late
    assert late.of_member(2).spare == 3 and not late.of_member(2).late


def test_a_late_member_takes_the_first_spare_only_if_no_on_time_relief_is_lost():
    # member 1 leaves at 100 s (no spare can be on time: 60 s transit, 200 s take-over);
    # member 2 at 400 s, only spare 10 (ready now) can be on time for it. Rule 3 does not take
    # 10 from 2: 1 gets 11 (ready at 300 s), late
    members = [OnStation(1, 100.0), OnStation(2, 400.0)]
    spares = [Standby(10, 0.0, 60.0), Standby(11, 300.0, 60.0)]
    p = plan(0.0, members, spares, 200.0)
    assert p.of_member(2).spare == 10 and not p.of_member(2).late
    assert p.of_member(1).spare == 11 and p.of_member(1).late
    # with member 2 leaving at 2000 s, 11 is on time for it too: 1 gets 10, the earlier
    p = plan(0.0, [members[0], OnStation(2, 2000.0)], spares, 200.0)
    assert p.of_member(1).spare == 10 and p.of_member(1).late
    assert p.of_member(2).spare == 11 and not p.of_member(2).late


def test_a_lost_member_whose_spare_has_launched_keeps_it():
    members = [OnStation(1, 3000.0), OnStation(3, 400.0, lost=True)]
    p = plan(500.0, members, [Standby(11, 0.0, 60.0)], 200.0, under_way={10: 3})
    assert p.of_member(3).spare == 10 and p.of_member(3).under_way
    assert p.of_member(1).spare == 11
