"""The autopilot's messages, one by one: HEARTBEAT (the Agent starts, armed, command
authority), SYSTEM_TIME (vehicle time), GLOBAL_POSITION_INT (the estimate, then a control
step), ATTITUDE, VFR_HUD, WIND, battery reports, COMMAND_ACK, and the camera's detections."""

from __future__ import annotations

import selectors
from typing import Any

from companion.agent.agent import Agent
from companion.agent.config import AgentConfig
from companion.group.flood import FloodGate
from companion.link import px4

CAMERA_COMPID = 100
TRACKING_ACTIVE = 1  # CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
MAV_MODE_FLAG_SAFETY_ARMED = 128


class LinkMessages:
    """What each autopilot or camera message does.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _on_mavlink(self, m: Any, steer: bool = True) -> None:
        link = self.link
        if link.sysid is None or m.get_srcSystem() != link.sysid:
            return
        t = m.get_type()
        comp = m.get_srcComponent()
        if comp == CAMERA_COMPID:
            if t == "CAMERA_TRACKING_GEO_STATUS":
                self._on_detection(m)
            return
        if not link.is_autopilot(m):
            return
        self._supervise_message(m, t)
        if t == "HEARTBEAT":
            self._on_heartbeat(m)
        elif t == "SYSTEM_TIME":
            self.clock.on_system_time(int(m.time_unix_usec), int(m.time_boot_ms))
        elif t == "GLOBAL_POSITION_INT":
            self._on_position(m, steer)
        elif t == "ATTITUDE":
            self.estimator.on_attitude(int(m.time_boot_ms), float(m.yaw))
            if self.px4:
                self.offboard.data.on_attitude(float(m.roll), float(m.pitch), float(m.yaw))
        elif t == "VFR_HUD":
            self.estimator.on_airspeed(float(m.airspeed))
            if self.px4:
                self.offboard.data.on_vfr_hud(float(m.airspeed), float(m.throttle))
        elif t == "WIND" and self.now_s is not None:
            self.estimator.on_autopilot_wind(self.now_s, float(m.speed), float(m.direction))
        elif t == "WIND_COV" and self.now_s is not None:
            self.estimator.on_autopilot_wind_vector(self.now_s, float(m.wind_x), float(m.wind_y))
        elif t == "SYS_STATUS" and self.now_s is not None:
            self.battery.on_sys_status(
                self.now_s, m.voltage_battery, m.current_battery, m.battery_remaining
            )
        elif t == "BATTERY_STATUS" and self.now_s is not None:
            self.battery.on_battery_status(
                self.now_s, m.id, m.voltages, m.current_battery, m.current_consumed,
                m.battery_remaining,
            )  # fmt: skip
        elif t == "COMMAND_ACK":
            if m.result not in (0, 5):  # not ACCEPTED / IN_PROGRESS
                self._log("command_refused", command=int(m.command), result=int(m.result))
            if self.px4 and int(m.command) == 176 and self.now_s is not None:
                self._entry_steps(self.entry.answer(self.now_s, int(m.result)))

    def _on_heartbeat(self, m: Any) -> None:
        if self.agent is None:
            self._start_agent()
        armed = bool(m.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if armed != self.armed:
            if self.armed is not None:
                self._log("armed" if armed else "disarmed")
            self.armed = armed
        self.authority.own_modes = self.ground.own_modes()
        self._authority(self.authority.heartbeat(int(m.custom_mode), self.link.autopilot))
        if self.ground.heartbeat(int(m.custom_mode), armed) and self.authority.commanding:
            self.targets.take_over(self.now_s)  # climbed and GUIDED: the mission's targets
            if self.agent is not None:
                self.agent.climbed_out()
        if self.px4:
            self._entry_steps(self.entry.heartbeat(px4.is_offboard(int(m.custom_mode))))

    def _start_agent(self) -> None:
        sysid = int(self.link.sysid)
        cfg = self.config
        self.agent = Agent(
            sysid,
            self.mission,
            AgentConfig(
                policy=cfg.policy,
                on_confirm=cfg.on_confirm,
                member_timeout_s=cfg.member_timeout_s,
                max_prosecutors=cfg.max_prosecutors,
                lead_s=cfg.lead_s,
                hold_s=2.0 * cfg.lead_s,  # the setpoint period: a path's turns are averaged over it
            ),
        )
        if not self.targets.free or (self.px4 and self.profile == "path"):
            self.agent.fix_airspeed()  # PX4's path: TECS flies its own trim airspeed
        self._cpu0, self._wall0 = self.cpu(), self.wall()
        self.group = self.group_factory(sysid)
        if self.budget is not None:
            self._flood_gate = FloodGate(self.budget.schedule(1).rate_hz)
            self.group.limit_floods(self._flood_gate)
        if self._sel is not None:
            self._sel.register(self.group.fileno(), selectors.EVENT_READ, "group")
        self._log("link_up", autopilot_sysid=sysid)

    def _on_detection(self, m: Any) -> None:
        if not m.tracking_status & TRACKING_ACTIVE or self.agent is None or self.now_s is None:
            return
        if not self.authority.commanding:
            return
        site = self.estimator.site_from_geodetic(int(m.lat), int(m.lon))
        self.counters.detections += 1
        self.agent.detect(site, self.now_s)

    def _on_position(self, m: Any, steer: bool = True) -> None:
        t = self.clock.to_vehicle_s(int(m.time_boot_ms))
        if t is None:
            return
        est = self.estimator.from_global_position(
            t, int(m.time_boot_ms), m.lat, m.lon, m.alt, m.vx, m.vy, m.hdg
        )
        if est is None:
            return
        if self.px4:
            self.offboard.data.on_position(int(m.alt), int(m.vz))
        self.now_s = t
        self.last_est = est
        self.counters.estimates += 1
        if self._status_vt0 is None:
            self._status_vt0 = t
        if self.agent is not None and self.authority.commanding:
            if steer:
                self._step(est)
            else:
                self.counters.skipped += 1
                self.shaper.reset_sample()
        elif self._prestream and steer:
            self._prestream_step(est)
