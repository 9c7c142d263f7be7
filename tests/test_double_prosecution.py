"""Two UAVs on one alert: the lower system id keeps it, the other yields and rejoins.

Tasking is every companion's own decision from the states it has heard; on a loaded link those
states are late, and a UAV near the site's phase can be "next" in one member's view and not in
another's. The alert storm against real companions on a loaded machine (CI beside two other
jobs, load 7) showed the result: UAVs 4 and 5 each tasked the other, both timed out after
10 s and each then tasked itself, and both flew to the same site for 13 s. Here the split view
is made on purpose in the guidance-level fleet: one companion's tasking picks itself where the
rule picks another.
"""

from __future__ import annotations

import companion.agent.alerts.tasking as tasking_mod
from companion.agent.alerts.prosecution import keeps_it
from companion.mission import load_mission
from tests.fleet_harness import FAST
from tests.particle_fleet import FleetSimulation

SPLIT_SYSID = 3  # neither the decoy's detector (2) nor the rule's prosecutor (1)


def test_the_lowest_sysid_keeps_it():
    assert keeps_it(4, [5]) is None  # 4 keeps it
    assert keeps_it(5, [4]) == 4
    assert keeps_it(6, [5, 2, 9]) == 2
    assert keeps_it(3, []) is None


def test_a_split_tasking_ends_with_one_prosecutor_within_a_state_period(monkeypatch):
    sim = FleetSimulation(load_mission(FAST))
    split = sim.agents[sim.sysids.tolist().index(SPLIT_SYSID)]
    real_next = tasking_mod.next_in_sequence
    inside = {"split": False}

    def next_in_sequence(phase_rad: float, candidates: dict[int, float]) -> int | None:
        if inside["split"] and SPLIT_SYSID in candidates:
            return SPLIT_SYSID  # this companion's view: itself next
        return real_next(phase_rad, candidates)

    real_assign = split.tasking.assign

    def assign(*args, **kwargs):
        inside["split"] = True
        try:
            return real_assign(*args, **kwargs)
        finally:
            inside["split"] = False

    monkeypatch.setattr(tasking_mod, "next_in_sequence", next_in_sequence)
    split.tasking.assign = assign
    events: list[dict] = []
    sim.run(260.0, on_event=events.append)
    plans = [e for e in events if e["event"] == "plan"]
    ends = [e for e in events if e["event"] == "prosecution_end"]
    assert {e["sysid"] for e in plans} == {1, SPLIT_SYSID}  # the split happened: two went
    assert len({e["t_s"] for e in plans}) == 1  # at the same step
    (yielded,) = [e for e in ends if e["outcome"] == "yielded"]
    assert yielded["sysid"] == SPLIT_SYSID and yielded["by_sysid"] == 1
    assert yielded["t_s"] - plans[0]["t_s"] <= 0.2 + 1e-9  # as soon as it heard the other
    (kept,) = [e for e in ends if e["outcome"] != "yielded"]
    assert kept["sysid"] == 1 and kept["outcome"] == "cleared"  # the decoy, checked once
    covered = [e for e in events if e["event"] == "site_covered"]
    assert [e["sysid"] for e in covered] == [1]
    rejoined = [e for e in events if e["event"] == "rejoined" and e["sysid"] == SPLIT_SYSID]
    assert rejoined and rejoined[0]["t_s"] < kept["t_s"]  # back before the other is done
