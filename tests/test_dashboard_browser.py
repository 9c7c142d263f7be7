"""The live patrol page in a real browser: Chromium from the distribution's packages, driven
by Playwright for Python (``executable_path``; Playwright's own browser builds are never
downloaded). Skipped, with the reason, where no Chromium or Playwright is installed.

* During a real fleet run (``companion fleet tests/data/companion_ellipse_fast.yaml
  --dashboard PORT``): the page shows six UAVs and the loop, the scenario's alert with its
  prosecutor; a click on the map raises an alert (confirmed in the dialog) and exactly one
  UAV answers it.
* Against a dashboard on a test group: the map click sends a signed alert at the clicked
  point and the alert table's Cancel button sends the operator's clear.
* With spares: every frame of an in-memory relief run (``tests/relief_frames.py``: the four
  spares on the ground, one climbing out, in the slot, the tired UAV going home and landing)
  is sent to a dashboard on a test group, and the page's gauges and counts (splay, T/N,
  members; spares, climbing out, going home) and ``GET /api/state``'s are those of the
  aircraft in the formation, computed independently from the frame's states; every UAV has
  its own icon, none on another; at most one standing warning and one log line per late
  relief.

Screenshots go to the test's folder, or to ``$DASHBOARD_SCREENSHOT_DIR`` (e.g. ``docs/img``).
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

from companion.group.keys import load_key
from companion.group.messages import Alert, MemberState
from companion.mission import load_mission
from tests import test_dashboard as td
from tests.relief_frames import MISSION as RELIEF
from tests.relief_frames import Frame, relief_frames
from tests.test_dashboard import heard_alerts, http, member_group, poll_state

addr, key_file, start_dashboard = td.addr, td.key_file, td.start_dashboard  # fixtures

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
try:
    from playwright.sync_api import expect, sync_playwright
except ImportError:  # pragma: no cover - depends on the machine
    expect = sync_playwright = None

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed (apt-get install chromium)"),
    pytest.mark.skipif(sync_playwright is None, reason="Playwright for Python is not installed"),
]


@pytest.fixture
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        try:
            yield b
        finally:
            b.close()


def shots(tmp_path: Path) -> Path:
    folder = Path(os.environ.get("DASHBOARD_SCREENSHOT_DIR") or tmp_path)
    if not folder.is_absolute():
        folder = ROOT / folder
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_http(url: str, proc: subprocess.Popen, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with urllib.request.urlopen(url, timeout=2):
                return
        except OSError:
            assert proc.poll() is None, "the fleet exited early"
            assert time.monotonic() < deadline, f"{url} did not answer"
            time.sleep(0.5)


def screen_xy(page, north_m: float, east_m: float) -> tuple[float, float]:
    """Where the map draws local point (north, east) on the screen (CSS pixels)."""
    return page.evaluate(
        """([n, e]) => { const svg = document.getElementById('map');
            const p = svg.createSVGPoint(); p.x = e; p.y = -n;
            const q = p.matrixTransform(svg.getScreenCTM()); return [q.x, q.y]; }""",
        [north_m, east_m],
    )


def page_picture(page) -> dict:
    """UAVs (sysid -> (mode, alert)) and alerts (id -> (state, prosecutor)) as drawn."""
    return page.evaluate(
        """() => ({
          uavs: [...document.querySelectorAll('#vehicles tbody tr')].map(
            r => [r.dataset.sysid, r.dataset.mode, r.children[6].textContent]),
          alerts: [...document.querySelectorAll('#alerts tbody tr')].map(
            r => [r.dataset.alertId, r.dataset.state, r.dataset.prosecutor,
                  r.querySelector('.prosecutor').textContent, r.dataset.responders]),
          markers: document.querySelectorAll('#uavs g.uav').length })"""
    )


def wait_picture(page, until, timeout_s: float, what: str) -> dict:
    deadline = time.monotonic() + timeout_s
    while True:
        pic = page_picture(page)
        if until(pic):
            return pic
        assert time.monotonic() < deadline, f"timed out waiting for {what}: {pic}"
        page.wait_for_timeout(200)


@pytest.mark.extended
@pytest.mark.slow
def test_page_during_a_fleet_run(browser, tmp_path):
    out = tmp_path / "run"
    port = free_tcp_port()
    # the fast test mission: its decoy comes at 180 s (the paper mission's at 600 s), and
    # the run ends before its persistent intruder (400 s)
    cmd = [
        sys.executable,
        "-m",
        "companion",
        "fleet",
        str(ROOT / "tests/data/companion_ellipse_fast.yaml"),
    ]
    cmd += ["--dashboard", str(port), "--speedup", "10", "--duration", "390"]
    cmd += ["--out", str(out), "--no-progress"]
    fleet = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    folder = shots(tmp_path)
    try:
        url = f"http://127.0.0.1:{port}/"
        wait_http(url + "api/state", fleet, 120)
        page = browser.new_page(viewport={"width": 1400, "height": 860})
        page.goto(url)
        # six UAVs and the loop
        wait_picture(page, lambda p: len(p["uavs"]) == 6 and p["markers"] == 6, 120, "6 UAVs")
        assert len(page.get_attribute("#loop", "points").split()) >= 100
        assert "live" in page.inner_text("#conn")
        page.screenshot(path=str(tmp_path / "dashboard_start.png"))

        # the scenario's alert (the decoy at 180 s) appears with its prosecutor
        pic = wait_picture(
            page,
            lambda p: any(a[2] and not a[0].startswith("255-") for a in p["alerts"]),
            600,
            "the scenario's alert with a prosecutor",
        )
        (scenario,) = [a for a in pic["alerts"] if not a[0].startswith("255-")]
        assert scenario[3].startswith(f"UAV {scenario[2]}")
        page.screenshot(path=str(folder / "dashboard_alert.png"))
        # ... is cleared (the decoy vanished) and its prosecutor is back on patrol
        wait_picture(
            page,
            lambda p: (
                all(a[1] in ("cleared", "lost") for a in p["alerts"])
                and all(u[1] == "patrol" for u in p["uavs"])
            ),
            300,
            "the scenario's alert cleared and every UAV on patrol",
        )
        page.screenshot(path=str(folder / "dashboard.png"))

        # the operator clicks the map, confirms, and exactly one UAV answers
        site = (-300.0, 160.0)  # 30 m outside the loop, south-east
        x, y = screen_xy(page, *site)
        page.mouse.click(x, y)
        dialog = page.locator("#confirm")
        assert dialog.is_visible()
        assert "north -300 m, east 160 m" in page.inner_text("#confirmText")
        page.click("#confirmYes")
        pic = wait_picture(
            page,
            lambda p: any(a[0].startswith("255-") and a[2] for a in p["alerts"]),
            120,
            "the operator's alert with a prosecutor",
        )
        (op,) = [a for a in pic["alerts"] if a[0].startswith("255-")]
        page.screenshot(path=str(folder / "dashboard_operator.png"))
        answering: set[str] = set()
        deadline = time.monotonic() + 240
        while True:  # until the prosecutor has flown there and is back on patrol
            p = page_picture(page)
            answering |= {u[0] for u in p["uavs"] if u[1] == "prosecuting" and u[2] == op[0]}
            (row,) = [a for a in p["alerts"] if a[0] == op[0]]
            if row[1] == "cleared" and all(u[1] == "patrol" for u in p["uavs"]):
                break
            assert time.monotonic() < deadline, p
            page.wait_for_timeout(200)
        # every UAV seen prosecuting it, by the page (its table) and by the server (all the
        # states it heard): the one prosecutor
        assert row[4] == op[2] and answering <= {op[2]}
        assert "[" not in row[3]  # no second responder listed
        log = page.inner_text("#log")
        assert f"operator raised alert {op[0]}" in log
        assert f"alert {op[0]}: UAV {op[2]} prosecuting" in log
    finally:
        if fleet.poll() is None:
            fleet.send_signal(signal.SIGINT)
        try:
            output, _ = fleet.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            fleet.kill()
            output, _ = fleet.communicate()
    assert fleet.returncode in (0, 130), output[-3000:]
    assert "unclean exits" not in output, output[-3000:]
    leftover = subprocess.run(["pgrep", "-af", str(out)], capture_output=True, text=True).stdout
    assert [ln for ln in leftover.splitlines() if "pgrep" not in ln] == []
    with pytest.raises(OSError):  # the page's port was released
        urllib.request.urlopen(f"http://127.0.0.1:{port}/api/state", timeout=2)


def test_page_click_sends_an_alert_and_cancel_clears_it(
    browser, start_dashboard, key_file, addr, tmp_path
):
    d = start_dashboard()
    with member_group(addr, 3, load_key(key_file)) as g:
        g.send_state(MemberState(3, 50.0, 0j, 2.0))
        g.send_alert(Alert("3-1", complex(230.0, -200.0), 3, 50.0, "new"))
        poll_state(d, lambda s: s["vehicles"] and s["alerts"])
        page = browser.new_page(viewport={"width": 1200, "height": 800})
        page.goto(d.url)
        pic = wait_picture(page, lambda p: p["uavs"] and p["alerts"], 20, "a UAV and an alert")
        assert pic["uavs"][0][0] == "3" and pic["alerts"][0][0] == "3-1"
        heard_alerts(g, 0.2)  # drop what is queued

        x, y = screen_xy(page, -120.0, 80.0)
        page.mouse.click(x, y)
        assert page.locator("#confirm").is_visible()
        page.click("#confirmYes")
        got = heard_alerts(g, 2.0)
        assert {(a.state, a.detector_sysid) for a in got} == {("new", 255)}
        assert abs(got[0].site_m - complex(-120.0, 80.0)) < 5.0  # a few pixels of the map

        # a dismissed dialog sends nothing
        page.mouse.click(x + 30, y)
        page.click("#confirmNo")
        assert heard_alerts(g, 1.0) == []

        page.click('#alerts tr[data-alert-id="3-1"] button.cancel')
        assert "Cancel alert 3-1" in page.inner_text("#confirmText")
        page.click("#confirmYes")
        got = heard_alerts(g, 2.0)
        assert {(a.alert_id, a.state, a.detector_sysid) for a in got} == {("3-1", "cleared", 255)}
        wait_picture(
            page,
            lambda p: [a[1] for a in p["alerts"] if a[0] == "3-1"] == ["cleared"],
            10,
            "3-1 cleared",
        )
        page.screenshot(path=str(tmp_path / "dashboard_test_group.png"))


def test_page_with_a_token_off_loopback(browser, start_dashboard, key_file, addr):
    token = "k" * 20
    d = start_dashboard("--bind", "0.0.0.0", "--token", token)
    base = f"http://127.0.0.1:{d.port}/"
    page = browser.new_page(viewport={"width": 1200, "height": 800})
    assert page.goto(base).status == 403  # no token: not even the page
    page.goto(f"{base}?token={token}")  # the page passes it on to its stream and posts
    # a locator wait, not wait_for_function: the page's CSP forbids eval, which newer
    # Chromium builds enforce on Playwright's string predicates
    expect(page.locator("#conn")).to_have_text("live", timeout=20_000)
    with member_group(addr, 2, load_key(key_file)) as g:
        x, y = screen_xy(page, 0.0, 250.0)
        page.mouse.click(x, y)
        page.click("#confirmYes")
        got = heard_alerts(g, 2.0)
    assert {(a.state, a.detector_sysid) for a in got} == {("new", 255)}


FRAME_JS = """() => {
  const c = document.getElementById('counts'), g = document.querySelectorAll('#gauges .gauge');
  const icons = [...document.querySelectorAll('#uavs g.uav')].map(u => {
    const r = u.querySelector('.icon').getBoundingClientRect();
    return [u.dataset.sysid, r.x + r.width / 2, r.y + r.height / 2]; });
  return {
    rows: [...document.querySelectorAll('#vehicles tbody tr')].map(
      r => [r.dataset.sysid, r.dataset.tS, r.dataset.station]),
    counts: Object.assign({}, c.dataset), countsText: c.textContent,
    splayText: g[0].querySelector('.val').textContent,
    splayColour: g[0].querySelector('.bar i').style.background,
    icons: icons,
    warnings: [...document.querySelectorAll('#warnings .warning')].map(w => w.dataset.member),
    log: [...document.querySelectorAll('#log div')].map(d => d.textContent) }; }"""


def wait_frame(page, frame: Frame, resend, timeout_s: float) -> dict:
    """The page's picture once it shows every state of ``frame`` (``resend()`` every 2 s
    meanwhile: a datagram lost on the way is sent again)."""
    want = {str(s): st.t_s for s, st in frame.states.items()}
    deadline = time.monotonic() + timeout_s
    resent = time.monotonic()
    while True:
        pic = page.evaluate(FRAME_JS)
        rows = {sysid: float(t) for sysid, t, _ in pic["rows"]}
        if rows.keys() == want.keys() and all(abs(rows[s] - t) < 1e-3 for s, t in want.items()):
            return pic
        assert time.monotonic() < deadline, f"the page never showed the frame at {frame.t_s} s"
        if time.monotonic() - resent > 2.0:
            resend()
            resent = time.monotonic()
        page.wait_for_timeout(50)


@pytest.fixture(scope="module")
def relief_run() -> list[Frame]:
    return relief_frames(duration_s=490.0, every_s=10.0)


@pytest.mark.slow
def test_page_counts_the_aircraft_on_the_loop_in_every_frame_of_a_relief_run(
    browser, start_dashboard, key_file, addr, relief_run, tmp_path
):
    d = start_dashboard("--mission", str(RELIEF), "--member-timeout-s", "300", mission=False)
    period_s = load_mission(RELIEF).patrol.period_s
    key = load_key(key_file)
    page = browser.new_page(viewport={"width": 1400, "height": 860})
    page.goto(d.url)
    expect(page.locator("#conn")).to_have_text("live", timeout=20_000)
    groups = {}
    seen = {"spares": 0, "climbing_out": 0, "going_home": 0}
    try:
        for frame in relief_run:

            def send(frame=frame):
                for s, st in sorted(frame.states.items()):
                    if s not in groups:
                        groups[s] = member_group(addr, s, key)
                    groups[s].send_state(st)

            send()
            pic = wait_frame(page, frame, send, 30.0)
            exp = frame.expected(period_s)
            at = f"frame at {frame.t_s} s: {pic['countsText']}"
            # the counts: the formation, and the others apart, on the page and in the API
            c = pic["counts"]
            got = {k: int(c[k]) for k in ("members", "spares", "climbingOut", "goingHome")}
            assert got == {"members": exp["members"], "spares": exp["spares"],
                           "climbingOut": exp["climbing_out"],
                           "goingHome": exp["going_home"]}, at  # fmt: skip
            text = f"{exp['members']} on the loop"
            assert pic["countsText"].startswith(text), at
            assert f"{exp['spares']} spares waiting, {exp['climbing_out']} climbing out, " \
                   f"{exp['going_home']} going home" in pic["countsText"], at  # fmt: skip
            assert f"T/N = {exp['ideal_s']:.1f} s" in pic["countsText"], at
            assert float(c["idealS"]) == pytest.approx(exp["ideal_s"], abs=0.006), at
            splay = float(pic["splayText"].split()[0])
            assert splay == pytest.approx(exp["splay_deg"], abs=0.006), at
            if frame.t_s >= 200.0:  # converged: green or amber, never the red 36 deg
                assert splay < 2.0 and "prosecuting" not in pic["splayColour"], at
            status, api = http("GET", d.base + "/api/state?events=500")
            assert status == 200
            g = api["gauges"]
            assert (g["members"], g["spares"], g["climbing_out"], g["going_home"]) == (
                exp["members"],
                exp["spares"],
                exp["climbing_out"],
                exp["going_home"],
            ), at
            assert g["splay_deg"] == pytest.approx(exp["splay_deg"], abs=1e-3), at
            assert g["coverage_ideal_s"] == pytest.approx(exp["ideal_s"], abs=0.006), at
            # every UAV its own icon, none on another (the spares share one base)
            assert sorted(int(s) for s, _, _ in pic["icons"]) == sorted(frame.states), at
            xy = [(x, y) for _, x, y in pic["icons"]]
            closest = min(math.dist(a, b) for i, a in enumerate(xy) for b in xy[i + 1 :])
            assert closest >= 12.0, at  # icons are 12 px across
            # one standing warning per late relief, and one log line each
            assert len(pic["warnings"]) == len(set(pic["warnings"])), at
            assert sorted(pic["warnings"]) == sorted(
                str(w["member_sysid"]) for w in api["warnings"]
            ), at
            late = [ln.split("  ", 1)[1].split(":")[0] for ln in pic["log"] if ": relief " in ln]
            assert len(late) == len(set(late)), at
            for k in seen:
                seen[k] += exp[k] > 0
            if seen["going_home"] == 1 and exp["going_home"]:  # the first going home
                page.screenshot(path=str(shots(tmp_path) / "dashboard_relief.png"))
    finally:
        for g in groups.values():
            g.close()
    assert seen["climbing_out"] >= 3 and seen["going_home"] >= 3  # the run had both
    assert len(relief_run) == 49
