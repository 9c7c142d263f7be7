"""Fast unit tests of the simulator's pure parts: autopilot, physics in the loop, world,
mission protocol, parameters, control lines and the codec (no sockets, simulated clock)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.mission import Intruder
from sitl_model.autopilot import G_M_S2, Mode, Obs, RefusedError, Setpoint, SetpointKind
from sitl_model.codec import Decoder, Encoder, dialect
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.mission_protocol import MissionItem, MissionProtocol
from sitl_model.operator_input import ControlError, parse_line
from sitl_model.params import ParamError, Params
from sitl_model.sim import DT_S, Simulation, VehicleSetup
from sitl_model.telemetry import Streams
from sitl_model.world import World

FRAME = LocalFrame(*DEFAULT_ORIGIN)


def make_sim(n: int = 1, **overrides: float) -> Simulation:
    setups = [VehicleSetup(i + 1, 0.0, 1000.0 * i, 0.0, 100.0) for i in range(n)]
    return Simulation(setups, Params(overrides), FRAME)


def run(sim: Simulation, seconds: float, every=None) -> list[complex]:
    """Step ``seconds``; return vehicle 0's position after every step."""
    track = []
    for _ in range(round(seconds / DT_S)):
        if every is not None:
            every(sim)
        sim.step()
        track.append(complex(sim.state.pos_m[0]))
    return track


def fit_circle(pts: np.ndarray) -> tuple[complex, float]:
    """Least-squares circle through complex points: centre, radius."""
    x, y = pts.real, pts.imag
    a = np.column_stack([x, y, np.ones_like(x)])
    b = x**2 + y**2
    cx, cy, c = np.linalg.lstsq(a, b, rcond=None)[0]
    cx, cy = cx / 2, cy / 2
    return complex(cx, cy), math.sqrt(c + cx**2 + cy**2)


@pytest.mark.parametrize("rate_deg_s", [5.0, 10.0, -12.0])
def test_turn_rate_setpoint_flies_circle_of_radius_v_over_u(rate_deg_s: float) -> None:
    sim = make_sim(GUID_TIMEOUT=1000.0)
    u = math.radians(rate_deg_s)
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.TURN_RATE, u), 0.0)
    track = np.array(run(sim, 2 * math.pi / abs(u)))
    centre, radius = fit_circle(track)
    assert radius == pytest.approx(20.0 / abs(u), rel=0.01)
    # positive = right turn: seen from the start heading North, the centre is to the East
    assert np.sign(centre.imag) == np.sign(u)


def test_roll_setpoint_turns_at_g_tan_phi_over_v_times_efficiency() -> None:
    for eff in (1.0, 0.75):
        sim = make_sim(GUID_TIMEOUT=1000.0, SIM_TR_EFF=eff)
        phi = math.radians(20.0)
        sim.autopilots[0].setpoint(Setpoint(SetpointKind.ROLL, phi), 0.0)
        run(sim, 1.0)
        expected = eff * G_M_S2 * math.tan(phi) / 20.0
        assert float(sim.state.turn_rate_rad_s[0]) == pytest.approx(expected, rel=1e-9)


def test_turn_rate_limit_and_lag_apply() -> None:
    sim = make_sim(GUID_TIMEOUT=1000.0, SIM_TURN_MAX=10.0, SIM_LAG=1.0)
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.TURN_RATE, 1.0), 0.0)
    run(sim, 1.0)
    u1 = float(sim.state.turn_rate_rad_s[0])
    assert u1 == pytest.approx(math.radians(10.0) * (1 - math.exp(-1.0)), rel=1e-3)
    run(sim, 10.0)
    assert float(sim.state.turn_rate_rad_s[0]) == pytest.approx(math.radians(10.0), rel=1e-3)


def test_trochoid_in_wind_matches_closed_form() -> None:
    """Eq. 22-23: r(t) = r0 + (s0/u)(-i)(e^{i(th0+ut)} - e^{i th0}) + w t."""
    sim = make_sim(GUID_TIMEOUT=1000.0, SIM_WIND_SPD=6.0, SIM_WIND_DIR=250.0)
    u = math.radians(9.0)
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.TURN_RATE, u), 0.0)
    track = np.array(run(sim, 90.0))
    t = DT_S * np.arange(1, len(track) + 1)
    w = sim.wind_m_s
    expected = (20.0 / u) * (-1j) * (np.exp(1j * u * t) - 1.0) + w * t
    assert np.max(np.abs(track - expected)) < 1e-6


def test_course_hold_converges_and_respects_lateral_accel_limit() -> None:
    sim = make_sim(GUID_TIMEOUT=1000.0, SIM_WIND_SPD=5.0, SIM_WIND_DIR=180.0)
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.COURSE, math.radians(90.0), 2.0), 0.0)
    rates = []
    run(sim, 40.0, every=lambda s: rates.append(abs(float(s.state.turn_rate_rad_s[0]))))
    assert max(rates) <= 2.0 / 20.0 + 1e-9
    assert math.degrees(float(sim.course_rad[0])) == pytest.approx(90.0, abs=0.5)


def test_heading_hold_targets_air_heading() -> None:
    sim = make_sim(GUID_TIMEOUT=1000.0, SIM_WIND_SPD=5.0, SIM_WIND_DIR=180.0)
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.HEADING, math.radians(-90.0)), 0.0)
    run(sim, 40.0)
    assert math.degrees(float(sim.state.heading_rad[0])) == pytest.approx(-90.0, abs=0.5)


def test_guided_timeout_loiters_then_resumes() -> None:
    sim = make_sim()
    ap = sim.autopilots[0]
    ap.setpoint(Setpoint(SetpointKind.TURN_RATE, 0.1), 0.0)
    run(sim, 2.9)
    assert not ap.guided_loitering
    run(sim, 0.2)
    assert ap.guided_loitering
    events = [e.event for e in sim.drain_events()]
    assert events == ["guided_timeout"]
    run(sim, 120.0)  # loiters: stays within the loiter circle's neighbourhood
    _, radius = fit_circle(np.array(run(sim, 40.0)))
    assert radius == pytest.approx(sim.params["WP_LOITER_RAD"], rel=0.05)
    ap.setpoint(Setpoint(SetpointKind.TURN_RATE, -0.1), sim.t_s)
    assert not ap.guided_loitering
    assert [e.event for e in ap.drain_events()] == ["guided_resumed"]


def test_setpoints_refused_outside_guided_and_bad_values_refused() -> None:
    sim = make_sim()
    ap = sim.autopilots[0]
    ap.set_mode(Mode.LOITER, 0.0, sim.obs(0))
    with pytest.raises(RefusedError):
        ap.setpoint(Setpoint(SetpointKind.TURN_RATE, 0.1), 0.0)
    ap.set_mode(Mode.GUIDED, 0.0, sim.obs(0))
    for bad in (
        Setpoint(SetpointKind.TURN_RATE, math.nan),
        Setpoint(SetpointKind.ROLL, math.radians(89.5)),
        Setpoint(SetpointKind.COURSE, 1.0, -1.0),
        Setpoint(SetpointKind.COURSE, math.inf),
    ):
        with pytest.raises(RefusedError):
            ap.setpoint(bad, 0.0)


def test_mode_changes_table() -> None:
    sim = make_sim()
    ap = sim.autopilots[0]
    for mode in (Mode.MANUAL, Mode.CIRCLE, Mode.RTL, Mode.LOITER, Mode.GUIDED):
        ap.set_mode(int(mode), 0.0, sim.obs(0))
        assert ap.mode is mode
    with pytest.raises(RefusedError):
        ap.set_mode(10, 0.0, sim.obs(0))  # AUTO without a mission
    with pytest.raises(RefusedError):
        ap.set_mode(5, 0.0, sim.obs(0))  # FBWA: not modelled
    with pytest.raises(RefusedError):
        ap.arm(False)
    ap.arm(False, force=True)
    assert not ap.armed
    assert ap.turn_rate_command(0.0, sim.obs(0)) == 0.0


def test_auto_flies_the_waypoints_in_a_loop() -> None:
    sim = make_sim()
    pts = np.array([600 + 0j, 600 + 600j, 0 + 600j, 0j])
    items = sim.patrol_items(0, pts)
    assert items[0] == sim.home_item() and (items[0].frame, items[0].command) == (0, 16)
    ap = sim.autopilots[0]
    ap.set_waypoints(sim.nav_points(items), 0.0, sim.obs(0))
    assert [s for s, _ in ap.nav] == [1, 2, 3, 4]  # item 0 is home: never flown
    assert abs(ap.nav[1][1] - pts[1]) < 0.01  # geodetic round trip
    ap.set_mode(Mode.AUTO, 0.0, sim.obs(0))
    run(sim, 400.0)
    reached = [e.data["seq"] for e in sim.drain_events() if e.event == "waypoint_reached"]
    assert reached[:6] == [1, 2, 3, 4, 1, 2]


def test_loiter_circles_entry_point() -> None:
    sim = make_sim(SIM_WIND_SPD=5.0, SIM_WIND_DIR=90.0)
    course = sim.obs(0).course_rad
    assert math.degrees(course) == pytest.approx(-14.04, abs=0.01)  # crabbing into the wind
    sim.autopilots[0].set_mode(Mode.LOITER, 0.0, sim.obs(0))
    run(sim, 200.0)
    centre, radius = fit_circle(np.array(run(sim, 60.0)))
    assert radius == pytest.approx(100.0, rel=0.05)
    # right-hand circle tangent to the entry course: centre 100 m to the right of the track
    assert abs(centre - 100.0 * np.exp(1j * (course + math.pi / 2))) < 5.0


def test_world_detection_events_and_decoy_vanishes() -> None:
    world = World(
        (
            Intruder("a", "static", 1.0, 100.0, 0.0),
            Intruder("d", "decoy", 0.0, 0.0, 0.0, vanish_after_detection_s=2.0),
        )
    )
    pos = np.array([0j, 1000j])
    s, ev = world.update(0.5, pos, 50.0)
    assert [(e.event, e.intruder_id) for e in ev] == [
        ("intruder_appeared", "d"),
        ("detection", "d"),
    ]
    assert [(x.index, x.intruder_id) for x in s] == [(0, "d")]
    s, ev = world.update(1.0, pos, 50.0)
    assert [(e.event, e.intruder_id) for e in ev] == [("intruder_appeared", "a")]
    s, ev = world.update(2.6, pos, 50.0)
    assert ("intruder_vanished", "d") in [(e.event, e.intruder_id) for e in ev]
    assert ("detection_lost", "d") in [(e.event, e.intruder_id) for e in ev]
    with pytest.raises(ValueError):
        world.add(Intruder("a", "static", 0.0, 0.0, 0.0))


def _count(n: int):
    return dialect.MAVLink_mission_count_message(1, 1, n, 0)


def _item(seq: int, lat: float = -35.36):
    return dialect.MAVLink_mission_item_int_message(
        1, 1, seq, 6, 16, 0, 1, 0, 0, 0, 0, round(lat * 1e7), round(149.16 * 1e7), 100.0, 0
    )


def _decoded(msg):
    """A message as the peer's bytes would decode (so it has a source system/component)."""
    return Decoder().decode(Encoder(255, 190).pack(msg))[0][0]


def test_mission_upload_replaces_only_when_complete_and_stall_cancels() -> None:
    old = (MissionItem(0, 6, 16, 1, 1, 0, 0, 0, 0, 1, 2, 3.0),)
    mp = MissionProtocol(old)
    out = mp.handle(_decoded(_count(3)), "A", 0.0)
    assert out[0][0].get_type() == "MISSION_REQUEST_INT" and out[0][0].seq == 0
    mp.handle(_decoded(_item(0)), "A", 0.1)
    # another peer cannot start an upload meanwhile
    assert mp.handle(_decoded(_count(2)), "B", 0.2)[0][0].type == dialect.MAV_MISSION_DENIED
    assert mp.items == old
    acks = []
    for k in range(1, 20):
        acks += [m for m, _ in mp.tick(0.1 + 0.6 * k) if m.get_type() == "MISSION_ACK"]
    assert acks and acks[0].type == dialect.MAV_MISSION_OPERATION_CANCELLED
    assert mp.items == old and mp.state == "IDLE"
    mp.handle(_decoded(_count(2)), "B", 20.0)
    mp.handle(_decoded(_item(0)), "B", 20.1)
    out = mp.handle(_decoded(_item(1)), "B", 20.2)
    assert out[0][0].get_type() == "MISSION_ACK" and out[0][0].type == 0
    assert [it.seq for it in mp.items] == [0, 1]
    bad = mp.handle(_decoded(_count(1)), "B", 21.0)
    assert bad[0][0].get_type() == "MISSION_REQUEST_INT"
    ack = mp.handle(_decoded(_item(0, lat=95.0)), "B", 21.1)[0][0]
    assert ack.type == dialect.MAV_MISSION_INVALID
    assert len(mp.items) == 2


def test_item_0_is_home_like_ardupilot() -> None:
    """With a home item, a completed upload's item 0 is home, downloads return it, and
    MISSION_CURRENT's total leaves it out; without one (PX4) item 0 stays as sent."""
    sim = make_sim()
    home = sim.home_item()
    lat, lon, alt = FRAME.to_geodetic(0.0, 0.0, 0.0)
    assert (home.x, home.y, home.z) == (round(lat * 1e7), round(lon * 1e7), pytest.approx(alt))
    mp = MissionProtocol(home=home)
    mp.handle(_decoded(_count(3)), "A", 0.0)
    for k in range(3):
        out = mp.handle(_decoded(_item(k, lat=-35.36 - 0.001 * k)), "A", 0.1 * k)
    assert out[0][0].get_type() == "MISSION_ACK" and out[0][0].type == 0
    assert mp.items[0] == home and mp.total == 2
    assert [it.x for it in mp.items[1:]] == [round((-35.36 - 0.001 * k) * 1e7) for k in (1, 2)]
    got = mp.handle(_decoded(dialect.MAVLink_mission_request_int_message(1, 1, 0, 0)), "A", 1.0)
    m = got[0][0]
    assert (m.seq, m.frame, m.command, m.x, m.y) == (0, 0, 16, home.x, home.y)
    assert m.z == pytest.approx(alt)
    legacy = mp.handle(_decoded(dialect.MAVLink_mission_request_message(1, 1, 0, 0)), "A", 1.1)
    assert legacy[0][0].x == pytest.approx(lat, abs=1e-5)  # float lat/lon in deg
    assert [s for s, _ in sim.nav_points(mp.items)] == [1, 2]
    px4 = MissionProtocol()
    px4.handle(_decoded(_count(1)), "A", 0.0)
    px4.handle(_decoded(_item(0, lat=-35.37)), "A", 0.1)
    assert px4.items[0].x == round(-35.37 * 1e7) and px4.total == 1
    mp.handle(_decoded(dialect.MAVLink_mission_clear_all_message(1, 1, 0)), "A", 2.0)
    assert mp.items == () and mp.total == 0


def test_params_validate() -> None:
    p = Params()
    assert p["GUID_TIMEOUT"] == 3.0
    v = p.version
    p.set("SIM_LAG", 0.5)
    assert p["SIM_LAG"] == 0.5 and p.version == v + 1
    for name, value in (("SIM_LAG", math.nan), ("SIM_LAG", -1.0), ("NOPE", 1.0)):
        with pytest.raises(ParamError):
            p.set(name, value)
    assert p["SIM_LAG"] == 0.5


def test_streams_rates_and_interval_changes() -> None:
    s = Streams()
    sent: dict[str, int] = {}
    s.set_interval("ATTITUDE", 0.1, 0.0)
    s.set_interval("WIND", -1.0, 0.0)
    for k in range(500):  # 10 s at 50 Hz
        for name in s.due(k * DT_S):
            sent[name] = sent.get(name, 0) + 1
    assert sent["HEARTBEAT"] == 10
    assert sent["ATTITUDE"] == 100
    assert sent["GLOBAL_POSITION_INT"] == 50
    assert "WIND" not in sent


def test_control_lines() -> None:
    c = parse_line("intruder id=x north_m=10 east_m=-5 velocity_east_m_s=2", 7.0)
    assert c.intruder is not None and c.intruder.kind == "moving"
    assert c.intruder.appear_t_s == 7.0 and c.intruder.position_m(8.0) == 10 - 3j
    assert parse_line("  # comment", 0.0).verb == ""
    for bad in (
        "fly away",
        "intruder id=x north_m=1",
        "intruder id=x north_m=a east_m=0",
        "intruder id=x north_m=1 east_m=nan",
        "intruder id=x north_m=1 east_m=0 kind=ufo",
    ):
        with pytest.raises(ControlError):
            parse_line(bad, 0.0)


def test_decoder_survives_garbage_and_truncation() -> None:
    enc = Encoder(1, 1)
    good = enc.pack(dialect.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3))
    dec = Decoder()
    msgs, bad = dec.decode(b"\x00\xffgarbage" + good)
    assert [m.get_type() for m in msgs] == ["HEARTBEAT"] and bad >= 1
    msgs, bad = dec.decode(good[:-3])
    assert msgs == [] and bad == 1
    corrupt = bytearray(good)
    corrupt[12] ^= 0xFF
    msgs, bad = dec.decode(bytes(corrupt))
    assert msgs == [] and bad >= 1
    assert [m.get_type() for m in dec.decode(good)[0]] == ["HEARTBEAT"]


def test_observed_state_in_wind() -> None:
    sim = make_sim(SIM_WIND_SPD=5.0, SIM_WIND_DIR=180.0)
    obs: Obs = sim.obs(0)
    assert obs.groundspeed_m_s == pytest.approx(25.0)
    assert obs.course_rad == pytest.approx(0.0)


def test_reselecting_the_current_mode_keeps_its_setpoint() -> None:
    sim = make_sim(GUID_TIMEOUT=1000.0)
    ap = sim.autopilots[0]
    ap.setpoint(Setpoint(SetpointKind.TURN_RATE, 0.2), 0.0)
    ap.set_mode(Mode.GUIDED, 0.0, sim.obs(0))
    assert ap.turn_rate_command(0.0, sim.obs(0)) == 0.2
    assert ap.drain_events() == []


def test_legacy_float_mission_item_upload_is_stored_as_deg_e7() -> None:
    mp = MissionProtocol()
    mp.handle(_decoded(_count(1)), "A", 0.0)
    legacy = dialect.MAVLink_mission_item_message(
        1, 1, 0, 3, 16, 0, 1, 0, 0, 0, 0, -35.3612345, 149.1654321, 80.0, 0
    )
    ack = mp.handle(_decoded(legacy), "A", 0.1)[0][0]
    assert ack.get_type() == "MISSION_ACK" and ack.type == dialect.MAV_MISSION_ACCEPTED
    it = mp.items[0]
    assert (it.frame, it.z) == (3, 80.0)
    # float32 lat/lon: about 1e-6 deg resolution, which is why MISSION_ITEM_INT exists
    assert abs(it.x - -353612345) < 50 and abs(it.y - 1491654321) < 100
    back = it.message_float(255, 190)
    assert back.x == pytest.approx(-35.3612345, abs=1e-5)


def _link(sim: Simulation, index: int = 0):
    from sitl_model.link import VehicleLink
    from sitl_model.telemetry import Telemetry

    return VehicleLink(sim, index, Telemetry(sim), MissionProtocol())


def test_link_in_memory_request_data_stream_and_foreign_target() -> None:
    sim = make_sim(2)
    link = _link(sim, 1)
    msg = _decoded(dialect.MAVLink_request_data_stream_message(2, 1, 6, 10, 1))
    assert link.handle(msg, "A", 0.0) == []
    assert link.streams.interval_s["GLOBAL_POSITION_INT"] == pytest.approx(0.1)
    off = _decoded(dialect.MAVLink_request_data_stream_message(2, 1, 10, 0, 0))
    link.handle(off, "A", 0.0)
    assert "ATTITUDE" not in link.streams.interval_s
    foreign = _decoded(dialect.MAVLink_command_long_message(1, 1, 176, 0, 1, 12, 0, 0, 0, 0, 0))
    assert link.handle(foreign, "A", 0.0) == [] and link.counters.foreign == 1
    to_camera = dialect.MAVLink_command_long_message(2, 100, 176, 0, 1, 12, 0, 0, 0, 0, 0)
    assert link.handle(_decoded(to_camera), "A", 0.0) == [] and link.counters.foreign == 2
    ack = link.handle(
        _decoded(dialect.MAVLink_command_long_message(2, 1, 176, 0, 1, 12, 0, 0, 0, 0, 0)),
        "A",
        0.0,
    )[0]
    assert ack == (ack[0], "A") and ack[0].result == 0 and ack[0].target_system == 255
    assert sim.autopilots[1].mode is Mode.LOITER and sim.autopilots[0].mode is Mode.GUIDED


def test_cli_build_wires_a_mission() -> None:
    from sitl_model.assembly import PATROL_WAYPOINTS
    from sitl_model.cli import build, build_parser
    from sitl_model.testing import REPO

    ellipse = str(REPO / "missions/ellipse_6uav.yaml")
    args = build_parser().parse_args(["--mission", ellipse, "--param", "SIM_LAG=0.4"])
    sim, links, cfg = build(args)
    assert sim.sysids == [1, 2, 3, 4, 5, 6] and cfg.base_port == 5760
    assert sim.params["SIM_WIND_SPD"] == 5.0 and sim.params["SIM_WIND_DIR"] == 180.0
    assert sim.params["SIM_LAG"] == 0.4 and sim.params["SIM_TURN_MAX"] == 18.0
    assert [it.id for it in sim.world.intruders] == ["paper-alert"]
    assert all(len(link.missions.items) == PATROL_WAYPOINTS + 1 for link in links)
    assert all(link.missions.items[0] == sim.home_item() for link in links)  # ArduPilot's home
    assert len(sim.autopilots[3].nav) == PATROL_WAYPOINTS
    assert list(sim.alt_m) == [100.0, 110.0, 120.0, 130.0, 140.0, 150.0]
    with pytest.raises(ValueError):
        build(
            build_parser().parse_args(
                ["--vehicles", "3", "--mission", "missions/ellipse_6uav.yaml"]
            )
        )


def _gusty_track(seed: int) -> np.ndarray:
    setups = [VehicleSetup(i + 1, 0.0, 500.0 * i, 0.0, 100.0) for i in range(3)]
    sim = Simulation(setups, Params({"SIM_WIND_TURB": 2.0, "SIM_WIND_SPD": 4.0}), FRAME, seed=seed)
    out = []
    for _ in range(500):
        sim.step()
        out.append(sim.state.pos_m.copy())
    return np.array(out)


def test_gusts_are_deterministic_per_seed() -> None:
    a, b, c = _gusty_track(7), _gusty_track(7), _gusty_track(8)
    assert np.array_equal(a, b)
    assert np.max(np.abs(a - c)) > 1.0
