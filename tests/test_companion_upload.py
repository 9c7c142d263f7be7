"""``companion upload``: perimeter file parsing (pure), the mission-item convention of
ArduPilot (item 0 is home) against PX4 (pure, and in memory against the simulator's mission
protocol), and upload + verify against the real simulator over loopback UDP."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.link.mission_protocol.from_autopilot import mission_yaml
from companion.link.mission_protocol.home_slot import first_seq, home_in_item0, loop_items
from companion.link.mission_protocol.transfer import upload_and_verify
from companion.mission import MissionError, load_mission, parse_mission
from companion.mission.perimeter_files import PerimeterPoint, loop_points, parse_plan, parse_wpl
from sitl_model.codec import Decoder, Encoder
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.mission_protocol import MissionItem, MissionProtocol, home_item
from sitl_model.testing import REPO, MavClient, SitlProcess

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

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


# ---- ArduPilot's item 0 (home) against PX4 -----------------------------------------------
CMAC = LocalFrame(*DEFAULT_ORIGIN)


def heartbeat(autopilot: int):
    """A fixed-wing autopilot's HEARTBEAT with this MAV_AUTOPILOT type."""
    return mav.MAVLink_heartbeat_message(mav.MAV_TYPE_FIXED_WING, autopilot, 0, 0, 4, 3)


ARDUPILOT_HB = heartbeat(mav.MAV_AUTOPILOT_ARDUPILOTMEGA)
PX4_HB = heartbeat(mav.MAV_AUTOPILOT_PX4)


def square_points(half_m: float = 300.0, alt_m: float = 100.0) -> list[PerimeterPoint]:
    """Four corners of a square around the CMAC origin (the simulator's default home)."""
    out = []
    for n, e in ((half_m, -half_m), (half_m, half_m), (-half_m, half_m), (-half_m, -half_m)):
        lat, lon, _ = CMAC.to_geodetic(n, e, 0.0)
        out.append(PerimeterPoint(float(lat), float(lon), alt_m))
    return out


def stored(seq: int, p: PerimeterPoint, command: int = 16) -> MissionItem:
    x, y = round(p.lat_deg * 1e7), round(p.lon_deg * 1e7)
    return MissionItem(seq, 6, command, 0, 1, 0.0, 0.0, 0.0, 0.0, x, y, p.alt_m)


def test_loop_items_skip_item_0_only_on_ardupilot():
    """The item-selection rule: ArduPilot's item 0 is home (inside the perimeter), PX4's is
    the first corner; DO commands and waypoints without a position never count."""
    sq = square_points()
    home = home_item(*DEFAULT_ORIGIN)
    ardupilot_mission = [home, *(stored(k + 1, p) for k, p in enumerate(sq))]
    ardupilot_mission.append(stored(5, sq[0], command=mav.MAV_CMD_DO_CHANGE_SPEED))
    ardupilot_mission.append(stored(6, PerimeterPoint(0.0, 0.0, 100.0)))
    px4_mission = [stored(k, p) for k, p in enumerate(sq)]
    assert home_in_item0(ARDUPILOT_HB.autopilot) and not home_in_item0(PX4_HB.autopilot)
    assert (first_seq(ARDUPILOT_HB.autopilot), first_seq(PX4_HB.autopilot)) == (1, 0)
    assert [it.seq for it in loop_items(ardupilot_mission, ARDUPILOT_HB.autopilot)] == [1, 2, 3, 4]
    assert [it.seq for it in loop_items(px4_mission, PX4_HB.autopilot)] == [0, 1, 2, 3]
    assert [it.seq for it in loop_items(px4_mission, mav.MAV_AUTOPILOT_GENERIC)] == [0, 1, 2, 3]

    # why it matters: read with PX4's rule, ArduPilot's home is a waypoint inside the hull
    def loaded(items):
        wps = [(it.x * 1e-7, it.y * 1e-7) for it in items]
        return parse_mission(mission_yaml(1, wps, {}), "<test>")

    assert loaded(loop_items(ardupilot_mission, ARDUPILOT_HB.autopilot)).patrol.length_m > 0
    with pytest.raises(MissionError):
        loaded(loop_items(ardupilot_mission, PX4_HB.autopilot))


class MissionPeer:
    """A fake pymavlink connection whose far end is the simulator's mission protocol (in
    memory, as bytes both ways): ``home`` makes it keep home in item 0 like ArduPilot."""

    def __init__(self, home: MissionItem | None, sysid: int = 1) -> None:
        self.protocol = MissionProtocol(home=home)
        self.mav = self  # conn.mav.send(...)
        self._gcs, self._ap = Encoder(255, 190), Encoder(sysid, 1)
        self.inbox: list = []
        self.t_s = 0.0

    def send(self, msg) -> None:
        self.t_s += 0.01
        (decoded,), _ = Decoder().decode(self._gcs.pack(msg))
        for out, _peer in self.protocol.handle(decoded, "gcs", self.t_s):
            self.inbox.extend(Decoder().decode(self._ap.pack(out))[0])

    def recv_match(self, type, blocking=True, timeout=None):  # pymavlink's signature
        types = [type] if isinstance(type, str) else type
        while self.inbox:
            m = self.inbox.pop(0)
            if m.get_type() in types:
                return m
        return None


@pytest.mark.parametrize(
    ("home", "hb", "first", "says"),
    [
        (home_item(*DEFAULT_ORIGIN), ARDUPILOT_HB, 1, "(ArduPilot: item 0 is home at -35.3632610"),
        (None, PX4_HB, 0, "(PX4: no home item; perimeter in items 0..3)"),
    ],
)
def test_upload_follows_the_autopilots_convention(home, hb, first, says):
    sq = square_points()
    peer = MissionPeer(home)
    ok, text = upload_and_verify(peer, 1, sq, hb.autopilot)
    assert ok, text
    assert text.startswith("uploaded 4 waypoints, verified") and says in text, text
    items = peer.protocol.items
    assert len(items) == 4 + first
    if home is not None:
        assert items[0] == home and text.endswith("perimeter in items 1..4)"), text
    assert [(it.x, it.y) for it in items[first:]] == [(stored(0, p).x, stored(0, p).y) for p in sq]


def test_px4_layout_on_an_ardupilot_fails_verification():
    """Sending the first corner at seq 0 to an autopilot that keeps home there loses it."""
    ok, text = upload_and_verify(MissionPeer(home_item(*DEFAULT_ORIGIN)), 1, square_points(), 12)
    assert not ok and text == "uploaded 4 waypoints, item 0 differs on download"


def upload(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run(
        [sys.executable, "-m", "companion", "upload", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=180,
    )


def test_upload_ellipse_and_wpl_to_the_simulator(tmp_path):
    with SitlProcess("--vehicles", "2", "--speedup", "5", vehicles=2) as sitl:
        urls = [f"udpout:127.0.0.1:{sitl.port(i)}" for i in range(2)]
        r = upload(str(REPO / "missions" / "ellipse_6uav.yaml"), "--connect", urls[0],
                   "--connect", urls[1], "--points", "12")  # fmt: skip
        assert r.returncode == 0, r.stderr
        home = "item 0 is home at -35.3632610, 149.1652300, 584.0 m AMSL"
        assert r.stdout.splitlines() == [
            f"sysid {s}: uploaded 12 waypoints, verified (ArduPilot: {home}; perimeter in "
            "items 1..12); fence: 32 vertices verified, FENCE_ALT_MIN=50 FENCE_ALT_MAX=200 "
            "FENCE_TYPE=13 FENCE_ACTION=1; FENCE_ENABLE left as it is"
            for s in (1, 2)
        ]
        wpl = tmp_path / "loop.waypoints"
        wpl.write_text(WPL)
        r = upload(str(wpl), "--connect", urls[1], "--sysid", "2", "--listen-s", "10")
        assert r.returncode == 0, r.stderr
        assert r.stdout.strip() == (
            f"sysid 2: uploaded 3 waypoints, verified (ArduPilot: {home}; perimeter in items 1..3)"
        )
        # the stored mission (independent download with the test client): home, then the WPL
        client = MavClient(sitl.port(1))
        try:
            from sitl_model.codec import dialect

            client.send(dialect.MAVLink_mission_request_list_message(2, 1, 0))
            assert client.match("MISSION_COUNT").count == 4
            client.send(dialect.MAVLink_mission_request_int_message(2, 1, 1, 0))
            first = client.match("MISSION_ITEM_INT", cond=lambda m: m.seq == 1)
            assert (first.x, first.y, first.z) == (398010000, -840010000, 100.0)
        finally:
            client.close()
    bad = upload(str(wpl), "--connect", "udpout:127.0.0.1:9", "--listen-s", "0.5")
    assert bad.returncode == 2 and "no autopilot heard" in bad.stderr


def test_upload_vehicle_the_fleets_way(tmp_path):
    """``upload_vehicle`` (the fleet uploads to every vehicle at once with it, one thread per
    vehicle): the same line as ``companion upload --sysid``, the fence switched on; a link
    with no autopilot on it says so."""
    from concurrent.futures import ThreadPoolExecutor

    from companion.link.mission_protocol.vehicle import upload_vehicle

    mission = REPO / "missions" / "ellipse_6uav.yaml"
    with SitlProcess("--vehicles", "2", "--speedup", "5", vehicles=2) as sitl:
        urls = {s: f"udpout:127.0.0.1:{sitl.port(s - 1)}" for s in (1, 2)}
        with ThreadPoolExecutor(2) as pool:
            done = {
                s: pool.submit(upload_vehicle, url, s, mission, enable_fence=True)
                for s, url in urls.items()
            }
            results = {s: f.result() for s, f in done.items()}
    for s, (ok, line) in results.items():
        assert ok, line
        assert line.startswith(f"sysid {s}: uploaded 16 waypoints, verified (ArduPilot: ")
        assert line.endswith("FENCE_TYPE=13 FENCE_ACTION=1 FENCE_ENABLE=1"), line
    ok, line = upload_vehicle("udpout:127.0.0.1:9", 3, mission, listen_s=0.5)
    assert not ok and line == "sysid 3: no heartbeat on udpout:127.0.0.1:9 within 0.5 s"


def test_upload_vehicle_over_a_signed_link(tmp_path):
    """With the link key, ``upload_vehicle`` signs every frame (``companion fleet
    --link-signing``) and the upload is verified; without it the simulator refuses it."""
    from companion.group.keys import generate_key_file
    from companion.link.mission_protocol.vehicle import upload_vehicle

    key = tmp_path / "link.key"
    generate_key_file(key)
    mission = REPO / "missions" / "ellipse_6uav.yaml"
    with SitlProcess("--speedup", "5", "--signing-key-file", str(key), vehicles=1) as sitl:
        ok, line = upload_vehicle(
            f"udpout:127.0.0.1:{sitl.port(0)}", 1, mission, link_key_file=str(key)
        )
        assert ok, line
        assert line.startswith("sysid 1: uploaded 16 waypoints, verified"), line
        ok, line = upload_vehicle(f"udpout:127.0.0.1:{sitl.port(0)}", 1, mission, listen_s=1.0)
        assert not ok and "no answer to MISSION_COUNT" in line, line  # refused unsigned
