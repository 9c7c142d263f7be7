"""The PX4 fleet's pieces without PX4 (``companion/sim/px4/``): finding the folder, choosing
instances, the mission's parameters, PX4's integer parameter encoding, the clock discipline's
pause, the fixed-epoch vehicle clock, and bad input: one line, exit 2, nothing left running."""

from __future__ import annotations

import math
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.commands.main import main
from companion.contracts.errors import UserError
from companion.link.clock import VehicleClock
from companion.link.mission_protocol.params import decode_param, encode_param
from companion.mission import load_mission
from companion.sim.px4 import bringup, fleet, params, sitl
from companion.sim.px4.world import pause_s
from tests import firmware_env
from tests.firmware_env import provide_firmware

REPO = Path(__file__).resolve().parents[1]
MISSION_3 = REPO / "tests" / "data" / "ellipse_3uav_still.yaml"

RELIEF = REPO / "tests" / "data" / "ellipse_3uav_relief.yaml"


def _fake_px4(tmp_path: Path, with_binary: bool = True) -> Path:
    d = tmp_path / "px4"
    (d / "etc" / "init.d-posix").mkdir(parents=True)
    (d / "etc" / "init.d-posix" / "rcS").write_text("#!/bin/sh\n")
    (d / "bin").mkdir()
    if with_binary:
        exe = d / "bin" / "px4"
        exe.write_text("#!/bin/sh\nexec sleep 60\n")
        exe.chmod(0o755)
    return d


def test_px4_folder_lookup_order_and_errors(tmp_path: Path):
    good = _fake_px4(tmp_path)
    other = _fake_px4(tmp_path / "other")
    assert sitl.find_px4_dir(str(good), env={sitl.ENV_VAR: str(other)}) == good
    assert sitl.find_px4_dir(None, env={sitl.ENV_VAR: str(other)}) == other
    # neither given: the product looks nowhere else and says what to set (no folder beside
    # the repository is guessed any more)
    with pytest.raises(UserError, match=r"no PX4 SITL folder given: pass --px4-dir DIR or set "
                       r"\$PX4_SITL_DIR.*docs/px4\.md"):  # fmt: skip
        sitl.find_px4_dir(None, env={})
    with pytest.raises(UserError, match="no PX4 SITL folder given"):
        sitl.find_px4_dir(None, env={sitl.ENV_VAR: ""})
    with pytest.raises(UserError, match=r"no PX4 SITL folder at .*--px4-dir.*docs/px4\.md"):
        sitl.find_px4_dir(str(tmp_path / "nowhere"), env={})
    no_bin = _fake_px4(tmp_path / "b", with_binary=False)
    with pytest.raises(UserError, match=r"no executable PX4 SITL binary .*PX4_SITL_DIR"):
        sitl.find_px4_dir(None, env={sitl.ENV_VAR: str(no_bin)})


def test_the_tests_point_px4_sitl_dir_at_the_shared_folder_beside_the_clone(tmp_path: Path):
    # tests/conftest.py's provider: ../shared/px4 beside the repository when the variable is
    # unset and the folder exists; a variable already set is kept; nothing where it is absent
    repo = tmp_path / "repo"
    repo.mkdir()
    env: dict[str, str] = {}
    assert provide_firmware(env, repo) == {} and env == {}
    beside = _fake_px4(tmp_path / "shared")
    assert provide_firmware(env, repo) == {sitl.ENV_VAR: str(beside)}
    assert sitl.find_px4_dir(None, env=env) == beside
    env = {sitl.ENV_VAR: str(tmp_path / "mine")}
    assert provide_firmware(env, repo) == {} and env == {sitl.ENV_VAR: str(tmp_path / "mine")}
    env = {sitl.ENV_VAR: ""}  # set but empty counts as unset, as for the product
    assert provide_firmware(env, repo) == {sitl.ENV_VAR: str(beside)}
    # the provider's own root is the repository (a move of the module one folder deeper would
    # point it at the wrong place and every PX4 test would skip without a word)
    assert (firmware_env.REPO / "pyproject.toml").is_file()
    assert firmware_env.beside()[sitl.ENV_VAR] == firmware_env.REPO.parent / "shared" / "px4"
    assert firmware_env.PX4_VAR == sitl.ENV_VAR


@pytest.mark.parametrize("kind", ["missing folder", "missing binary", "nothing given"])
def test_fleet_without_px4_is_one_line_and_exit_2(tmp_path: Path, capsys, monkeypatch, kind: str):
    out = tmp_path / "run"
    argv = ["fleet", str(MISSION_3), "--autopilot", "px4", "--out", str(out)]
    if kind == "nothing given":
        monkeypatch.delenv(sitl.ENV_VAR, raising=False)
    else:
        d = tmp_path / "nowhere" if kind == "missing folder" else _fake_px4(tmp_path, False)
        argv += ["--px4-dir", str(d)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "PX4 SITL" in err[0] and "--px4-dir" in err[0], err
    assert not out.exists()  # nothing was started or written


@pytest.mark.integration  # binds a real UDP port
def test_an_instance_whose_port_is_taken_is_refused_or_skipped():
    # instance 9's camera port, held by us: asked for explicitly it is refused in one line,
    # chosen automatically it is skipped
    if sitl.instance_busy(9) is not None:
        pytest.skip("instance 9 is in use on this machine")
    port = sitl.instance_ports(9)["camera"]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", port))
        assert sitl.instance_busy(9) == f"UDP port {port} (instance 9's camera link) is in use"
        with pytest.raises(UserError, match=f"PX4 instance 9 cannot start: UDP port {port}"):
            sitl.pick_instances(1, [9])
        assert 9 not in sitl.pick_instances(len(sitl.pick_instances(1)))
    with pytest.raises(UserError, match="distinct"):
        sitl.pick_instances(2, [3, 3])
    with pytest.raises(UserError, match=r"expected 0\.\.9"):
        sitl.pick_instances(1, [10])


def test_mission_parameters_fly_the_missions_airspeed_and_turn_limit():
    m = load_mission(MISSION_3)
    p = params.mission_params(m, 3)  # by sysid
    assert p["FW_AIRSPD_TRIM"] == 20.0 and p["FW_AIRSPD_MIN"] == 12.0 and p["FW_AIRSPD_MAX"] == 25.0
    assert p["SIH_T_MAX"] == 15.0  # the stock 6 N cruises at only 12 m/s
    # 18 deg/s at 20 m/s: atan(20 * 0.314 / 9.807) = 32.65 deg, rounded up to 0.1 deg
    assert math.isclose(params.coordinated_bank_deg(20.0, math.radians(18.0)), 32.65, abs_tol=0.01)
    assert p["FW_R_LIM"] == 32.7
    assert p["MIS_TAKEOFF_ALT"] == 120.0 and p["MAV_SYS_ID"] == 3.0
    env = sitl.Px4Instance(2, 3, Path("/tmp/x"), 3.0, p, (39.8, -84.0, 250.0)).env({})
    assert env["PX4_PARAM_FW_R_LIM"] == "32.7" and env["PX4_PARAM_MAV_SYS_ID"] == "3"
    assert env["PX4_SIM_SPEED_FACTOR"] == "3" and env["PX4_SYS_AUTOSTART"] == "10041"
    assert env["PX4_HOME_LAT"] == "39.8000000" and env["PX4_HOME_ALT"] == "250.00"


def test_px4_integer_parameters_travel_as_their_bits():
    i32 = mav.MAV_PARAM_TYPE_INT32
    raw = encode_param(3, i32, bytewise=True)
    assert raw != 3.0 and decode_param(raw, i32, bytewise=True) == 3.0
    assert encode_param(3, i32, bytewise=False) == 3.0  # ArduPilot: the number as a float
    real = mav.MAV_PARAM_TYPE_REAL32
    assert encode_param(170.0, real, True) == 170.0 and decode_param(170.0, real, True) == 170.0
    for v in (-1, 0, 1, 5, 1000):
        assert decode_param(encode_param(v, i32, True), i32, True) == v


def test_clock_discipline_pauses_an_instance_for_its_share_of_the_interval():
    assert pause_s(3.0, 3.0) == 0.0  # the slowest runs free
    assert math.isclose(pause_s(1.5, 3.0, 0.25), 0.125)
    assert math.isclose(pause_s(0.5, 3.0, 0.25), 0.25 * (1 - 0.5 / 3))  # the hand-over hold
    assert pause_s(2.99, 3.0) == 0.0  # below MIN_PAUSE_FRACTION: not worth two signals
    assert pause_s(4.0, 3.0) == 0.0 and pause_s(-1.0, 3.0, 0.25) == 0.25


def test_boot_epoch_clock_ignores_px4s_host_time():
    c = VehicleClock(fixed_offset_s=1_767_225_600.0)
    assert c.valid and c.to_vehicle_s(62_500) == 1_767_225_662.5
    c.on_system_time(1_800_000_000_000_000, 62_600)  # the host's clock: ignored
    assert c.to_vehicle_s(62_600) == 1_767_225_662.6
    assert c.to_vehicle_s(1_000) == 1_767_225_601.0  # a restart does not lose the epoch


@pytest.mark.integration  # a real process, a 1 s wall-clock heartbeat wait
def test_an_instance_that_never_answers_is_one_line_naming_it(tmp_path: Path):
    # a "PX4" that never sends a heartbeat (sleep): the bring-up gives up in one line
    inst = sitl.Px4Instance(9, 10, tmp_path / "uav10", 3.0)
    inst.proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    b = bringup.Bringup([inst], [100.0], 3.0, lambda *_: (True, ""))
    b.heartbeat_timeout_s = 1.0
    try:
        b.connect()
        with pytest.raises(UserError) as exc:
            b.run()
    finally:
        b.close()
        rc = sitl.stop_px4(inst.proc, 5.0)
    text = str(exc.value)
    assert "\n" not in text
    assert "PX4 did not send a HEARTBEAT" in text and "instance 9 (sysid 10): no heartbeat" in text
    assert rc != 0 and inst.proc.poll() is not None


def test_a_px4_fleet_starts_its_spares_at_their_bases_with_the_missions_battery() -> None:
    m = load_mission(RELIEF)
    homes = fleet.spare_homes(m)
    assert set(homes) == {10}
    lat, lon, alt = homes[10]  # (0, 300) m from the origin, on the ground
    assert bringup.distance_m(m.origin.lat_deg, m.origin.lon_deg, lat, lon) == pytest.approx(
        300.0, abs=0.5
    )
    assert lat == pytest.approx(m.origin.lat_deg, abs=1e-6) and alt == m.origin.alt_m
    p = params.mission_params(m, 10)
    # a relief's climb-out: to 0.6 of its 130 m (PX4 climbs about 24 m per 100 m ahead; the
    # companion takes over above half its altitude and climbs the rest); the patrol's: all of it
    assert p["MAV_SYS_ID"] == 10.0 and p["MIS_TAKEOFF_ALT"] == 78.0
    assert params.mission_params(m, 1)["MIS_TAKEOFF_ALT"] == 100.0
    assert params.takeoff_alt_m(m, 1, relief=True) == 60.0
    # the battery simulator drains over the endurance, to 0 %; PX4's own action only warns
    assert p["SIM_BAT_DRAIN"] == 60.0 * 20 and p["SIM_BAT_MIN_PCT"] == 0.0
    assert p["SIM_BAT_ENABLE"] == 1.0 and p["COM_LOW_BAT_ACT"] == 0.0
    assert fleet.battery_pct(m, ((1, 1100.0),)) == {1: pytest.approx(66.667, abs=1e-3)}
    with pytest.raises(UserError, match="spare"):
        fleet.battery_pct(m, ((10, 100.0),))  # full whenever disarmed: not to be had
    still = load_mission(REPO / "tests" / "data" / "ellipse_3uav_still.yaml")
    assert "SIM_BAT_DRAIN" not in params.mission_params(still, 1)  # no battery section
    with pytest.raises(UserError, match="no battery section"):
        fleet.battery_pct(still, ((1, 100.0),))
