"""The group's state-rate schedule under a bandwidth budget (pure, companion/group/budget.py)."""

from __future__ import annotations

import dataclasses
import itertools
import time

import pytest

from companion.contracts.signing import Signing
from companion.group.budget import (
    ENERGY_STATE_DATAGRAM_BYTES,
    HEARD_PER_TIMEOUT,
    MAX_MEMBER_TIMEOUT_S,
    STATE_DATAGRAM_BYTES,
    Budget,
    group_state_bytes_s,
    member_timeout_for_rate_s,
    min_rate_for_timeout_hz,
    state_rate_hz,
)
from companion.group.codec import encode
from companion.group.messages import Energy, MemberState, WindRecord


def test_the_datagram_size_is_the_largest_signed_state() -> None:
    full = MemberState(
        200, 1e6 + 0.123, 123.4 - 567.8j, 3.0, "prosecuting", "255-123456789012", pos_m=1 + 1j,
        wind_est_m_s=2 - 3j, wind_record=WindRecord(65535, 200, 4 + 5j, 1e6 + 0.5),
    )  # fmt: skip
    assert len(encode(full, 200, Signing(bytes(32), time.time))) == STATE_DATAGRAM_BYTES
    small = MemberState(1, 1.0, 0j, 0.0)
    assert len(encode(small, 1, Signing(bytes(32), time.time))) < STATE_DATAGRAM_BYTES
    energy = Energy("relieving", 55.5, 1e6 + 900.0, 200)  # version 3: every field set
    v3 = dataclasses.replace(full, energy=energy)
    assert len(encode(v3, 200, Signing(bytes(32), time.time))) == ENERGY_STATE_DATAGRAM_BYTES


# (members, budget bytes/s, max Hz, min Hz) -> rate Hz, worked by hand with b = 100 bytes
TABLE = [
    ((1, 10_000.0, 5.0, 0.0), 5.0),  # plenty: the ceiling
    ((6, 3_000.0, 5.0, 0.0), 5.0),  # 6 * 5 * 100 = 3000: exactly at the budget
    ((12, 3_000.0, 5.0, 0.0), 2.5),
    ((30, 3_000.0, 5.0, 0.0), 1.0),
    ((100, 3_000.0, 5.0, 0.0), 0.3),
    ((100, 3_000.0, 5.0, 0.4), 0.4),  # floored: over budget (4000 bytes/s)
]


@pytest.mark.parametrize(("args", "want"), TABLE)
def test_rate_table(args: tuple[int, float, float, float], want: float) -> None:
    n, budget, hi, lo = args
    got = state_rate_hz(n, budget, datagram_bytes=100, max_rate_hz=hi, min_rate_hz=lo)
    assert got == pytest.approx(want, rel=1e-12)


def test_rate_falls_with_n_and_keeps_the_budget_above_the_floor() -> None:
    budget, floor = 2_000.0, min_rate_for_timeout_hz(3.0)  # 4 states per 3 s
    rates = [state_rate_hz(n, budget, min_rate_hz=floor) for n in range(1, 201)]
    assert all(a >= b for a, b in itertools.pairwise(rates))  # non-increasing
    assert rates[0] == 5.0 and rates[-1] == pytest.approx(floor)
    for n, r in enumerate(rates, start=1):
        total = group_state_bytes_s(n, r)
        assert total <= budget * (1 + 1e-12) or r == pytest.approx(floor), (n, r, total)
    # where the budget binds, the whole group's states fill it exactly
    n = 20
    assert group_state_bytes_s(n, state_rate_hz(n, budget)) == pytest.approx(budget)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"members": 0, "budget_bytes_s": 1.0},
        {"members": 3, "budget_bytes_s": 0.0},
        {"members": 3, "budget_bytes_s": float("inf")},
        {"members": 3, "budget_bytes_s": 1.0, "datagram_bytes": 0},
        {"members": 3, "budget_bytes_s": 1.0, "min_rate_hz": 6.0},
        {"members": 3, "budget_bytes_s": 1.0, "min_rate_hz": -1.0},
    ],
)
def test_bad_arguments_are_value_errors(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        state_rate_hz(**kwargs)


def test_min_rate_for_timeout() -> None:
    assert min_rate_for_timeout_hz(10.0) == pytest.approx(0.4)
    assert min_rate_for_timeout_hz(3.0, heard_per_timeout=3.0) == pytest.approx(1.0)
    with pytest.raises(ValueError):
        min_rate_for_timeout_hz(0.0)


# ---- the Runner's schedule: rate, period and member time-out ---------------------------------
def test_without_binding_the_schedule_is_todays_5_hz_and_3_s() -> None:
    sched = Budget(12_500.0).schedule(6)  # 6 * 5 * 95 = 2850 bytes/s: the budget does not bind
    assert (sched.rate_hz, sched.period_s, sched.member_timeout_s) == (5.0, 0.2, 3.0)


# (members, budget bytes/s) -> (rate Hz, time-out s), by hand with b = 95, 4 states per time-out
SCHEDULE = [
    ((12, 12_500.0), (5.0, 3.0)),  # 12 * 5 * 95 = 5700 <= 12500
    ((100, 12_500.0), (12_500 / 9_500, 4 * 9_500 / 12_500)),  # 1.316 Hz, 3.04 s
    ((100, 1_900.0), (0.2, 20.0)),
    ((1000, 1_900.0), (4 / 30, 30.0)),  # floored: the budget is exceeded, time-out <= 30 s
]


@pytest.mark.parametrize(("args", "want"), SCHEDULE)
def test_schedule_table(args: tuple[int, float], want: tuple[float, float]) -> None:
    sched = Budget(args[1]).schedule(args[0])
    assert sched.rate_hz == pytest.approx(want[0], rel=1e-12)
    assert sched.period_s == pytest.approx(1.0 / want[0], rel=1e-12)
    assert sched.member_timeout_s == pytest.approx(want[1], rel=1e-12)


def test_a_member_is_heard_at_least_four_times_per_time_out_at_every_size() -> None:
    budget = Budget(1_000.0)
    for n in range(1, 400):
        sched = budget.schedule(n)
        assert sched.member_timeout_s * sched.rate_hz >= HEARD_PER_TIMEOUT * (1 - 1e-12), n
        assert sched.member_timeout_s <= MAX_MEMBER_TIMEOUT_S


def test_members_whose_views_differ_by_up_to_n_still_hear_each_other_twice() -> None:
    """A receiver hearing n - 1 others keeps the time-out of n members; a sender that hears
    up to n more sends slower, and is still heard at least twice within that time-out."""
    budget = Budget(1_000.0)
    for n in range(1, 200):
        receiver = budget.schedule(n)
        for d in range(n + 1):
            sender = budget.schedule(n + d)
            assert receiver.member_timeout_s * sender.rate_hz >= 2.0 - 1e-9, (n, d)


def test_the_time_out_is_a_function_of_the_rate() -> None:
    assert member_timeout_for_rate_s(5.0, 3.0) == 3.0
    assert member_timeout_for_rate_s(0.5, 3.0) == pytest.approx(8.0)
    assert member_timeout_for_rate_s(0.5, 10.0) == 10.0
    with pytest.raises(ValueError):
        member_timeout_for_rate_s(0.0, 3.0)
    with pytest.raises(ValueError):
        Budget(0.0)
