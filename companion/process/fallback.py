"""What the aircraft flies if its companion falls silent, kept sensible while the companion
commands (:mod:`companion.link.fallback`): ArduPlane's GUIDED target kept on the loop ahead
(DO_REPOSITION every few seconds), PX4's offboard-loss action set at take-over (PARAM_SET
until read back; logged, a refusal told to the pilot). One component of the
:class:`~companion.process.runner.Runner`."""

from __future__ import annotations

from typing import Any

from companion.agent.agent import Agent
from companion.link.estimate import StateEstimate
from companion.link.fallback import (
    PX4_LOITER_FACTOR,
    GuidedFallback,
    ParamsAtTakeOver,
    loiter_radius_m,
    px4_loss_params,
)
from companion.link.outbox import MAV_SEVERITY_WARNING, Statustext
from companion.mission import Mission
from companion.process.config import Counters
from companion.process.events import TakeOverParams
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effect, Effects
from companion.process.setpoint import SetpointChannel
from companion.process.telemetry import Telemetry


class Fallback:
    """The fallback of a silent companion's aircraft.

    Args:
        mission: the mission (origin, airspeed, turn-rate limit: the loiter radius).
        link: what is read of the link (sysid).
        telemetry: the aircraft's state (vehicle time, for the events' stamps).
        channel: the setpoint channel (PX4 or not; the vehicle's mission altitude).
        counters: the process's counts (``fallbacks``).

    Attributes:
        guided: ArduPlane's GUIDED target on the loop ahead.
        loss_params: PX4's offboard-loss parameters.
    """

    def __init__(
        self,
        mission: Mission,
        link: LinkState,
        telemetry: Telemetry,
        channel: SetpointChannel,
        counters: Counters,
    ) -> None:
        """Nothing sent yet."""
        v = mission.vehicles
        self.radius_m = loiter_radius_m(v.airspeed_m_s, v.max_turn_rate_rad_s)
        self.origin_alt_m = mission.origin.alt_m
        self.link = link
        self.telemetry = telemetry
        self.channel = channel
        self.counters = counters
        self.guided = GuidedFallback(mission.origin, self.radius_m)
        px4_radius_m = loiter_radius_m(v.airspeed_m_s, v.max_turn_rate_rad_s, PX4_LOITER_FACTOR)
        self.loss_params = ParamsAtTakeOver(px4_loss_params(px4_radius_m))
        self._said = False

    def before_setpoint(self, est: StateEstimate, agent: Agent, guided: bool) -> Effects:
        """Before a setpoint from ``est``: ArduPilot in GUIDED (``guided``), the GUIDED target
        on ``agent``'s loop ahead when due; PX4, its offboard-loss parameters until read
        back."""
        sysid = self.link.sysid
        if sysid is None:
            return NOTHING
        if self.channel.px4:
            return self.params(est.t_s)
        if not guided:
            return NOTHING
        alt_amsl_m = self.origin_alt_m + self.channel.mission_alt_m()
        msg = self.guided.refresh_if_due(est.t_s, agent.patrol, est.pos_m, alt_amsl_m, sysid)
        if msg is None:
            return NOTHING
        self.counters.fallbacks += 1
        return (msg,)

    def params(self, t_s: float) -> Effects:
        """PX4: PARAM_SETs of the offboard-loss action not yet read back at ``t_s`` (vehicle
        s; paced), also while OFFBOARD is being entered."""
        sysid = self.link.sysid
        if sysid is None or not self.channel.px4 or self.loss_params.done:
            return NOTHING
        return self.loss_params.due(t_s, sysid)

    def on_param_value(self, m: Any) -> Effects:
        """PARAM_VALUE: PX4's offboard-loss parameters read back; once all are (or some were
        never accepted) it is logged, a refusal told to the pilot."""
        if not self.channel.px4:
            return NOTHING
        name = m.param_id if isinstance(m.param_id, str) else m.param_id.decode()
        lp = self.loss_params
        lp.on_param_value(name, float(m.param_value), int(m.param_type))
        if self._said or not lp.done:
            return NOTHING
        self._said = True
        params = " ".join(f"{k}={v:g}" for k, v in lp.confirmed.items())
        out: list[Effect] = [
            TakeOverParams(
                t_s=self.telemetry.now_s,
                sysid=self.link.sysid,
                params=params,
                refused=" ".join(lp.refused),
            )
        ]
        if lp.refused:
            text = f"companion {self.link.sysid}: not set: {' '.join(lp.refused)}"
            out.append(Statustext(text, MAV_SEVERITY_WARNING))
        return out

    def on_command_ack(self, m: Any) -> Effects:
        """COMMAND_ACK: DO_REPOSITION unknown to the autopilot is not sent again."""
        self.guided.on_ack(int(m.command), int(m.result))
        return NOTHING

    def forget(self) -> None:
        """Command gained again: a GUIDED target at once with the first setpoint."""
        self.guided.forget()
