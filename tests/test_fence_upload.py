"""``companion upload`` sends the mission's geofence (issue 14): FENCE items over the mission
protocol, verified by download, and the fence parameters, against the real simulator over
loopback UDP, and against the real ArduPlane SITL firmware where its binary is installed;
the parameter names per autopilot type (pure)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.link.mission_protocol.fence import fence_params, fence_vertices_e7
from companion.link.mission_protocol.home_slot import MAV_AUTOPILOT_ARDUPILOTMEGA, MAV_AUTOPILOT_PX4
from companion.mission import load_mission
from companion.sim.arduplane.sitl import find_binary
from sitl_model.codec import dialect
from sitl_model.testing import REPO, MavClient, SitlProcess

# real processes or sockets, wall clock; alone: real ArduPlane SITL, free-running
pytestmark = [pytest.mark.integration, pytest.mark.alone]

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


def _free_instance() -> int:
    """An ArduPlane SITL instance number whose TCP ports 5760 + 10 i .. + 3 are free now."""
    for i in range(30, 90):
        socks = []
        try:
            for port in range(5760 + 10 * i, 5764 + 10 * i):
                s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                socks.append(s)
                s.bind(("127.0.0.1", port))
            return i
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError("no free ArduPlane instance ports")


def _arduplane() -> Path | None:
    try:
        return find_binary(None)
    except UserError:
        return None


ARDUPLANE = _arduplane()


@pytest.mark.skipif(ARDUPLANE is None, reason="no ArduPlane SITL binary (docs/arduplane.md)")
def test_upload_the_fence_to_real_arduplane(tmp_path):
    """The real firmware (ArduPlane SITL) stores the FENCE items and has every parameter."""
    i = _free_instance()
    proc = subprocess.Popen(
        [str(ARDUPLANE), "--model", "plane", "-I", str(i), "--sysid", "1", "--speedup", "1",
         "--home", "39.8,-84.0,250.0,0", "--defaults", str(ARDUPLANE.parent / "plane.parm"),
         "--wipe"],
        cwd=tmp_path, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    try:
        env = dict(os.environ, PYTHONPATH=str(REPO))
        url = f"tcp:127.0.0.1:{5760 + 10 * i}"
        cmd = [sys.executable, "-m", "companion", "upload", str(PAPER), "--connect", url,
               "--sysid", "1", "--enable-fence", "--listen-s", "5"]  # fmt: skip
        for _ in range(4):  # just booted, ArduPlane may refuse a mission for a few seconds
            time.sleep(3.0)
            p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
            if p.returncode == 0:
                break
        assert p.returncode == 0, p.stdout + p.stderr
        assert "(ArduPilot: item 0 is home" in p.stdout
        assert p.stdout.strip().endswith(
            "fence: 32 vertices verified, FENCE_ALT_MIN=50 FENCE_ALT_MAX=200 FENCE_TYPE=13 "
            "FENCE_ACTION=1 FENCE_ENABLE=1"
        )
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
