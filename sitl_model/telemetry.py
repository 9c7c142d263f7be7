"""Telemetry of one vehicle as MAVLink message objects, and the per-vehicle stream schedule.

Builders read the pure :class:`sitl_model.sim.Simulation` and return pymavlink message
objects (plain data; :mod:`sitl_model.codec` turns them into bytes). Times: ``time_boot_ms``
is simulated milliseconds since start; ``time_unix_usec`` is
:data:`~companion.contracts.simulator.SIM_EPOCH_UNIX_S` plus the simulated time, so every
vehicle and companion shares one time base. The battery (:mod:`sitl_model.battery`) is
reported as ArduPilot reports it: SYS_STATUS ``voltage_battery`` (mV), ``current_battery``
(cA) and ``battery_remaining`` (%), and BATTERY_STATUS (id 0: consumed mAh, energy in hJ,
remaining %, the pack voltage in the first cell with the rest unused, charge state).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from sitl_model.autopilot import G_M_S2, Mode
from sitl_model.battery import LEVEL_CRITICAL
from sitl_model.codec import dialect as d
from sitl_model.sim import Simulation

FLIGHT_SW_VERSION = (4 << 24) | (6 << 16) | (0 << 8) | 255  # "4.6.0 official" in ArduPilot form
CAPABILITIES = (
    d.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | d.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | d.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | d.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | d.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | d.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
)

# Default stream rates (Hz, simulated time); SET_MESSAGE_INTERVAL changes them per vehicle.
DEFAULT_RATES_HZ: dict[str, float] = {
    "HEARTBEAT": 1.0,
    "SYS_STATUS": 1.0,
    "GPS_RAW_INT": 2.0,
    "GLOBAL_POSITION_INT": 5.0,
    "LOCAL_POSITION_NED": 5.0,
    "ATTITUDE": 5.0,
    "VFR_HUD": 2.0,
    "HOME_POSITION": 0.2,
    "EXTENDED_SYS_STATE": 1.0,
    "SYSTEM_TIME": 1.0,
    "WIND": 1.0,
    "MISSION_CURRENT": 1.0,
    "BATTERY_STATUS": 1.0,  # ArduPilot's EXTRA3 group: in step with SYS_STATUS
}
MAX_RATE_HZ = 50.0
SENSORS = 0x1 | 0x2 | 0x4 | 0x8 | 0x20 | 0x8000 | 0x200000  # gyro acc mag baro gps ahrs ...
CELL_MV_MAX = 0xFFFE  # BATTERY_STATUS: most a cell field carries (mV); 0xFFFF = no cell
INT16_MAX = 0x7FFF  # BATTERY_STATUS temperature: unknown


def _base_mode(mode: Mode, armed: bool) -> int:
    bm = d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if armed:
        bm |= d.MAV_MODE_FLAG_SAFETY_ARMED
    if mode is Mode.MANUAL:
        bm |= d.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    else:
        bm |= d.MAV_MODE_FLAG_STABILIZE_ENABLED | d.MAV_MODE_FLAG_GUIDED_ENABLED
    if mode is Mode.AUTO:
        bm |= d.MAV_MODE_FLAG_AUTO_ENABLED
    return bm


class Telemetry:
    """Builds the messages of vehicle ``index`` from the simulation's current state."""

    def __init__(self, sim: Simulation) -> None:
        """Builders over ``sim``; geodetic positions are computed once per step for all."""
        self.sim = sim
        self._geo_step = -1
        self._kin_step = -1
        self._kin_rows: list[tuple[complex, float, float, float]] = []
        self._geo_rows: list[tuple[float, float, float]] = []  # lat deg, lon deg, AMSL m
        self._home = sim.frame.geodetic_rows([0.0], [0.0], [0.0])[0]
        self.builders: dict[str, Callable[[int], Any]] = {
            "HEARTBEAT": self.heartbeat,
            "SYS_STATUS": self.sys_status,
            "GPS_RAW_INT": self.gps_raw_int,
            "GLOBAL_POSITION_INT": self.global_position_int,
            "LOCAL_POSITION_NED": self.local_position_ned,
            "ATTITUDE": self.attitude,
            "VFR_HUD": self.vfr_hud,
            "HOME_POSITION": self.home_position,
            "EXTENDED_SYS_STATE": self.extended_sys_state,
            "SYSTEM_TIME": self.system_time,
            "WIND": self.wind,
            "MISSION_CURRENT": self.mission_current,
            "BATTERY_STATUS": self.battery_status,
            "AUTOPILOT_VERSION": self.autopilot_version,
        }
        self.mission_total: list[int] = [0] * len(sim.sysids)
        self.errors_comm: list[int] = [0] * len(sim.sysids)

    def _geo(self, i: int) -> tuple[float, float, float]:
        """Vehicle ``i``'s GPS position: latitude (deg), longitude (deg), AMSL (m)."""
        sim = self.sim
        if self._geo_step != sim.steps:
            p = sim.nav_pos_m  # what the GPS says
            self._geo_rows = sim.frame.geodetic_rows(
                p.real.tolist(), p.imag.tolist(), sim.alt_m.tolist()
            )
            self._geo_step = sim.steps
        return self._geo_rows[i]

    @property
    def _ms(self) -> int:
        return round(self.sim.t_s * 1000.0) & 0xFFFFFFFF

    def _kin(self, i: int) -> tuple[complex, float, float, float]:
        """Ground velocity (m/s), heading (rad), course (rad), achieved turn rate (rad/s)."""
        sim = self.sim
        if self._kin_step != sim.steps:
            st = sim.state
            vel = sim.nav_velocity_m_s  # what the GPS says
            u = np.broadcast_to(st.turn_rate_rad_s, st.heading_rad.shape)
            self._kin_rows = list(
                zip(
                    vel.tolist(),
                    st.heading_rad.tolist(),
                    np.angle(vel).tolist(),
                    u.tolist(),
                    strict=True,
                )
            )
            self._kin_step = sim.steps
        return self._kin_rows[i]

    def heartbeat(self, i: int) -> Any:
        """HEARTBEAT: fixed wing, ArduPilot, ArduPlane custom mode."""
        ap = self.sim.autopilots[i]
        return d.MAVLink_heartbeat_message(
            d.MAV_TYPE_FIXED_WING,
            d.MAV_AUTOPILOT_ARDUPILOTMEGA,
            _base_mode(ap.mode, ap.armed),
            int(ap.mode),
            d.MAV_STATE_ACTIVE,
            3,
        )

    def sys_status(self, i: int) -> Any:
        """SYS_STATUS; ``errors_comm`` counts this vehicle's dropped and refused inputs.
        The geofence bit, as on ArduPilot: present with a stored fence, enabled with
        FENCE_ENABLE, healthy unless breached. The battery bit: healthy until critical;
        voltage (mV), current (cA), remaining (%, -1 unknown) of the battery."""
        fence = d.MAV_SYS_STATUS_GEOFENCE if self.sim.fences[i] else 0
        on = fence if self.sim.params["FENCE_ENABLE"] >= 0.5 else 0
        ok = fence if self.sim.breached[i] is None else 0
        batt = d.MAV_SYS_STATUS_SENSOR_BATTERY
        b = self.sim.batteries
        if b.level[i] < LEVEL_CRITICAL:
            ok |= batt
        mv, ca = self._battery_mv_ca(i)
        return d.MAVLink_sys_status_message(
            SENSORS | fence | batt, SENSORS | on | batt, SENSORS | ok, 100, min(mv, 65535), ca,
            b.remaining_pct(i, self.sim.params), 0, min(self.errors_comm[i], 65535), 0, 0, 0, 0,
        )  # fmt: skip

    def _battery_mv_ca(self, i: int) -> tuple[int, int]:
        """The battery's terminal voltage (mV, >= 0) and current (cA, int16) now."""
        b = self.sim.batteries
        mv = max(round(float(b.voltage_v[i]) * 1000.0), 0)
        ca = min(max(round(float(b.current_a[i]) * 100.0), -INT16_MAX), INT16_MAX)
        return mv, ca

    def battery_status(self, i: int) -> Any:
        """BATTERY_STATUS of battery 0 as ArduPilot sends it without cell monitoring: the
        pack voltage (mV) in the first cell (spilling into the next past 65534 mV), the
        rest 0xFFFF; current (cA), consumed charge (mAh) and energy (hJ = Wh * 36),
        remaining (%), time to 0 % at this current (s), charge state; no temperature."""
        p, b = self.sim.params, self.sim.batteries
        mv, ca = self._battery_mv_ca(i)
        cells = []
        for _ in range(10):
            cells.append(min(mv, CELL_MV_MAX) if mv > 0 else 0xFFFF)
            mv = max(mv - CELL_MV_MAX, 0)
        return d.MAVLink_battery_status_message(
            0, d.MAV_BATTERY_FUNCTION_UNKNOWN, d.MAV_BATTERY_TYPE_UNKNOWN, INT16_MAX, cells, ca,
            round(float(b.consumed_mah[i])), round(float(b.energy_wh[i]) * 36.0),
            b.remaining_pct(i, p), b.time_remaining_s(i, p), int(b.level[i]), [0, 0, 0, 0], 0, 0,
        )  # fmt: skip

    def gps_raw_int(self, i: int) -> Any:
        """GPS_RAW_INT: 3D fix, course over ground and ground speed."""
        lat, lon, amsl = self._geo(i)
        v, _, course, _ = self._kin(i)
        return d.MAVLink_gps_raw_int_message(
            (SIM_EPOCH_UNIX_S * 1_000_000 + round(self.sim.t_s * 1e6)),
            d.GPS_FIX_TYPE_3D_FIX,
            round(lat * 1e7),
            round(lon * 1e7),
            round(amsl * 1000),
            100, 150, round(abs(v) * 100), round(math.degrees(course) % 360.0 * 100) % 36000, 12,
        )  # fmt: skip

    def global_position_int(self, i: int) -> Any:
        """GLOBAL_POSITION_INT: position, ground velocity (cm/s), heading (cdeg)."""
        lat, lon, amsl = self._geo(i)
        v, hdg, _, _ = self._kin(i)
        return d.MAVLink_global_position_int_message(
            self._ms,
            round(lat * 1e7),
            round(lon * 1e7),
            round(amsl * 1000),
            round(float(self.sim.alt_m[i]) * 1000),
            round(v.real * 100),
            round(v.imag * 100),
            0,
            round(math.degrees(hdg) % 360.0 * 100) % 36000,
        )

    def local_position_ned(self, i: int) -> Any:
        """LOCAL_POSITION_NED relative to the origin (m, m/s), GPS errors included."""
        v, _, _, _ = self._kin(i)
        p = complex(self.sim.state.pos_m[i] + self.sim.errors.gps_pos_m[i])
        return d.MAVLink_local_position_ned_message(
            self._ms, p.real, p.imag, -float(self.sim.alt_m[i]), v.real, v.imag, 0.0
        )

    def roll_rad(self, i: int) -> float:
        """Bank angle of the coordinated turn: ``atan(V u / (g eff))`` (rad)."""
        p = self.sim.params
        _, _, _, u = self._kin(i)
        v = float(self.sim.airspeed_m_s[i])
        return math.atan(v * u / (G_M_S2 * p["SIM_TR_EFF"]))

    def attitude(self, i: int) -> Any:
        """ATTITUDE: roll from the coordinated turn, zero pitch, yaw = air heading."""
        _, hdg, _, u = self._kin(i)
        return d.MAVLink_attitude_message(self._ms, self.roll_rad(i), 0.0, hdg, 0.0, 0.0, u)

    def vfr_hud(self, i: int) -> Any:
        """VFR_HUD: the vehicle's airspeed, ground speed, heading (deg), altitude AMSL (m)."""
        amsl = self._geo(i)[2]
        v, hdg, _, _ = self._kin(i)
        return d.MAVLink_vfr_hud_message(
            float(self.sim.airspeed_m_s[i]),
            abs(v),
            round(math.degrees(hdg)) % 360,
            50,
            amsl,
            0.0,
        )

    def home_position(self, i: int) -> Any:
        """HOME_POSITION: the origin on the ground."""
        lat, lon, alt = self._home
        return d.MAVLink_home_position_message(
            round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
            0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0,
            SIM_EPOCH_UNIX_S * 1_000_000 + round(self.sim.t_s * 1e6),
        )  # fmt: skip

    def extended_sys_state(self, i: int) -> Any:
        """EXTENDED_SYS_STATE: in the air, or on the ground (a spare, a landed vehicle)."""
        landed = d.MAV_LANDED_STATE_ON_GROUND if self.sim.grounded[i] else d.MAV_LANDED_STATE_IN_AIR
        return d.MAVLink_extended_sys_state_message(d.MAV_VTOL_STATE_UNDEFINED, landed)

    def system_time(self, i: int) -> Any:
        """SYSTEM_TIME: the shared time base (fixed epoch + simulated time)."""
        return d.MAVLink_system_time_message(
            SIM_EPOCH_UNIX_S * 1_000_000 + round(self.sim.t_s * 1e6), self._ms
        )

    def wind(self, i: int) -> Any:
        """WIND (ArduPilot): the autopilot's estimate, not the truth (lagged, with an error):
        direction the wind blows FROM (deg), speed (m/s), vertical speed 0."""
        e = self.sim.errors
        w = complex(e.wind_est_m_s[i] + e.wind_err_m_s[i])
        from_deg = (math.degrees(math.atan2(w.imag, w.real)) + 180.0) % 360.0
        return d.MAVLink_wind_message(from_deg, abs(w), 0.0)

    def mission_current(self, i: int) -> Any:
        """MISSION_CURRENT: current item and total count."""
        ap = self.sim.autopilots[i]
        state = d.MISSION_STATE_ACTIVE if ap.mode is Mode.AUTO else d.MISSION_STATE_PAUSED
        total = self.mission_total[i]
        if total == 0:
            state = d.MISSION_STATE_NO_MISSION
        return d.MAVLink_mission_current_message(ap.current_seq, total, state, 0)

    def autopilot_version(self, i: int) -> Any:
        """AUTOPILOT_VERSION with the capabilities this simulator really has."""
        return d.MAVLink_autopilot_version_message(
            CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0,
            [0] * 8, [0] * 8, [0] * 8, 0, 0, self.sim.sysids[i],
        )  # fmt: skip

    def camera_tracking(self, i: int, intruder_pos_m: complex, vel_m_s: complex, dist_m: float):
        """CAMERA_TRACKING_GEO_STATUS (sent as component 100) for a detected intruder.

        Geolocated from the vehicle's own GPS position: it carries the vehicle's GPS error.
        """
        intruder_pos_m += complex(self.sim.errors.gps_pos_m[i])
        ((lat, lon, alt),) = self.sim.frame.geodetic_rows(
            [intruder_pos_m.real], [intruder_pos_m.imag], [0.0]
        )
        slant = math.hypot(dist_m, float(self.sim.alt_m[i]))
        hdg = math.atan2(vel_m_s.imag, vel_m_s.real) if abs(vel_m_s) > 0 else math.nan
        return d.MAVLink_camera_tracking_geo_status_message(
            d.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE,
            round(lat * 1e7), round(lon * 1e7), alt,
            1.0, 1.0, vel_m_s.real, vel_m_s.imag, 0.0, 0.1, slant, hdg, math.nan,
        )  # fmt: skip


class Streams:
    """Per-vehicle message intervals (s, simulated) and when each is next due."""

    def __init__(self, offset_s: float = 0.0) -> None:
        """Default rates; the first messages go out at ``offset_s`` (spreads vehicles)."""
        self.interval_s: dict[str, float] = {k: 1.0 / v for k, v in DEFAULT_RATES_HZ.items()}
        self.next_due: dict[str, float] = dict.fromkeys(self.interval_s, offset_s)
        self.next_any = offset_s

    def set_interval(self, name: str, interval_s: float | None, t_s: float) -> None:
        """Interval (s) for ``name``; None = default; 0 or less = off."""
        if interval_s is None:
            rate = DEFAULT_RATES_HZ.get(name)
            if rate is None:
                self.interval_s.pop(name, None)
                return
            interval_s = 1.0 / rate
        if interval_s <= 0:
            self.interval_s.pop(name, None)
            self.next_due.pop(name, None)
        else:
            self.interval_s[name] = max(interval_s, 1.0 / MAX_RATE_HZ)
            self.next_due[name] = t_s
        self.next_any = min(self.next_due.values(), default=math.inf)

    def due(self, t_s: float) -> list[str]:
        """Names due at ``t_s`` (s); advances their schedule."""
        if t_s + 1e-9 < self.next_any:
            return []
        out = []
        for name, nd in self.next_due.items():
            if t_s + 1e-9 >= nd:
                out.append(name)
                iv = self.interval_s[name]
                nxt = nd + iv
                self.next_due[name] = nxt if nxt > t_s else t_s + iv
        self.next_any = min(self.next_due.values(), default=math.inf)
        return out
