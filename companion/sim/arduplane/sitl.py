"""ArduPlane SITL instances for a mission: the binary, free ports, command line, parameters.

One ``arduplane`` process per vehicle, each in its own working directory under the run
folder (it writes ``eeprom.bin`` and its logs there), started with ``--wipe`` so nothing is
inherited from an earlier run. Instance ``i`` listens on three TCP ports (see
:class:`InstancePorts`): SERIAL0 is the fleet's ground-station link (the instance does not
run until a client connects there), SERIAL1 the companion's, SERIAL2 the camera's and the
telemetry logger's (:mod:`companion.sim.arduplane.world`).

Every instance gets ``--start-time`` = the fleet's epoch, so its SYSTEM_TIME unix time is
epoch + its own simulated time since boot: the same time base as our simulator, as long as
the instances' clocks agree (the world process measures how far they do not).

The bring-up over SERIAL0 (parameters, perimeter, arming, take-off) is
:mod:`companion.sim.arduplane.bringup`; this module is the instances themselves and what the
mission sets on them.
"""

from __future__ import annotations

import math
import os
import random
import socket
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.contracts.simulator import PORT_SPACING
from companion.link.setpoints import G_M_S2, MAX_BANK_RAD
from companion.mission import Mission
from sitl_model.geo import LocalFrame

ENV_VAR = "ARDUPLANE_SITL"
BUILD_HINT = (
    "build one from ArduPilot's source with './waf configure --board sitl && ./waf plane' "
    "(binary build/sitl/bin/arduplane; see docs/arduplane.md), then pass --arduplane-bin PATH "
    f"or set ${ENV_VAR}"
)
TAKEOFF_MODE = 13  # ArduPlane custom modes: TAKEOFF 13, GUIDED 15, LOITER 12, AUTO 10
GUIDED_MODE = 15
MODE_NAMES = {
    0: "MANUAL",
    2: "STABILIZE",
    5: "FBWA",
    10: "AUTO",
    11: "RTL",
    12: "LOITER",
    13: "TAKEOFF",
    15: "GUIDED",
}


def find_binary(
    explicit: str | os.PathLike[str] | None, env: Mapping[str, str] = os.environ
) -> Path:
    """The ArduPlane SITL binary: ``explicit`` (``--arduplane-bin``), else ``$ARDUPLANE_SITL``.

    Raises :class:`UserError` (one line saying what to set and how to get one) when neither
    is given, or when the one given is missing or not an executable file.
    """
    if explicit:
        path, how = Path(explicit), "--arduplane-bin"
    elif env.get(ENV_VAR):
        path, how = Path(env[ENV_VAR]), f"${ENV_VAR}"
    else:
        raise UserError(
            f"no ArduPlane SITL binary given: pass --arduplane-bin PATH or set ${ENV_VAR} "
            "(to build one: './waf configure --board sitl && ./waf plane' in ArduPilot's "
            "source, binary build/sitl/bin/arduplane; docs/arduplane.md)"
        )
    if not path.is_file():
        raise UserError(f"{how} {path}: no such file; {BUILD_HINT}")
    if not os.access(path, os.X_OK):
        raise UserError(f"{how} {path}: not executable (chmod +x it, or {BUILD_HINT})")
    return path.resolve()


@dataclass(frozen=True)
class InstancePorts:
    """The TCP ports of one instance (its UDP RC input port too)."""

    serial0: int  # fleet set-up (ground station); the instance waits for it to connect
    serial1: int  # the companion
    serial2: int  # the camera component and the telemetry logger
    rc_in: int  # UDP, the simulated RC input

    @classmethod
    def at(cls, base: int, index: int) -> InstancePorts:
        """Ports of instance ``index`` (0-based) from ``base``: 10 ports per instance."""
        b = base + PORT_SPACING * index
        return cls(b, b + 2, b + 3, b + 5)

    def all(self) -> list[tuple[str, int]]:
        """(protocol, port) of every port the instance binds."""
        return [
            ("tcp", self.serial0),
            ("tcp", self.serial1),
            ("tcp", self.serial2),
            ("udp", self.rc_in),
        ]


def port_in_use(proto: str, port: int) -> bool:
    """Whether ``port`` (TCP or UDP, all interfaces) cannot be bound now."""
    kind = socket.SOCK_STREAM if proto == "tcp" else socket.SOCK_DGRAM
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            return True
    return False


def check_ports(base: int, count: int) -> None:
    """Raise a one-line :class:`UserError` if a port of the ``count`` instances is taken."""
    top = 65535 - PORT_SPACING * count
    if not 1024 <= base <= top:
        raise UserError(f"--arduplane-base-port must be in [1024, {top}]")
    for i in range(count):
        for proto, port in InstancePorts.at(base, i).all():
            if port_in_use(proto, port):
                raise UserError(
                    f"port {port}/{proto} (ArduPlane instance {i}) is in use: stop what holds "
                    "it or give another --arduplane-base-port"
                )


def free_base(count: int, rng: random.Random | None = None) -> int:
    """A base port whose ``count`` instances' ports are all free now."""
    rng = rng or random.Random()
    for _ in range(200):
        base = rng.randrange(20000, 60000 - PORT_SPACING * count, PORT_SPACING)
        try:
            check_ports(base, count)
        except UserError:
            continue
        return base
    raise UserError("no free port range for the ArduPlane instances")


@dataclass(frozen=True)
class InstanceSpec:
    """How to start one instance."""

    index: int
    sysid: int
    ports: InstancePorts
    home: tuple[float, float, float, float]  # lat (deg), lon (deg), alt (m AMSL), heading (deg)
    workdir: Path


def instance_specs(mission: Mission, base: int, out: Path) -> list[InstanceSpec]:
    """One spec per vehicle, the patrol's then the spares' (``Vehicles.all_sysids``): home at
    its initial pose in the mission, or a ground spare's launch point facing its runway, on
    the ground.

    Raises:
        UserError: a spare waits holding in the air (ArduPlane's take-off starts on the
            ground; not supported here).
    """
    o = mission.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    v = mission.vehicles
    poses = [(p.north_m, p.east_m, p.heading_deg) for p in v.initial]
    for sp in v.spares:
        if sp.waits != "ground":
            raise UserError(
                f"spare {sp.sysid} waits holding in the air: with --autopilot arduplane a "
                "spare waits on the ground (vehicles.spares: ground:)"
            )
        poses.append((sp.north_m, sp.east_m, sp.heading_deg))
    specs = []
    for i, (sysid, (north, east, heading)) in enumerate(zip(v.all_sysids, poses, strict=True)):
        lat, lon, _ = frame.to_geodetic(np.array([north]), np.array([east]), np.zeros(1))
        home = (float(lat[0]), float(lon[0]), o.alt_m, heading % 360.0)
        specs.append(
            InstanceSpec(
                i, sysid, InstancePorts.at(base, i), home, out / f"uav{sysid}" / "arduplane"
            )
        )
    return specs


# A landing: from an approach point this far before the runway's threshold, at this height,
# down the runway's heading (the way a spare takes off there) to the threshold
APPROACH_M = 400.0
APPROACH_ALT_M = 30.0


def landing_items(mission: Mission) -> list[tuple[int, float, float, float]]:
    """The landing sequences of the mission's spare bases, for every vehicle's mission:
    (MAV_CMD, lat deg, lon deg, alt m above home) of DO_LAND_START at the threshold (ArduPlane
    jumps to the one nearest it), the approach point ``APPROACH_M`` back along the runway at
    ``APPROACH_ALT_M``, and NAV_LAND at the threshold. Empty without ground spares."""
    o = mission.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    bases = sorted(
        {(sp.north_m, sp.east_m, sp.heading_deg % 360.0) for sp in mission.vehicles.spares
         if sp.waits == "ground"}
    )  # fmt: skip
    items = []
    for north, east, heading in bases:
        h = math.radians(heading)
        back = complex(north, east) - APPROACH_M * complex(math.cos(h), math.sin(h))
        pts = [(north, east, 0.0), (back.real, back.imag, APPROACH_ALT_M), (north, east, 0.0)]
        cmds = (mav.MAV_CMD_DO_LAND_START, mav.MAV_CMD_NAV_WAYPOINT, mav.MAV_CMD_NAV_LAND)
        for cmd, (n, e, alt) in zip(cmds, pts, strict=True):
            lat, lon, _ = frame.to_geodetic(np.array([n]), np.array([e]), np.zeros(1))
            items.append((int(cmd), float(lat[0]), float(lon[0]), alt))
    return items


def instance_argv(binary: Path, spec: InstanceSpec, speedup: float, epoch_unix_s: int) -> list[str]:
    """The command line of one instance (run in ``spec.workdir``)."""
    defaults = binary.parent / "plane.parm"
    lat, lon, alt, hdg = spec.home
    argv = [
        str(binary),
        "--model",
        "plane",
        "--base-port",
        str(spec.ports.serial0),
        "-I",
        str(spec.index),
        "--rc-in-port",
        str(spec.ports.rc_in),
        "--sysid",
        str(spec.sysid),
        "--speedup",
        f"{speedup:g}",
        "--home",
        f"{lat:.7f},{lon:.7f},{alt:.2f},{hdg:.1f}",
        "--start-time",
        str(int(epoch_unix_s)),
        "--wipe",
    ]
    if defaults.is_file():
        argv += ["--defaults", str(defaults)]
    return argv


# ArduPlane SITL's plane turns at about 0.70 of g tan(phi) / V for a bank phi (the bank
# gain the companions learn, docs/arduplane.md): the roll limit must allow the bank that
# gives the mission's turn-rate limit at that efficiency, not the ideal coordinated bank
ARDUPLANE_TURN_EFFICIENCY = 0.70
MAX_ROLL_LIMIT_DEG = math.degrees(MAX_BANK_RAD)  # the companion's own bank cap


def roll_limit_deg(airspeed_m_s: float, max_turn_rate_rad_s: float) -> float:
    """The bank (deg) at which ArduPlane turns at ``max_turn_rate_rad_s`` (rad/s) at
    ``airspeed_m_s`` (m/s): ``atan(V omega / (g k))`` with k its turn efficiency, at most
    ``MAX_ROLL_LIMIT_DEG``."""
    x = airspeed_m_s * max_turn_rate_rad_s / (G_M_S2 * ARDUPLANE_TURN_EFFICIENCY)
    return min(MAX_ROLL_LIMIT_DEG, math.degrees(math.atan(x)))


def mission_params(mission: Mission, sysid: int, guided_timeout_s: float) -> dict[str, float]:
    """The parameters the fleet sets on vehicle ``sysid`` from the mission.

    Wind (SIM_WIND_SPD, SIM_WIND_DIR from where it blows, SIM_WIND_TURB from the gusts),
    AIRSPEED_CRUISE = the mission airspeed, ROLL_LIMIT_DEG = the bank at which ArduPlane
    flies the mission's turn-rate limit at that airspeed (:func:`roll_limit_deg`),
    TKOFF_ALT = the vehicle's altitude, GUIDED_TIMEOUT (s) for attitude and rate setpoints;
    with a battery section BATT_CAPACITY (mAh) and BATT_LOW_MAH = the reserve (a warning
    only: ArduPlane's battery failsafe actions stay off, the companion brings it home); with
    ground spares RTL_AUTOLAND = 2 (an RTL lands at the nearest spare base).
    """
    v = mission.vehicles
    bank_deg = roll_limit_deg(v.airspeed_m_s, v.max_turn_rate_rad_s)
    own = [sp.battery for sp in v.spares if sp.sysid == sysid and sp.battery is not None]
    b = own[0] if own else v.battery
    battery = {}
    if b is not None:  # its monitor counts the mission's capacity; low is the reserve
        battery = {"BATT_CAPACITY": b.capacity_mah, "BATT_LOW_MAH": b.reserve_mah}
    if any(sp.waits == "ground" for sp in v.spares):
        # the mission has landing sequences (landing_items): ArduPlane refuses to arm with
        # one unless RTL may use it; 2 = an RTL goes straight to the nearest one
        battery["RTL_AUTOLAND"] = 2.0
    return battery | {
        "SIM_WIND_SPD": mission.wind.speed_m_s,
        "SIM_WIND_DIR": mission.wind.from_deg % 360.0,
        "SIM_WIND_TURB": mission.wind.gust_std_m_s,
        "AIRSPEED_CRUISE": v.airspeed_m_s,
        "ROLL_LIMIT_DEG": round(bank_deg, 1),
        "TKOFF_ALT": v.altitude_m(sysid),
        "GUIDED_TIMEOUT": guided_timeout_s,
    }
