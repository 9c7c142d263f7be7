"""The simulator's geofence (issue 14): FENCE items over the mission protocol, the mission's
fence loaded at start, and a breach that switches to RTL with a STATUSTEXT and an event."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_model.autopilot import Mode, Setpoint, SetpointKind
from sitl_model.cli import build, build_parser
from sitl_model.codec import Decoder, Encoder, dialect
from sitl_model.fence import FENCE_VERTEX_INCLUSION, breaches, fence_fault
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.testing import REPO

PAPER = str(REPO / "missions" / "ellipse_6uav.yaml")
FENCE = dialect.MAV_MISSION_TYPE_FENCE


def _decoded(msg):
    """A message as the peer's bytes would decode (so it has a source system/component)."""
    return Decoder().decode(Encoder(255, 190).pack(msg))[0][0]


def _vertex(seq: int, n: int, lat: float, lon: float, command: int = FENCE_VERTEX_INCLUSION):
    return dialect.MAVLink_mission_item_int_message(
        1, 1, seq, 0, command, 0, 1, n, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 0.0, FENCE
    )


SQUARE = [(39.79, -84.01), (39.81, -84.01), (39.81, -83.99), (39.79, -83.99)]


def _upload(mp: MissionProtocol, items, peer="A"):
    out = mp.handle(
        _decoded(dialect.MAVLink_mission_count_message(1, 1, len(items), FENCE)), peer, 0
    )
    for it in items:
        assert out[0][0].get_type() == "MISSION_REQUEST_INT" and out[0][0].mission_type == FENCE
        out = mp.handle(_decoded(it), peer, 0.1)
    return out[0][0]


def test_fence_upload_download_round_trip_in_memory():
    mp = MissionProtocol()
    ack = _upload(mp, [_vertex(k, 4, *p) for k, p in enumerate(SQUARE)])
    assert ack.get_type() == "MISSION_ACK" and ack.type == 0 and ack.mission_type == FENCE
    assert mp.items == () and len(mp.fence) == 4 and mp.fence_version == 1  # mission untouched
    req = dialect.MAVLink_mission_request_list_message(1, 1, FENCE)
    ((count, _),) = mp.handle(_decoded(req), "A", 1.0)
    assert count.count == 4 and count.mission_type == FENCE
    back = []
    for k in range(4):
        req = dialect.MAVLink_mission_request_int_message(1, 1, k, FENCE)
        back.append(mp.handle(_decoded(req), "A", 1.0)[0][0])
    assert [(m.command, m.param1, m.x, m.y, m.mission_type) for m in back] == [
        (5001, 4.0, round(a * 1e7), round(b * 1e7), FENCE) for a, b in SQUARE
    ]
    mission = dialect.MAVLink_mission_request_list_message(1, 1, 0)
    assert mp.handle(_decoded(mission), "A", 1.0)[0][0].count == 0  # the types stay apart
    clear = dialect.MAVLink_mission_clear_all_message(1, 1, FENCE)
    assert mp.handle(_decoded(clear), "A", 2.0)[0][0].type == 0 and mp.fence == ()


@pytest.mark.parametrize(
    "items",
    [
        [_vertex(k, 3, *p) for k, p in enumerate(SQUARE)],  # count 3, four vertices
        [_vertex(k, 2, *p) for k, p in enumerate(SQUARE[:2])],  # two vertices
        [_vertex(k, 4, *p, command=16) for k, p in enumerate(SQUARE)],  # a waypoint
    ],
)
def test_malformed_fence_upload_is_refused_and_the_old_fence_kept(items):
    mp = MissionProtocol()
    _upload(mp, [_vertex(k, 4, *p) for k, p in enumerate(SQUARE)])
    ack = _upload(mp, items, peer="B")
    assert ack.type == dialect.MAV_MISSION_INVALID and len(mp.fence) == 4
    assert mp.events[-1][0] == "fence_upload_refused"
    assert fence_fault(mp.fence) is None


def test_breaches_of_polygon_and_altitude():
    sq = [np.array([-100 - 100j, 100 - 100j, 100 + 100j, -100 + 100j])]
    pos = np.array([0j, 150 + 0j, 0j, 0j])
    alt = np.array([50.0, 50.0, 250.0, 5.0])
    assert breaches(pos, alt, [sq] * 4, 10.0, 200.0, 13) == [None, "polygon", "max_alt", "min_alt"]
    assert breaches(pos, alt, [sq] * 4, 10.0, 200.0, 5) == [None, "polygon", "max_alt", None]
    assert breaches(pos, alt, [[]] * 4, 10.0, 200.0, 4) == [None] * 4  # no polygon stored


def _sim(*params: str):
    args = build_parser().parse_args(
        ["--mission", PAPER, *(a for p in params for a in ("--param", p))]
    )
    return build(args)


def test_sitl_model_mission_loads_the_fence_into_every_vehicle():
    sim, links, _ = _sim()
    assert sim.params["FENCE_ENABLE"] == 0.0  # ArduPilot's default: off until enabled
    assert (sim.params["FENCE_ALT_MIN"], sim.params["FENCE_ALT_MAX"]) == (50.0, 200.0)
    for i, link in enumerate(links):
        assert len(link.missions.fence) == 32 and {it.command for it in link.missions.fence} == {
            FENCE_VERTEX_INCLUSION
        }
        assert len(sim.fences[i]) == 1 and len(sim.fences[i][0]) == 32


def _fly_south(sim, until_s: float) -> list:
    """Vehicle 1 (index 0, at north -200 m) holds course South until ``until_s``; the others
    loiter where they are (well inside)."""
    for i, other in enumerate(sim.autopilots[1:], start=1):
        other.set_mode(Mode.LOITER, sim.t_s, sim.obs(i))
    ap = sim.autopilots[0]
    ap.setpoint(Setpoint(SetpointKind.COURSE, math.pi), sim.t_s)
    events = []
    while sim.t_s < until_s:
        sim.step()
        events += sim.drain_events()
    return events


def test_a_breach_switches_to_rtl_says_so_and_logs_it():
    sim, _, _ = _sim("FENCE_ENABLE=1", "GUID_TIMEOUT=600")
    events = _fly_south(sim, 120.0)
    breach = [e for e in events if e.event == "fence_breach"]
    assert len(breach) == 1 and breach[0].sysid == 1
    b = breach[0]
    assert b.text == "Fence Breached: polygon" and b.data["kind"] == "polygon"
    assert b.data["action"] == "RTL" and b.data["north_m"] < -550
    poly = sim.fences[0][0]
    from companion.core.fence import signed_distance_m

    assert -5.0 < signed_distance_m(complex(b.data["north_m"], b.data["east_m"]), poly) <= 0.0
    modes = [e for e in events if e.event == "mode_change" and e.sysid == 1]
    assert modes[-1].data["to"] == "RTL" and modes[-1].t_s == b.t_s
    assert sim.autopilots[0].mode is Mode.RTL
    # RTL loiters round home, well inside: the breach clears; the others never breached
    cleared = [e for e in events if e.event == "fence_breach_cleared"]
    assert cleared and cleared[0].sysid == 1 and cleared[0].t_s > b.t_s
    assert all(e.sysid == 1 for e in events if e.event.startswith("fence_breach"))
    assert all(ap.mode is Mode.LOITER for ap in sim.autopilots[1:])


def test_no_breach_while_the_fence_is_disabled_and_report_only_keeps_the_mode():
    sim, _, _ = _sim("GUID_TIMEOUT=600")
    events = _fly_south(sim, 60.0)
    assert not [e for e in events if e.event.startswith("fence")]
    assert sim.autopilots[0].mode is Mode.GUIDED
    sim, _, _ = _sim("FENCE_ENABLE=1", "FENCE_ACTION=0", "GUID_TIMEOUT=600")
    events = _fly_south(sim, 60.0)
    (b,) = [e for e in events if e.event == "fence_breach"]
    assert b.data["action"] == "report" and sim.autopilots[0].mode is Mode.GUIDED


def test_an_altitude_breach():
    sim, _, _ = _sim("FENCE_ENABLE=1", "FENCE_ALT_MAX=125")
    events = []
    for _ in range(10):
        sim.step()
        events += sim.drain_events()
    got = sorted((e.sysid, e.data["kind"]) for e in events if e.event == "fence_breach")
    assert got == [(4, "max_alt"), (5, "max_alt"), (6, "max_alt")]  # at 130, 140, 150 m


def test_sys_status_geofence_bit_like_ardupilot():
    geofence = dialect.MAV_SYS_STATUS_GEOFENCE
    sim, links, _ = _sim("GUID_TIMEOUT=600")
    s = links[0].tm.sys_status(0)
    assert s.onboard_control_sensors_present & geofence  # a fence is stored
    assert not s.onboard_control_sensors_enabled & geofence  # FENCE_ENABLE 0
    sim.params.set("FENCE_ENABLE", 1)
    events = _fly_south(sim, 120.0)
    seen = [e.event for e in events if e.event.startswith("fence_breach") and e.sysid == 1]
    assert seen == ["fence_breach", "fence_breach_cleared"]
    s0, s1 = links[0].tm.sys_status(0), links[1].tm.sys_status(1)
    assert s0.onboard_control_sensors_enabled & geofence
    assert s0.onboard_control_sensors_health & geofence  # back inside (cleared)
    sim.breached[1] = "polygon"  # as _check_fences records a breach
    assert not links[1].tm.sys_status(1).onboard_control_sensors_health & geofence
    assert s1.onboard_control_sensors_health & geofence


def test_a_disarmed_spare_on_the_ground_is_no_breach_and_is_checked_once_flying():
    # ellipse_relief: four ground spares at altitude 0, under FENCE_ALT_MIN (50 m). As
    # ArduPlane (landing_or_landed when disarmed) they breach nothing while on the ground, so
    # an enabled fence (what `companion fleet` uploads) does not send them to RTL.
    relief = str(REPO / "missions" / "ellipse_relief.yaml")
    args = build_parser().parse_args(
        ["--mission", relief, "--param", "FENCE_ENABLE=1", "--param", "GUID_TIMEOUT=600"]
    )
    sim, _, _ = build(args)
    ten = sim.sysids.index(10)
    assert sim.grounded[ten] and sim.alt_m[ten] == 0.0
    events = []
    while sim.t_s < 2.0:
        sim.step()
        events += sim.drain_events()
    assert not [e for e in events if e.event.startswith("fence")]
    assert sim.autopilots[ten].mode is Mode.GUIDED
    # flying, the spare is checked: put it above the ceiling, and it breaches (RTL)
    sim.take_off(ten)
    sim.alt_m[ten] = sim.params["FENCE_ALT_MAX"] + 10.0
    while sim.t_s < 3.0:
        sim.step()
        events += sim.drain_events()
    breach = [e for e in events if e.event == "fence_breach"]
    assert [(e.sysid, e.data["kind"]) for e in breach] == [(10, "max_alt")]
