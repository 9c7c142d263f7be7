"""An operator's cancel (PATROL_ALERT cleared, detector 255, as the dashboard sends it) closes
the alert for every companion and sends its prosecutor back into its slot at once.

The real companion stack in memory (``companion.sim.inmemory``): the operator's alert and its
cancel are signed frames on the group, heard by six real ``Runner``s flying the simulator.
"""

import numpy as np
import pytest

from companion.group.messages import Alert
from companion.mission import load_mission
from companion.sim.inmemory import Engine, EngineConfig
from tests.fleet_harness import PAPER, quiet_mission

OPERATOR = 255


@pytest.mark.contract
def test_operator_cancel_ends_the_prosecution_and_the_uav_rejoins(tmp_path):
    path = quiet_mission(tmp_path, 900.0, source=PAPER)  # the paper's patrol alone
    mission = load_mission(path)
    with Engine(EngineConfig(path)) as sim:

        def modes() -> list[str]:
            return [r.agent_mode for r in sim.runners]

        def vehicle_s() -> float:  # the companions' clock (vehicle time, unix s)
            return sim.runners[0].now_s

        sim.run(150.0)
        agents = [r.agent for r in sim.runners]
        # 50 m outside the loop, where no UAV is near: the cancel, not the sensor, must end it
        patrol = mission.patrol
        loop = patrol.point_at_phase(np.linspace(0, 2 * np.pi, 72, endpoint=False))
        out = loop + 50.0 * (loop - patrol.centre_m) / np.abs(loop - patrol.centre_m)
        gaps = np.min(np.abs(out[:, None] - sim.sim.state.pos_m[None, :]), axis=1)
        site = complex(out[int(np.argmax(gaps))])
        sim.operator_alert("255-1", site.real, site.imag)
        sim.run(sim.t_s + 3.0)
        away = [k for k, m in enumerate(modes()) if m == "prosecuting"]
        assert len(away) == 1, modes()
        k = away[0]
        prosecutor = agents[k]
        assert prosecutor.away.alert_id == "255-1"
        left = prosecutor.away.plan.time_s - (vehicle_s() - prosecutor.away.plan_t0_s)
        assert left > 3.0  # still far from the site: the cancel, not the arrival, ends it

        t1 = sim.t_s
        sim.operator_send(Alert("255-1", site, OPERATOR, vehicle_s(), "cleared"))
        sim.run(t1 + 0.2)
        assert modes()[k] == "rejoining"
        assert all(a.alerts.get("255-1").status == "done" for a in agents)
        events = sim.companion_events
        (end,) = [e for e in events if e["event"] == "prosecution_end" and e["alert_id"] == "255-1"]
        assert end["outcome"] == "cancelled" and end["by_sysid"] == OPERATOR
        assert end["sysid"] == prosecutor.sysid
        # it flies back into its slot and hands back its real state; nobody else is sent
        sim.run(t1 + 3 * mission.patrol.period_s)
        assert modes() == ["patrol"] * len(modes())
        assert [e for e in events if e["event"] == "rejoined" and e["sysid"] == prosecutor.sysid]
        tasked = {
            e["prosecutor_sysid"]
            for e in events
            if e["event"] == "alert_tasked" and e["alert_id"] == "255-1"
        }
        assert tasked == {prosecutor.sysid}
        assert not [e for e in events if e["event"] == "site_covered"]
