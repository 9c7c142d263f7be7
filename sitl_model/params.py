"""The simulator's parameters: the knobs a ground station can list, read and set.

Parameters are fleet-wide (one world, one airframe type): setting one through any vehicle
changes it for all. Names follow ArduPilot where ArduPilot has the same knob
(``GUID_TIMEOUT``, ``WP_LOITER_RAD``, ``WP_RADIUS``, ``SIM_WIND_SPD``, ``SIM_WIND_DIR``,
``SIM_WIND_TURB``, the battery's ``BATT_CAPACITY``, ``BATT_LOW_MAH``, ``BATT_CRT_MAH``,
``SIM_BATT_VOLTAGE``, ``SIM_BATT_CAP_AH``); the rest are ``SIM_*``. Values are floats
(MAV_PARAM_TYPE_REAL32) in the unit named in :data:`SPECS`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name (<= 16 chars), default, allowed closed range, unit, meaning."""

    name: str
    default: float
    lo: float
    hi: float
    unit: str
    doc: str


SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("SIM_WIND_SPD", 0.0, 0.0, 50.0, "m/s", "steady wind speed"),
    ParamSpec("SIM_WIND_DIR", 0.0, 0.0, 360.0, "deg", "direction the wind blows FROM"),
    ParamSpec("SIM_WIND_TURB", 0.0, 0.0, 20.0, "m/s", "gust std dev per axis (0 = none)"),
    ParamSpec("SIM_GUST_TAU", 5.0, 0.1, 600.0, "s", "gust correlation time"),
    ParamSpec("SIM_AIRSPEED", 20.0, 1.0, 100.0, "m/s", "constant airspeed"),
    ParamSpec("SIM_TURN_MAX", 18.0, 0.5, 90.0, "deg/s", "turn-rate limit"),
    ParamSpec("SIM_LAG", 0.0, 0.0, 10.0, "s", "first-order turn (roll) response lag; 0 = off"),
    ParamSpec("SIM_TR_EFF", 1.0, 0.1, 1.5, "1", "achieved / g tan(phi)/V for roll setpoints"),
    ParamSpec("ROLL_LIMIT_DEG", 60.0, 5.0, 89.0, "deg", "bank limit of roll setpoints (ArduPlane)"),
    ParamSpec("SIM_CRS_KP", 1.0, 0.01, 20.0, "1/s", "course/heading hold gain"),
    ParamSpec(
        "SIM_RATE_OK",
        0.0,
        0.0,
        1.0,
        "1",
        "0: SET_ATTITUDE_TARGET as ArduPlane (rates ignored); 1: body yaw rate flown too",
    ),
    ParamSpec("GUID_TIMEOUT", 3.0, 0.1, 3600.0, "s", "GUIDED setpoint timeout -> loiter"),
    ParamSpec("SIM_SENS_RAD", 50.0, 0.0, 5000.0, "m", "downward sensor footprint radius"),
    ParamSpec("WP_LOITER_RAD", 100.0, 10.0, 5000.0, "m", "loiter radius (LOITER, RTL, timeout)"),
    ParamSpec("WP_RADIUS", 60.0, 1.0, 5000.0, "m", "AUTO waypoint acceptance radius"),
    # the geofence (ArduPilot's names; sitl_model/fence.py): off by default, as on ArduPilot
    ParamSpec("FENCE_ENABLE", 0.0, 0.0, 1.0, "1", "geofence on (1) or off (0)"),
    ParamSpec("FENCE_TYPE", 7.0, 0.0, 15.0, "1", "bits: 1 max alt, 4 polygon, 8 min alt"),
    ParamSpec("FENCE_ACTION", 1.0, 0.0, 1.0, "1", "on a breach: 0 report only, 1 RTL"),
    ParamSpec("FENCE_ALT_MIN", -10.0, -100.0, 10000.0, "m", "fence floor above home"),
    ParamSpec("FENCE_ALT_MAX", 100.0, 10.0, 10000.0, "m", "fence ceiling above home"),
    # the world and sensors as they are (sitl_model/disturbances.py)
    ParamSpec("SIM_GPS_NOISE", 0.0, 0.0, 100.0, "m", "GPS position error std dev per axis"),
    ParamSpec("SIM_GPS_TAU", 30.0, 0.1, 3600.0, "s", "GPS position error correlation time"),
    ParamSpec("SIM_GPS_VNOISE", 0.0, 0.0, 10.0, "m/s", "GPS velocity white noise per axis"),
    ParamSpec("SIM_WDRIFT_SPD", 0.0, 0.0, 50.0, "m/s", "amplitude of the wind speed drift"),
    ParamSpec("SIM_WDRIFT_DIR", 0.0, 0.0, 180.0, "deg", "amplitude of the wind direction drift"),
    ParamSpec("SIM_WDRIFT_T", 600.0, 1.0, 86400.0, "s", "period of the wind drift"),
    ParamSpec("SIM_WSTEP_T", 0.0, 0.0, 1e6, "s", "sim time of the wind step (0 = never)"),
    ParamSpec("SIM_WSTEP_SPD", 0.0, -50.0, 50.0, "m/s", "wind speed added by the step"),
    ParamSpec("SIM_WSTEP_DIR", 0.0, -180.0, 180.0, "deg", "wind direction added by the step"),
    ParamSpec("SIM_WEST_TAU", 10.0, 0.0, 600.0, "s", "lag of the WIND estimate (0 = none)"),
    ParamSpec("SIM_WEST_ERR", 0.3, 0.0, 20.0, "m/s", "WIND estimate error std dev per axis"),
    # the battery (sitl_model/battery.py); ArduPilot's names where it has the knob
    ParamSpec("BATT_CAPACITY", 10000.0, 0.0, 1e7, "mAh", "the monitor's pack capacity (0 = none)"),
    ParamSpec("BATT_LOW_MAH", 0.0, 0.0, 1e7, "mAh", "remaining charge that is low (0 = off)"),
    ParamSpec("BATT_CRT_MAH", 0.0, 0.0, 1e7, "mAh", "remaining charge that is critical (0 = off)"),
    ParamSpec("SIM_BATT_VOLTAGE", 12.6, 1.0, 100.0, "V", "voltage of the full pack at rest"),
    ParamSpec("SIM_BATT_CAP_AH", 0.0, 0.0, 10000.0, "Ah", "the cells' capacity (0 = unlimited)"),
    ParamSpec("SIM_BATT_SWAP", 1200.0, 0.0, 86400.0, "s", "disarmed this long: a full battery"),
    ParamSpec("SIM_PWR_LEVEL", 90.0, 0.0, 1e6, "W", "propulsion power, level at SIM_PWR_VREF"),
    ParamSpec("SIM_PWR_IND", 0.4, 0.0, 1.0, "1", "induced fraction of SIM_PWR_LEVEL"),
    ParamSpec("SIM_PWR_VREF", 20.0, 1.0, 100.0, "m/s", "airspeed of SIM_PWR_LEVEL"),
    ParamSpec("SIM_PWR_AVION", 10.0, 0.0, 1e5, "W", "avionics and payload power, always on"),
)

_BY_NAME = {s.name: s for s in SPECS}


class ParamError(ValueError):
    """A parameter set was refused (unknown name or bad value)."""


class Params:
    """Current parameter values with validation; ``version`` bumps on every change."""

    def __init__(self, overrides: dict[str, float] | None = None) -> None:
        """Defaults from :data:`SPECS`, then ``overrides`` (validated)."""
        self._values = {s.name: float(s.default) for s in SPECS}
        self.version = 0
        for name, value in (overrides or {}).items():
            self.set(name, value)

    @staticmethod
    def names() -> list[str]:
        """All parameter names in index order."""
        return [s.name for s in SPECS]

    def __getitem__(self, name: str) -> float:
        """Current value of ``name``."""
        return self._values[name]

    def index(self, name: str) -> int:
        """Index of ``name`` in the list (-1 if unknown)."""
        names = self.names()
        return names.index(name) if name in names else -1

    def set(self, name: str, value: float) -> float:
        """Set ``name`` to ``value``; raises :class:`ParamError` if unknown or out of range."""
        spec = _BY_NAME.get(name)
        if spec is None:
            raise ParamError(f"unknown parameter {name!r}")
        v = float(value)
        if not math.isfinite(v) or not spec.lo <= v <= spec.hi:
            raise ParamError(f"{name} must be in [{spec.lo:g}, {spec.hi:g}] {spec.unit}, got {v!r}")
        if self._values[name] != v:
            self._values[name] = v
            self.version += 1
        return v
