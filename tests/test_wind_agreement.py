"""The fleet's wind agreement (companion/agent/wind/agreement.py), pure and in memory.

Members are wired together by hand: each one's shared estimate and newest record are
handed to the others, as the group would deliver them.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from companion.agent.wind.agreement import WindAgreement, robust_wind
from companion.core.wind import valid_wind
from companion.group.messages import WindRecord

AIRSPEED = 20.0
MISSION_WIND = 5j  # 5 m/s towards the East


def fleet(sysids: list[int], **kw) -> dict[int, WindAgreement]:
    return {s: WindAgreement(s, AIRSPEED, MISSION_WIND, **kw) for s in sysids}


def exchange(members: dict[int, WindAgreement], t_s: float) -> None:
    """Every member hears every other's estimate and newest record."""
    for s, a in members.items():
        for o, b in members.items():
            if o == s:
                continue
            est = b.estimates.get(o)
            a.member_estimate(o, est[0] if est else None, t_s)
            a.member_record(b.latest)


def run(members, own: dict[int, complex], t0: float, t1: float, dt: float = 0.5) -> None:
    t = t0
    while t <= t1:
        for s, a in members.items():
            a.own_estimate(own[s], t)
        exchange(members, t)
        for s, a in members.items():
            a.step(t, set(members) - {s})
        t += dt


def test_members_that_disagree_end_on_one_wind_at_one_time():
    members = fleet([4, 2, 7, 5])
    own = {4: 8 + 1j, 2: 7.5 + 0.5j, 7: 8.4 + 1.2j, 5: 7.9 + 0.7j}
    run(members, own, 0.0, 60.0)
    winds = {s: a.wind_at(60.0) for s, a in members.items()}
    assert len(set(winds.values())) == 1, winds
    agreed = winds[2]
    # all four within 1 m/s of their median: their mean (independent arithmetic)
    assert agreed == pytest.approx(complex((8 + 7.5 + 8.4 + 7.9) / 4, (1 + 0.5 + 1.2 + 0.7) / 4))
    # the switch time is the same on every member, and it came from the lowest sysid
    recs = {a.record_at(60.0) for a in members.values()}
    assert len(recs) == 1 and next(iter(recs)).proposer == 2


def test_an_outlier_does_not_move_the_agreed_wind():
    members = fleet([1, 2, 3, 4, 5])
    own = {1: 6 + 0j, 2: 6.2 + 0.1j, 3: 5.9 - 0.1j, 4: 6.1 + 0j, 5: -15 + 12j}
    run(members, own, 0.0, 60.0)
    agreed = members[3].wind_at(60.0)
    assert abs(agreed - (6.05 + 0j)) < 0.15
    assert abs(agreed - np.mean(list(own.values()))) > 2.0  # the mean would have moved


def test_a_bias_that_turns_with_the_heading_averages_out_across_the_members():
    # three members a third of a loop apart, each with the same 0.3 m/s bias along its own
    # heading: the median keeps a bias that depends on where they are, the mean none
    true = 5 + 0j
    for turn in np.linspace(0.0, 2 * math.pi, 13):
        ests = [true + 0.3 * np.exp(1j * (turn + k * 2 * math.pi / 3)) for k in range(3)]
        assert abs(robust_wind(ests) - true) < 1e-12
    ests = [true + 0.3 * np.exp(1j * (0.4 + k * 2 * math.pi / 3)) for k in range(3)]
    med = complex(np.median([e.real for e in ests]), np.median([e.imag for e in ests]))
    assert abs(med - true) > 0.05  # what the median would have said


def test_hysteresis_small_changes_do_not_switch():
    members = fleet([1, 2, 3])
    own = {s: MISSION_WIND + 0.2 for s in members}  # below the 0.25 m/s threshold
    run(members, own, 0.0, 120.0)
    assert all(a.latest.seq == 0 for a in members.values())


def test_a_newcomer_adopts_the_fleet_wind_from_one_state():
    members = fleet([1, 2, 3])
    own = {s: 3 + 4j for s in members}
    run(members, own, 0.0, 40.0)
    rec = members[1].latest
    assert rec.seq >= 1
    newcomer = WindAgreement(9, AIRSPEED, MISSION_WIND)
    assert newcomer.member_record(rec)
    assert newcomer.wind_at(41.0) == members[2].wind_at(41.0)


def test_a_wind_step_is_followed():
    members = fleet([1, 2, 3])
    run(members, {s: 8 + 0j for s in members}, 0.0, 60.0)
    run(members, {s: 5 + 5j for s in members}, 60.5, 150.0)
    assert all(abs(a.wind_at(150.0) - (5 + 5j)) < 1e-9 for a in members.values())
    assert members[3].latest.seq == 2


def test_record_takes_effect_at_its_time_only():
    a = WindAgreement(3, AIRSPEED, MISSION_WIND)
    assert a.member_record(WindRecord(1, 1, 2 + 2j, 100.0))
    assert a.wind_at(99.9) == MISSION_WIND
    assert a.wind_at(100.0) == 2 + 2j
    # a newer record due later keeps the one in force until then
    assert a.member_record(WindRecord(2, 1, 4 + 0j, 130.0))
    assert a.wind_at(120.0) == 2 + 2j and a.wind_at(131.0) == 4 + 0j
    # an older or equal record is not adopted; same seq from a lower proposer wins
    assert not a.member_record(WindRecord(1, 1, 9 + 0j, 10.0))
    assert a.member_record(WindRecord(2, 0, 1 + 1j, 140.0))


@pytest.mark.parametrize(
    "bad",
    [complex(math.nan, 0), complex(0, math.inf), 25 + 0j, 18 + 0j, None],
)
def test_bad_winds_are_ignored_and_counted(bad):
    a = WindAgreement(1, AIRSPEED, MISSION_WIND)
    assert not a.own_estimate(bad, 1.0)
    assert not a.member_estimate(2, bad, 1.0)
    if bad is not None:
        assert not a.member_record(WindRecord(5, 2, bad, 3.0))
        assert a.counts["bad_own"] == 1 and a.counts["bad_member"] == 2
    assert a.combined(1.0) is None
    assert a.wind_at(10.0) == MISSION_WIND


def test_valid_wind_and_robust_wind():
    assert valid_wind(3 + 4j, 20.0) and not valid_wind(20 + 0j, 20.0)
    # median (2, 1): 1+1j is 1.0 m/s from it (kept), the others 4 and 3.2 m/s (left out)
    assert robust_wind([1 + 1j, 2 + 5j, 3 - 2j]) == 1 + 1j
    # no estimate near the median: the median itself
    assert robust_wind([0j, 10 + 0j, 20 + 10j]) == 10 + 0j
    with pytest.raises(ValueError):
        robust_wind([])


def test_stale_estimates_and_lost_members_do_not_count():
    a = WindAgreement(1, AIRSPEED, MISSION_WIND, stale_s=5.0)
    a.member_estimate(2, 8 + 0j, 0.0)
    assert a.combined(4.0) == 8 + 0j
    assert a.combined(6.0) is None
    a.member_estimate(3, 6 + 0j, 6.0)
    a.forget(3)
    assert a.combined(6.0) is None


def test_a_rate_limited_wind_walks_to_a_step_at_its_rate():
    rate = 0.05  # m/s per s
    members = fleet([1, 2, 3], max_rate_m_s2=rate)
    run(members, {s: 8 + 0j for s in members}, 0.0, 60.0)
    # the mission's wind is only a guess: the first record takes the estimate whole
    first = members[1].latest
    assert first.seq == 1 and first.wind_m_s == pytest.approx(8 + 0j)
    target = 5 + 5j
    run(members, {s: target for s in members}, 60.5, 400.0)
    recs = []
    a = members[2]  # a follower: it holds the proposer's records as relayed
    seen = {r.seq: r for r in a.records}
    recs = [seen[k] for k in sorted(seen) if k >= 1]
    assert len(recs) >= 2
    for prev, rec in itertools.pairwise(recs):
        assert abs(rec.wind_m_s - prev.wind_m_s) <= rate * 30.0 + 1e-9  # at most 30 s of rate
    # |target - 8| = 5.83 m/s at 0.05 m/s/s: about 117 s of rate, then within the threshold
    assert abs(a.wind_at(400.0) - target) <= 0.25
    assert len({m.wind_at(400.0) for m in members.values()}) == 1
    # and no faster than the rate allows: in 60 s it moved at most 30 s + 60 s of the rate
    assert abs(a.wind_at(60.5 + 60.0) - target) >= 5.83 - rate * 90.0 - 1e-6


def test_the_agent_says_when_the_agreed_wind_makes_the_loop_unflyable():
    # The paper's ellipse needs 11.7 deg/s in its 5 m/s from the South; 12 m/s from the
    # South-West asks 24 deg/s of aircraft limited to 18 (Patrol.required_turn_rate).
    from companion.agent.agent import Agent
    from companion.agent.fix import Fix
    from companion.core.wind import Wind
    from companion.group.messages import MemberState
    from companion.mission import load_mission

    mission = load_mission("missions/ellipse_6uav.yaml")
    agent = Agent(1, mission)
    pos = complex(mission.patrol.point_at_phase(0.0))

    def fly(t_s: float, record: WindRecord) -> list[dict]:
        agent.receive_state(MemberState(2, t_s, 0j, 1.0, wind_record=record), t_s)
        return list(agent.update(Fix(t_s, pos, 0.0, agent.patrol)).events)

    strong = Wind.from_meteo(12.0, 225.0).vector
    evs = fly(10.0, WindRecord(1, 2, strong, 10.0))
    bad = [e for e in evs if e["event"] == "loop_infeasible"]
    assert len(bad) == 1, evs
    assert bad[0]["limit_deg_s"] == pytest.approx(18.0)
    assert 22.0 < bad[0]["need_deg_s"] < 26.0
    # said once, not at every step
    assert not [e for e in fly(10.5, WindRecord(1, 2, strong, 10.0)) if "loop_" in e["event"]]
    calm = Wind.from_meteo(5.0, 180.0).vector
    evs = fly(20.0, WindRecord(2, 2, calm, 20.0))
    assert [e["event"] for e in evs if "loop_" in e["event"]] == ["loop_flyable"]
