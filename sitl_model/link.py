"""MAVLink behaviour of one simulated vehicle: incoming messages in, messages to send out.

No sockets: :meth:`VehicleLink.handle` takes a decoded message, the peer it came from (an
opaque key, the UDP address in practice) and the wall-clock time for protocol timeouts,
and returns ``(message, peer)`` pairs; ``peer`` None means every peer of this vehicle.
Everything bad is dropped or refused and counted in :class:`Counters`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from companion.contracts.attitude_target import arduplane_forced_axes
from sitl_model.autopilot import Mode, RefusedError, Setpoint, SetpointKind
from sitl_model.codec import dialect as d
from sitl_model.mission_protocol import MissionProtocol
from sitl_model.params import ParamError, Params
from sitl_model.sim import Simulation
from sitl_model.telemetry import Streams, Telemetry

MAV_CMD_GUIDED_CHANGE_HEADING = 43002
FORCE_DISARM_MAGIC = 21196
MAX_YAW_RATE_RAD_S = 10.0
ACCEPTED, DENIED, UNSUPPORTED, FAILED = (
    d.MAV_RESULT_ACCEPTED,
    d.MAV_RESULT_DENIED,
    d.MAV_RESULT_UNSUPPORTED,
    d.MAV_RESULT_FAILED,
)

Out = tuple[Any, Any]

# REQUEST_DATA_STREAM groups (ArduPilot's SRx_* grouping, restricted to what is streamed)
_GROUPS: dict[int, tuple[str, ...]] = {
    d.MAV_DATA_STREAM_EXTENDED_STATUS: (
        "SYS_STATUS", "GPS_RAW_INT", "MISSION_CURRENT", "EXTENDED_SYS_STATE",
    ),
    d.MAV_DATA_STREAM_POSITION: ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED"),
    d.MAV_DATA_STREAM_EXTRA1: ("ATTITUDE",),
    d.MAV_DATA_STREAM_EXTRA2: ("VFR_HUD",),
    d.MAV_DATA_STREAM_EXTRA3: ("WIND", "SYSTEM_TIME", "HOME_POSITION", "BATTERY_STATUS"),
}  # fmt: skip
DATA_STREAMS: dict[int, tuple[str, ...]] = {
    **_GROUPS,
    d.MAV_DATA_STREAM_ALL: tuple(n for g in _GROUPS.values() for n in g),
}


@dataclass
class Counters:
    """What came in and what became of it (per vehicle)."""

    rx: int = 0  # valid messages received
    tx: int = 0  # messages sent (frames, to each peer)
    bad: int = 0  # garbage / CRC / unknown-id chunks
    foreign: int = 0  # addressed to another system id
    refused: int = 0  # commands denied, setpoints and params refused, mission refusals
    unsupported: int = 0  # commands we do not implement
    unsigned: int = 0  # link signing on: frames without a signature (or MAVLink 1)
    bad_signature: int = 0  # link signing on: signature wrong for the key
    replayed: int = 0  # link signing on: timestamp not newer than the stream's last

    def add(self, other: Counters) -> None:
        """Accumulate ``other`` into this one."""
        for k in vars(self):
            setattr(self, k, getattr(self, k) + getattr(other, k))


def _finite(*xs: float) -> bool:
    return all(math.isfinite(x) for x in xs)


class VehicleLink:
    """The MAVLink face of vehicle ``index`` of ``sim``."""

    def __init__(
        self, sim: Simulation, index: int, telemetry: Telemetry, missions: MissionProtocol
    ) -> None:
        """Bind to the simulation; ``missions`` is this vehicle's stored mission + protocol."""
        self.sim = sim
        self.index = index
        self.sysid = sim.sysids[index]
        self.tm = telemetry
        self.missions = missions
        self.streams = Streams()  # all vehicles in phase: one geodetic conversion per step
        self.counters = Counters()
        self.setpoints_rx = 0  # new GUIDED setpoints received (any outcome): lockstep answers
        self._last_setpoint: tuple | None = None  # (type, field values) of the last one
        self._mission_version = -1
        self._fence_version = -1
        self.sync_mission()

    @property
    def params(self) -> Params:
        """The fleet-wide parameters."""
        return self.sim.params

    @property
    def ap(self):
        """This vehicle's autopilot model."""
        return self.sim.autopilots[self.index]

    def sync_mission(self) -> None:
        """Give the autopilot the stored mission's waypoints if the mission changed."""
        if self.missions.version != self._mission_version:
            self._mission_version = self.missions.version
            self.ap.set_waypoints(
                self.sim.nav_points(self.missions.items), self.sim.t_s, self.sim.obs(self.index)
            )
            self.tm.mission_total[self.index] = self.missions.total
        if self.missions.fence_version != self._fence_version:  # the fence the vehicle holds
            self._fence_version = self.missions.fence_version
            self.sim.set_fence(self.index, self.missions.fence)

    # ------------------------------------------------------------------------ inbound
    def handle(self, m: Any, peer: Any, wall_s: float) -> list[Out]:
        """React to one decoded message from ``peer``."""
        self.counters.rx += 1
        target = getattr(m, "target_system", 0)
        component = getattr(m, "target_component", 0)
        if target not in (0, self.sysid) or component not in (0, d.MAV_COMP_ID_AUTOPILOT1):
            self.counters.foreign += 1  # another system, or e.g. our camera (component 100)
            return []
        t = m.get_type()
        if t in ("COMMAND_LONG", "COMMAND_INT"):
            if m.command == MAV_CMD_GUIDED_CHANGE_HEADING:
                self._count_setpoint(m)
            return self._command(m, peer)
        if t == "SET_MODE":
            return self._set_mode_msg(m, peer)
        if t == "SET_ATTITUDE_TARGET":
            self._count_setpoint(m)
            self._attitude_target(m)
            return []
        if t.startswith("PARAM_"):
            return self._param(m, peer)
        if t.startswith("MISSION_"):
            return self._mission(m, peer, wall_s)
        if t == "REQUEST_DATA_STREAM":
            self._data_stream(m)
            return []
        if t == "TIMESYNC" and m.tc1 == 0:
            return [(d.MAVLink_timesync_message(round(self.sim.t_s * 1e9), m.ts1), peer)]
        return []

    def _count_setpoint(self, m: Any) -> None:
        """Count a new setpoint. A field-for-field repeat of the previous one (a companion's
        keep-alive) is flown but is not new: it answers no position report in lockstep."""
        d = m.__dict__
        fields = (m.get_type(), *[d[f] for f in m.get_fieldnames()])
        if fields != self._last_setpoint:
            self._last_setpoint = fields
            self.setpoints_rx += 1

    def _refuse(self) -> None:
        self.counters.refused += 1
        self.tm.errors_comm[self.index] += 1

    def _ack(self, m: Any, peer: Any, command: int, result: int) -> Out:
        return (
            d.MAVLink_command_ack_message(
                command, result, 0, 0, m.get_srcSystem(), m.get_srcComponent()
            ),
            peer,
        )

    def _command(self, m: Any, peer: Any) -> list[Out]:
        cmd = int(m.command)
        p = (m.param1, m.param2, m.param3, m.param4)
        extra: list[Out] = []
        result = self._run_command(cmd, p, m, peer, extra)
        if result == UNSUPPORTED:
            self.counters.unsupported += 1
        elif result != ACCEPTED:
            self._refuse()
        return [self._ack(m, peer, cmd, result), *extra]

    def _run_command(self, cmd: int, p: tuple, m: Any, peer: Any, extra: list[Out]) -> int:
        sim, ap, i = self.sim, self.ap, self.index
        try:
            if cmd == d.MAV_CMD_DO_SET_MODE:
                if not _finite(p[0], p[1]) or not int(p[0]) & d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                    return DENIED
                ap.set_mode(int(p[1]), sim.t_s, sim.obs(i))
                return ACCEPTED
            if cmd == d.MAV_CMD_MISSION_START:
                if not _finite(p[0], p[1]):
                    return DENIED
                ap.set_mode(Mode.AUTO, sim.t_s, sim.obs(i))
                if p[0] > 0:
                    ap.set_current(int(p[0]), sim.obs(i))
                return ACCEPTED
            if cmd == d.MAV_CMD_NAV_RETURN_TO_LAUNCH:
                ap.set_mode(Mode.RTL, sim.t_s, sim.obs(i))
                return ACCEPTED
            if cmd in (d.MAV_CMD_NAV_TAKEOFF, d.MAV_CMD_NAV_LAND):
                # ArduPlane's fixed wing: NAV_TAKEOFF is a quadplane's; it takes off armed in
                # TAKEOFF and lands by its mission's landing sequence (DO_LAND_START)
                return UNSUPPORTED
            if cmd == d.MAV_CMD_DO_LAND_START:  # where it is, at once (no approach)
                sim.land(i)
                return ACCEPTED
            if cmd == d.MAV_CMD_COMPONENT_ARM_DISARM:
                if not _finite(p[0], p[1]) or p[0] not in (0.0, 1.0):
                    return DENIED
                if p[0] == 1.0 and ap.mode is Mode.TAKEOFF and sim.grounded[i]:
                    sim.take_off(i)  # armed in TAKEOFF on the ground: it takes off at once
                    return ACCEPTED
                # on the ground a disarm needs no force (ArduPlane refuses one only in flight)
                ap.arm(p[0] == 1.0, force=round(p[1]) == FORCE_DISARM_MAGIC or sim.grounded[i])
                return ACCEPTED
            if cmd == MAV_CMD_GUIDED_CHANGE_HEADING:
                return self._change_heading(p)
            if cmd == d.MAV_CMD_GUIDED_CHANGE_SPEED:
                # ArduPlane: GUIDED only, param1 0 = airspeed, param2 m/s, param3 accel
                if not _finite(p[0], p[1]) or p[0] != 0.0:
                    return DENIED
                ap.change_airspeed(float(p[1]))
                return ACCEPTED
            if cmd == d.MAV_CMD_DO_CHANGE_SPEED:
                # ArduPlane: GUIDED or AUTO; speed type 0 = airspeed (param2 m/s)
                if not _finite(p[0], p[1]) or p[0] != 0.0:
                    return DENIED
                if ap.mode is not Mode.GUIDED:
                    return FAILED
                ap.change_airspeed(float(p[1]))
                extra.append((self._text(f"Set airspeed {int(p[1])} m/s"), peer))
                return ACCEPTED
            if cmd == d.MAV_CMD_GUIDED_CHANGE_ALTITUDE:
                return self._change_altitude(m)
            if cmd == d.MAV_CMD_DO_SET_MISSION_CURRENT:
                if not _finite(p[0]):
                    return DENIED
                ap.set_current(int(p[0]), sim.obs(i))
                extra.append((self.tm.mission_current(i), None))
                return ACCEPTED
            if cmd in (d.MAV_CMD_REQUEST_MESSAGE, d.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
                msg_id = d.MAVLINK_MSG_ID_AUTOPILOT_VERSION
                if cmd == d.MAV_CMD_REQUEST_MESSAGE:
                    if not _finite(p[0]):
                        return DENIED
                    msg_id = int(p[0])
                msg = self._build_by_id(msg_id)
                if msg is None:
                    return DENIED
                extra.append((msg, peer))
                return ACCEPTED
            if cmd == d.MAV_CMD_SET_MESSAGE_INTERVAL:
                return self._set_interval(p)
            if cmd == d.MAV_CMD_GET_MESSAGE_INTERVAL:
                name = self._name_of(p[0])
                if name is None:
                    return DENIED
                iv = self.streams.interval_s.get(name)
                us = -1 if iv is None else round(iv * 1e6)
                extra.append((d.MAVLink_message_interval_message(int(p[0]), us), peer))
                return ACCEPTED
        except RefusedError as e:
            extra.append((self._text(str(e), d.MAV_SEVERITY_WARNING), peer))
            return DENIED
        return UNSUPPORTED

    def _change_heading(self, p: tuple) -> int:
        kind_f, deg, accel = p[0], p[1], p[2]
        if not _finite(kind_f, deg, accel) or kind_f not in (0.0, 1.0) or accel < 0:
            return DENIED
        kind = SetpointKind.COURSE if kind_f == 0.0 else SetpointKind.HEADING
        self.ap.setpoint(Setpoint(kind, math.radians(deg), accel), self.sim.t_s)
        return ACCEPTED

    def _change_altitude(self, m: Any) -> int:
        """GUIDED_CHANGE_ALTITUDE as ArduPlane takes it: COMMAND_INT, the altitude in ``z``
        (m) in ``frame`` (GLOBAL: AMSL; GLOBAL_RELATIVE_ALT: above home, the origin)."""
        if m.get_type() != "COMMAND_INT":
            return UNSUPPORTED
        z = float(m.z)
        if not _finite(z) or z in (-1.0, 0.0):
            return DENIED
        if m.frame in (d.MAV_FRAME_GLOBAL, d.MAV_FRAME_GLOBAL_INT):
            alt = z - self.sim.frame.alt_m
        elif m.frame in (d.MAV_FRAME_GLOBAL_RELATIVE_ALT, d.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
            alt = z
        else:
            return DENIED
        if self.ap.mode is not Mode.GUIDED:
            return FAILED
        self.ap.change_altitude(alt)
        return ACCEPTED

    def _name_of(self, msg_id: float) -> str | None:
        if not _finite(msg_id) or int(msg_id) not in d.mavlink_map:
            return None
        name = d.mavlink_map[int(msg_id)].msgname
        return name if name in self.tm.builders else None

    def _build_by_id(self, msg_id: int) -> Any:
        name = self._name_of(msg_id)
        return None if name is None else self.tm.builders[name](self.index)

    def _set_interval(self, p: tuple) -> int:
        name = self._name_of(p[0])
        if name is None or name == "AUTOPILOT_VERSION" or not _finite(p[1]):
            return DENIED
        us = p[1]
        if us == 0:
            self.streams.set_interval(name, None, self.sim.t_s)
        elif us < 0:
            self.streams.set_interval(name, 0.0, self.sim.t_s)
        else:
            self.streams.set_interval(name, us * 1e-6, self.sim.t_s)
        return ACCEPTED

    def _data_stream(self, m: Any) -> None:
        """Legacy REQUEST_DATA_STREAM (MAVProxy, older ground stations): rate per group."""
        names = DATA_STREAMS.get(int(m.req_stream_id))
        rate = float(m.req_message_rate)
        if names is None or not math.isfinite(rate) or rate < 0:
            self._refuse()
            return
        for name in names:
            interval = 1.0 / rate if m.start_stop and rate > 0 else -1.0
            self.streams.set_interval(name, interval, self.sim.t_s)

    def _set_mode_msg(self, m: Any, peer: Any) -> list[Out]:
        result = ACCEPTED
        try:
            if not m.base_mode & d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                result = DENIED
            else:
                self.ap.set_mode(int(m.custom_mode), self.sim.t_s, self.sim.obs(self.index))
        except RefusedError:
            result = DENIED
        if result != ACCEPTED:
            self._refuse()
        return [self._ack(m, peer, d.MAVLINK_MSG_ID_SET_MODE, result)]

    def _attitude_target(self, m: Any) -> None:
        """SET_ATTITUDE_TARGET: as ArduPlane reads the mask (``SIM_RATE_OK`` 0), or as a
        rate-controlled autopilot (``SIM_RATE_OK`` 1: the body yaw rate is flown too)."""
        mask = int(m.type_mask)
        try:
            if self.params["SIM_RATE_OK"] >= 0.5:
                self._attitude_target_spec(m, mask)
                return
            # ArduPlane: no body rate is read; roll / pitch / rudder / throttle are forced
            # by the inverted mask; a message forcing nothing is accepted and does nothing.
            axes = arduplane_forced_axes(mask)
            if axes["roll"] or axes["pitch"]:
                roll = _roll_of(m.q)
            if axes["pitch"]:
                self.ap.force_pitch(self.sim.t_s)
            if axes["roll"]:
                self.ap.setpoint(Setpoint(SetpointKind.ROLL, roll), self.sim.t_s)
        except RefusedError:
            self._refuse()

    def _attitude_target_spec(self, m: Any, mask: int) -> None:
        """Rate-controlled: the roll of ``q`` where ArduPlane would take it (so the bank
        profile works the same; no pitch forcing, the speed is kept), else the body yaw rate
        when its bit is clear."""
        if arduplane_forced_axes(mask)["roll"]:
            sp = Setpoint(SetpointKind.ROLL, _roll_of(m.q))
        elif not mask & d.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE:
            r = float(m.body_yaw_rate)
            if not (math.isfinite(r) and abs(r) <= MAX_YAW_RATE_RAD_S):
                raise RefusedError("bad yaw rate")
            sp = Setpoint(SetpointKind.TURN_RATE, r)
        else:
            raise RefusedError("nothing to fly")
        self.ap.setpoint(sp, self.sim.t_s)

    # ------------------------------------------------------------------------- params
    def _param_value(self, name: str) -> Any:
        names = self.params.names()
        return d.MAVLink_param_value_message(
            name.encode(), self.params[name], d.MAV_PARAM_TYPE_REAL32, len(names), names.index(name)
        )

    def _param(self, m: Any, peer: Any) -> list[Out]:
        t = m.get_type()
        names = self.params.names()
        if t == "PARAM_REQUEST_LIST":
            return [(self._param_value(n), peer) for n in names]
        if t == "PARAM_REQUEST_READ":
            idx = int(m.param_index)
            name = m.param_id if idx < 0 else (names[idx] if idx < len(names) else "")
            if name not in names:
                self._refuse()
                return []
            return [(self._param_value(name), peer)]
        if t == "PARAM_SET":
            name = m.param_id
            if name not in names:
                self._refuse()
                return [(self._text(f"Unknown parameter {name}", d.MAV_SEVERITY_WARNING), peer)]
            try:
                self.params.set(name, m.param_value)
            except ParamError as e:
                self._refuse()
                return [(self._text(str(e)[:50], d.MAV_SEVERITY_WARNING), peer),
                        (self._param_value(name), peer)]  # fmt: skip
            return [(self._param_value(name), None)]
        return []

    # ----------------------------------------------------------------------- missions
    def _mission(self, m: Any, peer: Any, wall_s: float) -> list[Out]:
        t = m.get_type()
        if t == "MISSION_SET_CURRENT":
            try:
                self.ap.set_current(int(m.seq), self.sim.obs(self.index))
            except RefusedError:
                self._refuse()
                return []
            return [(self.tm.mission_current(self.index), None)]
        before = self.missions.refused
        outs = self.missions.handle(m, peer, wall_s)
        if self.missions.refused != before:
            self.counters.refused += self.missions.refused - before
            self.tm.errors_comm[self.index] += self.missions.refused - before
        self.sync_mission()
        return outs

    def tick(self, wall_s: float) -> list[Out]:
        """Protocol timeouts (stalled mission uploads)."""
        before = self.missions.refused
        outs = self.missions.tick(wall_s)
        if self.missions.refused != before:
            self.counters.refused += self.missions.refused - before
        return outs

    # ---------------------------------------------------------------------- outbound
    def _text(self, text: str, severity: int = d.MAV_SEVERITY_INFO) -> Any:
        return d.MAVLink_statustext_message(severity, text[:50].encode())

    def statustext(self, text: str, severity: int) -> Any:
        """A STATUSTEXT message (text truncated to 50 characters)."""
        return self._text(text, severity)

    def due_telemetry(self) -> list[Any]:
        """Stream messages due now."""
        names = self.streams.due(self.sim.t_s)
        b = self.tm.builders
        return [b[n](self.index) for n in names]


def _roll_of(q: Any) -> float:
    """Euler roll (rad) of a quaternion (w, x, y, z); :class:`RefusedError` if not one."""
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z) if _finite(w, x, y, z) else math.nan
    if not (math.isfinite(n) and 0.5 < n < 1.5):
        raise RefusedError("bad quaternion")
    w, x, y, z = w / n, x / n, y / n, z / n
    return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
