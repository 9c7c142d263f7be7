"""An operator's cancel (PATROL_ALERT cleared, detector 255) closes the alert for every
companion and sends its prosecutor back into its slot at once (in-process fleet)."""

import dataclasses

import numpy as np

from companion.alerts import Alert
from companion.mission import load_mission
from companion.simulation import FleetSimulation

OPERATOR = 255


def test_operator_cancel_ends_the_prosecution_and_the_uav_rejoins():
    mission = dataclasses.replace(load_mission("missions/ellipse_6uav.yaml"), intruders=())
    sim = FleetSimulation(mission, dt_s=0.1)
    sim.run(150.0)
    t0 = sim.t_s
    # 50 m outside the loop, where no UAV is near: the cancel, not the sensor, must end it
    patrol = mission.patrol
    loop = patrol.point_at_phase(np.linspace(0, 2 * np.pi, 72, endpoint=False))
    out = loop + 50.0 * (loop - patrol.centre_m) / np.abs(loop - patrol.centre_m)
    gaps = np.min(np.abs(out[:, None] - sim.state.pos_m[None, :]), axis=1)
    site = complex(out[int(np.argmax(gaps))])
    new = Alert("255-1", site, OPERATOR, t0, "new")
    for agent in sim.agents:
        agent.receive_alert(new, t0)
    sim.run(t0 + 3.0)
    away = [k for k, m in enumerate(sim.modes) if m == "prosecuting"]
    assert len(away) == 1, sim.modes
    k = away[0]
    prosecutor = sim.agents[k]
    assert prosecutor.away.alert_id == "255-1"
    left = prosecutor.away.plan.time_s - (sim.t_s - prosecutor.away.plan_t0_s)
    assert left > 3.0  # still far from the site: the cancel, not the arrival, ends it

    t1 = sim.t_s
    cleared = Alert("255-1", site, OPERATOR, t1, "cleared")
    for agent in sim.agents:
        agent.receive_alert(cleared, t1)
    sim.run(t1 + 0.2)
    assert sim.modes[k] == "rejoining"
    assert all(a.alerts["255-1"].status == "done" for a in sim.agents)
    (end,) = [e for e in sim.events if e["event"] == "prosecution_end" and e["alert_id"] == "255-1"]
    assert end["outcome"] == "cancelled" and end["by_sysid"] == OPERATOR
    assert end["sysid"] == prosecutor.sysid
    # it flies back into its slot and hands back its real state; nobody else is sent
    sim.run(t1 + 3 * mission.patrol.period_s)
    assert sim.modes == ["patrol"] * len(sim.modes)
    assert [e for e in sim.events if e["event"] == "rejoined" and e["sysid"] == prosecutor.sysid]
    tasked = {
        e["prosecutor_sysid"]
        for e in sim.events
        if e["event"] == "alert_tasked" and e["alert_id"] == "255-1"
    }
    assert tasked == {prosecutor.sysid}
    assert not [e for e in sim.events if e["event"] == "site_covered"]
