"""A real third-party client: MAVSDK 4 (native binding) against the simulator over UDP.

Each simulated vehicle gets its own ``Mavsdk`` instance connected with ``udpout://``; the
test reads position and attitude and checks them against the truth log, uploads a mission
with MissionRaw and downloads it back (item 0 is home, as on ArduPilot; the rest unchanged),
and changes the flight mode.
"""

from __future__ import annotations

import csv
import math
import time

import numpy as np
import pytest

from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.testing import MavClient, SitlProcess

mavsdk = pytest.importorskip("mavsdk")
from mavsdk import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.plugins.action import Action  # noqa: E402
from mavsdk.plugins.mission_raw import MissionItem, MissionRaw  # noqa: E402
from mavsdk.plugins.telemetry import FlightMode, Telemetry  # noqa: E402

pytestmark = pytest.mark.integration

N = 2
FRAME = LocalFrame(*DEFAULT_ORIGIN)


def wait_for(fn, timeout_s: float = 10.0, what: str = "condition"):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        v = fn()
        if v:
            return v
        time.sleep(0.05)
    raise TimeoutError(what)


def truth(path) -> dict[int, np.ndarray]:
    """sysid -> array of (t_s, north, east, heading_deg, turn_rate_deg_s) rows."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    out = {}
    cols = ("t_s", "north_m", "east_m", "heading_deg", "turn_rate_deg_s")
    for sid in range(1, N + 1):
        sel = [r for r in rows if r["sysid"] == str(sid)]
        out[sid] = np.array([[float(r[k]) for k in cols] for r in sel])
    return out


@pytest.fixture(scope="module")
def sitl_mavsdk_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sitl_mavsdk")
    proc = SitlProcess("--speedup", "5", "--truth-log", str(tmp / "truth.csv"), vehicles=N)
    proc.tmp = tmp
    drones = []
    try:
        for i in range(N):
            m = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
            assert m.add_any_connection(f"udpout://127.0.0.1:{proc.port(i)}") == 0
            system = m.first_autopilot(10.0)
            assert system is not None
            drones.append((m, system))
        yield proc, drones
    finally:
        for m, _ in drones:
            m.destroy()
        assert proc.stop() == 0


def test_mavsdk_position_and_attitude_match_truth(sitl_mavsdk_run):
    proc, drones = sitl_mavsdk_run
    samples = []
    for i, (_, system) in enumerate(drones):
        tel = Telemetry(system)
        wait_for(lambda tel=tel: math.isfinite(tel.position().latitude_deg), what="position")
        time.sleep(1.5)  # 7.5 s simulated: the GUIDED timeout has started a loiter turn
        for _ in range(5):
            pos, att = tel.position(), tel.attitude_euler()
            samples.append((i + 1, pos, att))
            time.sleep(0.1)
    time.sleep(0.3)  # let the truth log flush
    tr = truth(proc.tmp / "truth.csv")
    for sysid, pos, att in samples:
        rows = tr[sysid]
        local = FRAME.to_local(pos.latitude_deg, pos.longitude_deg)
        track = rows[:, 1] + 1j * rows[:, 2]
        assert np.min(np.abs(track - local)) < 2.5  # on the true track (rows 2 m apart)
        assert pos.relative_altitude_m == pytest.approx(100.0 + 10.0 * (sysid - 1), abs=0.01)
        t = att.timestamp_us / 1e6
        assert rows[0, 0] <= t <= rows[-1, 0]
        u = math.radians(np.interp(t, rows[:, 0], rows[:, 4]))
        hdg = np.degrees(np.unwrap(np.radians(rows[:, 3])))
        roll_truth = math.degrees(math.atan(20.0 * u / 9.80665))
        assert att.roll_deg == pytest.approx(roll_truth, abs=0.5)
        yaw_err = (att.yaw_deg - np.interp(t, rows[:, 0], hdg) + 180.0) % 360.0 - 180.0
        assert abs(yaw_err) < 0.5
    assert any(abs(a.roll_deg) > 10 for _, _, a in samples)  # a real turn was compared


def test_mavsdk_mission_raw_round_trip_and_mode_changes(sitl_mavsdk_run):
    proc, drones = sitl_mavsdk_run
    for i, (_, system) in enumerate(drones):
        items = [
            MissionItem(
                seq=k,
                frame=6,
                command=16,
                current=int(k == 0),
                autocontinue=1,
                param1=0.0,
                param2=30.0,
                x=round((DEFAULT_ORIGIN[0] + 0.004 * (k % 2) + 0.0001 * i) * 1e7),
                y=round((DEFAULT_ORIGIN[1] + 0.004 * (k // 2)) * 1e7),
                z=120.0 + k,
                mission_type=0,
            )
            for k in range(4)
        ]
        mr = MissionRaw(system)
        mr.upload_mission(items)
        back = mr.download_mission()
        assert [str(x) for x in back[1:]] == [str(x) for x in items[1:]]
        home = back[0]  # ArduPilot's item 0: home (the origin on the ground), frame GLOBAL
        assert (home.seq, home.frame, home.command) == (0, 0, 16)
        assert (home.x, home.y) == (round(DEFAULT_ORIGIN[0] * 1e7), round(DEFAULT_ORIGIN[1] * 1e7))
        tel = Telemetry(system)
        act = Action(system)
        # a second, plain client on the same vehicle at the same time sees the change
        other = MavClient(proc.port(i), sysid=250)
        try:
            other.match("HEARTBEAT")
            act.hold()
            wait_for(lambda tel=tel: tel.flight_mode() == FlightMode.HOLD, what="HOLD")
            assert other.match("HEARTBEAT", cond=lambda m: m.custom_mode == 12).type == 1
        finally:
            other.close()
        act.return_to_launch()
        wait_for(lambda tel=tel: tel.flight_mode() == FlightMode.RETURN_TO_LAUNCH, what="RTL")
        mr.start_mission()
        wait_for(lambda tel=tel: tel.flight_mode() == FlightMode.MISSION, what="MISSION")
    time.sleep(0.3)
    with open(proc.tmp / "truth.csv") as f:
        last = {r["sysid"]: r["mode"] for r in csv.DictReader(f)}
    assert last == {str(s): "AUTO" for s in range(1, N + 1)}
