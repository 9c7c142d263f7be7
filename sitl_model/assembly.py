"""The simulator's objects, built from a mission: one :class:`~sitl_model.sim.Simulation`
and one :class:`~sitl_model.link.VehicleLink` per vehicle (telemetry, mission protocol with
the patrol and the fence preloaded; the mission's battery, if it has one, as the battery
parameters). Behind UDP they are ``sitl-model``
(:mod:`sitl_model.cli`, :mod:`sitl_model.server`); in memory they are ``companion simulate``
(:mod:`companion.sim.inmemory`). Nothing here opens a socket or reads a clock; the mission
file is read once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from companion.mission import Mission, load_mission
from companion.mission.model import Vehicles
from sitl_model.autopilot import Mode
from sitl_model.battery import level_power_for_endurance
from sitl_model.geo import DEFAULT_ORIGIN, LocalFrame
from sitl_model.link import VehicleLink
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import SPECS, Params
from sitl_model.sim import Simulation, VehicleSetup
from sitl_model.telemetry import Telemetry

PATROL_WAYPOINTS = 16  # the fallback AUTO mission preloaded from a mission's patrol loop
MAX_VEHICLES = 250


@dataclass(frozen=True)
class WorldSpec:
    """What to simulate.

    Attributes:
        mission_path: mission YAML (origin, fleet, wind, sensor, intruders, fence), or None
            for ``vehicles`` bare vehicles on a line.
        vehicles: number of vehicles (None: the mission's, or 1); must match the mission's.
        params: initial parameter values ``(NAME, value)``, applied after the mission's.
        seed: seed of the simulator's one random generator.
        start_mode: mode at t = 0 (an :class:`~sitl_model.autopilot.Mode` name, lower case).
        wind_speed_m_s: wind speed overriding the mission's (m/s), with ``wind_from_deg``.
        wind_from_deg: direction the wind blows FROM (deg).
        battery_used_mah: ``(sysid, mAh)``: that vehicle starts with a battery that has
            already given that much charge (a used battery; ``--battery-used``).
    """

    mission_path: str | None = None
    vehicles: int | None = None
    params: tuple[tuple[str, float], ...] = ()
    seed: int = 0
    start_mode: str = "guided"
    wind_speed_m_s: float | None = None
    wind_from_deg: float | None = None
    battery_used_mah: tuple[tuple[int, float], ...] = ()


def _setups(spec: WorldSpec, mission: Mission | None) -> list[VehicleSetup]:
    """Each vehicle's sysid and initial pose: the mission's (and its spares'), or bare ones
    300 m apart."""
    if mission is None:
        n = 1 if spec.vehicles is None else spec.vehicles
        return [VehicleSetup(i + 1, 0.0, 300.0 * i, 0.0, 100.0 + 10.0 * i) for i in range(n)]
    v = mission.vehicles
    if spec.vehicles is not None and spec.vehicles != v.count:
        raise ValueError(f"--vehicles {spec.vehicles} does not match the mission's {v.count}")
    setups = [
        VehicleSetup(sid, pose.north_m, pose.east_m, pose.heading_deg, alt)
        for sid, pose, alt in zip(v.sysids, v.initial, v.altitudes_m, strict=True)
    ]
    return setups + spare_setups(v)


def spare_setups(v: Vehicles) -> list[VehicleSetup]:
    """The mission's spares as vehicles after the patrol's: a ground spare on the ground at
    its launch point (flying, once launched, at its patrol altitude,
    :meth:`~companion.mission.model.Vehicles.altitude_m`: above the patrol's), a holding
    spare in the air at its holding point; a ground spare faces its runway (``heading_deg``),
    a holding one North."""
    return [
        VehicleSetup(
            sp.sysid,
            sp.north_m,
            sp.east_m,
            sp.heading_deg,
            sp.alt_m if sp.alt_m is not None else v.altitude_m(sp.sysid),
            grounded=sp.waits == "ground",
        )
        for sp in v.spares
    ]


def battery_params(vehicles: Vehicles) -> dict[str, float]:
    """The battery parameters for a fleet with a battery section (empty without one).

    The cells and the monitor hold the mission's capacity (``SIM_BATT_CAP_AH``,
    ``BATT_CAPACITY``), low is the reserve (``BATT_LOW_MAH``), the turnaround the spares'
    longest (``SIM_BATT_SWAP``), and the power law is scaled so that level flight at the
    mission's airspeed (``SIM_PWR_VREF``) empties the battery in the mission's endurance:
    ``SIM_PWR_LEVEL + SIM_PWR_AVION`` = that power (W; the avionics' default share kept).
    """
    b = vehicles.battery
    if b is None:
        return {}
    cells_ah = b.capacity_mah / 1000.0
    total_w = level_power_for_endurance(b.endurance_min * 60.0, b.capacity_mah, b.voltage_v,
                                        cells_ah)  # fmt: skip
    avionics_w = min(next(s.default for s in SPECS if s.name == "SIM_PWR_AVION"), total_w)
    out = {
        "BATT_CAPACITY": b.capacity_mah,
        "BATT_LOW_MAH": b.reserve_mah,
        "SIM_BATT_VOLTAGE": b.voltage_v,
        "SIM_BATT_CAP_AH": cells_ah,
        "SIM_PWR_VREF": vehicles.airspeed_m_s,
        "SIM_PWR_LEVEL": total_w - avionics_w,
        "SIM_PWR_AVION": avionics_w,
    }
    if vehicles.spares:
        out["SIM_BATT_SWAP"] = max(sp.turnaround_s for sp in vehicles.spares)
    return out


def assemble(spec: WorldSpec) -> tuple[Simulation, list[VehicleLink]]:
    """The simulation and its vehicle links for ``spec``.

    Raises :class:`~companion.mission.MissionError` for a bad mission and ``ValueError`` for
    a bad spec (the messages name the ``sitl-model`` option).
    """
    mission = load_mission(spec.mission_path) if spec.mission_path else None
    setups = _setups(spec, mission)
    if not 1 <= len(setups) <= MAX_VEHICLES:
        raise ValueError(f"--vehicles must be 1..{MAX_VEHICLES}, got {len(setups)}")
    if spec.start_mode == "auto" and mission is None:
        raise ValueError("--start-mode auto needs a --mission (its patrol is the AUTO mission)")
    if (spec.wind_speed_m_s is None) != (spec.wind_from_deg is None):
        raise ValueError("give --wind-speed and --wind-from together")
    overrides: dict[str, float] = {}
    frame = LocalFrame(*DEFAULT_ORIGIN)
    if mission is not None:
        overrides |= {
            "SIM_AIRSPEED": mission.vehicles.airspeed_m_s,
            "SIM_TURN_MAX": mission.vehicles.max_turn_rate_deg_s,
            "SIM_WIND_SPD": mission.wind.speed_m_s,
            "SIM_WIND_DIR": mission.wind.from_deg % 360.0,
            "SIM_SENS_RAD": mission.sensor.footprint_radius_m,
        }
        overrides |= battery_params(mission.vehicles)
        if mission.fence is not None:  # the band of the fence loaded below (still disabled)
            overrides |= {
                "FENCE_ALT_MIN": mission.fence.min_alt_m,
                "FENCE_ALT_MAX": mission.fence.max_alt_m,
                "FENCE_TYPE": 13.0,  # max altitude, polygon, min altitude
            }
        o = mission.origin
        frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    if spec.wind_speed_m_s is not None:
        overrides |= {"SIM_WIND_SPD": spec.wind_speed_m_s, "SIM_WIND_DIR": spec.wind_from_deg % 360}
    overrides |= dict(spec.params)
    sim = Simulation(
        setups,
        Params(overrides),
        frame,
        mission.intruders if mission else (),
        seed=spec.seed,
        start_mode=Mode[spec.start_mode.upper()],
    )
    sim.truth_energy = mission is not None and mission.vehicles.battery is not None
    for sysid, mah in spec.battery_used_mah:
        if sysid not in sim.sysids:
            raise ValueError(f"--battery-used {sysid}={mah:g}: no vehicle {sysid}")
        if not 0.0 <= mah <= sim.params["BATT_CAPACITY"]:
            raise ValueError(f"--battery-used {sysid}={mah:g}: expected 0..BATT_CAPACITY mAh")
        sim.batteries.consumed_mah[sim.sysids.index(sysid)] = mah
    tm = Telemetry(sim)
    patrol_points = None
    if mission is not None:
        patrol_points = mission.patrol.sample_by_time(PATROL_WAYPOINTS)
    links = []
    fence: tuple = ()  # every vehicle holds the mission's fence, as it holds the patrol
    if mission is not None and mission.fence is not None:
        fence = sim.fence_items(np.array(mission.fence.fence.polygon_m))
    for i in range(len(setups)):
        items = () if patrol_points is None else sim.patrol_items(i, patrol_points)
        protocol = MissionProtocol(items, home=sim.home_item(), fence=fence)
        links.append(VehicleLink(sim, i, tm, protocol))
    return sim, links
