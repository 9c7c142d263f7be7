"""Integration tests: the real simulator and six real ``companion run`` processes over loopback.

Every test starts the companions first (they wait for their autopilots), then
``python -m sitl_model`` at a speed-up, and always stops every process in a finaliser,
asserting exit status 0 on SIGTERM and that none is left. Formation and episode measures
are judged from the simulator's truth log plus the companions' events.
"""

from __future__ import annotations

import json
import socket
import threading
import time

import numpy as np
import pytest

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.mission import load_mission
from companion.report.metrics import loop_geometry
from tests.fleet_harness import (
    FAST,
    PAPER,
    companion_cli,
    companion_events,
    episode,
    final_status,
    group_listener,
    last_truth_time,
    measures,
    plans_for,
    quiet_mission,
    report,
    status_field,
)

# real processes or sockets, wall clock; alone: the pilot override's length is wall time
pytestmark = [pytest.mark.integration, pytest.mark.alone]


# ---- tests -------------------------------------------------------------------------------
@pytest.mark.extended
@pytest.mark.slow
def test_fast_mission_formation_decoy_and_persistent_intruder(fleet_factory):
    """Turn-rate profile: converges, the decoy is cleared by the next UAV, the persistent
    intruder is confirmed and handed on, and nobody else leaves its slot. Extended tier
    (60 s): the same checks run in the default tier in memory
    (tests/test_alert_simulation.py), and tests/test_inmemory_equivalence.py flies this
    mission over UDP against the in-memory run."""
    f = fleet_factory()
    f.wait_sim_time(480.0, timeout_s=150)
    m, events = measures(f.out, FAST)
    t_alert = min(e["t_s"] for e in events if e["event"] == "alert_new")
    conv = m.convergence_time_s(t_alert)
    ep = episode(m, events, FAST, complex(230, -200))
    confirmed = [e for e in events if e["event"] == "alert_confirmed"]
    persist = {e["alert_id"] for e in events if e["event"] == "alert_new" and e["east_m"] > 0}
    handoffs = sorted(
        {
            (e["t_s"], e["sysid"])
            for e in events
            if e["event"] == "plan" and e["alert_id"] in persist
        }
    )
    report(
        "fast",
        {
            "convergence_s": conv,
            "splay_deg_at_alert": float(m.splay_deg[m.t_s <= t_alert][-1]),
            "centre_m_at_alert": float(m.centre_m[m.t_s <= t_alert][-1]),
            **ep,
            "persistent_prosecutors": handoffs,
        },
    )
    assert conv is not None  # converged before the alert, and held until it
    assert ep["prosecutors"] == {ep["prosecutor"]}
    assert ep["prosecutor"] == ep["expected"]
    assert set(ep["tasked_by"].values()) == {ep["prosecutor"]}
    assert abs(ep["arrive_s"] - ep["planned_s"]) <= 0.05 * ep["planned_s"]
    assert ep["miss_m"] < 15.0
    assert ep["outcome"] in ("cleared", "lost")  # not found: "lost" after a short detection
    assert ep["rejoined"] is not None and ep["rejoined"]["in_slot"]
    # the episode does not disturb the others (the strict 2 m is the paper test's, after
    # 600 s of convergence; here the formation has had 180 s)
    before = (m.t_s > t_alert - 30) & (m.t_s <= t_alert)
    others = [j for j, s in enumerate(m.sysids) if s != ep["prosecutor"]]
    settled = float(np.max(np.abs(m.centres_m[before][:, others])))
    assert ep["others_max_centre_m"] < max(2.0, settled + 1.0)
    assert confirmed, "the persistent intruder was never confirmed"
    assert len({s for _, s in handoffs}) >= 2, "not handed on to a second UAV"


@pytest.mark.extended
@pytest.mark.slow
def test_paper_mission(fleet_factory):
    """missions/ellipse_6uav.yaml: converged by 600 s; the decoy at north 230, east -200 is
    prosecuted by exactly the next UAV, on time; the others stay within 2 m of the loop; it
    rejoins. Extended tier (90 s): the same checks run in the default tier on the in-memory
    run (tests/test_simulate_cli.py::test_paper_mission_claims_hold_in_memory), and the
    fast mission over UDP (tests/test_inmemory_equivalence.py) flies the same stack and
    decoy over loopback."""
    f = fleet_factory(mission=PAPER)
    f.wait_sim_time(700.0, timeout_s=200)
    m, events = measures(f.out, PAPER)
    t_alert = min(e["t_s"] for e in events if e["event"] == "alert_new")
    conv = m.convergence_time_s(t_alert)
    ep = episode(m, events, PAPER, complex(230, -200))
    report(
        "paper",
        {
            "convergence_s": conv,
            "splay_deg_at_alert": float(m.splay_deg[m.t_s <= t_alert][-1]),
            "centre_m_at_alert": float(m.centre_m[m.t_s <= t_alert][-1]),
            **ep,
        },
    )
    assert conv is not None and t_alert >= 600.0
    assert ep["prosecutors"] == {ep["prosecutor"]} and ep["prosecutor"] == ep["expected"]
    assert set(ep["tasked_by"].values()) == {ep["prosecutor"]}
    assert abs(ep["arrive_s"] - ep["planned_s"]) <= 0.05 * ep["planned_s"]
    assert ep["outcome"] == "cleared"
    assert ep["rejoined"] is not None and ep["rejoined"]["in_slot"]
    # the paper's bound, no other UAV's centre error above 2 m during the episode, read
    # where the others really were: within 2 m of the loop. The course-based centre error
    # (from the true course) already read 2.3-2.4 m before the tasking with the phase held
    # by airspeed (0.8 m at a fixed airspeed): the episode must not raise it (docs/companion.md)
    assert ep["others_max_offset_m"] < 2.0
    assert ep["others_max_centre_m"] <= ep["others_max_centre_before_m"] + 0.5


@pytest.mark.slow
def test_operator_alerts_signed_only_and_pilot_override(fleet_factory, tmp_path):
    """A signed operator alert is prosecuted; unsigned, wrong-key and replayed copies move no
    UAV. A vehicle switched to LOITER stops getting setpoints within one control period and
    is steered back to the loop after GUIDED returns (its slot: tests/test_inmemory.py)."""
    from sitl_model.testing import MavClient

    key, wrong = tmp_path / "fleet.key", tmp_path / "wrong.key"
    assert companion_cli("keygen", str(key)).returncode == 0
    assert companion_cli("keygen", str(wrong)).returncode == 0
    mission = quiet_mission(tmp_path)
    f = fleet_factory(mission=mission, key_file=key)
    group = next(a for a in f.companions[0].proc.args if a.startswith("239.255."))
    listener = group_listener(group)
    f.wait_sim_time(40.0)
    site = "--at=-250,180"
    common = ["--group", group, "--listen-s", "1", site]
    bad1 = companion_cli("alert", "--insecure", "--alert-id", "op-unsigned", *common)
    bad2 = companion_cli("alert", "--key-file", str(wrong), "--alert-id", "op-wrongkey", *common)
    assert bad1.returncode == 0 and bad2.returncode == 0, bad1.stderr + bad2.stderr
    captured: list[bytes] = []
    stop = threading.Event()

    def capture() -> None:  # drain concurrently: the members' states would overflow it
        listener.settimeout(0.05)
        while not stop.is_set():
            try:
                data = listener.recv(4096)
            except TimeoutError:
                continue
            if data[0] == 0xFD and data[5] == 255:  # MAVLink 2 from the operator (sysid 255)
                captured.append(data)

    th = threading.Thread(target=capture, daemon=True)
    th.start()
    good = companion_cli("alert", "--key-file", str(key), "--alert-id", "op-good", *common)
    time.sleep(0.3)
    stop.set()
    th.join(2.0)
    assert good.returncode == 0, good.stderr
    assert captured, "did not capture the operator's alert"
    t_good = last_truth_time(f.out / "truth.csv")
    f.wait_sim_time(t_good + 30.0)
    plans = plans_for(f.out, "op-good")
    assert len({e["sysid"] for e in plans}) == 1  # prosecuted by exactly one UAV
    assert not plans_for(f.out, "op-unsigned") and not plans_for(f.out, "op-wrongkey")
    assert not [e for e in companion_events(f.out) if "op-unsigned" in str(e.get("alert_id"))]
    prosecutor = plans[0]["sysid"]
    # replay the captured signed datagram: dropped as replayed, no new plan
    addr, port = group.rsplit(":", 1)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
        tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
        for data in captured:
            tx.sendto(data, (addr, int(port)))
    # pilot override on a UAV that is not away
    k = next(s for s in range(1, 7) if s != prosecutor)
    client = MavClient(f.port(k - 1), sysid=254)

    def set_mode(mode: int) -> None:
        for _ in range(3):  # the telemetry backlog can overflow the socket: drain, retry
            client.drain()
            try:
                assert client.command_long(176, 1, mode, target=k).result == 0
                return
            except TimeoutError:
                continue
        raise TimeoutError(f"mode {mode} not acknowledged")

    try:
        set_mode(12)  # LOITER
        f.wait_sim_time(last_truth_time(f.out / "truth.csv") + 15.0)
        set_mode(15)  # GUIDED
        f.wait_sim_time(last_truth_time(f.out / "truth.csv") + 120.0, timeout_s=120)
    finally:
        client.close()
    listener.close()
    codes = f.stop()
    assert codes == [0] * 7
    assert len({e["sysid"] for e in plans_for(f.out, "op-good")}) == 1
    finals = [final_status(c) for c in f.companions]
    drops = [json.loads(status_field(ln, "drops")) for ln in finals]
    assert all(d.get("unsigned", 0) >= 1 for d in drops), drops
    assert all(d.get("bad_signature", 0) >= 1 for d in drops), drops
    assert sum(d.get("replayed", 0) for d in drops) >= 6, drops
    # the override, from the simulator's events and the companion's log and tlog
    sim_events = [json.loads(ln) for ln in (f.out / "sitl_events.jsonl").read_text().splitlines()]
    changes = [e for e in sim_events if e["event"] == "mode_change" and e.get("sysid") == k]
    t_loiter = next(e["t_s"] for e in changes if e["to"] == "LOITER")
    t_guided = next(e["t_s"] for e in changes if e["to"] == "GUIDED" and e["t_s"] > t_loiter)
    evs = [e for e in companion_events(f.out) if e.get("sysid") == k]
    t_override = next(e["t_s"] for e in evs if e["event"] == "override")
    t_resumed = next(e["t_s"] for e in evs if e["event"] == "resumed")
    from pymavlink import mavutil

    log = mavutil.mavlink_connection(str(f.out / f"c{k}" / "autopilot.tlog"))
    setpoint_times = []
    while (msg := log.recv_match(type="SET_ATTITUDE_TARGET")) is not None:
        setpoint_times.append(msg._timestamp - SIM_EPOCH_UNIX_S)
    log.close()
    during = [t for t in setpoint_times if t_loiter + 0.1 < t < t_guided]
    last_before = max(t for t in setpoint_times if t <= t_loiter + 0.1 + 1e-6)
    m, _ = measures(f.out, mission)
    j = m.sysids.index(k)
    after = (m.t_s > t_guided) & (m.t_s < t_guided + 115.0)  # the companions still run
    back = (m.t_s > t_guided + 100.0) & (m.t_s < t_guided + 115.0)
    peak = float(np.max(np.abs(m.centres_m[after, j])))
    _, loop = loop_geometry(load_mission(mission).patrol)
    report(
        "override",
        {
            "sysid": k,
            "t_loiter": t_loiter,
            "t_override_logged": t_override,
            "last_setpoint_after_loiter_s": last_before - t_loiter,
            "setpoints_in_loiter": len(during),
            "t_guided": t_guided,
            "t_resumed": t_resumed,
            "centre_m_peak_after_guided": peak,
            "centre_m_100s_after_guided": float(np.max(np.abs(m.centres_m[back, j]))),
            "cross_track_m_100s_after_guided": float(np.max(loop.distance_m(m.pos_m[back, j]))),
            "closest_to_loop_after_guided_m": float(np.min(loop.distance_m(m.pos_m[after, j]))),
            "drops": drops,
        },
    )
    # events carry the latest vehicle time known (the last position, <= 0.1 s old), the
    # simulator's the step of the change: equal within a control period
    assert abs(t_override - t_loiter) <= 0.2
    assert not during  # no setpoint while the pilot had it
    assert abs(t_resumed - t_guided) <= 0.2
    # steered back to the loop (true distance under 5 m at some point after GUIDED). Its
    # return into its slot is checked in memory (test_inmemory.py): here the others drop it
    # after the member timeout and re-splay twice, and the length of the loiter depends on
    # the wall time the mode commands take (10 s of flight per second at 10x)
    assert float(np.min(loop.distance_m(m.pos_m[after, j]))) < 5.0
