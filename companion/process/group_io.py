"""The companion's traffic on the signed group: its state and alerts out after each step,
the members' states and alerts in, stamped with the latest vehicle time."""

from __future__ import annotations

from typing import Any

from companion.group.messages import Alert, MemberState
from companion.link.estimate import StateEstimate


class GroupIO:
    """The group: what goes out after a step, what comes in.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _share(self, out: Any, est: StateEstimate) -> None:
        """The step's state and alerts to the group.

        The group hears this step's state before the autopilot hears its setpoint: a
        lockstepped simulator (docs/sitl.md, "Lockstep") advances on the last setpoint,
        so every member's state of step k is on the group before any member decides k+1.
        The state goes first: a confirmation must not reach the others before the
        prosecutor's new mode, or they keep it "taken" by the prosecutor (see the report on
        Tasking.assign)."""
        group, c = self.group, self.counters
        if group is None:
            return
        if self.budget is not None:
            self._follow_budget()
        if est.t_s - self._last_state_sent_s >= self._state_period_s - 1e-6 or (out.alerts_out):
            group.send_state(out.broadcast)
            self._last_state_sent_s = est.t_s
            c.states_sent += 1
        for alert in out.alerts_out:
            group.send_alert(alert)
            c.alerts_sent += 1

    def _follow_budget(self) -> None:
        """The budget's schedule for the members heard now plus this one: the state period,
        the Agent's member time-out and the flood gate's share follow it (event
        ``group_schedule`` when it changes)."""
        agent, budget = self.agent, self.budget
        if agent is None or budget is None:
            return
        members = len(agent.neighbours) + 1
        sched = budget.schedule(members)
        if sched == self._schedule:
            return
        self._schedule = sched
        self._state_period_s = sched.period_s
        agent.set_member_timeout(sched.member_timeout_s)
        if self._flood_gate is not None:
            self._flood_gate.share_hz = sched.rate_hz
        self._log(
            "group_schedule",
            members=members,
            rate_hz=round(sched.rate_hz, 4),
            member_timeout_s=round(sched.member_timeout_s, 3),
            budget_bytes_s=budget.bytes_s,
        )

    def _on_group(self) -> None:
        group, agent = self.group, self.agent
        got = group.receive(self.now_s)
        if agent is None or self.now_s is None:
            return
        for msg in got:
            if isinstance(msg, MemberState):
                agent.receive_state(msg, self.now_s)
            elif isinstance(msg, Alert):
                agent.receive_alert(msg, self.now_s)  # its events come with the next update
