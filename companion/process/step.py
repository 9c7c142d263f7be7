"""One control step (10 Hz, on each new position): the group's news, the checks,
``Agent.update``, then the state to the group before the setpoint to the autopilot; the
step's events and ground-station values; the setpoint kept alive when telemetry stalls."""

from __future__ import annotations

from typing import Any

from companion.agent.fix import Fix
from companion.link.estimate import StateEstimate
from companion.link.ground import GROUND_PHASES

KEEPALIVE_WALL_S = 0.25  # resend the setpoint in force after this much wall time without one:
# ArduPlane drops an attitude override 3 s (vehicle time) after the last message
LATENCY_WINDOW = 20_000
VEHICLE_COMMANDS = {"takeoff": 22, "land": 21}  # PX4: MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_LAND


class ControlStep:
    """One control step and the setpoint it sends.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _step(self, est: StateEstimate) -> None:
        agent = self.agent
        if self.group is not None:
            self._on_group()  # everything the others sent until now, before deciding
        self._supervise_step(est)
        self.shaper.observe(est.t_s, est.turn_rate_rad_s)
        agent.observe_wind(self.estimator.wind_estimator.estimate(est.t_s), est.t_s)
        b = self.battery.last
        if b is not None:
            agent.observe_battery(b.t_s, b.remaining_pct, b.consumed_mah, b.current_a)
        out = agent.update(Fix(est.t_s, est.pos_m, est.heading_rad, agent.patrol))
        if agent.patrol.wind != self.estimator.wind:  # the fleet switched to another wind
            self.estimator.set_wind(agent.patrol.wind)
        if out.command is not None:  # the reliefs: take off, land (companion/agent/relief)
            self._log("vehicle_command", command=out.command)
            if self.px4:
                self.link.command_long(VEHICLE_COMMANDS[out.command])
            else:  # ArduPlane's way (companion/link/ground.py)
                takeoff = out.command == "takeoff"
                for cmd in self.ground.takeoff(est.t_s) if takeoff else self.ground.land():
                    self.link.command_long(*cmd)
        if self.ground.phase in GROUND_PHASES:  # armed in TAKEOFF, GUIDED once it flies
            # there; GUIDED again once landed
            for cmd in self.ground.step(est.t_s, self.not_flying_reason() is None):
                self.link.command_long(*cmd)
        if out.hold or self.ground.in_progress:  # on the ground, or in its own take-off:
            # no setpoint, nothing to keep alive
            self._last_sp_msg = None
            self._share(out, est)
            self._after_step(out, est)
            return
        if not self.px4:
            self.targets.command_speed(out.airspeed_m_s, est.t_s)
        elif out.airspeed_m_s != self.offboard.target_airspeed_m_s:  # held by our own loop
            self.offboard.target_airspeed_m_s = out.airspeed_m_s
            self._airspeed_sent(out.airspeed_m_s)
        msg = self.shaper.setpoint(
            est.t_s,
            out.turn_rate_rad_s,
            est.course_rad,
            est.time_boot_ms,
            self.link.sysid,
            pos_m=est.pos_m,
            heading_rad=est.heading_rad,
            wind_m_s=self.estimator.wind.vector,
        )
        c = self.counters
        self._share(out, est)
        self._send_setpoint(msg)
        c.setpoints += 1
        if self._rx_perf:
            c.latency_s.append(self.perf() - self._rx_perf)
            if len(c.latency_s) > LATENCY_WINDOW:
                del c.latency_s[: LATENCY_WINDOW // 2]
        self._after_step(out, est)

    def _after_step(self, out: Any, est: StateEstimate) -> None:
        """The step's events, the ground stations' texts and values (the reliefs' too:
        ``relief_late`` before it is late, link/gcs.py), a STATUSTEXT on a new mode."""
        for ev in out.typed_events:
            self.events.write(ev.to_record())
        for gcs_msg in self.gcs.messages(est.t_s, est.time_boot_ms, self.agent, out, est.pos_m):
            self.link.send(gcs_msg)
        if out.mode != self.agent_mode:
            self.agent_mode = out.mode
            self.link.statustext(f"companion {self.link.sysid}: {out.mode}")

    def _send_setpoint(self, msg: Any) -> None:
        self.link.send(msg)
        self._last_sp_msg, self._last_sp_wall = msg, self.wall()

    def _keepalive(self) -> None:
        """Resend the setpoint in force when telemetry (and so the control step) stalls:
        ArduPlane forgets an attitude override 3 s after the last one."""
        msg = self._last_sp_msg
        if msg is None or not self.authority.commanding:
            return
        now = self.wall()
        if now - self._last_sp_wall >= KEEPALIVE_WALL_S:
            self.link.send(msg)
            self._last_sp_wall = now
            self.counters.keepalives += 1
