"""The companion's traffic on the signed group: its state and alerts out after each step
(paced by the state period, or by the group budget's schedule), the members' states and
alerts in, stamped with the latest vehicle time (one component of the
:class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

from collections.abc import Callable

from companion.agent.agent import Agent
from companion.agent.output import AgentOutput
from companion.group.budget import (
    ENERGY_STATE_DATAGRAM_BYTES,
    STATE_DATAGRAM_BYTES,
    Budget,
    Schedule,
)
from companion.group.flood import FloodGate
from companion.group.messages import Alert, MemberState, Mode
from companion.group.transport import Group
from companion.link.estimate import StateEstimate
from companion.process.config import Counters, RunConfig
from companion.process.events import GroupSchedule
from companion.process.ports import LinkState
from companion.process.sender import Effect, Effects
from companion.process.telemetry import Telemetry


class GroupIO:
    """The group: opened once the sysid is known, what goes out after a step, what comes in.

    Args:
        config: the run configuration (state period, member time-out, group budget).
        group_factory: sysid -> the group endpoint.
        link: what is read of the link (the sysid, for the events' stamps).
        telemetry: the aircraft's state (vehicle time).
        counters: the process's counts (``states_sent``, ``alerts_sent``).

    Attributes:
        group: the group endpoint (None until :meth:`open`).
        group_factory: what :meth:`open` calls (a test may replace it before).
        budget: the group budget (``--group-budget``), or None.
    """

    def __init__(
        self,
        config: RunConfig,
        group_factory: Callable[[int], Group],
        link: LinkState,
        telemetry: Telemetry,
        counters: Counters,
    ) -> None:
        """No group yet; the budget (if any) made from the configuration."""
        self.group_factory = group_factory
        self.link = link
        self.telemetry = telemetry
        self.counters = counters
        self.group: Group | None = None
        self.budget: Budget | None = None
        if config.group_budget_bytes_s is not None:
            v = config.mission.vehicles
            shares_energy = v.battery is not None and bool(v.spares)  # version 3 states
            self.budget = Budget(
                config.group_budget_bytes_s,
                config.agent.member_timeout_s,
                ENERGY_STATE_DATAGRAM_BYTES if shares_energy else STATE_DATAGRAM_BYTES,
            )
        self._state_period_s = config.state_period_s
        self._last_state_sent_s = -1e18
        self._away_since_s: float | None = None  # sharing it is out of the formation since
        self._schedule: Schedule | None = None  # the budget's, for the members last heard
        self._flood_gate: FloodGate | None = None

    def open(self, sysid: int) -> Group:
        """The group endpoint for ``sysid``, its floods limited under a budget."""
        group = self.group = self.group_factory(sysid)
        if self.budget is not None:
            self._flood_gate = FloodGate(self.budget.schedule(1).rate_hz)
            group.limit_floods(self._flood_gate)
        return group

    def receive(self, agent: Agent | None) -> None:
        """Everything the members sent until now to ``agent``, stamped with the latest
        vehicle time (drained even before the Agent or vehicle time exist)."""
        if self.group is None:
            return
        now_s = self.telemetry.now_s
        got = self.group.receive(now_s)
        if agent is None or now_s is None:
            return
        for msg in got:
            if isinstance(msg, MemberState):
                agent.receive_state(msg, now_s)
            elif isinstance(msg, Alert):
                agent.receive_alert(msg, now_s)  # its events come with the next update

    def share(self, out: AgentOutput, est: StateEstimate, agent: Agent) -> Effects:
        """The step's state and alerts to the group.

        The group hears this step's state before the autopilot hears its setpoint: a
        lockstepped simulator (docs/sitl.md, "Lockstep") advances on the last setpoint,
        so every member's state of step k is on the group before any member decides k+1.
        The state goes first: a confirmation must not reach the others before the
        prosecutor's new mode, or they keep it "taken" by the prosecutor (see the report on
        Tasking.assign)."""
        if self.group is None:
            return ()
        effects: list[Effect] = []
        if self.budget is not None:
            effects += self._follow_budget(agent, self.budget)
        c = self.counters
        self._away_since_s = None
        if est.t_s - self._last_state_sent_s >= self._state_period_s - 1e-6 or (out.alerts_out):
            effects.append(out.broadcast)
            self._last_state_sent_s = est.t_s
            c.states_sent += 1
        for alert in out.alerts_out:
            effects.append(alert)
            c.alerts_sent += 1
        return effects

    def share_away(self, est: StateEstimate, agent: Agent) -> Effects:
        """Taken away by the autopilot: the real state shared as ``overridden`` (out of the
        formation: the others splay without it at once, not after the member time-out), the
        first at once, then at the state period."""
        if self.group is None:
            return ()
        first = self._away_since_s is None
        if first:
            self._away_since_s = est.t_s
        if not first and est.t_s - self._last_state_sent_s < self._state_period_s - 1e-6:
            return ()
        centre, phase = agent.patrol.centre_and_phase(est.pos_m, est.heading_rad)
        state = MemberState(
            agent.sysid,
            est.t_s,
            complex(centre),
            float(phase),
            Mode.OVERRIDDEN,
            pos_m=complex(est.pos_m),
            wind_record=agent.wind.latest,
        )
        self._last_state_sent_s = est.t_s
        self.counters.states_sent += 1
        self.counters.out_of_formation += 1
        return (state,)

    def _follow_budget(self, agent: Agent, budget: Budget) -> Effects:
        """The budget's schedule for the members heard now plus this one: the state period,
        the Agent's member time-out and the flood gate's share follow it (event
        ``group_schedule`` when it changes)."""
        members = len(agent.neighbours) + 1
        sched = budget.schedule(members)
        if sched == self._schedule:
            return ()
        self._schedule = sched
        self._state_period_s = sched.period_s
        agent.set_member_timeout(sched.member_timeout_s)
        if self._flood_gate is not None:
            self._flood_gate.share_hz = sched.rate_hz
        return (
            GroupSchedule(
                t_s=self.telemetry.now_s,
                sysid=self.link.sysid,
                members=members,
                rate_hz=round(sched.rate_hz, 4),
                member_timeout_s=round(sched.member_timeout_s, 3),
                budget_bytes_s=budget.bytes_s,
            ),
        )
