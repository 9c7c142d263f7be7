"""Alerts in the in-process fleet simulation: one prosecutor, the next in line, on time."""

import dataclasses

import numpy as np
import pytest

from companion.core.particle import ParticleParams, ParticleState, step
from companion.core.wind import TWO_PI
from companion.mission import load_mission
from companion.mission.model import Intruder
from companion.planner import Plan
from companion.simulation import FleetSimulation


@pytest.fixture(scope="module")
def paper_run():
    mission = load_mission("missions/ellipse_6uav.yaml")
    sim = FleetSimulation(mission, dt_s=0.05)
    snapshots = {}

    def on_event(ev):
        if ev["event"] == "alert_new":
            snapshots["state"] = sim.state

    sim.run(850.0, on_event=on_event)
    return mission, sim, snapshots


def events_of(sim, name):
    return [e for e in sim.events if e["event"] == name]


def own_new(sim):
    """Alerts as raised by their detector (every other companion logs its receipt too)."""
    return [e for e in events_of(sim, "alert_new") if e["own"]]


def taken(sim):
    """Taskings as logged by the prosecutor itself (every companion logs its decision)."""
    return [e for e in events_of(sim, "alert_tasked") if e["sysid"] == e["prosecutor_sysid"]]


def test_paper_alert_is_prosecuted_once_by_the_next_uav_in_line(paper_run):
    mission, sim, snap = paper_run
    (new,) = own_new(sim)
    (tasked,) = taken(sim)
    assert tasked["alert_id"] == new["alert_id"] and tasked["sysid"] != new["sysid"]
    # every companion came to the same decision on its own
    decisions = events_of(sim, "alert_tasked")
    assert len(decisions) == 6 and {e["prosecutor_sysid"] for e in decisions} == {tasked["sysid"]}
    # independent check of "next in line": from the truth state at detection, the tasked
    # UAV is the one whose loop position is next behind the detector along the loop
    patrol = mission.patrol
    st = snap["state"]
    phases = [patrol.nearest(complex(p)).phase_rad for p in st.pos_m]
    det = mission.vehicles.sysids.index(new["sysid"])
    behind = [(phases[det] - p) % TWO_PI if k != det else TWO_PI for k, p in enumerate(phases)]
    assert mission.vehicles.sysids[int(np.argmin(behind))] == tasked["sysid"]


def test_paper_alert_response_time_and_outcome(paper_run):
    _, sim, _ = paper_run
    (plan,) = events_of(sim, "plan")
    (covered,) = events_of(sim, "site_covered")
    (end,) = events_of(sim, "prosecution_end")
    assert 14.0 < covered["response_time_s"] < 20.0  # the paper reports 16.9 s
    assert covered["response_time_s"] <= plan["planned_time_s"]
    # the decoy vanished: the path is flown to its end (within 5 % of plan) and cleared
    assert end["outcome"] == "cleared"
    assert end["response_time_s"] == pytest.approx(plan["planned_time_s"], rel=0.05)
    assert events_of(sim, "alert_cleared") and events_of(sim, "rejoined")


def test_formation_is_undisturbed_while_one_uav_is_away(paper_run):
    _, sim, _ = paper_run
    t = np.array(sim.series.t_s)
    tasked = taken(sim)[0]["t_s"]
    back = events_of(sim, "rejoined")[0]["t_s"]
    # until the hand-back the prosecutor shares its virtual particle (centre c0 exactly), so
    # the fleet measure over [tasked, rejoined) is the other UAVs' own error
    # (the agent decides half a step ahead, so its events carry t + dt/2: the sample of the
    # hand-back step itself, already the real state, is excluded)
    episode = (t >= tasked) & (t < back - sim.dt_s)
    assert np.max(np.array(sim.series.splay_deg)[episode]) < 1.0
    assert np.max(np.array(sim.series.centre_m)[episode]) < 2.0


def test_plan_flown_through_the_particle_reaches_the_site():
    mission = load_mission("missions/ellipse_6uav.yaml")
    from companion.alerts import plan_to_site

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


def test_persistent_intruder_is_confirmed_and_handed_off():
    mission = load_mission("missions/ellipse_6uav.yaml")
    static = Intruder("stay", "static", 500.0, 230.0, -200.0, vanish_t_s=560.0)
    sim = FleetSimulation(dataclasses.replace(mission, intruders=(static,)), dt_s=0.05)
    sim.run(700.0)
    tasked = taken(sim)
    ends = events_of(sim, "prosecution_end")
    assert ends[0]["outcome"] == "confirmed"
    assert len(tasked) >= 2 and tasked[0]["sysid"] != tasked[1]["sysid"]
    assert len({e["alert_id"] for e in own_new(sim)}) == 1  # merged, not re-raised
    assert ends[-1]["outcome"] == "cleared"  # once it is gone, the last prosecutor clears it
    prosecuting = {}
    for e in sim.events:  # never two prosecutors on the alert at once
        if e["event"] == "alert_tasked" and e["sysid"] == e["prosecutor_sysid"]:
            prosecuting[e["sysid"]] = True
            assert sum(prosecuting.values()) == 1
        if e["event"] == "prosecution_end":
            prosecuting[e["sysid"]] = False


@pytest.mark.extended
def test_rejoining_into_the_slot_spares_the_others_measured_both_ways():
    """The paper's direct hand-back pushes the others off the loop; the slot rejoin does not.

    Judged on the others' loop centres (from their true positions and headings) from the
    tasking on: within the paper's 2 m bound with the slot rejoin. The returning UAV itself
    is handed back by its slot position where the loop is curved, so its own centre may
    read a little above its tolerance just after (3.2 m against 3 m, measured)."""
    mission = load_mission("missions/ellipse_6uav.yaml")
    patrol = mission.patrol
    worst = {}
    for rejoin in ("slot", "direct"):
        rows: list = []
        sim = FleetSimulation(mission, dt_s=0.05, agent_options={"rejoin": rejoin})
        sim.run(850.0, on_truth=rows.extend)
        t0 = taken(sim)[0]["t_s"]
        prosecutor = taken(sim)[0]["prosecutor_sysid"]
        others = [r for r in rows if r[0] >= t0 and r[1] != prosecutor]
        pos = np.array([r[2] + 1j * r[3] for r in others])
        centres, _ = patrol.centre_and_phase(pos, np.radians([r[5] for r in others]))
        worst[rejoin] = float(np.max(np.abs(centres - patrol.centre_m)))
    print(f"the others' worst centre error after the tasking: {worst}")
    assert worst["slot"] <= 2.0  # the paper's bound on the others during an episode
    assert worst["direct"] > 3 * worst["slot"]  # the paper's way reshuffles the formation


def test_events_logged_on_receipt_reach_the_log():
    """An alert heard from the group is logged with the next update, not lost."""
    from companion.agent import Agent
    from companion.alerts import Alert

    mission = load_mission("missions/ellipse_6uav.yaml")
    agent = Agent(2, mission)
    agent.receive_alert(Alert("1-1", 230 - 200j, 1, 10.0, "new"), 10.0)
    out = agent.update(10.05, complex(mission.patrol.point_at_phase(1.0)), 0.0)
    assert [e["alert_id"] for e in out.events if e["event"] == "alert_new"] == ["1-1"]
    assert not [e for e in agent.update(10.1, 0j, 0.0).events if e["event"] == "alert_new"]
