"""Contract test: a companion killed mid-patrol is replaced by a spare, in memory (issue 22's
fault "a companion killed mid-patrol is replaced"; docs/energy.md, "Reliefs").

``missions/ellipse_relief.yaml`` (6 on station, 4 ground spares 100 m east of the loop),
full batteries: nobody needs a relief in the run. UAV 3's companion is killed (SIGKILL in
memory: it says nothing more) once the formation has converged; its autopilot goes on
alone (GUIDED time-out, then a loiter where it is). The others time it out (3 s) and, as
it was on station, every member plans its slot as open now (the schedule's rule 1a), so the
first spare, 10, launches at once, flies in, takes the slot as the formation leaves it and
shares that it relieved 3; nobody else takes off.

Coverage is judged by brute force from the truth log (``tests/relief_coverage.py``, not the
report's code) without UAV 3's aircraft (its loiter covers one spot of the loop by chance;
the fleet no longer has it): over the loop period before the kill, from the kill to
the spare in the slot plus one period (the gap), and over two periods once three have
passed since (recovered: the issue's bounds, revisit <= 1.15 and longest unseen <= 1.5 T/N).
"""

from __future__ import annotations

import pytest

from companion.sim.inmemory import Engine, EngineConfig
from tests.relief_coverage import brute_coverage, companion_events, on_loop_counts, read_truth
from tests.test_relief_inmemory import MISSION

pytestmark = [pytest.mark.contract, pytest.mark.slow]

KILLED = 3
KILL_T_S = 300.0  # converged (about 110 s), and well before any battery runs low
SETTLE_PERIODS = 3.0  # after the spare is in, the six re-splay (a few loop periods)


@pytest.fixture(scope="module")
def lost_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("lost")
    eng = Engine(EngineConfig(MISSION, out))
    period = eng.mission.patrol.period_s
    eng.run(KILL_T_S)
    eng.kill(KILLED)
    eng.run(KILL_T_S + 60.0 + (SETTLE_PERIODS + 2.0) * period)
    eng.close()
    return eng, out


def test_a_spare_launches_for_the_killed_uav_and_takes_its_slot(lost_run):
    eng, _ = lost_run
    lost = [e for e in companion_events(eng, "member_lost") if e["member_sysid"] == KILLED]
    assert {e["sysid"] for e in lost} == set(eng.sysids) - {KILLED}  # every other heard it go
    (launched,) = companion_events(eng, "relief_launched")
    (in_slot,) = companion_events(eng, "relief_in_slot")
    assert launched["sysid"] == 10 and launched["member_sysid"] == KILLED
    # at once: the time-out (3 s) and the next plan (1 s)
    assert KILL_T_S + 3.0 < launched["t_s"] <= KILL_T_S + 5.0
    assert in_slot["sysid"] == 10 and in_slot["member_sysid"] == KILLED
    assert in_slot["reason"] == "member_gone"  # nobody to meet: the slot as the formation has it
    takeoffs = [e["sysid"] for e in eng.sim_events if e["event"] == "takeoff"]
    assert takeoffs == [10]  # no spare booked twice
    assert not companion_events(eng, "relieved")  # nobody else left
    ten = eng.runners[eng.sysids.index(10)].agent.duty
    assert ten.state == "on_station" and ten.lost == {}
    for s in set(eng.sysids) - {KILLED}:  # the claim ended the loss everywhere
        assert eng.runners[eng.sysids.index(s)].agent.duty.lost == {}, s
    print(f"killed {KILLED} at {KILL_T_S:.0f} s: lost at {min(e['t_s'] for e in lost):.1f} s, "
          f"spare 10 launched at {launched['t_s']:.1f} s, in the slot at {in_slot['t_s']:.1f} s "
          f"({in_slot['took_s']:.1f} s after its launch)")  # fmt: skip


def test_coverage_recovers_with_the_spare(lost_run):
    eng, out = lost_run
    tr = read_truth(out)
    (in_slot,) = companion_events(eng, "relief_in_slot")
    patrol = eng.mission.patrol
    period, radius = patrol.period_s, eng.mission.sensor.footprint_radius_m
    revisit_s = period / eng.mission.vehicles.count  # T/N
    windows = {
        "before the kill": (KILL_T_S - period, KILL_T_S),
        "kill to spare in + T": (KILL_T_S, in_slot["t_s"] + period),
        "recovered": (in_slot["t_s"] + SETTLE_PERIODS * period,
                      in_slot["t_s"] + (SETTLE_PERIODS + 2) * period),
    }  # fmt: skip
    assert windows["recovered"][1] <= float(tr["t_s"].max())
    figures = {}
    for name, (w0, w1) in windows.items():
        gap, unseen = brute_coverage(tr, patrol, radius, w0, w1, revisit_s, exclude=[KILLED])
        figures[name] = (gap / revisit_s, unseen / revisit_s)
        print(f"{name} ({w0:.0f}-{w1:.0f} s): coverage revisit {gap / revisit_s:.3f}, longest "
              f"unseen {unseen:.1f} s = {unseen / revisit_s:.2f} T/N")  # fmt: skip
    counts = on_loop_counts(tr, patrol, *windows["recovered"], exclude=[KILLED])
    assert min(n for _, n in counts) >= 6  # six on the loop again, UAV 3's aircraft aside
    revisit, unseen = figures["recovered"]
    assert revisit <= 1.15 and unseen <= 1.5
    assert figures["kill to spare in + T"][0] > revisit  # there was a gap, and it closed
