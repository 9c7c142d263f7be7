"""``companion upload`` sends the mission's geofence (issue 14): FENCE items over the mission
protocol, verified by download, and the fence parameters, against the real simulator over
loopback UDP; the parameter names per autopilot type (pure)."""

from __future__ import annotations

import os
import subprocess
import sys

from companion.link.fence_upload import fence_params, fence_vertices_e7
from companion.link.home_slot import MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4
from companion.mission import load_mission
from sitl_model.codec import dialect
from sitl_model.testing import REPO, MavClient, SitlProcess

PAPER = REPO / "missions" / "ellipse_6uav.yaml"
FENCE = dialect.MAV_MISSION_TYPE_FENCE


def test_fence_parameters_per_autopilot():
    m = load_mission(PAPER)
    ap = fence_params(m, MAV_AUTOPILOT_ARDUPILOTMEGA, enable=True)
    assert ap == [
        ("FENCE_ALT_MIN", 50.0),
        ("FENCE_ALT_MAX", 200.0),
        ("FENCE_TYPE", 13.0),
        ("FENCE_ACTION", 1.0),
        ("FENCE_ENABLE", 1.0),
    ]
    assert ("FENCE_ENABLE", 1.0) not in fence_params(m, MAV_AUTOPILOT_ARDUPILOTMEGA, False)
    assert fence_params(m, MAV_AUTOPILOT_PX4, enable=True) == [
        ("GF_MAX_VER_DIST", 200.0),
        ("GF_ACTION", 3.0),
    ]


def _download_fence(c: MavClient) -> list:
    c.drain()
    c.send(dialect.MAVLink_mission_request_list_message(1, 1, FENCE))
    n = c.match("MISSION_COUNT", cond=lambda m: m.mission_type == FENCE).count
    out = []
    for seq in range(n):
        c.send(dialect.MAVLink_mission_request_int_message(1, 1, seq, FENCE))
        out.append(c.match("MISSION_ITEM_INT", cond=lambda m, s=seq: m.seq == s))
    return out


def _param(c: MavClient, name: str) -> float:
    c.send(dialect.MAVLink_param_request_read_message(1, 1, name.encode(), -1))
    return c.match("PARAM_VALUE", cond=lambda m: m.param_id == name).param_value


def test_upload_sends_verifies_and_enables_the_fence():
    mission = load_mission(PAPER)
    with SitlProcess(vehicles=1) as sitl:  # no --mission: the vehicle holds no fence yet
        c = MavClient(sitl.port(0))
        try:
            assert _download_fence(c) == [] and _param(c, "FENCE_ENABLE") == 0.0
            env = dict(os.environ, PYTHONPATH=str(REPO))
            url = f"udpout:127.0.0.1:{sitl.port(0)}"
            cmd = [sys.executable, "-m", "companion", "upload", str(PAPER), "--connect", url,
                   "--sysid", "1", "--enable-fence"]  # fmt: skip
            p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=60)
            assert p.returncode == 0, p.stdout + p.stderr
            line = p.stdout.strip()
            assert "fence: 32 vertices verified" in line and "FENCE_ENABLE=1" in line
            back = _download_fence(c)
            assert [(it.command, it.param1, (it.x, it.y)) for it in back] == [
                (5001, 32.0, ll) for ll in fence_vertices_e7(mission)
            ]
            assert _param(c, "FENCE_ENABLE") == 1.0 and _param(c, "FENCE_ACTION") == 1.0
            assert _param(c, "FENCE_ALT_MIN") == 50.0 and _param(c, "FENCE_ALT_MAX") == 200.0
            assert _param(c, "FENCE_TYPE") == 13.0
        finally:
            c.close()
        status = sitl.control("status")
    assert "refused=0" in status
