"""Beside PX4: the world process of :mod:`companion.sim.firmware.world` on PX4 SITL (SIH).

``python -m companion.sim.px4.world --mission M --sysids 1,2,3 --ports P1,P2,P3 --pids ...``
connects to every PX4 instance's camera link (UDP 14280+i, an "onboard" MAVLink instance
with forwarding on) as component 100 of the aircraft's system. PX4 forwards the camera's
CAMERA_TRACKING_GEO_STATUS to its other forwarding links, so it reaches the companion on the
offboard link (measured on PX4 main 02e73e3: 428 of 428 sent arrived).

Time base: PX4's SYSTEM_TIME carries the host's clock, so vehicle time is the fleet epoch plus
each instance's ``time_boot_ms`` (its simulated time since boot), here and in every companion
(``companion run --boot-epoch``). The instances start within a few hundred milliseconds of
each other and then run at slightly different rates (PX4 rarely reaches its speed factor on
a busy machine). PX4 cannot change its speed factor while it runs, so the clock discipline
pauses the instances ahead: every ``CLOCK_SAMPLE_S`` an instance asked to run at ``x`` of
the speed factor ``X`` is stopped (SIGSTOP, by its pid) for ``(1 - x / X)`` of the interval and
continued (SIGCONT). PX4's lockstep clock stands still while its process is stopped and does
not catch up afterwards (measured: 1 s stopped, 0 s of vehicle time lost or gained, the rate
after as before), so this is a speed actuator. Every paused instance is continued on exit.

SIH has no wind: the truth log's wind columns are zero (still air), whatever the mission says.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.clock import VehicleClock
from companion.link.px4 import OFFBOARD_CUSTOM_MODE, mode_name
from companion.sim.firmware.timebase import CLOCK_SAMPLE_S
from companion.sim.firmware.world import (
    CAMERA_COMPID,
    FirmwareWorld,
    Link,
    parser,
    serve,
)

POSITION_HZ = 20.0  # on the camera link (4000 B/s in PX4's SITL start script): 800 B/s
# What the camera link streams by default ("onboard" mode), measured per wall second at speed
# factor 3: ATTITUDE 42, GPS_RAW_INT 23, ATTITUDE_QUATERNION, HIGHRES_IMU, GLOBAL_POSITION_INT
# 21 each, LOCAL_POSITION_NED, ODOMETRY 13, ... about 230 messages/s. Six of them starved the
# world process on the loaded 2-core machine (no truth row for 60 s): every stream but
# GLOBAL_POSITION_INT and HEARTBEAT is switched off (SET_MESSAGE_INTERVAL -1).
UNWANTED_STREAMS = (
    mav.MAVLINK_MSG_ID_ATTITUDE,
    mav.MAVLINK_MSG_ID_GPS_RAW_INT,
    mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
    mav.MAVLINK_MSG_ID_HIGHRES_IMU,
    mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    mav.MAVLINK_MSG_ID_ODOMETRY,
    mav.MAVLINK_MSG_ID_ALTITUDE,
    mav.MAVLINK_MSG_ID_DISTANCE_SENSOR,
    mav.MAVLINK_MSG_ID_ATTITUDE_TARGET,
    mav.MAVLINK_MSG_ID_POSITION_TARGET_LOCAL_NED,
    mav.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW,
    mav.MAVLINK_MSG_ID_VFR_HUD,
    mav.MAVLINK_MSG_ID_PING,
    mav.MAVLINK_MSG_ID_TIMESYNC,
)
MIN_PAUSE_FRACTION = 0.01  # shorter pauses are not worth two signals


def pause_s(speedup: float, full_speedup: float, interval_s: float = CLOCK_SAMPLE_S) -> float:
    """Wall seconds to stop an instance per ``interval_s`` so that it runs at ``speedup``
    where it would run at ``full_speedup`` (pure; 0 when it should run free)."""
    frac = 1.0 - speedup / full_speedup if full_speedup > 0 else 0.0
    frac = min(1.0, max(0.0, frac))
    return frac * interval_s if frac >= MIN_PAUSE_FRACTION else 0.0


class Px4World(FirmwareWorld):
    """The world process on PX4 SITL instances (their camera links, UDP)."""

    controlled_mode = mode_name(OFFBOARD_CUSTOM_MODE)
    slew_actuator = "the run fraction (SIGSTOP/SIGCONT by pid)"
    truth_source = (
        "telemetry: GLOBAL_POSITION_INT of each PX4 SITL (SIH) instance; still air (SIH has no "
        "wind: the wind columns are zero)"
    )
    time_base = (
        "the fleet epoch + each instance's time_boot_ms (its simulated time since boot; the "
        "companions run with --boot-epoch); rows interpolated onto a common grid"
    )

    def __init__(self, args: Any, mission: Any) -> None:
        """The pids of the instances (to pause them), then the links."""
        pids = [int(x) for x in args.pids.split(",")] if args.pids else []
        self.pids = dict(zip([int(x) for x in args.sysids.split(",")], pids, strict=False))
        self.resume_at: dict[int, float] = {}  # sysid -> wall s when it is continued
        self.last_duty = time.monotonic()
        self.paused_s = dict.fromkeys(self.pids, 0.0)  # wall s each was stopped, in all
        super().__init__(args, mission)

    world_wind_source = "still air: PX4's SIH simulates no wind, whatever the mission says"

    def true_wind_m_s(self) -> complex:
        """SIH has no wind: still air."""
        return 0j

    def open_link(self, link: Link) -> Any:
        """UDP to the instance's camera link, as component 100 of its system; its clock is
        the fleet epoch + ``time_boot_ms``."""
        link.clock = VehicleClock(fixed_offset_s=self.epoch)
        link.got_time = True  # no SYSTEM_TIME needed (it is the host's clock)
        return mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{link.port}",
            source_system=link.sysid,
            source_component=CAMERA_COMPID,
            dialect="ardupilotmega",
        )

    def mode_name(self, custom_mode: int) -> str:
        """PX4's name of a custom mode (main.sub)."""
        return mode_name(custom_mode)

    def request_telemetry(self, link: Link) -> None:
        """GLOBAL_POSITION_INT at POSITION_HZ on the camera link, the rest off."""
        asks = [(mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 1e6 / POSITION_HZ)]
        asks += [(msg_id, -1.0) for msg_id in UNWANTED_STREAMS]
        with contextlib.suppress(OSError):
            for msg_id, interval_us in asks:
                link.conn.mav.command_long_send(
                    link.sysid, 1, mav.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    msg_id, interval_us, 0, 0, 0, 0, 0,
                )  # fmt: skip

    def _sample(self, link: Link, t_s: float, m: Any) -> None:
        """A position sample is also the instance's clock sample."""
        super()._sample(link, t_s, m)
        self.clock_sample(link, t_s + self.epoch)

    def send_speedup(self, link: Link, speedup: float) -> None:
        """Nothing to send: ``link.speedup`` (set by the caller) is applied by :meth:`tick`
        as a duty cycle."""

    def tick(self, now: float) -> None:
        """Continue the instances whose pause is over; at each CLOCK_SAMPLE_S stop the ones
        asked to run below the speed factor for their share of the interval."""
        for sysid, at in list(self.resume_at.items()):
            if now >= at:
                self._signal(sysid, signal.SIGCONT)
                del self.resume_at[sysid]
        if now - self.last_duty < CLOCK_SAMPLE_S or self.stop:
            return
        self.last_duty = now
        for link in self.links:
            p = pause_s(link.speedup or self.args.speedup, self.args.speedup)
            if p > 0.0 and link.sysid not in self.resume_at and link.sysid in self.pids:
                self._signal(link.sysid, signal.SIGSTOP)
                self.resume_at[link.sysid] = now + p
                self.paused_s[link.sysid] += p

    def select_timeout_s(self, now: float) -> float:
        """Wake for the next continuation."""
        if not self.resume_at:
            return 0.05
        return max(0.0, min(0.05, min(self.resume_at.values()) - now))

    def _signal(self, sysid: int, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(self.pids[sysid], sig)

    def clock_report(self) -> dict[str, Any]:
        """The shared clock figures, plus the wall seconds each instance was paused."""
        rep = super().clock_report()
        rep["paused_wall_s"] = {str(s): round(v, 2) for s, v in self.paused_s.items()}
        return rep

    def close(self) -> None:
        """Continue every instance (never leave one stopped), then the shared close."""
        for sysid in self.pids:
            self._signal(sysid, signal.SIGCONT)
        self.resume_at.clear()
        super().close()


def main(argv: list[str] | None = None) -> int:
    """Entry point (see the module docstring)."""
    p = parser(
        "python -m companion.sim.px4.world",
        "each instance's camera UDP port (14280+i)",
        "the instances' run fraction",
    )
    p.add_argument("--pids", default="", help="each instance's pid (to pause it), in order")
    return serve(Px4World, p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
