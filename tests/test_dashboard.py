"""``companion dashboard`` against a live signed group: the state endpoint, the operator's
signed alerts and cancels, the token when bound off loopback, forged traffic not shown.

Each test starts a real dashboard process on a free port and its own multicast group with a
fresh key, and plays the members from here with the group codec (real signed datagrams).
"""

from __future__ import annotations

import itertools
import json
import os
import selectors
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from companion.contracts.signing import Signing
from companion.dashboard.model import FleetView
from companion.group.keys import generate_key_file, load_key
from companion.group.messages import Alert, MemberState, Track
from companion.group.transport import Group
from companion.mission import load_mission

ROOT = Path(__file__).resolve().parents[1]
MISSION = ROOT / "missions" / "ellipse_6uav.yaml"
_ports = itertools.count()
pytestmark = pytest.mark.integration


@pytest.fixture
def addr() -> tuple[str, int]:
    """A multicast group of this test's own."""
    n = next(_ports)
    return f"239.255.{150 + os.getpid() % 90}.{1 + n % 250}", 21000 + (os.getpid() * 11 + n) % 20000


@pytest.fixture
def key_file(tmp_path: Path) -> Path:
    path = tmp_path / "fleet.key"
    generate_key_file(path)
    return path


class Dashboard:
    """A ``companion dashboard`` subprocess; ``url`` as it printed it."""

    def __init__(self, args: list[str]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "companion", "dashboard", *args],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        with selectors.DefaultSelector() as sel:  # until it serves (or dies), at most 90 s
            sel.register(self.proc.stdout, selectors.EVENT_READ)
            line = self.proc.stdout.readline() if sel.select(90.0) else ""
        if not line.startswith("dashboard: http://"):
            self.stop()
            raise RuntimeError(f"dashboard did not start: {line!r} {self.proc.stderr.read()}")
        self.url = line.split()[1]
        self.base = self.url.split("?")[0].rstrip("/")
        self.port = int(self.base.rsplit(":", 1)[1])

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc.stdout.close()
        self.proc.stderr.close()
        return self.proc.returncode


@pytest.fixture
def start_dashboard(tmp_path: Path, key_file: Path, addr: tuple[str, int]):
    """Start dashboards on ``addr`` with ``key_file``; stopped (exit 0, port free) after."""
    started: list[Dashboard] = []

    def start(*extra: str, mission: bool = True) -> Dashboard:
        args = ["--group", f"{addr[0]}:{addr[1]}", "--key-file", str(key_file)]
        args += ["--state-dir", str(tmp_path), "--port", "0", *extra]
        if mission:
            args += ["--mission", str(MISSION)]
        d = Dashboard(args)
        started.append(d)
        return d

    yield start
    for d in started:
        assert d.stop() == 0
        with pytest.raises(OSError):  # the port was released
            urllib.request.urlopen(f"http://127.0.0.1:{d.port}/api/state", timeout=2)


def http(
    method: str, url: str, body: object = None, headers: dict[str, str] | None = None
) -> tuple[int, dict]:
    """(status, JSON body) of one request; errors are returned, not raised."""
    data = None if body is None else json.dumps(body).encode()
    h = {"Content-Type": "application/json"} if body is not None else {}
    h.update(headers or {})
    req = urllib.request.Request(url, data=data, method=method, headers=h)
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, json.loads(resp.read() or b"{}")
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read() or b"{}")


def member_group(addr: tuple[str, int], sysid: int, key: bytes) -> Group:
    return Group(sysid, Signing(key, time.time), address=addr[0], port=addr[1])


def heard_alerts(group: Group, timeout_s: float) -> list[Alert]:
    """Every alert received on ``group`` within ``timeout_s``."""
    got: list[Alert] = []
    deadline = time.monotonic() + timeout_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)
        while (left := deadline - time.monotonic()) > 0:
            sel.select(min(left, 0.05))
            got += [m for m in group.receive() if isinstance(m, Alert)]
    return got


def poll_state(d: Dashboard, until, timeout_s: float = 5.0, headers=None) -> dict:
    """GET /api/state until ``until(state)`` holds; the last state."""
    deadline = time.monotonic() + timeout_s
    while True:
        status, state = http("GET", d.base + "/api/state", headers=headers)
        assert status == 200, state
        if until(state) or time.monotonic() > deadline:
            return state
        time.sleep(0.1)


def test_state_endpoint_shows_members_alerts_and_prosecutor(start_dashboard, key_file, addr):
    d = start_dashboard("--member-timeout-s", "1.5")
    mission = load_mission(MISSION)
    patrol = mission.patrol
    key = load_key(key_file)
    c0 = patrol.centre_m
    t0 = 1_767_225_600.0 + 600.0
    members = {1: (c0 + complex(2.0, -1.0), 0.3), 2: (c0, 1.4), 3: (c0 + 3j, 4.0)}
    groups = {s: member_group(addr, s, key) for s in members}
    try:
        site = complex(230.0, -200.0)
        groups[2].send_alert(Alert("2-1", site, 2, t0, "new"))
        for k in range(5):  # a few rounds of states, 3 prosecuting the alert
            for s, (c, psi) in members.items():
                mode, alert_id = ("prosecuting", "2-1") if s == 3 else ("patrol", "")
                groups[s].send_state(MemberState(s, t0 + 0.2 * k, c, psi, mode, alert_id))
            time.sleep(0.05)
        state = poll_state(d, lambda s: len(s["vehicles"]) == 3 and s["alerts"])
        assert state["t_s"] == pytest.approx(t0 + 0.8, abs=1e-3)
        vehicles = {v["sysid"]: v for v in state["vehicles"]}
        assert set(vehicles) == {1, 2, 3}
        for s, (c, psi) in members.items():
            v = vehicles[s]
            # without a reported position: the loop point c + rho(gamma(psi)) of its state
            expected = c + complex(patrol.point_at_phase(psi)) - c0
            assert v["north_m"] == pytest.approx(expected.real, abs=0.02)
            assert v["east_m"] == pytest.approx(expected.imag, abs=0.02)
        assert vehicles[1]["mode"] == vehicles[2]["mode"] == "patrol"
        assert vehicles[3]["mode"] == "prosecuting"
        assert vehicles[3]["position_source"] == "virtual particle"
        assert vehicles[1]["cross_track_m"] == pytest.approx(abs(2 - 1j), abs=1.0)
        (alert,) = state["alerts"]
        assert alert["alert_id"] == "2-1" and alert["state"] == "new"
        assert (alert["north_m"], alert["east_m"]) == (230.0, -200.0)
        assert alert["prosecutor_sysid"] == 3 and alert["prosecuting"] is True
        assert state["gauges"]["members"] == 3 and state["gauges"]["away"] == 1
        kinds = [e["kind"] for e in state["events"]]
        assert kinds.count("member_joined") == 3 and "alert_new" in kinds and "tasked" in kinds

        # 3 clears it and flies back; 1 goes silent and is shown lost
        groups[3].send_alert(Alert("2-1", site, 3, t0 + 1.0, "cleared"))
        end = time.monotonic() + 2.5
        while time.monotonic() < end:
            for s in (2, 3):
                c, psi = members[s]
                mode, alert_id = ("rejoining", "2-1") if s == 3 else ("patrol", "")
                groups[s].send_state(MemberState(s, t0 + 1.0, c, psi, mode, alert_id))
            time.sleep(0.1)
        state = poll_state(d, lambda s: s["alerts"][0]["state"] == "cleared")
        vehicles = {v["sysid"]: v for v in state["vehicles"]}
        assert vehicles[1]["mode"] == "lost"
        assert vehicles[3]["mode"] == "rejoining"
        (alert,) = state["alerts"]
        assert alert["state"] == "cleared" and alert["prosecutor_sysid"] == 3
        assert alert["prosecuting"] is False
        assert "member_lost" in [e["kind"] for e in state["events"]]
    finally:
        for g in groups.values():
            g.close()


def test_reported_position_is_used_when_the_state_carries_one(start_dashboard, key_file, addr):
    if "pos_m" not in MemberState.__dataclass_fields__:
        pytest.skip("PATROL_STATE does not carry the position yet (MemberState.pos_m)")
    d = start_dashboard()
    with member_group(addr, 4, load_key(key_file)) as g:
        st = MemberState(4, 100.0, 0j, 1.0, "prosecuting", "x-1", pos_m=complex(-123.5, 456.25))
        g.send_state(st)
        state = poll_state(d, lambda s: s["vehicles"])
    (v,) = state["vehicles"]
    assert (v["north_m"], v["east_m"]) == (-123.5, 456.25)
    assert v["position_source"] == "reported"


def test_api_state_carries_batteries_spares_and_the_relief_plan(start_dashboard, key_file, addr):
    from companion.group.messages import Energy

    relief = ROOT / "missions" / "ellipse_relief.yaml"
    d = start_dashboard("--mission", str(relief), mission=False)
    key = load_key(key_file)
    spare = Energy("spare", 100.0, 50.0, 0)
    states = [
        MemberState(
            3, 100.0, 0j, 1.0, pos_m=-400 + 0j, energy=Energy("on_station", 42.5, 900.0, 0)
        ),
        MemberState(10, 100.0, 0j, 0.0, "spare", pos_m=300j, energy=spare),
        MemberState(20, 100.0, 0j, 0.0, "spare", pos_m=-390 + 0j, energy=spare),  # not listed
    ]
    for st in states:
        with member_group(addr, st.sysid, key) as g:
            g.send_state(st)
    state = poll_state(d, lambda s: len(s["vehicles"]) == 3 and s["reliefs"]["plan"])
    by = {v["sysid"]: v for v in state["vehicles"]}
    assert by[3]["energy"]["battery_pct"] == 42.5 and by[3]["energy"]["role"] == "on_station"
    assert 0.0 < by[3]["energy"]["leave_in_s"] <= 800.0
    rel = state["reliefs"]
    assert rel["enabled"] and [s["sysid"] for s in rel["spares"]] == [10]
    assert rel["refused"] == [{"sysid": 20, "role": "spare", "reason": "not_in_mission"}]
    (plan,) = rel["plan"]
    assert plan["member_sysid"] == 3 and plan["spare_sysid"] == 10 and not plan["late"]
    assert by[3]["energy"]["relief"] == plan
    status, geometry = http("GET", d.base + "/api/mission")
    spares = geometry["mission"]["spares"]
    assert status == 200 and [s["sysid"] for s in spares] == [10, 11, 12, 13]


def test_operator_alert_and_cancel_are_signed_and_sent(start_dashboard, key_file, addr):
    d = start_dashboard()
    with member_group(addr, 5, load_key(key_file)) as g:
        g.send_state(MemberState(5, 5000.0, 0j, 0.0))
        poll_state(d, lambda s: s["vehicles"])
        status, sent = http("POST", d.base + "/api/alert", {"north_m": -450, "east_m": 0.0})
        assert status == 200, sent
        assert sent["sent"] == 3 and sent["state"] == "new" and sent["detector_sysid"] == 255
        got = heard_alerts(g, 1.5)
        assert {(a.alert_id, a.state, a.detector_sysid, a.site_m) for a in got} == {
            (sent["alert_id"], "new", 255, complex(-450.0, 0.0))
        }
        assert len(got) == 3
        assert got[0].t_s >= 5000.0  # the members' vehicle time, heard from the group
        state = poll_state(d, lambda s: s["alerts"])
        assert [a["alert_id"] for a in state["alerts"]] == [sent["alert_id"]]

        status, cancel = http("POST", d.base + "/api/cancel", {"alert_id": sent["alert_id"]})
        assert status == 200, cancel
        got = heard_alerts(g, 1.5)
        assert {(a.alert_id, a.state, a.detector_sysid) for a in got} == {
            (sent["alert_id"], "cleared", 255)
        }
        state = poll_state(d, lambda s: s["alerts"][0]["state"] == "cleared")
        assert state["alerts"][0]["state"] == "cleared"
        assert http("POST", d.base + "/api/cancel", {"alert_id": sent["alert_id"]})[0] == 409
        assert http("POST", d.base + "/api/cancel", {"alert_id": "nope-1"})[0] == 404

        # bad input: refused, nothing sent
        for body in (
            {"north_m": float("nan"), "east_m": 0},
            {"north_m": 1e9, "east_m": 0},
            {"north_m": "12", "east_m": 0},
            {"north_m": True, "east_m": 0},
            {"east_m": 5},
            {"north_m": 1, "east_m": 2, "alert_id": "x" * 17},
            [1, 2],
        ):
            assert http("POST", d.base + "/api/alert", body)[0] == 400, body
        # a cross-site page cannot post: not JSON, or from another origin
        req = urllib.request.Request(
            d.base + "/api/alert",
            data=b"north_m=1&east_m=2",
            method="POST",
            headers={"Content-Type": "application/x-www-form-urlencoded"},
        )
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req, timeout=5)
        assert err.value.code == 415
        evil = {"Origin": "http://evil.example"}
        assert http("POST", d.base + "/api/alert", {"north_m": 1, "east_m": 2}, evil)[0] == 403
        # a loopback-bound dashboard answers only loopback host names (no DNS rebinding)
        assert http("GET", d.base + "/api/state", headers={"Host": "evil.example"})[0] == 403
        assert heard_alerts(g, 1.0) == []


def test_off_loopback_every_request_needs_the_token(start_dashboard, key_file, addr):
    token = "t" * 8 + "0123456789abcdef"
    d = start_dashboard("--bind", "0.0.0.0", "--token", token)
    base = f"http://127.0.0.1:{d.port}"
    ok = {"X-Dashboard-Token": token}
    with member_group(addr, 6, load_key(key_file)) as g:
        for headers in ({}, {"X-Dashboard-Token": "wrong" * 5}):
            status, body = http("POST", base + "/api/alert", {"north_m": 10, "east_m": 20}, headers)
            assert status == 403, body
            assert http("GET", base + "/api/state", headers=headers)[0] == 403
            assert http("POST", base + "/api/cancel", {"alert_id": "a"}, headers)[0] == 403
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base + "/", timeout=5)  # the page too
        assert err.value.code == 403
        assert heard_alerts(g, 1.0) == []  # nothing was sent
        # with the token: the page, the state and a signed alert
        with urllib.request.urlopen(f"{base}/?token={token}", timeout=5) as resp:
            assert b"<svg" in resp.read()
        assert http("GET", base + "/api/state", headers=ok)[0] == 200
        status, sent = http("POST", base + "/api/alert", {"north_m": 10, "east_m": 20}, ok)
        assert status == 200, sent
        assert {a.alert_id for a in heard_alerts(g, 1.5)} == {sent["alert_id"]}


def test_off_loopback_without_a_token_generates_one(start_dashboard):
    d = start_dashboard("--bind", "0.0.0.0")
    assert "?token=" in d.url
    token = d.url.split("?token=")[1]
    assert len(token) >= 24
    base = f"http://127.0.0.1:{d.port}"
    assert http("GET", base + "/api/state")[0] == 403
    assert http("GET", base + f"/api/state?token={token}")[0] == 200


def test_forged_and_unsigned_alerts_are_not_shown(start_dashboard, key_file, addr):
    d = start_dashboard()
    wrong = Group(7, Signing(bytes(range(32)), time.time), address=addr[0], port=addr[1])
    unsigned = Group(8, None, address=addr[0], port=addr[1])
    right = member_group(addr, 9, load_key(key_file))
    try:
        for k in range(3):
            wrong.send_alert(Alert(f"7-{k}", complex(100, 100), 7, 10.0, "new"))
            wrong.send_state(MemberState(7, 10.0, 0j, 1.0))
            unsigned.send_alert(Alert(f"8-{k}", complex(-100, 100), 8, 10.0, "new"))
            forged_op = Alert(f"255-{k}", complex(0, 300), 255, 10.0, "cleared")
            wrong.send_alert(forged_op)
        right.send_alert(Alert("9-1", complex(50, 50), 9, 10.0, "new"))
        state = poll_state(d, lambda s: s["alerts"] and s["group"]["bad_signature"] >= 9)
        assert [a["alert_id"] for a in state["alerts"]] == ["9-1"]
        assert state["vehicles"] == []
        assert state["group"]["bad_signature"] == 9 and state["group"]["unsigned"] == 3
    finally:
        for g in (wrong, unsigned, right):
            g.close()


def test_view_coverage_gauge_is_the_longest_unseen_time_over_a_period():
    """Pure: one UAV flying the loop at the nominal rate leaves every point unseen for about
    one period less the time its sensor disc covers it."""
    mission = load_mission(MISSION)
    patrol = mission.patrol
    view = FleetView(mission)
    T = patrol.period_s
    dt = 0.2
    for k in range(int(2.5 * T / dt)):
        t = k * dt
        psi = (2 * 3.141592653589793 * t / T) % (2 * 3.141592653589793)
        view.feed(MemberState(1, t, patrol.centre_m, psi), rx_s=t)
        snap = view.snapshot(now_s=t, events=0)
    g = snap["gauges"]
    cover_s = 2 * mission.sensor.footprint_radius_m / (patrol.length_m / T)
    assert T - 2 * cover_s < g["coverage_max_unseen_s"] < T
    assert g["splay_deg"] == 0.0 and g["cross_track_max_m"] < 0.5
    # the fastest crossing it is sure to see: the band 2 r_s over the gap, T / 1 here, as
    # planned T / N (companion/core/guarantee.py)
    band = 2 * mission.sensor.footprint_radius_m
    assert g["crossing_sure_m_s"] == pytest.approx(band / T, abs=0.01)
    assert g["crossing_sure_plan_m_s"] == pytest.approx(band * mission.vehicles.count / T, abs=0.01)
    # a second UAV half a period behind halves it
    view2 = FleetView(mission)
    for k in range(int(2.5 * T / dt)):
        t = k * dt
        for s, lag in ((1, 0.0), (2, 3.141592653589793)):
            psi = (2 * 3.141592653589793 * t / T + lag) % (2 * 3.141592653589793)
            view2.feed(MemberState(s, t, patrol.centre_m, psi), rx_s=t)
        snap2 = view2.snapshot(now_s=t, events=0)
    g2 = snap2["gauges"]
    assert T / 2 - 2 * cover_s < g2["coverage_max_unseen_s"] < T / 2
    assert g2["splay_deg"] < 0.5
    assert g2["crossing_sure_m_s"] == pytest.approx(2 * band / T, abs=0.01)


def test_bad_options_exit_2_and_start_nothing(tmp_path, key_file):
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "companion", *args],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=180,
        )

    out = tmp_path / "run"
    fleet = run("fleet", str(MISSION), "--dashboard", "70000", "--out", str(out))
    assert fleet.returncode == 2 and "--dashboard 70000" in fleet.stderr
    assert not out.exists()
    base = ["dashboard", "--group", "239.255.14.1:14600", "--key-file", str(key_file)]
    short = run(*base, "--bind", "0.0.0.0", "--token", "short")
    assert short.returncode == 2 and "--token" in short.stderr
    not_multicast = run("dashboard", "--group", "10.0.0.1:14600", "--key-file", str(key_file))
    assert not_multicast.returncode == 2 and "multicast" in not_multicast.stderr


def test_view_follows_a_hand_off_and_ignores_repeats():
    """Pure: new by 2, prosecuted by 3, confirmed by 3 (handed off), prosecuted by 4,
    cleared by 4; repeats change nothing and log nothing."""
    view = FleetView(load_mission(MISSION))
    site = complex(230.0, -200.0)
    t = 100.0

    def states(t_s: float, away: dict[int, tuple[str, str]]) -> None:
        for s in (2, 3, 4):
            mode, alert_id = away.get(s, ("patrol", ""))
            view.feed(MemberState(s, t_s, 0j, 0.5 * s, mode, alert_id), rx_s=t_s)

    view.feed(Alert("2-1", site, 2, t, "new"), rx_s=t)
    states(t + 1, {3: ("prosecuting", "2-1")})
    view.feed(Alert("2-1", site, 2, t, "new"), rx_s=t + 1.5)  # a repeat
    view.feed(Alert("2-1", site, 3, t + 10, "confirmed"), rx_s=t + 10)
    view.feed(Alert("2-1", site, 3, t + 10, "confirmed"), rx_s=t + 10.5)  # a repeat
    view.feed(Alert("2-1", site, 2, t, "new"), rx_s=t + 10.6)  # a late first report
    states(t + 11, {3: ("rejoining", "2-1"), 4: ("prosecuting", "2-1")})
    (a,) = view.snapshot(now_s=t + 11)["alerts"]
    assert (a["state"], a["prosecutor_sysid"], a["prosecuting"]) == ("confirmed", 4, True)
    view.feed(Alert("2-1", site, 4, t + 20, "cleared"), rx_s=t + 20)
    view.feed(Alert("2-1", site, 4, t + 20, "new"), rx_s=t + 20.5)  # nothing reopens it
    states(t + 21, {4: ("rejoining", "2-1")})
    snap = view.snapshot(now_s=t + 21, events=100)
    (a,) = snap["alerts"]
    assert a["state"] == "cleared" and a["prosecutor_sysid"] == 4 and not a["prosecuting"]
    assert a["responders"] == [3, 4]
    kinds = [e["kind"] for e in snap["events"] if e.get("alert_id") == "2-1"]
    assert kinds == [
        "alert_new",
        "tasked",
        "alert_confirmed",
        "rejoining",
        "tasked",
        "alert_cleared",
        "rejoining",
    ]
    modes = {v["sysid"]: v["mode"] for v in snap["vehicles"]}
    assert modes == {2: "patrol", 3: "patrol", 4: "rejoining"}


def test_the_page_shows_a_track_its_tracker_a_search_and_a_lost_track():
    """A walker's alert with its track, newer tracks by update, a UAV searching, then
    tracking it, then its tracker losing it: GET /api/state's alert carries the track
    (where it predicts the intruder now, its velocity, sigma, age), the tracker and the
    search, and the lost state ends it."""
    view = FleetView(load_mission(MISSION), member_timeout_s=3.0)
    t = 1000.0
    site = complex(230.0, -215.0)
    walk = complex(-1.1, 1.1)
    track = Track(t, site, walk, 2.0, 0.3, 20)
    view.feed(Alert("2-1", site, 2, t, "new", track=track), rx_s=t)
    later = Track(t + 10, site + 10 * walk, walk, 1.5, 0.2, 45)
    view.feed(Alert("2-1", later.pos_m, 3, t + 10, "update", track=later), rx_s=t + 10)
    view.feed(MemberState(3, t + 11, 0j, 0.5, "searching", "2-1"), rx_s=t + 11)
    (a,) = view.snapshot(now_s=t + 11)["alerts"]
    assert a["state"] == "new" and a["searching"] and a["prosecuting"]
    k = a["track"]
    assert (k["t_s"], k["sightings"], k["speed_m_s"]) == (t + 10, 45, round(abs(walk), 2))
    assert (k["north_m"], k["east_m"]) == (round(later.pos_m.real, 2), round(later.pos_m.imag, 2))
    pred = later.predict(t + 11)
    assert (k["predicted_north_m"], k["predicted_east_m"]) == (
        round(pred.real, 2),
        round(pred.imag, 2),
    )
    assert k["age_s"] == 1.0 and k["sigma_m"] == round(later.sigma_m(t + 11), 1)
    view.feed(MemberState(3, t + 20, 0j, 0.5, "tracking", "2-1"), rx_s=t + 20)
    (a,) = view.snapshot(now_s=t + 20)["alerts"]
    assert a["tracker_sysid"] == 3 and not a["searching"]
    view.feed(Alert("2-1", site, 3, t + 60, "lost"), rx_s=t + 60)
    snap = view.snapshot(now_s=t + 60, events=100)
    (a,) = snap["alerts"]
    assert a["state"] == "lost" and a["tracker_sysid"] is None
    kinds = [e["kind"] for e in snap["events"] if e.get("alert_id") == "2-1"]
    assert kinds[0] == "alert_new" and "tracking" in kinds and kinds[-1] == "alert_lost"
    json.dumps(snap, allow_nan=False)  # the page's JSON


def test_the_page_draws_a_turning_tracks_path_estimate_with_its_model_and_band():
    """A vehicle's track in the turn model: the alert's track carries the model in use, its
    probability and rate, and the path estimate along the arc with a sigma that grows."""
    import cmath
    import math

    view = FleetView(load_mission(MISSION), member_timeout_s=3.0)
    t = 1000.0
    site = complex(230.0, -215.0)
    tr = Track(t, site, 10.0 + 0j, 2.0, 0.5, 20, "turn", 0.7, 0.1, 2.0)
    view.feed(Alert("2-1", site, 2, t, "new", track=tr), rx_s=t)
    (a,) = view.snapshot(now_s=t + 2)["alerts"]
    k = a["track"]
    assert (k["model"], k["model_p"], k["turn_deg_s"]) == ("turn", 0.7, round(math.degrees(0.1), 1))
    path = k["path"]
    now = t + k["age_s"]  # the view's time: the newest message's
    assert len(path) == 7 and [path[0][0], path[0][1]] == [
        round(tr.predict(now).real, 1),
        round(tr.predict(now).imag, 1),
    ]
    # along the arc: 10 s on, 0.1 rad/s off the straight line (a quarter turn takes 15.7 s)
    dt = now + 10.0 - t
    arc = site + 10.0 * (cmath.exp(1j * 0.1 * dt) - 1) / (1j * 0.1)
    assert abs(complex(path[2][0], path[2][1]) - arc) < 0.2
    assert abs(complex(path[2][0], path[2][1]) - (site + 10.0 * dt)) > 20.0
    sigmas = [p[2] for p in path]
    assert sigmas == sorted(sigmas) and sigmas[-1] > 5 * sigmas[0]
    html = (Path(__file__).parents[1] / "companion/dashboard/static/index.html").read_text()
    assert "track-path" in html and "track-band" in html
