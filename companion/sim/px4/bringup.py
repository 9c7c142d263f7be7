"""Taking PX4 SITL instances off for a fleet, over each one's ground-station link.

:class:`Bringup` takes every instance off over its ground-station link as the README says
(home, 20 s of vehicle time, OFFBOARD on the ground for 3 s so that TECS re-initialises,
AUTO.TAKEOFF, arm, AUTO.LOITER at the take-off altitude) and uploads the perimeter and
geofence (:func:`companion.link.mission_protocol.vehicle.upload_perimeter`, verified by
download). Wall-clock deadlines: it is plumbing. Every failure is a :class:`UserError` of one
line naming the instance, its mode, armed state and altitude.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.link.px4 import OFFBOARD_CUSTOM_MODE, mode_name
from companion.sim.firmware.links import autopilot_messages, close_links
from companion.sim.px4.sitl import Px4Instance

AUTO_TAKEOFF = (4 << 16) | (2 << 24)
AUTO_LOITER = (4 << 16) | (3 << 24)  # 50593792
GCS_SYSID = 255
GCS_COMPID = 190  # MAV_COMP_ID_MISSIONPLANNER
READY_AFTER_HOME_S = 20.0  # vehicle s after HOME_POSITION before the take-off (README)
GROUND_OFFBOARD_S = 3.0  # vehicle s of OFFBOARD on the ground before it (TECS re-initialises)
HEARTBEAT_TIMEOUT_S = 30.0  # wall s for an instance's first HEARTBEAT
HOME_TIMEOUT_SIM_S = 120.0  # vehicle s for HOME_POSITION (the EKF origin)
OFFBOARD_TIMEOUT_SIM_S = 15.0  # vehicle s for OFFBOARD on the ground
ARM_TIMEOUT_SIM_S = 20.0  # vehicle s from the arm command to armed
CLIMB_TIMEOUT_SIM_S = 120.0  # vehicle s from arming to AUTO.LOITER at the take-off altitude
CLIMB_FRACTION = 0.9  # climbed when at this fraction of the take-off altitude, in AUTO.LOITER
REPOSITION_TIMEOUT_SIM_S = 120.0  # vehicle s to fly from the climb-out to the loiter point
DRAIN_CHECK_S = 5.0  # wall s between asks for a used battery's drain until it drains
DRAIN_TIMEOUT_SIM_S = 90.0  # vehicle s for it to fall a percent (12 s at 20 min a charge)
BATTERY_TIMEOUT_SIM_S = 30.0  # vehicle s for a used battery's charge to be read (9 s measured)
LOITER_NEAR_M = 160.0  # at the loiter point when this close (m; NAV_LOITER_RAD is 80 m)
EARTH_M_PER_DEG = 111_320.0  # metres per degree of latitude (flat-earth distance, < 2 km)
MIN_WALL_TIMEOUT_S = 60.0  # the clock discipline may slow an instance to 0.05 of its factor
WALL_PER_SIM_MARGIN = 3.0  # wall timeouts: this many times the vehicle time at the factor
RETRY_S = 1.0  # wall s between repeated commands
UPLOAD_POINTS = 16  # as ``companion upload``'s default


def distance_m(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Horizontal distance (m) between two nearby points (flat earth; NaN if unknown)."""
    dn = (lat2_deg - lat1_deg) * EARTH_M_PER_DEG
    de = (lon2_deg - lon1_deg) * EARTH_M_PER_DEG * math.cos(math.radians(lat1_deg))
    return math.hypot(dn, de)


def last_line(path: Path | None) -> str:
    """The last non-empty line of a log file ('' if none)."""
    if path is None or not path.is_file():
        return ""
    lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    return lines[-1][-160:] if lines else ""


@dataclass
class _Vehicle:
    """Bring-up state of one instance, from its ground-station link."""

    inst: Px4Instance
    conn: Any = None
    heard: bool = False
    mode: int | None = None
    armed: bool = False
    boot_ms: int = 0
    rel_alt_m: float = 0.0
    lat_deg: float = math.nan
    lon_deg: float = math.nan
    home: bool = False
    battery_pct: float | None = None  # BATTERY_STATUS battery_remaining (%)
    params: dict[str, float] = field(default_factory=dict)  # PARAM_VALUE read back
    last_hb_s: float = -1e9
    last_cmd_s: float = -1e9
    mark_ms: int = 0  # boot ms at which the current stage began
    acks: dict[int, int] = field(default_factory=dict)  # command -> latest result

    def describe(self) -> str:
        """Its mode, armed state and altitude in one phrase."""
        mode = "no heartbeat" if self.mode is None else mode_name(self.mode)
        arm = "armed" if self.armed else "disarmed"
        return f"{mode}, {arm}, {self.rel_alt_m:.0f} m above home"


def _reads(v: _Vehicle, name: str, value: float) -> bool:
    """Whether ``v``'s parameter ``name`` was read back as ``value`` (a REAL32's precision)."""
    got = v.params.get(name)
    return got is not None and math.isclose(got, value, rel_tol=1e-6, abs_tol=1e-6)


class Bringup:
    """Take every instance off over its ground-station link (see the module docstring).

    Args:
        instances: the started instances.
        altitudes_m: each one's take-off altitude (m above home; MIS_TAKEOFF_ALT).
        speed: the speed factor (vehicle s per wall s), to turn vehicle timeouts into wall.
        upload: ``upload(conn, sysid, index) -> (ok, line)``: the perimeter and fence.
        say: where progress lines go.
        clock: wall clock (s).
        loiter_at: where each one loiters after the climb (lat deg, lon deg, alt m AMSL),
            sent by DO_REPOSITION (None: where PX4's take-off ends, straight ahead of home),
            one per aircraft that takes off.
        spares: the sysids that stay on the ground (a relief's spares: home, settled,
            disarmed; their companions take them into OFFBOARD parked).
        battery_pct: the charge (%) some of those that take off start on (``--battery-used``):
            set through the battery simulator once they are armed (:meth:`use_batteries`).
        drain_s: SIM_BAT_DRAIN (s) to restore after that.
        relief_takeoff_m: MIS_TAKEOFF_ALT (m) of each one that took off, set (and read back)
            once it has: the climb-out of its later take-offs, a relief's (sysid -> m).
    """

    def __init__(
        self,
        instances: list[Px4Instance],
        altitudes_m: list[float],
        speed: float,
        upload: Callable[[Any, int, int], tuple[bool, str]],
        say: Callable[[str], None] = print,
        clock: Callable[[], float] = time.monotonic,
        loiter_at: list[tuple[float, float, float]] | None = None,
        spares: frozenset[int] = frozenset(),
        battery_pct: Mapping[int, float] | None = None,
        drain_s: float | None = None,
        relief_takeoff_m: Mapping[int, float] | None = None,
    ) -> None:
        """Nothing is opened yet."""
        self.loiter_at = loiter_at
        self.v = [_Vehicle(inst) for inst in instances]
        self.fly = [v for v in self.v if v.inst.sysid not in spares]  # these take off
        self.battery_pct = dict(battery_pct or {})
        self.drain_s = drain_s
        self.relief_takeoff_m = dict(relief_takeoff_m or {})
        self.altitudes_m = list(altitudes_m)
        self.speed = speed
        self.upload = upload
        self.say = say
        self.clock = clock
        self.upload_lines: dict[int, str] = {}
        self.heartbeat_timeout_s = HEARTBEAT_TIMEOUT_S  # wall s for the first HEARTBEAT

    def _wall(self, sim_s: float) -> float:
        """A vehicle-time timeout as wall seconds: PX4 rarely reaches its speed factor on a
        busy machine, and the world process pauses the instances ahead of the slowest (six
        instances started 8 s of vehicle time apart; the first was held to 0.15 of its
        factor while the others caught up)."""
        return max(MIN_WALL_TIMEOUT_S, WALL_PER_SIM_MARGIN * sim_s / self.speed)

    def check_alive(self) -> None:
        """:class:`UserError` if an instance exited (naming its log's last line)."""
        for v in self.v:
            p = v.inst.proc
            if p is not None and p.poll() is not None:
                why = last_line(v.inst.log_path)
                raise UserError(
                    f"PX4 instance {v.inst.i} (sysid {v.inst.sysid}) exited with status "
                    f"{p.returncode}" + (f": {why}" if why else "") + f" (see {v.inst.log_path})"
                )

    def connect(self) -> None:
        """Open every ground-station link (udpout: PX4 answers the first sender)."""
        for v in self.v:
            v.conn = mavutil.mavlink_connection(
                f"udpout:127.0.0.1:{v.inst.ports['gcs']}",
                source_system=GCS_SYSID,
                source_component=GCS_COMPID,
                dialect="ardupilotmega",
            )

    def pump(self) -> None:
        """Read every link and heartbeat (1 Hz); call now and then between the stages."""
        for v in self.v:
            self._pump(v)

    def _pump(self, v: _Vehicle) -> None:
        now = self.clock()
        if now - v.last_hb_s >= 1.0:
            v.last_hb_s = now
            with contextlib.suppress(OSError):
                v.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        for m in autopilot_messages(v.conn, v.inst.sysid):
            t = m.get_type()
            if t == "HEARTBEAT":
                v.heard = True
                v.mode = int(m.custom_mode)
                v.armed = bool(m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
            elif t == "GLOBAL_POSITION_INT":
                v.boot_ms = int(m.time_boot_ms)
                v.rel_alt_m = m.relative_alt * 1e-3
                v.lat_deg, v.lon_deg = m.lat * 1e-7, m.lon * 1e-7
            elif t == "HOME_POSITION":
                v.home = True
            elif t == "BATTERY_STATUS" and m.battery_remaining >= 0:
                v.battery_pct = float(m.battery_remaining)
            elif t == "PARAM_VALUE":
                v.params[str(m.param_id)] = float(m.param_value)
            elif t == "COMMAND_ACK":
                v.acks[int(m.command)] = int(m.result)

    def _command(self, v: _Vehicle, command: int, *params: float) -> None:
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        v.conn.mav.command_long_send(v.inst.sysid, 1, command, 0, *p)

    def _level_setpoint(self, v: _Vehicle) -> None:
        """SET_ATTITUDE_TARGET level, thrust 0 (type_mask 0x07: a valid offboard setpoint)."""
        v.conn.mav.set_attitude_target_send(
            v.boot_ms, v.inst.sysid, 1, 0x07, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 0.0
        )

    def _wait(
        self,
        what: str,
        done: Callable[[_Vehicle], bool],
        act: Callable[[_Vehicle], None],
        timeout_s: float,
        period_s: float = 0.05,
        among: list[_Vehicle] | None = None,
    ) -> None:
        """Until ``done`` for every vehicle (of ``among``: default those that take off),
        calling ``act`` on the others every turn (``period_s`` wall); :class:`UserError`
        naming the late ones at ``timeout_s``. Every link is read meanwhile."""
        deadline = self.clock() + timeout_s
        vs = self.fly if among is None else among
        while True:
            self.check_alive()
            waiting = []
            for v in self.v:
                self._pump(v)
            for v in vs:
                if not done(v):
                    waiting.append(v)
                    act(v)
            if not waiting:
                return
            if self.clock() > deadline:
                late = "; ".join(
                    f"instance {v.inst.i} (sysid {v.inst.sysid}): {v.describe()}" for v in waiting
                )
                raise UserError(f"PX4 did not {what} within {timeout_s:.0f} s of wall time: {late}")
            time.sleep(period_s)

    def run(self) -> None:
        """Heartbeat, upload, home, settled, for all; OFFBOARD on the ground, take-off, climb,
        loiter point and used batteries for those that take off (not the spares)."""
        everyone = self.v
        self._wait("send a HEARTBEAT", lambda v: v.heard, lambda v: None, self.heartbeat_timeout_s,
                   among=everyone)  # fmt: skip
        for k, v in enumerate(self.v):
            ok, line = self.upload(v.conn, v.inst.sysid, k)
            self.upload_lines[v.inst.sysid] = line
            if not ok:
                raise UserError(f"upload to PX4 sysid {v.inst.sysid} failed: {line}")
        self._wait("report HOME_POSITION", lambda v: v.home and v.boot_ms > 0, lambda v: None,
                   self._wall(HOME_TIMEOUT_SIM_S), among=everyone)  # fmt: skip
        for v in self.v:
            v.mark_ms = v.boot_ms
        ready_ms = READY_AFTER_HOME_S * 1e3
        self._wait("settle after HOME_POSITION", lambda v: v.boot_ms >= v.mark_ms + ready_ms,
                   lambda v: None, self._wall(READY_AFTER_HOME_S + 10.0),
                   among=everyone)  # fmt: skip
        self._ground_offboard()
        now = self.clock()
        for v in self.fly:
            self._command(v, mav.MAV_CMD_DO_SET_MODE, 1, 4, 2)  # AUTO.TAKEOFF
            v.last_cmd_s = now
        self._wait("enter AUTO.TAKEOFF", lambda v: v.mode == AUTO_TAKEOFF, self._retry_takeoff,
                   self._wall(10.0))  # fmt: skip
        self._wait("arm", lambda v: v.armed, self._retry_arm, self._wall(ARM_TIMEOUT_SIM_S))
        alts = self.altitudes_m
        want = {v.inst.sysid: CLIMB_FRACTION * alts[k] for k, v in enumerate(self.v)}
        self._wait(
            "climb into AUTO.LOITER at its take-off altitude",
            lambda v: v.mode == AUTO_LOITER and v.rel_alt_m >= want[v.inst.sysid],
            lambda v: None,
            self._wall(CLIMB_TIMEOUT_SIM_S),
            0.1,
        )
        if self.loiter_at is not None:
            self._reposition()
        if self.battery_pct:
            self.use_batteries()
        if self.relief_takeoff_m:
            self._set_params(
                "set the relief take-off altitude",
                {s: {"MIS_TAKEOFF_ALT": m} for s, m in self.relief_takeoff_m.items()},
            )

    def _set_params(self, what: str, params: dict[int, dict[str, float]]) -> None:
        """PARAM_SET each aircraft's ``params`` (sysid -> name -> value) until read back."""
        vs = [v for v in self.fly if v.inst.sysid in params]
        for v in vs:
            v.last_cmd_s = -1e9

        def done(v: _Vehicle) -> bool:
            return all(_reads(v, k, x) for k, x in params[v.inst.sysid].items())

        self._wait(what, done, lambda v: self._ask(v, params),
                   self._wall(BATTERY_TIMEOUT_SIM_S), 0.1, among=vs)  # fmt: skip

    def _ask(self, v: _Vehicle, params: dict[int, dict[str, float]]) -> None:
        """PARAM_SET those of ``v``'s ``params`` not read back yet, at most every RETRY_S."""
        if self.clock() - v.last_cmd_s < RETRY_S:
            return
        v.last_cmd_s = self.clock()
        for name, value in params[v.inst.sysid].items():
            if not _reads(v, name, value):
                v.conn.mav.param_set_send(v.inst.sysid, 1, name.encode(), value,
                                          mav.MAV_PARAM_TYPE_REAL32)  # fmt: skip

    def use_batteries(self) -> None:
        """Each armed aircraft of ``battery_pct`` on its used battery: PX4's battery simulator
        (full while disarmed) floored at the charge asked (SIM_BAT_MIN_PCT) and drained in 1 s
        (SIM_BAT_DRAIN) until BATTERY_STATUS reads it (9 s of vehicle time measured: PX4
        filters the voltage), then drained at ``drain_s`` from there with the floor at 0 again
        (read back, and seen falling a percent). The counterpart of ArduPlane's
        MAV_CMD_BATTERY_RESET (PX4 has none)."""
        want = {v.inst.sysid: self.battery_pct[v.inst.sysid] for v in self.fly
                if v.inst.sysid in self.battery_pct}  # fmt: skip
        vs = [v for v in self.fly if v.inst.sysid in want]
        floor = {s: {"SIM_BAT_MIN_PCT": float(p), "SIM_BAT_DRAIN": 1.0} for s, p in want.items()}
        for v in vs:
            v.last_cmd_s = -1e9

        def at(v: _Vehicle) -> bool:
            pct = v.battery_pct
            return pct is not None and pct <= want[v.inst.sysid] + 1.0

        self._wait("read its used battery's charge", at, lambda v: self._ask(v, floor),
                   self._wall(BATTERY_TIMEOUT_SIM_S), 0.1, among=vs)  # fmt: skip
        drain = {"SIM_BAT_MIN_PCT": 0.0, "SIM_BAT_DRAIN": float(self.drain_s or 0.0)}
        again = {s: drain for s in want}
        self._set_params("drain its used battery again", again)
        # and seen draining: once, under a load of 10-12 on the 2 cores, PX4 was left holding
        # the floor although both had been read back (its final parameters said so); the
        # drain is asked again every DRAIN_CHECK_S until the charge falls a percent
        for v in vs:
            v.last_cmd_s = self.clock()

        def ask(v: _Vehicle) -> None:
            if self.clock() - v.last_cmd_s >= DRAIN_CHECK_S:
                v.params = {}
                self._ask(v, again)

        def draining(v: _Vehicle) -> bool:
            pct = v.battery_pct
            return pct is not None and pct <= want[v.inst.sysid] - 1.0

        self._wait("drain its used battery", draining, ask,
                   self._wall(DRAIN_TIMEOUT_SIM_S), 0.1, among=vs)  # fmt: skip

    def _reposition(self) -> None:
        """DO_REPOSITION (COMMAND_INT, frame GLOBAL_INT: altitude AMSL) of each aircraft to
        its loiter point, repeated until it is there in AUTO.LOITER."""
        assert self.loiter_at is not None
        target = {v.inst.sysid: self.loiter_at[k] for k, v in enumerate(self.fly)}
        for v in self.fly:
            v.last_cmd_s = -1e9

        def there(v: _Vehicle) -> bool:
            lat, lon, _ = target[v.inst.sysid]
            d = distance_m(v.lat_deg, v.lon_deg, lat, lon)
            return v.mode == AUTO_LOITER and d <= LOITER_NEAR_M

        def ask(v: _Vehicle) -> None:
            if self.clock() - v.last_cmd_s < 2.0 * RETRY_S:
                return
            v.last_cmd_s = self.clock()
            lat, lon, alt = target[v.inst.sysid]
            v.conn.mav.command_int_send(
                v.inst.sysid, 1, mav.MAV_FRAME_GLOBAL_INT, mav.MAV_CMD_DO_REPOSITION, 0, 0,
                -1, mav.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, math.nan,
                round(lat * 1e7), round(lon * 1e7), alt,
            )  # fmt: skip

        self._wait("fly to its loiter point in AUTO.LOITER", there, ask,
                   self._wall(REPOSITION_TIMEOUT_SIM_S), 0.1)  # fmt: skip

    def _ground_offboard(self) -> None:
        """OFFBOARD on the ground for GROUND_OFFBOARD_S with a level setpoint stream."""
        for v in self.fly:
            v.mark_ms, v.last_cmd_s = v.boot_ms, -1e9
        asked: dict[int, int] = {}  # sysid -> boot ms when OFFBOARD was first seen

        def stream(v: _Vehicle) -> None:
            self._level_setpoint(v)
            if v.mode == OFFBOARD_CUSTOM_MODE:
                asked.setdefault(v.inst.sysid, v.boot_ms)
            elif v.boot_ms >= v.mark_ms + 1000 and self.clock() - v.last_cmd_s >= RETRY_S:
                self._command(v, mav.MAV_CMD_DO_SET_MODE, 1, 6)
                v.last_cmd_s = self.clock()

        def held(v: _Vehicle) -> bool:
            t = asked.get(v.inst.sysid)
            return t is not None and v.boot_ms >= t + GROUND_OFFBOARD_S * 1e3

        self._wait("enter OFFBOARD on the ground", held, stream,
                   self._wall(OFFBOARD_TIMEOUT_SIM_S), 0.05)  # fmt: skip

    def _retry_takeoff(self, v: _Vehicle) -> None:
        if self.clock() - v.last_cmd_s >= RETRY_S:
            self._command(v, mav.MAV_CMD_DO_SET_MODE, 1, 4, 2)
            v.last_cmd_s = self.clock()

    def _retry_arm(self, v: _Vehicle) -> None:
        if self.clock() - v.last_cmd_s >= RETRY_S:
            self._command(v, mav.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            v.last_cmd_s = self.clock()

    def close(self) -> None:
        """Close every ground-station link."""
        close_links(self.v)
