"""Energy: the simulator's battery, the companion's battery estimate, spares in the mission.

Expected values are worked out by hand in the tests (docs/energy.md states the model), not by
calling the model's own formulas a second time.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from companion.contracts.simulator import TRUTH_COLUMNS_ENERGY, TRUTH_HEADER
from companion.link.battery import BatteryMonitor
from companion.mission import MissionError, load_mission, parse_mission
from companion.mission.endurance import opening_note, rotation
from sitl_model.assembly import WorldSpec, assemble, spare_setups
from sitl_model.autopilot import RefusedError, Setpoint, SetpointKind
from sitl_model.battery import PowerParams, power_w
from sitl_model.codec import Decoder, Encoder, dialect
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.link import VehicleLink
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import Params
from sitl_model.sim import DT_S, Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

ROOT = Path(__file__).resolve().parents[1]
ELLIPSE = ROOT / "missions" / "ellipse_6uav.yaml"
G = 9.80665
BANK_30_RATE_RAD_S = G * math.tan(math.radians(30.0)) / 20.0  # 0.28312 rad/s at 20 m/s


def make_sim(n: int = 1, **overrides: float) -> Simulation:
    setups = [VehicleSetup(i + 1, 0.0, 1000.0 * i, 0.0, 100.0) for i in range(n)]
    params = Params({"GUID_TIMEOUT": 3600.0, **overrides})
    return Simulation(setups, params, LocalFrame(*DEFAULT_ORIGIN))


def fly(sim: Simulation, seconds: float) -> None:
    for _ in range(round(seconds / DT_S)):
        sim.step()


# ---- the power law -----------------------------------------------------------------------
def test_power_law_against_hand_calculation() -> None:
    pp = PowerParams(level_w=90.0, induced_frac=0.4, vref_m_s=20.0, avionics_w=10.0)
    # level at 20 m/s: 90 * (0.6 + 0.4) + 10
    # level at 25 m/s: 54 * 1.25^3 + 36 / 1.25 + 10 = 105.46875 + 28.8 + 10
    # 30 deg bank at 20 m/s: n^2 = 1 / cos^2(30 deg) = 4/3: 54 + 36 * 4/3 + 10 = 112
    # 30 deg bank at 25 m/s, motor off (disarmed): the avionics only
    got = power_w(
        np.array([20.0, 25.0, 20.0, 25.0]),
        np.array([0.0, 0.0, BANK_30_RATE_RAD_S, 0.3]),
        np.array([True, True, True, False]),
        pp,
    )
    assert got == pytest.approx([100.0, 144.26875, 112.0, 10.0], rel=1e-12)
    # a turn is a turn either way round
    left = power_w(np.array([20.0]), np.array([-BANK_30_RATE_RAD_S]), np.array([True]), pp)
    assert left == pytest.approx([112.0], rel=1e-12)


def test_level_flight_uses_the_hand_calculated_charge() -> None:
    sim = make_sim()  # defaults: 90 W + 10 W at 20 m/s, 12.6 V, unlimited cells, 10000 mAh
    fly(sim, 300.0)
    # 100 W / 12.6 V = 7.93651 A; 5 min: 7.93651 A * 1/12 h = 661.376 mAh; 8.3333 Wh
    b = sim.batteries
    assert b.consumed_mah[0] == pytest.approx(661.376, rel=1e-5)
    assert b.energy_wh[0] == pytest.approx(8.33333, rel=1e-5)
    # 100 (1 - 661.376 / 10000) = 93.39 %, reported as a whole 93
    assert b.remaining_pct(0, sim.params) == 93
    # terminal voltage: 12.6 V - 0.02 ohm * 7.93651 A
    assert b.voltage_v[0] == pytest.approx(12.6 - 0.158730, abs=1e-5)


def test_banked_orbit_draws_more_than_level_flight() -> None:
    sim = make_sim()
    sim.autopilots[0].setpoint(Setpoint(SetpointKind.TURN_RATE, BANK_30_RATE_RAD_S), 0.0)
    fly(sim, 300.0)
    # 112 W / 12.6 V = 8.88889 A; 5 min: 740.741 mAh; 100 (1 - 0.0740741) = 92.59 -> 92 %
    b = sim.batteries
    assert b.consumed_mah[0] == pytest.approx(740.741, rel=1e-5)
    assert b.remaining_pct(0, sim.params) == 92


def test_finite_cells_follow_the_voltage_down_and_the_mission_endurance_holds() -> None:
    # 1 Ah cells from 12.6 V, emptied in 5 min of level flight: the energy between full and
    # empty is 12.6 V * 1 Ah * (1 + 3.3/4.2) / 2 = 11.25 Wh, so 135 W for 5 min.
    sim = make_sim(
        SIM_BATT_CAP_AH=1.0, SIM_PWR_LEVEL=125.0, SIM_PWR_AVION=10.0, BATT_CAPACITY=1000.0
    )
    fly(sim, 150.0)
    b = sim.batteries
    # half way the charge drawn is a bit under half (the current rises as the voltage falls)
    assert 440.0 < b.consumed_mah[0] < 500.0
    soc = 1.0 - b.consumed_mah[0] / 1000.0
    v_oc = 12.6 * (3.3 / 4.2 + (0.9 / 4.2) * soc)
    assert b.voltage_v[0] == pytest.approx(v_oc - 0.02 * 135.0 / v_oc, abs=0.01)
    assert not sim.drain_events()
    fly(sim, 150.0)
    assert b.consumed_mah[0] == pytest.approx(1000.0, rel=0.003)
    assert b.energy_wh[0] == pytest.approx(11.25, rel=1e-6)  # 135 W * 5/60 h
    assert b.voltage_v[0] == pytest.approx(12.6 * 3.3 / 4.2 - 0.02 * 135.0 / 9.9, abs=0.02)
    fly(sim, 1.0)  # dry: said once
    assert [e.event for e in sim.drain_events()] == ["battery_empty"]


# ---- what the vehicle reports ------------------------------------------------------------
def _link(sim: Simulation, index: int = 0) -> VehicleLink:
    return VehicleLink(sim, index, Telemetry(sim), MissionProtocol())


def _wire(msgs: list) -> list:
    """Messages as the companion decodes them: packed by vehicle 1, decoded again."""
    enc, dec = Encoder(1, 1), Decoder()
    return [dec.decode(enc.pack(m))[0][0] for m in msgs]


def test_sys_status_and_battery_status_over_in_memory_mavlink() -> None:
    sim = make_sim()
    link = _link(sim)
    got: dict[str, list] = {}
    for _ in range(round(300.0 / DT_S)):
        sim.step()
        for m in _wire(link.due_telemetry()):
            got.setdefault(m.get_type(), []).append(m)
    # both at 1 Hz, in step: at the first step (0.02 s), then 1, 2, ... 300 s
    assert len(got["SYS_STATUS"]) == len(got["BATTERY_STATUS"]) == 301
    s, b = got["SYS_STATUS"][-1], got["BATTERY_STATUS"][-1]
    # 5 min at 100 W from 12.6 V: 7.94 A, 661.4 mAh, 93 %; 8.333 Wh = 300 hJ
    assert s.voltage_battery == 12441 and s.current_battery == 794 and s.battery_remaining == 93
    battery_bit = dialect.MAV_SYS_STATUS_SENSOR_BATTERY
    assert s.onboard_control_sensors_health & battery_bit
    assert b.id == 0 and b.current_consumed == 661 and b.energy_consumed == 300
    assert b.battery_remaining == 93 and b.current_battery == 794
    assert b.voltages[0] == 12441 and set(b.voltages[1:]) == {0xFFFF}
    assert b.charge_state == dialect.MAV_BATTERY_CHARGE_STATE_OK
    # 9338.6 mAh left at 7.93651 A: 4236 s
    assert b.time_remaining == pytest.approx(4236, abs=1)
    # the companion's estimate from the same bytes
    mon = BatteryMonitor()
    mon.on_sys_status(100.0, s.voltage_battery, s.current_battery, s.battery_remaining)
    est = mon.on_battery_status(
        101.0, b.id, b.voltages, b.current_battery, b.current_consumed, b.battery_remaining
    )
    assert est is not None and mon.rejected == {}
    assert (est.t_s, est.remaining_pct, est.consumed_mah) == (101.0, 93.0, 661.0)
    assert est.voltage_v == pytest.approx(12.441) and est.current_a == pytest.approx(7.94)


def test_battery_status_on_request_and_low_then_critical_say_so_once() -> None:
    sim = make_sim(BATT_CAPACITY=2000.0, BATT_LOW_MAH=800.0, BATT_CRT_MAH=400.0)
    link = _link(sim)
    req = dialect.MAVLink_command_long_message(1, 1, dialect.MAV_CMD_REQUEST_MESSAGE, 0,
                                               dialect.MAVLINK_MSG_ID_BATTERY_STATUS,
                                               0, 0, 0, 0, 0, 0)  # fmt: skip
    out = link.handle(Decoder().decode(Encoder(255, 190).pack(req))[0][0], "A", 0.0)
    assert [m.get_type() for m, _ in out] == ["COMMAND_ACK", "BATTERY_STATUS"]
    assert out[0][0].result == 0 and out[1][0].battery_remaining == 100
    events = []
    # 7.9365 A: 1200 mAh (low) after 544.3 s, 1600 mAh (critical) after 725.8 s
    for _ in range(round(900.0 / DT_S)):
        sim.step()
        events += [(e.t_s, e.event, e.text, e.severity) for e in sim.drain_events()]
    assert [e[1] for e in events] == ["battery_low", "battery_critical"]
    assert events[0][0] == pytest.approx(544.3, abs=0.11) and events[0][3] == 4
    assert events[1][0] == pytest.approx(725.8, abs=0.11) and events[1][3] == 2
    assert events[0][2].startswith("Battery 1 is low 12.44V used 120")
    tm = link.tm
    assert tm.battery_status(0).charge_state == dialect.MAV_BATTERY_CHARGE_STATE_CRITICAL
    health = tm.sys_status(0).onboard_control_sensors_health
    assert not health & dialect.MAV_SYS_STATUS_SENSOR_BATTERY


def test_a_disarmed_vehicle_gets_a_full_battery_after_the_turnaround() -> None:
    sim = make_sim(2, SIM_BATT_SWAP=60.0)
    fly(sim, 300.0)
    used = float(sim.batteries.consumed_mah[0])
    assert used == pytest.approx(661.376, rel=1e-5)  # 5 min at 7.93651 A
    for ap in sim.autopilots:
        ap.arm(False, force=True)
    fly(sim, 30.0)
    sim.autopilots[1].arm(True)  # back in the air before its turnaround: keeps its battery
    fly(sim, 29.8)
    # disarmed: the avionics' 10 W only, 0.79365 A for 59.8 s
    assert sim.batteries.consumed_mah[0] == pytest.approx(used + 13.183, rel=1e-4)
    sim.drain_events()
    # the battery samples at 10 Hz: disarmed from the sample at 300.1 s, so 60 s at 360.1 s
    fly(sim, 0.2)
    assert not [e for e in sim.drain_events() if e.event == "battery_swapped"]
    fly(sim, 0.1)
    swapped = [e for e in sim.drain_events() if e.event == "battery_swapped"]
    assert [(e.sysid, round(e.t_s, 1)) for e in swapped] == [(1, 360.1)]
    assert sim.batteries.consumed_mah[0] == 0.0 and sim.batteries.energy_wh[0] == 0.0
    assert sim.batteries.consumed_mah[1] > used
    fly(sim, 120.0)  # still on the ground: no second swap, and on ground power: no draw
    assert not [e for e in sim.drain_events() if e.event == "battery_swapped"]
    assert sim.batteries.consumed_mah[0] == 0.0 and sim.batteries.current_a[0] == 0.0
    sim.autopilots[0].arm(True)  # armed again: off ground power, the battery draws
    fly(sim, 1.0)
    assert sim.batteries.consumed_mah[0] > 0.0


def test_the_battery_is_deterministic() -> None:
    def run() -> np.ndarray:
        sim = make_sim(3, SIM_WIND_TURB=2.0, SIM_WIND_SPD=4.0)
        sim.autopilots[1].setpoint(Setpoint(SetpointKind.TURN_RATE, 0.1), 0.0)
        fly(sim, 60.0)
        return np.concatenate([sim.batteries.consumed_mah, sim.batteries.voltage_v])

    assert np.array_equal(run(), run())


# ---- the companion's estimate ------------------------------------------------------------
def test_battery_reports_out_of_range_are_ignored_and_counted() -> None:
    mon = BatteryMonitor()
    good = mon.on_sys_status(10.0, 12000, 850, 70)
    assert good is not None and (good.remaining_pct, good.voltage_v) == (70.0, 12.0)
    bad = [(-1, -1, -1), (65535, -5, 101), (math.nan, math.nan, math.nan), (-3, 100, -2)]
    for k, (mv, ca, pct) in enumerate(bad):
        est = mon.on_sys_status(11.0 + k, mv, ca, pct)
        assert est is not None and est.remaining_pct == 70.0 and est.voltage_v == 12.0
    # the valid current of the last report is taken, the rest is not
    assert mon.last.current_a == 1.0 and mon.last.t_s == 14.0
    mon.on_battery_status(20.0, 0, [65535] * 10, -1, -1, 255)  # nothing known, 255 %
    mon.on_battery_status(21.0, 0, [math.nan] * 10, 100, -7, 50)
    mon.on_battery_status(22.0, 1, [11000] * 10, 100, 5, 5)  # another battery: not followed
    assert mon.last.remaining_pct == 50.0 and mon.last.consumed_mah is None
    assert mon.reports == 7
    assert mon.rejected == {
        "voltage_v_unknown": 3,
        "voltage_v_not_finite": 2,
        "voltage_v_negative": 1,
        "current_a_unknown": 2,
        "current_a_negative": 1,
        "current_a_not_finite": 1,
        "remaining_pct_unknown": 1,
        "remaining_pct_above_100": 2,
        "remaining_pct_not_finite": 1,
        "remaining_pct_negative": 1,
        "consumed_mah_unknown": 1,
        "consumed_mah_negative": 1,
    }


def test_the_companions_hear_their_battery_in_memory() -> None:
    from companion.sim.inmemory import Engine, EngineConfig

    with Engine(EngineConfig(mission_path=ELLIPSE)) as engine:
        engine.run(3.0)  # the last SYS_STATUS and BATTERY_STATUS: at 3.0 s, this step
        estimates = [r.battery_estimate for r in engine.runners]
        assert all(r.battery.rejected == {} for r in engine.runners)
        b = engine.sim.batteries
    # what each vehicle's battery was at 3.0 s, at the messages' resolution (the companions
    # bank and change speed, so each draws its own current)
    for i, est in enumerate(estimates):
        assert est is not None
        assert est.remaining_pct == math.floor(100.0 * (1.0 - b.consumed_mah[i] / 10000.0))
        assert est.consumed_mah == round(b.consumed_mah[i])
        assert est.current_a == pytest.approx(round(b.current_a[i] * 100.0) / 100.0)
        assert est.voltage_v == pytest.approx(round(b.voltage_v[i] * 1000.0) / 1000.0)
    assert len({est.current_a for est in estimates}) > 1


# ---- the mission's batteries and spares ----------------------------------------------------
BATTERY = "  battery: {capacity_mah: 10000, reserve_pct: 20, endurance_min: 50}\n"


def mission_text(block: str) -> str:
    text = ELLIPSE.read_text()
    anchor = "  initial:\n    line:"
    assert anchor in text
    return text.replace(anchor, block + anchor)


def spares(*entries: str) -> str:
    return "  spares:\n" + "".join(f"    - {e}\n" for e in entries)


def ground(sysid: int, turnaround_s: float = 1200.0) -> str:
    return f"{{sysid: {sysid}, ground: {{north_m: 0, east_m: 300}}, turnaround_s: {turnaround_s}}}"


def test_missions_without_a_battery_load_unchanged() -> None:
    m = load_mission(ELLIPSE)
    assert m.vehicles.battery is None and m.vehicles.spares == ()


def test_spares_load_and_the_rotation_holds() -> None:
    four = [ground(10 + k) for k in range(3)]
    four.append(
        "{sysid: 20, holding: {north_m: -500, east_m: 0, alt_m: 200}, turnaround_s: 900,"
        " battery: {capacity_mah: 12000, cruise_current_a: 12, reserve_pct: 25}}"
    )
    m = parse_mission(mission_text(BATTERY + spares(*four)), "ok.yaml")
    v = m.vehicles
    assert v.battery.usable_min == pytest.approx(40.0)
    assert [s.sysid for s in v.spares] == [10, 11, 12, 20]
    hold = v.spares[3]
    assert (hold.waits, hold.north_m, hold.alt_m, hold.base_m) == ("holding", -500.0, 200.0, 0j)
    # 12 Ah at 12 A: 60 min; 25 % reserve: 45 min usable
    assert hold.battery.endurance_min == pytest.approx(60.0)
    assert hold.battery.usable_min == pytest.approx(45.0)
    assert v.opening == "battery"  # the default: each first stint as its battery says
    text = mission_text(BATTERY + spares(*four) + "  opening: staggered\n")
    assert parse_mission(text, "ok.yaml").vehicles.opening == "staggered"


def test_spares_fly_above_the_patrol_each_at_its_own_altitude() -> None:
    """missions/ellipse_relief.yaml: the patrol at 100, 110, ... 150 m (step 10 m), spares
    10-13 continue the ladder at 160-190 m, and the default fence band reaches 190 + 50 m;
    the simulator launches each ground spare to that same altitude."""
    m = load_mission(Path(__file__).parents[1] / "missions" / "ellipse_relief.yaml")
    v = m.vehicles
    assert [v.altitude_m(i) for i in v.sysids] == [100.0, 110.0, 120.0, 130.0, 140.0, 150.0]
    assert [v.altitude_m(sp.sysid) for sp in v.spares] == [160.0, 170.0, 180.0, 190.0]
    assert m.fence.fence.max_alt_m == pytest.approx(240.0)
    assert [s.alt_m for s in spare_setups(v)] == [160.0, 170.0, 180.0, 190.0]


def test_the_all_day_mission_is_the_relief_mission_with_a_fifth_spare_and_the_opening() -> None:
    """missions/ellipse_all_day.yaml: what bench/endurance.py measured as ellipse_relief with
    ``--extra-spares 1`` and ``--start opening`` (docs/results.md, "All day")."""
    root = Path(__file__).parents[1] / "missions"
    day, relief = (
        load_mission(root / "ellipse_all_day.yaml"),
        load_mission(root / "ellipse_relief.yaml"),
    )
    assert day.vehicles.opening == "staggered" and relief.vehicles.opening == "battery"
    assert [s.sysid for s in day.vehicles.spares] == [10, 11, 12, 13, 14]
    assert day.vehicles.spares[4] == replace(relief.vehicles.spares[3], sysid=14)
    assert (
        replace(day.vehicles, spares=relief.vehicles.spares, opening="battery") == relief.vehicles
    )
    assert (day.patrol.period_s, day.wind, day.sensor) == (
        relief.patrol.period_s,
        relief.wind,
        relief.sensor,
    )


def test_a_long_run_from_full_batteries_without_the_opening_is_told_to_stagger_it() -> None:
    """ellipse_relief (4 spares, 6 on station, 38.8 min on station per battery, docs/energy.md
    "Worked example"): two hours from full batteries get the note; a run shorter than one
    stint, batteries given as used, the staggered opening or as many spares as UAVs do not."""
    root = Path(__file__).parents[1] / "missions"
    relief = load_mission(root / "ellipse_relief.yaml")
    note = opening_note(relief, 7200.0, started_full=True)
    assert note is not None and "all 6 first stints end together, about 39 min in" in note
    assert "4 spares" in note and "vehicles.opening: staggered" in note
    assert opening_note(relief, 38.0 * 60.0, started_full=True) is None
    assert opening_note(relief, 7200.0, started_full=False) is None
    assert opening_note(load_mission(root / "ellipse_all_day.yaml"), 7200.0, True) is None
    six = replace(relief.vehicles, spares=relief.vehicles.spares + relief.vehicles.spares[:2])
    assert opening_note(replace(relief, vehicles=six), 7200.0, started_full=True) is None


def test_rotation_against_hand_calculation() -> None:
    # 6 on station, 40 min usable, 0.5 min transit, 20 min turnaround:
    # 39 min per stint, a relief every 39 / 6 = 6.5 min; each relief ties up 21 min
    two = rotation(6, 2, 40.0, 0.5, 20.0)
    assert (two.stint_min, two.relief_every_min, two.spare_ready_every_min) == (39.0, 6.5, 10.5)
    assert two.min_spares == 4 and not two.sustainable  # ceil(6 * 21 / 39) = ceil(3.23)
    assert rotation(6, 4, 40.0, 0.5, 20.0).sustainable  # 21 / 4 = 5.25 <= 6.5
    assert rotation(6, 1, 50.0, 0.0, 0.0).sustainable  # an instant swap needs one spare
    no_way = rotation(2, 5, 10.0, 6.0, 1.0)  # 12 min there and back on 10 min usable
    assert no_way.min_spares is None and not no_way.sustainable
    assert "does not cover the transit" in no_way.why()


def test_an_unsustainable_fleet_is_refused_with_the_figures() -> None:
    text = mission_text(BATTERY + spares(ground(10), ground(11)))
    with pytest.raises(MissionError) as exc:
        parse_mission(text, "two.yaml")
    msg = str(exc.value)
    line = text.splitlines().index("  spares:") + 2  # the list's first entry
    assert msg.startswith(f"two.yaml:{line}: vehicles.spares: the patrol cannot be kept up: ")
    # transit: the loop's farthest point from (0, 300) m is 529 m away, at 20 - 5 m/s: 0.59 min
    assert "6 on station, 2 spares: a spare is ready every 10.6 min" in msg
    assert "a relief is needed every 6.5 min" in msg and "at least 4 spares needed" in msg
    with pytest.raises(MissionError, match=r"vehicles.battery: .*6 on station, 0 spares: "):
        parse_mission(mission_text(BATTERY), "none.yaml")


@pytest.mark.parametrize(
    ("block", "where", "problem"),
    [
        (BATTERY + spares(ground(10), ground(10)), "vehicles.spares[1].sysid",
         "system id 10 repeats vehicles.spares[0].sysid"),
        (BATTERY + spares(ground(3)), "vehicles.spares[0].sysid",
         "system id 3 is a patrol UAV's (vehicles.sysids)"),
        (spares("{sysid: 9, turnaround_s: 60}"), "vehicles.spares[0]",
         "give exactly one of 'ground' or 'holding'"),
        (spares("{sysid: 9, ground: {north_m: 0, east_m: 0}, turnaround_s: 60,"
                " battery: {capacity_mah: 5000, endurance_min: 40}}"),
         "vehicles.spares[0].battery", "needs the fleet's too"),
        ("  battery: {capacity_mah: 5000, endurance_min: 40, cruise_current_a: 5}\n",
         "vehicles.battery", "give exactly one of 'endurance_min' or 'cruise_current_a'"),
        ("  battery: {capacity_mah: -5, endurance_min: 40}\n", "vehicles.battery.capacity_mah",
         "capacity (mAh)"),
        ("  battery: {capacity_mah: 5000, endurance_min: 40, reserve_pct: 100}\n",
         "vehicles.battery.reserve_pct", "below 100 %"),
        (BATTERY + spares(*(ground(10 + k) for k in range(4))) + "  opening: early\n",
         "vehicles.opening", "expected one of battery, staggered, got 'early'"),
        ("  opening: staggered\n", "vehicles.opening", "it needs spares"),
    ],
)  # fmt: skip
def test_bad_spares_and_batteries_name_the_field(block: str, where: str, problem: str) -> None:
    with pytest.raises(MissionError) as exc:
        parse_mission(mission_text(block), "bad.yaml")
    assert f": {where}: " in str(exc.value) and problem in str(exc.value)
    assert exc.value.field == where and exc.value.line is not None


# ---- the simulator built from such a mission -----------------------------------------------
def test_a_mission_battery_sets_the_simulator_and_the_truth_columns(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(mission_text(BATTERY + spares(*(ground(10 + k) for k in range(4)))))
    sim, _ = assemble(WorldSpec(mission_path=str(path)))
    p = sim.params
    assert (p["BATT_CAPACITY"], p["SIM_BATT_CAP_AH"], p["BATT_LOW_MAH"]) == (10000.0, 10.0, 2000.0)
    assert p["SIM_BATT_SWAP"] == 1200.0 and p["SIM_PWR_VREF"] == 20.0
    # 112.5 Wh in 50 min: 135 W, of which the avionics' 10 W
    assert (p["SIM_PWR_LEVEL"], p["SIM_PWR_AVION"]) == (pytest.approx(125.0), 10.0)
    assert sim.truth_header.split(",") == list(TRUTH_COLUMNS_ENERGY)
    sim.step()
    rows = sim.truth_rows()
    # the 6 on patrol and the 4 spares, on the ground at their launch points: still, at 0 m
    assert len(rows) == 10 and all(len(r.split(",")) == len(TRUTH_COLUMNS_ENERGY) for r in rows)
    assert rows[0].split(",")[-4] == "100.000"
    col = list(TRUTH_COLUMNS_ENERGY)
    for row in rows[6:]:
        f = dict(zip(col, row.split(","), strict=True))
        assert float(f["alt_m"]) == 0.0 and float(f["groundspeed_m_s"]) == 0.0, f
    plain, _ = assemble(WorldSpec(mission_path=str(ELLIPSE)))
    assert plain.truth_header == TRUTH_HEADER and not plain.truth_energy


def test_a_grounded_vehicle_stays_put_sees_nothing_takes_off_and_lands() -> None:
    params = Params({"SIM_WIND_SPD": 5.0, "SIM_WIND_DIR": 180.0})
    setups = [VehicleSetup(1, 0.0, 0.0, 0.0, 100.0), VehicleSetup(10, 0.0, 300.0, 0.0, 120.0, True)]
    sim = Simulation(setups, params, LocalFrame(*DEFAULT_ORIGIN))
    assert not sim.autopilots[1].armed and sim.alt_m[1] == 0.0
    for _ in range(50):
        sim.step()
    assert sim.state.pos_m[1] == 300j and abs(sim.ground_velocity_m_s[1]) == 0.0
    assert abs(sim.state.pos_m[0]) == pytest.approx(25.0, rel=0.01)  # 20 + 5 m/s for 1 s
    with pytest.raises(RefusedError):
        sim.land(1)
    sim.take_off(1)
    assert sim.autopilots[1].armed and sim.alt_m[1] == 120.0
    for _ in range(50):
        sim.step()
    assert abs(sim.state.pos_m[1] - 300j) == pytest.approx(25.0, rel=0.01)  # flies north
    with pytest.raises(RefusedError):
        sim.take_off(1)
    sim.land(1)
    here = sim.state.pos_m[1]
    for _ in range(50):
        sim.step()
    assert sim.state.pos_m[1] == here and not sim.autopilots[1].armed
    names = [e.event for e in sim.drain_events() if e.sysid == 10]
    assert names.count("takeoff") == 1 and names.count("landed") == 1


def test_a_ground_spare_faces_its_runway_and_lands_facing_it() -> None:
    # a runway heading east (90 deg) at the base (0, 300): the spare starts facing it and
    # takes off that way (no wind), and a vehicle landing within 100 m of the base faces it
    # again; one landing far from it keeps the heading it flew
    m = load_mission(ROOT / "missions" / "ellipse_relief.yaml")
    assert [s.heading_deg for s in m.vehicles.spares] == [180.0] * 4  # the mission's runway
    params = Params({"SIM_WIND_SPD": 0.0})
    setups = [
        VehicleSetup(1, 0.0, 0.0, 0.0, 100.0),
        VehicleSetup(10, 0.0, 300.0, 90.0, 120.0, True),
    ]
    sim = Simulation(setups, params, LocalFrame(*DEFAULT_ORIGIN))
    sim.take_off(1)
    for _ in range(50):
        sim.step()
    moved = complex(sim.state.pos_m[1]) - 300j  # 1 s at 20 m/s, east (its mode then steers)
    assert abs(moved) == pytest.approx(20.0, abs=0.5) and abs(np.angle(moved / 1j)) < 0.2
    sim.state.heading_rad[1] = math.pi  # turned south, 20 m from the base
    sim.land(1)
    assert sim.state.heading_rad[1] == pytest.approx(math.pi / 2)  # on the runway
    sim.state.heading_rad[0] = 1.0
    sim.state.pos_m[0] = -1000.0  # far from any base
    sim.land(0)
    assert sim.state.heading_rad[0] == 1.0
