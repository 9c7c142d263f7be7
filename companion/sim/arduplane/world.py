"""Beside ArduPlane: the world process of :mod:`companion.sim.firmware.world` on ArduPlane SITL.

``python -m companion.sim.arduplane.world --mission M --sysids 1,2,3 --ports P1,P2,P3 ...``
connects to every ArduPlane instance's SERIAL2 (TCP) as component 100 of the aircraft's
system (MAV_TYPE_CAMERA). ArduPilot forwards a component's broadcast messages to its other
links, so the camera's CAMERA_TRACKING_GEO_STATUS reaches the companion on SERIAL1 (measured
on 4.8.0-dev).

From each instance it requests GLOBAL_POSITION_INT (10 Hz) and SYSTEM_TIME (5 Hz) and maps
``time_boot_ms`` to vehicle time with :class:`companion.link.clock.VehicleClock` (the
instances share ``--start-time``, so vehicle time - epoch is each instance's own simulated
time). The clocks are disciplined through SIM_SPEEDUP (PARAM_SET; ArduPilot applies it at
once), and the hand-over hold lasts until every instance reports GUIDED.

It is also the spares' ground crew (docs/energy.md, "On real ArduPlane"): an aircraft that
has flown and is disarmed again (landed) has its battery swapped once the mission's
turnaround (the spares' longest, as our simulator's ``SIM_BATT_SWAP``) has passed in its
vehicle time: MAV_CMD_BATTERY_RESET to 100 % (ArduPlane SITL simulates no charge, so its
monitor's count is the battery; event ``battery_swapped``).
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.sim.arduplane.sitl import MODE_NAMES
from companion.sim.firmware.timebase import (
    SLEW_MIN,
    Sample,
    clocks_now_s,
    handover_cap,
    interpolate,
    slewed_speedups,
)
from companion.sim.firmware.world import (
    CAMERA_COMPID,
    POSITION_HZ,
    SYSTEM_TIME_HZ,
    FirmwareWorld,
    Link,
    parser,
    serve,
)

__all__ = [
    "SLEW_MIN",
    "ArduPlaneWorld",
    "Sample",
    "clocks_now_s",
    "handover_cap",
    "interpolate",
    "main",
    "mode_name",
    "slewed_speedups",
]


def mode_name(custom_mode: int) -> str:
    """ArduPlane's name of a custom mode (the number if unknown)."""
    return MODE_NAMES.get(custom_mode, str(custom_mode))


class ArduPlaneWorld(FirmwareWorld):
    """The world process on ArduPlane SITL instances (SERIAL2 over TCP)."""

    controlled_mode = "GUIDED"
    slew_actuator = "SIM_SPEEDUP"
    truth_source = "telemetry: GLOBAL_POSITION_INT of each ArduPlane SITL instance"
    time_base = (
        "each instance's SYSTEM_TIME (--start-time = the fleet epoch) "
        "minus the epoch; rows interpolated onto a common grid"
    )

    def __init__(self, args: Any, mission: Any) -> None:
        """As :class:`FirmwareWorld`, with the ground crew's turnaround from the mission."""
        super().__init__(args, mission)
        spares = mission.vehicles.spares
        self.turnaround_s = max((sp.turnaround_s for sp in spares), default=math.inf)
        self.landed_at: dict[int, float | None] = {}  # sysid -> vehicle s it was disarmed

    def open_link(self, link: Link) -> Any:
        """TCP to the instance's SERIAL2, as component 100 of its system."""
        return mavutil.mavlink_connection(
            f"tcp:127.0.0.1:{link.port}",
            source_system=link.sysid,
            source_component=CAMERA_COMPID,
            retries=0,
        )

    def mode_name(self, custom_mode: int) -> str:
        """ArduPlane's name of a custom mode."""
        return mode_name(custom_mode)

    def request_telemetry(self, link: Link) -> None:
        """GLOBAL_POSITION_INT, SYSTEM_TIME and HEARTBEAT by SET_MESSAGE_INTERVAL."""
        for msg_id, hz in (
            (mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, POSITION_HZ),
            (mav.MAVLINK_MSG_ID_SYSTEM_TIME, SYSTEM_TIME_HZ),
            (mav.MAVLINK_MSG_ID_HEARTBEAT, 1.0),
        ):
            link.conn.mav.command_long_send(
                link.sysid, 1, mav.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                msg_id, 1e6 / hz, 0, 0, 0, 0, 0,
            )  # fmt: skip

    def on_message(self, link: Link, m: Any) -> None:
        """SYSTEM_TIME: the instance's clock (epoch + its simulated time)."""
        if m.get_type() != "SYSTEM_TIME":
            return
        link.clock.on_system_time(int(m.time_unix_usec), int(m.time_boot_ms))
        link.got_time = True
        vt = link.clock.to_vehicle_s(int(m.time_boot_ms))
        if vt is not None:
            self.clock_sample(link, vt)

    def on_armed(self, link: Link, armed: bool) -> None:
        """Disarmed after flying: its turnaround starts (armed again: it is over)."""
        if link.armed is None:
            return  # the first heartbeat: nothing has flown yet
        if not armed and link.samples:
            self.landed_at[link.sysid] = link.samples[-1].t_s
        elif armed:
            self.landed_at[link.sysid] = None

    def on_row(self, t_s: float) -> None:
        """The ground crew: swap the battery of each aircraft whose turnaround is over."""
        for link in self.links:
            since = self.landed_at.get(link.sysid)
            if since is None or t_s - since < self.turnaround_s:
                continue
            self.landed_at[link.sysid] = None  # one battery per stay on the ground
            with contextlib.suppress(OSError):
                link.conn.mav.command_long_send(
                    link.sysid, 1, mav.MAV_CMD_BATTERY_RESET, 0, 1, 100, 0, 0, 0, 0, 0
                )
            rec = {"t_s": round(t_s, 3), "event": "battery_swapped", "sysid": link.sysid,
                   "turnaround_s": self.turnaround_s}  # fmt: skip
            self.events.write(json.dumps(rec) + "\n")

    def send_speedup(self, link: Link, speedup: float) -> None:
        """PARAM_SET SIM_SPEEDUP on one instance (ArduPilot applies it at once)."""
        with contextlib.suppress(OSError):
            link.conn.mav.param_set_send(
                link.sysid, 1, b"SIM_SPEEDUP", speedup, mav.MAV_PARAM_TYPE_REAL32
            )


def main(argv: list[str] | None = None) -> int:
    """Entry point (see the module docstring)."""
    p = parser(
        "python -m companion.sim.arduplane.world", "each instance's SERIAL2 TCP port", "SIM_SPEEDUP"
    )
    return serve(ArduPlaneWorld, p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
