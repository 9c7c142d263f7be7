"""One control step (10 Hz, on each new position): the group's news, the checks,
``Agent.update``, then the state to the group before the setpoint to the autopilot; the
step's events and ground-station values. The step sends nothing: it returns what to send
(:class:`Stepped`), and the Runner sends it (one component of the
:class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from companion.agent.agent import Agent
from companion.agent.fix import Fix
from companion.agent.output import AgentOutput
from companion.group.messages import Mode
from companion.link.estimate import StateEstimate
from companion.link.gcs import GcsReport
from companion.link.ground import GROUND_PHASES
from companion.link.outbox import CommandLong, Statustext
from companion.process.config import Counters
from companion.process.control import TakingControl
from companion.process.events import VehicleCommand
from companion.process.group_io import GroupIO
from companion.process.health import Health
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effect, Effects
from companion.process.setpoint import SetpointChannel
from companion.process.telemetry import Telemetry

TRACKING_ACTIVE = 1  # CAMERA_TRACKING_STATUS_FLAGS_ACTIVE


@dataclass(frozen=True)
class Stepped:
    """What a new position asks to send, in order.

    Attributes:
        effects: up to and with the setpoint (the checks' reports, vehicle commands, the
            state and alerts to the group, the setpoint last).
        after: what follows the setpoint (the Agent's events, ground-station texts and
            values).
        setpoint: a setpoint is among ``effects`` (last): its latency is measured once it
            is sent.
    """

    effects: Effects = NOTHING
    after: Effects = NOTHING
    setpoint: bool = False


NOT_STEPPED = Stepped()


class ControlStep:
    """The control step and the Agent it steps.

    Args:
        link: what is read of the link (the sysid).
        telemetry: the aircraft's state (estimator, battery, vehicle time).
        channel: the setpoint channel (shaper, profile, the setpoint in force).
        health: the checks (run before each setpoint).
        control: command authority, the targets and the reliefs' ground sequence.
        group_io: the group (news in before deciding, state out after).
        counters: the process's counts.
        wall: monotonic wall clock (s), for the setpoint's keep-alive.

    Attributes:
        agent: the Agent (None until the first heartbeat starts it).
        agent_mode: the Agent's mode after the last step.
    """

    def __init__(
        self,
        link: LinkState,
        telemetry: Telemetry,
        channel: SetpointChannel,
        health: Health,
        control: TakingControl,
        group_io: GroupIO,
        counters: Counters,
        wall: Callable[[], float],
    ) -> None:
        """No Agent yet."""
        self.link = link
        self.telemetry = telemetry
        self.channel = channel
        self.health = health
        self.control = control
        self.group_io = group_io
        self.counters = counters
        self.wall = wall
        self.agent: Agent | None = None
        self.agent_mode = Mode.PATROL
        self.gcs = GcsReport()  # STATUSTEXT / NAMED_VALUE_* for ground stations

    @property
    def sysid(self) -> int:
        """The autopilot's sysid: known once the Agent is (its first heartbeat started it)."""
        sysid = self.link.sysid
        if sysid is None:
            raise RuntimeError("a control step before the autopilot's first heartbeat")
        return sysid

    def on_detection(self, m: Any) -> Effects:
        """CAMERA_TRACKING_GEO_STATUS from the camera: a detection for the Agent (while
        commanding)."""
        agent, now_s = self.agent, self.telemetry.now_s
        if not m.tracking_status & TRACKING_ACTIVE or agent is None or now_s is None:
            return NOTHING
        if not self.control.authority.commanding:
            return NOTHING
        site = self.telemetry.estimator.site_from_geodetic(int(m.lat), int(m.lon))
        self.counters.detections += 1
        agent.detect(site, now_s)
        return NOTHING

    def on_position(self, m: Any, est: StateEstimate, steer: bool) -> Stepped:
        """A new estimate ``est`` from GLOBAL_POSITION_INT ``m``: a control step while
        commanding (``steer``: the newest position of its batch; an older one is skipped),
        PX4's pre-stream while taking control; taken away by the autopilot (a pilot, a
        failsafe), the state shared as out of the formation."""
        self.channel.on_position(m)
        self.control.position(self.wall(), est.t_s)
        agent = self.agent
        if agent is not None and self.control.authority.commanding:
            if steer:
                return self.step(agent, est)
            self.counters.skipped += 1
            self.channel.shaper.reset_sample()
            return NOT_STEPPED
        out: list[Effect] = []
        if agent is not None and steer and self.control.away:
            out += self.group_io.share_away(est, agent)
        if self.control.prestreaming and steer:
            out += self.control.prestream(est)
        return Stepped(out) if out else NOT_STEPPED

    def step(self, agent: Agent, est: StateEstimate) -> Stepped:
        """One control step of ``agent`` from estimate ``est``: what to send, in order."""
        tm, ch = self.telemetry, self.channel
        self.group_io.receive(agent)  # everything the others sent until now, before deciding
        out: list[Effect] = [*self.control.repeat_targets(est), *self.health.supervise(est)]
        ch.shaper.observe(est.t_s, est.turn_rate_rad_s)
        agent.observe_wind(tm.estimator.wind_estimator.estimate(est.t_s), est.t_s)
        b = tm.battery.last
        if b is not None:
            agent.observe_battery(b.t_s, b.remaining_pct, b.consumed_mah, b.current_a)
        decided = agent.update(Fix(est.t_s, est.pos_m, est.heading_rad, agent.patrol))
        if agent.patrol.wind != tm.estimator.wind:  # the fleet switched to another wind
            tm.estimator.set_wind(agent.patrol.wind)
        out += self._vehicle_commands(decided, est)
        if decided.hold or self.control.ground.in_progress:  # on the ground, or in its own
            out += self.control.hold(est, self.wall())  # take-off: none (PX4 parked: level)
            out += self.group_io.share(decided, est, agent)
            return Stepped(out, self._after(decided, est, agent))
        out += self.control.command_speed(decided.airspeed_m_s, est.t_s)
        msg = ch.setpoint(est, decided.turn_rate_rad_s, self.sysid)
        out += self.group_io.share(decided, est, agent)
        out.append(msg)
        ch.in_force(msg, self.wall())
        self.control.setpoint_sent(est.t_s)
        self.counters.setpoints += 1
        return Stepped(out, self._after(decided, est, agent), setpoint=True)

    def _vehicle_commands(self, decided: AgentOutput, est: StateEstimate) -> Effects:
        """The reliefs' take-off and landing (companion/agent/relief): ArduPlane's sequence
        (companion/link/ground.py) or PX4's (companion/link/px4_ground.py), then its next
        asks."""
        out: list[Effect] = []
        ground = self.control.ground
        if decided.command is not None:
            now_s = self.telemetry.now_s
            out.append(VehicleCommand(t_s=now_s, sysid=self.link.sysid, command=decided.command))
            takeoff = decided.command == "takeoff"
            cmds = ground.takeoff(est.t_s) if takeoff else ground.land()
            out += [CommandLong.of(*cmd) for cmd in cmds]
        if ground.phase in GROUND_PHASES:  # armed in TAKEOFF, GUIDED once it flies there;
            flying = self.health.not_flying_reason() is None  # GUIDED again once landed
            out += [CommandLong.of(*cmd) for cmd in ground.step(est.t_s, flying)]
        return out

    def _after(self, decided: AgentOutput, est: StateEstimate, agent: Agent) -> Effects:
        """The step's events, the ground stations' texts and values (the reliefs' too:
        ``relief_late`` before it is late, link/gcs.py), a STATUSTEXT on a new mode."""
        out: list[Effect] = list(decided.typed_events)
        out += self.gcs.messages(
            est.t_s, est.time_boot_ms, agent, decided, est.pos_m, est.course_rad
        )
        if decided.mode != self.agent_mode:
            self.agent_mode = decided.mode
            out.append(Statustext(f"companion {self.link.sysid}: {decided.mode}"))
        return out
