"""``companion upload``: perimeter file parsing (pure) and upload + verify against the real
simulator over loopback UDP."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from companion.errors import UserError
from companion.mission import load_mission
from companion.perimeter_files import loop_points, parse_plan, parse_wpl
from sitl_model.testing import REPO, MavClient, SitlProcess

WPL = """QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t39.800000\t-84.000000\t250.000000\t1
1\t0\t3\t16\t0\t0\t0\t0\t39.801000\t-84.001000\t100.000000\t1
2\t0\t3\t16\t0\t0\t0\t0\t39.802000\t-84.000000\t100.000000\t1
3\t0\t3\t22\t0\t0\t0\t0\t39.803000\t-84.000000\t100.000000\t1
4\t0\t3\t16\t0\t0\t0\t0\t39.801000\t-83.999000\t100.000000\t1
"""


def plan_text(points: list[tuple[float, float, float]]) -> str:
    items = [
        {"type": "SimpleItem", "command": 16, "frame": 3, "params": [0, 0, 0, None, a, b, c]}
        for a, b, c in points
    ]
    items.insert(0, {"type": "ComplexItem", "complexItemType": "survey"})
    return json.dumps({"fileType": "Plan", "mission": {"items": items}, "version": 1})


def test_parse_wpl_skips_home_and_non_waypoints():
    pts = parse_wpl(WPL, "x.waypoints")
    assert [(p.lat_deg, p.lon_deg, p.alt_m) for p in pts] == [
        (39.801, -84.001, 100.0),
        (39.802, -84.0, 100.0),
        (39.801, -83.999, 100.0),
    ]


def test_parse_plan_reads_simple_waypoints():
    pts = parse_plan(plan_text([(39.8, -84.0, 90.0), (39.81, -84.0, 90.0), (39.8, -84.01, 95.0)]))
    assert [p.alt_m for p in pts] == [90.0, 90.0, 95.0]
    assert pts[1].lat_deg == 39.81


@pytest.mark.parametrize(
    "text",
    ["QGC WPL 110\n1\t0\t3\t16\t0\t0\t0\t0\tx\t1\t1\t1\n", "QGC WPL 110\n", "hello"],
)
def test_bad_wpl_is_a_user_error(text):
    with pytest.raises(UserError):
        parse_wpl(text)


def test_bad_plan_is_a_user_error():
    with pytest.raises(UserError):
        parse_plan("{}")
    with pytest.raises(UserError):
        parse_plan(plan_text([(39.8, -84.0, 90.0), (95.0, -84.0, 90.0), (39.8, -84.1, 90.0)]))


def test_loop_points_lie_on_the_ellipse():
    import pymap3d

    m = load_mission(REPO / "missions" / "ellipse_6uav.yaml")
    pts = loop_points(m, 16, 100.0)
    assert len(pts) == 16
    for p in pts:
        n, e, _ = pymap3d.geodetic2ned(p.lat_deg, p.lon_deg, 250.0, 39.8, -84.0, 250.0)
        assert (n / 400.0) ** 2 + (e / 200.0) ** 2 == pytest.approx(1.0, abs=1e-3)


def upload(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run(
        [sys.executable, "-m", "companion", "upload", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_upload_ellipse_and_wpl_to_the_simulator(tmp_path):
    with SitlProcess("--vehicles", "2", "--speedup", "5", vehicles=2) as sitl:
        urls = [f"udpout:127.0.0.1:{sitl.port(i)}" for i in range(2)]
        r = upload(str(REPO / "missions" / "ellipse_6uav.yaml"), "--connect", urls[0],
                   "--connect", urls[1], "--points", "12")  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert r.stdout.splitlines() == [
            "sysid 1: uploaded 12 waypoints, verified",
            "sysid 2: uploaded 12 waypoints, verified",
        ]
        wpl = tmp_path / "loop.waypoints"
        wpl.write_text(WPL)
        r = upload(str(wpl), "--connect", urls[1], "--sysid", "2")
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip() == "sysid 2: uploaded 3 waypoints, verified"
        # the stored mission is what was uploaded (independent download with the test client)
        client = MavClient(sitl.port(1))
        try:
            from sitl_model.codec import dialect

            client.send(dialect.MAVLink_mission_request_list_message(2, 1, 0))
            assert client.match("MISSION_COUNT").count == 3
        finally:
            client.close()
    bad = upload(str(wpl), "--connect", "udpout:127.0.0.1:9", "--listen-s", "0.5")
    assert bad.returncode == 2 and "no autopilot heard" in bad.stderr
