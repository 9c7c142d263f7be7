"""Alerts answered by the real companion stack in memory (``companion.sim.inmemory``): one
prosecutor, the next in line, on time; a persistent intruder confirmed and handed on.

The paper's mission is the session's ``simulated_run`` (tests/conftest.py: the README demo,
760 s); the fast test mission (decoy at 180 s, a persistent intruder from 400 to 470 s) is
flown once here for 495 s. Both are judged from the companions' events and the simulator's
truth log, with the next UAV in line computed independently from true positions. One
extended test compares two rejoin laws in the guidance-level particle fleet instead.
"""

import json

import numpy as np
import pytest

from companion.core.particle import ParticleParams, ParticleState, step
from companion.core.wind import TWO_PI
from companion.mission import load_mission
from companion.planner import Plan
from companion.sim.inmemory import Engine, EngineConfig
from tests.fleet_harness import FAST, episode, true_phases_at, truth_measures
from tests.particle_fleet import FleetSimulation

FAST_END_S = 495.0  # s: the persistent intruder (400-470 s) handed on, gone and cleared


def run_events(folder) -> list[dict]:
    """The companions' events of an in-memory run folder (simulated seconds)."""
    rows = [json.loads(x) for x in (folder / "events.jsonl").read_text().splitlines()]
    return [e for e in rows if e.get("source") == "companion"]


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory):
    """The fast test mission, 495 s in memory: (run folder, companion events)."""
    out = tmp_path_factory.mktemp("fast") / "run"
    with Engine(EngineConfig(FAST, out)) as e:
        e.run(FAST_END_S)
    return out, run_events(out)


def events_of(events, name):
    return [e for e in events if e["event"] == name]


def own_new(events):
    """Alerts as raised by their detector (every other companion logs its receipt too)."""
    return [e for e in events_of(events, "alert_new") if e["own"]]


def taken(events):
    """Taskings as logged by the prosecutor itself (every companion logs its decision)."""
    return [e for e in events_of(events, "alert_tasked") if e["sysid"] == e["prosecutor_sysid"]]


def test_paper_alert_is_prosecuted_once_by_the_next_uav_in_line(simulated_run):
    events = run_events(simulated_run)
    (new,) = own_new(events)
    (tasked,) = taken(events)
    assert tasked["alert_id"] == new["alert_id"] and tasked["sysid"] != new["sysid"]
    # every companion came to the same decision on its own
    decisions = events_of(events, "alert_tasked")
    assert len(decisions) == 6 and {e["prosecutor_sysid"] for e in decisions} == {tasked["sysid"]}
    # independent check of "next in line": from the truth at detection, the tasked UAV is
    # the one whose loop position is next behind the detector along the loop
    phases = true_phases_at(simulated_run, new["t_s"])
    det = new["sysid"]
    behind = {s: (phases[det] - p) % TWO_PI for s, p in phases.items() if s != det}
    assert min(behind, key=behind.get) == tasked["sysid"]


def test_paper_alert_response_time_and_outcome(simulated_run):
    events = run_events(simulated_run)
    (plan,) = events_of(events, "plan")
    (covered,) = events_of(events, "site_covered")
    (end,) = events_of(events, "prosecution_end")
    assert 14.0 < covered["response_time_s"] < 20.0  # the paper reports 16.9 s
    assert covered["response_time_s"] <= plan["planned_time_s"]
    # the decoy vanished: the path is flown to its end (within 5 % of plan) and cleared
    assert end["outcome"] == "cleared"
    assert end["response_time_s"] == pytest.approx(plan["planned_time_s"], rel=0.05)
    assert events_of(events, "alert_cleared") and events_of(events, "rejoined")


def test_fast_mission_decoy_by_the_next_uav_and_the_others_undisturbed(fast_run):
    """Converged before the decoy (180 s); cleared by the next UAV, tasked by all, arriving
    within 5 % of its plan with its sensor (50 m) over the site, from the loop; back in its
    slot; the others' centre error not raised by the episode (after 180 s of convergence, not
    the paper's 600 s)."""
    out, events = fast_run
    m = truth_measures(out)
    t_alert = min(e["t_s"] for e in events if e["event"] == "alert_new")
    ep = episode(m, events, FAST, complex(230, -200))
    print("fast mission in memory:", m.convergence_time_s(t_alert), ep)
    assert m.convergence_time_s(t_alert) is not None
    assert ep["prosecutors"] == {ep["prosecutor"]} and ep["prosecutor"] == ep["expected"]
    assert set(ep["tasked_by"].values()) == {ep["prosecutor"]} and len(ep["tasked_by"]) == 6
    assert abs(ep["arrive_s"] - ep["planned_s"]) <= 0.05 * ep["planned_s"]
    # checked from the loop (the decoy is 35 m from it): the sensor (50 m) passes over it
    assert ep["miss_m"] < 50.0 and ep["outcome"] == "cleared"
    assert ep["rejoined"] is not None and ep["rejoined"]["in_slot"]
    before = (m.t_s > t_alert - 30) & (m.t_s <= t_alert)
    others = [j for j, s in enumerate(m.sysids) if s != ep["prosecutor"]]
    settled = float(np.max(np.abs(m.centres_m[before][:, others])))
    assert ep["others_max_centre_m"] < max(2.0, settled + 1.0)


def test_no_false_response_alarm_in_nominal_flight(fast_run):
    """Our simulator flies what it is asked: no companion may report its profile ignored or
    its aircraft not responding, through the decoy and five hand-offs (before the planned
    paths' turn rates were averaged over the control period, each prosecutor zig-zagged at
    the limit once a second along its straight leg and raised ``profile_ignored``: six in
    this run)."""
    _, events = fast_run
    alarms = [e for e in events if e["event"] in ("profile_ignored", "not_responding")]
    assert alarms == []


def test_persistent_intruder_is_tracked_by_its_first_prosecutor(fast_run):
    """Policy track (the default): the UAV that sees the persistent intruder stays over it,
    out of the formation (the others splay as five), and no second UAV is sent."""
    _, events = fast_run
    persist = {e["alert_id"] for e in own_new(events) if e["east_m"] > 0}
    assert len(persist) == 1  # every pass refines its track, none raises another alert
    mine = [e for e in events if e.get("alert_id") in persist]
    tasked = taken(mine)
    (end,) = events_of(mine, "prosecution_end")
    assert end["outcome"] == "tracking" and len(tasked) == 1
    assert end["sysid"] == tasked[0]["sysid"] and not events_of(mine, "alert_confirmed")
    passes = [e for e in events_of(mine, "sighted") if e["sysid"] == end["sysid"]]
    assert len(passes) >= 3  # pass after pass over it while it stays (400-470 s)


def test_plan_flown_through_the_particle_reaches_the_site():
    mission = load_mission("missions/ellipse_6uav.yaml")
    from companion.agent.alerts.paths import plan_to_site

    patrol = mission.patrol
    start = patrol.point_at_phase(1.0)
    heading = float(np.angle(np.exp(1j * patrol.course_at_phase(1.0))))
    plan = plan_to_site(
        patrol, complex(start), heading, 230 - 200j, mission.vehicles.max_turn_rate_rad_s
    )
    assert isinstance(plan, Plan)
    st = ParticleState.at(start.real, start.imag, heading)
    params = ParticleParams(20.0, mission.vehicles.max_turn_rate_rad_s)
    for seg in plan.segments:
        st = step(st, seg.turn_rate_rad_s, params, patrol.wind.vector, seg.duration_s)
    assert abs(complex(st.pos_m) - (230 - 200j)) < 0.5


@pytest.mark.extended
def test_rejoining_into_the_slot_spares_the_others_measured_both_ways():
    """The paper's direct hand-back pushes the others off the loop; the slot rejoin does not.

    Judged on the others' loop centres (from their true positions and headings) from the
    tasking on: within the paper's 2 m bound with the slot rejoin. The returning UAV itself
    is handed back by its slot position where the loop is curved, so its own centre may
    read a little above its tolerance just after (3.2 m against 3 m, measured).

    Flown by the guidance-level particle fleet (``tests/particle_fleet.py``), not the real
    stack: it compares two rejoin laws, and the product flies only the slot rejoin
    (``AgentConfig(rejoin="direct")`` is no companion option)."""
    mission = load_mission("missions/ellipse_6uav.yaml")
    patrol = mission.patrol
    worst = {}
    for rejoin in ("slot", "direct"):
        rows: list = []
        sim = FleetSimulation(mission, dt_s=0.05, agent_options={"rejoin": rejoin})
        sim.run(850.0, on_truth=rows.extend)
        t0 = taken(sim.events)[0]["t_s"]
        prosecutor = taken(sim.events)[0]["prosecutor_sysid"]
        others = [r for r in rows if r[0] >= t0 and r[1] != prosecutor]
        pos = np.array([r[2] + 1j * r[3] for r in others])
        centres, _ = patrol.centre_and_phase(pos, np.radians([r[5] for r in others]))
        worst[rejoin] = float(np.max(np.abs(centres - patrol.centre_m)))
    print(f"the others' worst centre error after the tasking: {worst}")
    assert worst["slot"] <= 2.0  # the paper's bound on the others during an episode
    assert worst["direct"] > 3 * worst["slot"]  # the paper's way reshuffles the formation


def test_events_logged_on_receipt_reach_the_log():
    """An alert heard from the group is logged with the next update, not lost."""
    from companion.agent.agent import Agent
    from companion.agent.fix import Fix
    from companion.group.messages import Alert

    mission = load_mission("missions/ellipse_6uav.yaml")
    agent = Agent(2, mission)
    agent.receive_alert(Alert("1-1", 230 - 200j, 1, 10.0, "new"), 10.0)
    out = agent.update(Fix(10.05, complex(mission.patrol.point_at_phase(1.0)), 0.0, agent.patrol))
    assert [e["alert_id"] for e in out.events if e["event"] == "alert_new"] == ["1-1"]
    assert not [
        e
        for e in agent.update(Fix(10.1, 0j, 0.0, agent.patrol)).events
        if e["event"] == "alert_new"
    ]


def test_a_planned_turn_rate_is_averaged_over_the_hold():
    """The command held for a control period turns the heading by what the plan turns in
    it: a 0.01 s arc at the limit then straight is 1/10 of the limit over a 0.1 s hold,
    not the limit (independent check: the segments' angles summed by hand)."""
    from companion.agent.alerts.paths import turn_rate_at
    from companion.planner import Segment

    segs = (Segment(0.3, 0.01), Segment(0.0, 5.0), Segment(-0.3, 2.0))
    plan = Plan(7.01, "RSL", segs, 0j, 0.0, 20.0, 0j)
    assert turn_rate_at(plan, 0.0) == 0.3  # the instant's rate
    assert turn_rate_at(plan, 0.0, 0.1) == pytest.approx(0.3 * 0.01 / 0.1)
    assert turn_rate_at(plan, 4.96, 0.1) == pytest.approx(-0.3 * 0.05 / 0.1)
    assert turn_rate_at(plan, 6.0, 0.1) == pytest.approx(-0.3)
    assert turn_rate_at(plan, 6.95, 0.1) == pytest.approx(-0.3 * 0.06 / 0.1)
    assert turn_rate_at(plan, 8.0, 0.1) == 0.0
