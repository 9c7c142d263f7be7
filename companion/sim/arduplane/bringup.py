"""Bringing ArduPlane SITL instances up over SERIAL0 (wall-clock deadlines: plumbing).

:class:`Bringup`: the mission's parameters by PARAM_SET (read back,
:func:`companion.sim.arduplane.sitl.mission_params`), the perimeter and landing sequences by
the mission protocol, a used battery's charge (MAV_CMD_BATTERY_RESET), the spares GUIDED on the
ground, the patrol armed in TAKEOFF (mode 13) and climbed to its altitudes. Every failure is a
:class:`UserError` of one line naming the instance.
"""

from __future__ import annotations

import contextlib
import subprocess
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.mission import Mission
from companion.sim.arduplane.sitl import (
    GUIDED_MODE,
    MODE_NAMES,
    TAKEOFF_MODE,
    InstanceSpec,
    mission_params,
)
from companion.sim.firmware.links import autopilot_messages, close_links

GCS_SYSID = 255
GCS_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER
CONNECT_TIMEOUT_S = 15.0  # wall s for an instance to listen on SERIAL0
PARAM_TIMEOUT_S = 10.0  # wall s for every PARAM_SET to be read back
ARM_TIMEOUT_SIM_S = 150.0  # simulated s for GPS lock and arming checks
CLIMB_TIMEOUT_SIM_S = 240.0  # simulated s from arming to the take-off altitude
MIN_WALL_TIMEOUT_S = 20.0
CLIMB_MARGIN_M = 5.0  # reached the take-off altitude when within this (m)
RETRY_S = 1.0  # wall s between repeated commands
UPLOAD_TRIES = 5


@dataclass
class _Vehicle:
    spec: InstanceSpec
    popen: subprocess.Popen
    log_path: Path
    conn: Any = None
    seen_hb: bool = False
    armed: bool = False
    mode: int = -1
    rel_alt_m: float = 0.0
    params_ok: set[str] | None = None
    last_cmd: float = -1e9
    last_text: str = ""
    reset_ok: bool = False  # MAV_CMD_BATTERY_RESET accepted


def last_line(path: Path) -> str:
    """The last non-empty line of a log file ("" if none)."""
    with contextlib.suppress(OSError):
        lines = [x.strip() for x in path.read_text(errors="replace").splitlines() if x.strip()]
        if lines:
            return lines[-1]
    return ""


class Bringup:
    """Brings instances up over SERIAL0: parameters, perimeter, arm, TAKEOFF, climb.

    Args:
        mission: the mission.
        vehicles: (spec, process, its log file) of every started instance.
        speedup: the instances' speed-up (scales the simulated-time deadlines to wall).
        guided_timeout_s: GUIDED_TIMEOUT to set (s, vehicle time).
        upload: (connection, sysid, vehicle index) -> (ok, text), the perimeter upload.
        say: where progress lines go.
        extra_params: parameters set after the mission's (``--sim-param``), e.g. SIM_WIND_TURB.
        clock: monotonic wall clock (s).
        battery_pct: sysid -> the charge (%) its battery starts with (``--battery-used``),
            set by MAV_CMD_BATTERY_RESET.
    """

    def __init__(
        self,
        mission: Mission,
        vehicles: list[tuple[InstanceSpec, subprocess.Popen, Path]],
        speedup: float,
        guided_timeout_s: float,
        upload: Callable[[Any, int, int], tuple[bool, str]],
        say: Callable[[str], None] = print,
        extra_params: Mapping[str, float] | None = None,
        clock: Callable[[], float] = time.monotonic,
        battery_pct: Mapping[int, float] | None = None,
    ) -> None:
        """Nothing is connected yet."""
        self.extra_params = dict(extra_params or {})
        self.battery_pct = dict(battery_pct or {})
        self.spares = {sp.sysid for sp in mission.vehicles.spares}
        self.mission = mission
        self.v = [_Vehicle(s, p, log) for s, p, log in vehicles]
        self.speedup = speedup
        self.guided_timeout_s = guided_timeout_s
        self.upload = upload
        self.say = say
        self.clock = clock

    def _wall(self, sim_s: float) -> float:
        return max(MIN_WALL_TIMEOUT_S, sim_s / self.speedup)

    def check_alive(self) -> None:
        for v in self.v:
            rc = v.popen.poll()
            if rc is not None:
                why = last_line(v.log_path)
                hint = ""
                if "bind failed" in why or "in use" in why:
                    hint = ": a port is in use (give another --arduplane-base-port)"
                raise UserError(
                    f"ArduPlane instance {v.spec.index} (sysid {v.spec.sysid}) exited with "
                    f"status {rc}{hint} ({why or 'no output'}; see {v.log_path})"
                )

    def connect(self) -> None:
        """Connect to every SERIAL0 (this starts the instances' clocks, close together)."""
        deadline = self.clock() + CONNECT_TIMEOUT_S
        pending = list(self.v)
        while pending:
            self.check_alive()
            for v in list(pending):
                try:
                    v.conn = mavutil.mavlink_connection(
                        f"tcp:127.0.0.1:{v.spec.ports.serial0}",
                        source_system=GCS_SYSID,
                        source_component=GCS_COMPID,
                        retries=0,
                    )
                except OSError:
                    continue
                pending.remove(v)
            if pending and self.clock() > deadline:
                raise UserError(
                    f"ArduPlane instance {pending[0].spec.index} does not listen on TCP port "
                    f"{pending[0].spec.ports.serial0} after {CONNECT_TIMEOUT_S:g} s (see "
                    f"{pending[0].log_path})"
                )
            if pending:
                time.sleep(0.05)

    def _pump(self, v: _Vehicle) -> None:
        for m in autopilot_messages(v.conn, v.spec.sysid):
            t = m.get_type()
            if t == "HEARTBEAT" and m.type != mav.MAV_TYPE_GCS:
                v.seen_hb = True
                v.armed = bool(m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
                v.mode = int(m.custom_mode)
            elif t == "GLOBAL_POSITION_INT":
                v.rel_alt_m = m.relative_alt * 1e-3
            elif t == "PARAM_VALUE" and v.params_ok is not None:
                name = str(m.param_id)
                want = self._params(v).get(name)
                if want is not None and abs(m.param_value - want) <= 1e-3 * max(1.0, abs(want)):
                    v.params_ok.add(name)
            elif t == "STATUSTEXT":
                v.last_text = m.text
            elif t == "COMMAND_ACK" and m.command == mav.MAV_CMD_BATTERY_RESET:
                v.reset_ok = m.result == mav.MAV_RESULT_ACCEPTED

    def _params(self, v: _Vehicle) -> dict[str, float]:
        return mission_params(self.mission, v.spec.sysid, self.guided_timeout_s) | self.extra_params

    def _wait(
        self,
        what: str,
        done: Callable[[_Vehicle], bool],
        act,
        timeout_s: float,
        among: Callable[[_Vehicle], bool] = lambda v: True,
    ) -> None:
        """Until ``done`` for every vehicle ``among`` says, calling ``act`` every RETRY_S on the
        others."""
        deadline = self.clock() + timeout_s
        while True:
            self.check_alive()
            waiting = []
            for v in self.v:
                self._pump(v)
                if not among(v) or done(v):
                    continue
                waiting.append(v)
                now = self.clock()
                if now - v.last_cmd >= RETRY_S:
                    v.last_cmd = now
                    v.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                    act(v)
            if not waiting:
                for v in self.v:
                    v.last_cmd = -1e9
                return
            if self.clock() > deadline:
                v = waiting[0]
                text = v.last_text
                if v.params_ok is not None and not set(self._params(v)) <= v.params_ok:
                    text = "parameters not read back: " + ", ".join(
                        sorted(set(self._params(v)) - v.params_ok)
                    )
                raise UserError(
                    f"ArduPlane sysid {v.spec.sysid} did not {what} within {timeout_s:.0f} s of "
                    f"wall time (mode {MODE_NAMES.get(v.mode, v.mode)}, armed {v.armed}, "
                    f"{v.rel_alt_m:.0f} m{'; last message: ' + text if text else ''})"
                )
            time.sleep(0.02)

    def run(self) -> None:
        """Connect (unless done), set the parameters, upload, set used batteries' charge;
        the spares GUIDED on the ground; the patrol armed in TAKEOFF, climbed."""
        if any(v.conn is None for v in self.v):
            self.connect()
        self._wait("send a heartbeat", lambda v: v.seen_hb, lambda v: None, CONNECT_TIMEOUT_S)
        for v in self.v:
            v.params_ok = set()
            # telemetry for this link: position at 4 Hz (vehicle time)
            v.conn.mav.command_long_send(
                v.spec.sysid, 1, mav.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 250_000, 0, 0, 0, 0, 0,
            )  # fmt: skip

        def set_params(v: _Vehicle) -> None:
            for name, value in self._params(v).items():
                if name not in v.params_ok:
                    v.conn.mav.param_set_send(
                        v.spec.sysid, 1, name.encode(), float(value), mav.MAV_PARAM_TYPE_REAL32
                    )

        self._wait(
            "accept the parameters",
            lambda v: v.params_ok is not None and set(self._params(v)) <= v.params_ok,
            set_params,
            PARAM_TIMEOUT_S,
        )
        for v in self.v:
            for _ in range(UPLOAD_TRIES):  # a just-booted ArduPilot may refuse (NO_SPACE)
                ok, text = self.upload(v.conn, v.spec.sysid, v.spec.index)
                if ok:
                    break
                self.check_alive()
                time.sleep(RETRY_S)
            if not ok:
                raise UserError(f"perimeter upload to ArduPlane sysid {v.spec.sysid}: {text}")
            self.say(f"fleet: sysid {v.spec.sysid}: {text}")

        def reset(v: _Vehicle) -> None:  # a used battery: its monitor's charge, as swapped
            v.conn.mav.command_long_send(
                v.spec.sysid, 1, mav.MAV_CMD_BATTERY_RESET, 0,
                1, self.battery_pct[v.spec.sysid], 0, 0, 0, 0, 0,
            )  # fmt: skip

        self._wait(
            "accept its battery's charge (MAV_CMD_BATTERY_RESET)",
            lambda v: v.reset_ok,
            reset,
            PARAM_TIMEOUT_S,
            among=lambda v: v.spec.sysid in self.battery_pct,
        )

        def guided(v: _Vehicle) -> None:  # a spare waits on the ground in GUIDED, disarmed
            v.conn.mav.command_long_send(
                v.spec.sysid, 1, mav.MAV_CMD_DO_SET_MODE, 0,
                mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED_MODE, 0, 0, 0, 0, 0,
            )  # fmt: skip

        self._wait(
            "wait on the ground in GUIDED",
            lambda v: v.mode == GUIDED_MODE and not v.armed,
            guided,
            PARAM_TIMEOUT_S,
            among=lambda v: v.spec.sysid in self.spares,
        )

        def arm(v: _Vehicle) -> None:
            v.conn.mav.command_long_send(
                v.spec.sysid, 1, mav.MAV_CMD_DO_SET_MODE, 0,
                mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, TAKEOFF_MODE, 0, 0, 0, 0, 0,
            )  # fmt: skip
            v.conn.mav.command_long_send(
                v.spec.sysid, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
            )

        self._wait(
            "arm in TAKEOFF mode",
            lambda v: v.armed and v.mode == TAKEOFF_MODE,
            arm,
            self._wall(ARM_TIMEOUT_SIM_S),
            among=lambda v: v.spec.sysid not in self.spares,
        )
        alt = self.mission.vehicles.altitude_m
        self._wait(
            "climb to its take-off altitude",
            lambda v: v.rel_alt_m >= alt(v.spec.sysid) - CLIMB_MARGIN_M,
            lambda v: None,
            self._wall(CLIMB_TIMEOUT_SIM_S),
            among=lambda v: v.spec.sysid not in self.spares,
        )

    def keep_alive(self) -> None:
        """Drain SERIAL0 and send the ground station's heartbeat (call now and then)."""
        for v in self.v:
            if v.conn is None:
                continue
            self._pump(v)
            now = self.clock()
            if now - v.last_cmd >= RETRY_S:
                v.last_cmd = now
                with contextlib.suppress(OSError):
                    v.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def close(self) -> None:
        """Close every SERIAL0 connection."""
        close_links(self.v)
