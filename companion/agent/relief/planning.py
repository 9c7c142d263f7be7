"""What one UAV's duty keeps of the fleet (pure; docs/energy.md, "Reliefs"): the plan it
makes from the shared states once a second (:class:`Planner`), and the members lost on
station (:class:`LostWatch`). Times vehicle s, positions complex m."""

from __future__ import annotations

import math

from companion.agent.events import AgentEvent
from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.events import ReliefRefused, SpareNoLaunch
from companion.agent.relief.roster import Roster, plan_from
from companion.agent.relief.schedule import NoLaunchWatch, Plan
from companion.group.messages import Energy

PLAN_EVERY_S = 1.0  # the plan is recomputed this often (s)


class Planner:
    """The fleet's reliefs as this UAV plans them (every member plans from the same shared
    states, its own included, so the spares agree on who goes).

    Args:
        sysid: this UAV's system id.
        roster: who may take part (:class:`~companion.agent.relief.roster.Roster`).
    """

    def __init__(self, sysid: int, roster: Roster) -> None:
        """No plan yet."""
        self.sysid = sysid
        self.roster = roster
        self.plan: Plan | None = None
        self.refused: dict[str, int] = {}  # shared states left out of the plan, by reason
        self._t_s = -math.inf  # when it last planned (s)
        self._watch = NoLaunchWatch()
        self._refused_said: set[tuple[int, str]] = set()

    def due(self, t_s: float) -> bool:
        """Whether to plan again at ``t_s`` (s): ``PLAN_EVERY_S`` after the last, or never yet."""
        return t_s - self._t_s >= PLAN_EVERY_S or self.plan is None

    def replan(
        self, fix: Fix, heard: Neighbours, own: Energy | None, lost: dict[int, float]
    ) -> list[AgentEvent]:
        """Plan at ``fix`` from the states ``heard`` and its own ``own`` (shared at
        ``fix.pos_m``), with the members ``lost`` (sysid -> the time of their last state,
        s); returns the events: each refused state said once per sysid and role
        (``relief_refused``), each spare booked for this UAV passed over (``spare_no_launch``)."""
        t_s, events = fix.t_s, []
        states = [(s, n.state.energy, n.state.pos_m) for s, n in heard.table.items()
                  if n.state.energy is not None]  # fmt: skip
        if own is not None:
            states.append((self.sysid, own, fix.pos_m))
        got = self.roster.inputs(t_s, states, fix.patrol, lost)
        for r in got.refused:  # never booked: counted each plan, said once per sysid and role
            self.refused[r.reason] = self.refused.get(r.reason, 0) + 1
            if (r.sysid, r.role) not in self._refused_said:
                self._refused_said.add((r.sysid, r.role))
                events.append(ReliefRefused(t_s=t_s, sysid=self.sysid, member_sysid=r.sysid,
                                            role=r.role, reason=r.reason))  # fmt: skip
        p, passed = plan_from(t_s, got, fix.patrol, self._watch)
        for spare, member in sorted(passed.items()):  # said by the member it was booked for
            if member == self.sysid:
                events.append(SpareNoLaunch(t_s=t_s, sysid=self.sysid, spare_sysid=spare))
        self.plan, self._t_s = p, t_s
        return events


class LostWatch:
    """The members that fell silent on station (see :meth:`track`)."""

    def __init__(self) -> None:
        """Nobody heard, nobody lost."""
        self.lost: dict[int, float] = {}  # fell silent on station: sysid -> its last t_s (s)
        self._last_heard: dict[int, tuple[str | None, float]] = {}  # sysid -> (role, t_s)

    def track(self, heard: Neighbours, own_claim: int | None) -> None:
        """Keep :attr:`lost` from the members heard now against those heard before: a member
        last heard ``on_station`` and gone from ``heard`` is lost (at the vehicle time of its
        last state, the same for every member that heard it); heard again, or claimed by a
        member on station that relieved it (this UAV's own claim: ``own_claim``), it is not."""
        table = heard.table
        for s in [s for s in self._last_heard if s not in table]:
            role, last_t_s = self._last_heard.pop(s)
            if role == "on_station":
                self.lost[s] = last_t_s
        if not self.lost and len(self._last_heard) == len(table):
            for s, n in table.items():  # the usual case: nobody new, nobody lost
                e = n.state.energy
                self._last_heard[s] = (None if e is None else e.role, n.state.t_s)
            return
        claimed = set() if own_claim is None else {own_claim}
        for s, n in table.items():
            e = n.state.energy
            self._last_heard[s] = (None if e is None else e.role, n.state.t_s)
            if e is not None and e.role == "on_station" and e.relief_sysid:
                claimed.add(e.relief_sysid)
        for s in [s for s in self.lost if s in table or s in claimed]:
            del self.lost[s]
