"""The fleet's reliefs, the same on every member (pure; docs/energy.md, "Reliefs").

Every member computes :func:`plan` from what the group shares -- each member on station
and the vehicle time it must leave (:mod:`companion.agent.relief.energy`), each spare and
the vehicle time it is ready, and the reliefs already under way -- and from nothing it alone
knows, so every member that hears the same states gets the same plan, as tasking does. The
inputs are sorted before use: the order they were heard in does not matter.

The rule, earliest deadline first:

1. A relief under way (a spare that shares it is flying in for member ``k``) stays booked.
1a. A member lost while on station (silent past the member time-out: its companion died,
   its link is gone for good; ``OnStation.lost``, its leave time the time of its last
   state) needs its relief now: the lost members, by (that time, sysid), each get before
   anyone else the free spare that can be in the slot first, late as it must be (it
   launches now, or when it is ready). A lost member never comes back as a spare.
2. The other members on station, by (leave time, sysid): each gets, of the spares not yet
   booked, the one that can be on station first (``max(ready, now) + transit``; a tie goes
   to the lower sysid), if that one is on time; a member no spare can relieve on time is
   skipped here, so it does not take a spare that would have been on time for the next
   (this books as many reliefs on time as any assignment can: a spare on time for one
   member is on time for every member that must leave later). It launches
   ``transit + take-over + lead_s`` before the member must leave, or as soon as it is
   ready if that is later, or now if both have passed.
3. The members no spare can relieve on time, in the same order: each takes the spare that
   can be on the loop first, late, if rule 2 on the spares then left still books as many
   on time of the members that must leave within ``returns_s`` (the spare given is back by
   then, as the late member's own return; without ``returns_s``, of all). So such a member
   is relieved as early as it can be unless that makes another late that must leave before
   it could be helped (before, a spare ready now went to a member leaving half an hour
   later, and the late member left unrelieved).
4. The members still without a spare get the spares left, in the same order: late, each
   by how much after its leave time its spare is in the slot; a member no spare is left for
   is late by ``inf``.

With ``returns_s`` the plan is the rotation: each member on station is also a spare to
come, ready ``returns_s`` after its leave time (home, landed, turned around), so a member
whose relief is a UAV not yet relieved itself is not announced late. The plan
says so as soon as it is computed, which is before the member's leave time.

A spare booked to launch that still shares it is waiting ``LAUNCH_GRACE_S`` after its
launch time has not launched: the caller (:class:`NoLaunchWatch`) passes it over
(``passed_over``) and the next spare is booked instead.

Times are vehicle seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

LAUNCH_GRACE_S = 5.0  # a spare not launched this long after its launch time is passed over
LEAD_S = 30.0  # a spare is booked to be in the slot this long before the member must leave


@dataclass(frozen=True)
class OnStation:
    """A member on the loop, as shared: ``sysid`` and the vehicle time it must leave (s);
    ``lost``: it fell silent on station, ``leave_t_s`` being the time of its last state (s),
    and its slot is open now (rule 1a)."""

    sysid: int
    leave_t_s: float
    lost: bool = False


@dataclass(frozen=True)
class Standby:
    """A spare, as shared.

    Attributes:
        sysid: its system id.
        ready_t_s: vehicle time from which it can launch (s; in the past: ready now).
        transit_s: its flight from where it waits to the loop's farthest point (s).
    """

    sysid: int
    ready_t_s: float
    transit_s: float


@dataclass(frozen=True)
class Relief:
    """One relief of the plan.

    Attributes:
        member: the member relieved.
        spare: the spare that relieves it, None if no spare is left for it.
        launch_t_s: when the spare launches (s; inf without a spare).
        on_station_t_s: when it is in the slot, take-over included (s; inf without one).
        leave_t_s: when the member must leave (s).
        late_s: how much after ``leave_t_s`` the spare is in the slot (s); 0 on time.
        under_way: the spare has launched (booked by rule 1).
    """

    member: int
    spare: int | None
    launch_t_s: float
    on_station_t_s: float
    leave_t_s: float
    late_s: float
    under_way: bool = False

    @property
    def late(self) -> bool:
        """Whether the member will have to wait past its leave time."""
        return self.late_s > 0.0


@dataclass(frozen=True)
class Plan:
    """The reliefs, in the members' (leave time, sysid) order, and the spares passed over
    for not launching (sysids, ascending)."""

    reliefs: tuple[Relief, ...]
    passed_over: tuple[int, ...] = ()

    def of_spare(self, sysid: int) -> Relief | None:
        """The relief ``sysid`` is booked for, or None."""
        return next((r for r in self.reliefs if r.spare == sysid), None)

    def of_member(self, sysid: int) -> Relief | None:
        """The relief of member ``sysid``, or None."""
        return next((r for r in self.reliefs if r.member == sysid), None)


def plan(
    t_s: float,
    on_station: list[OnStation] | tuple[OnStation, ...],
    standby: list[Standby] | tuple[Standby, ...],
    takeover_s: float,
    under_way: dict[int, int] | None = None,
    passed_over: frozenset[int] = frozenset(),
    lead_s: float = LEAD_S,
    returns_s: float | None = None,
    return_transit_s: float = 0.0,
) -> Plan:
    """The fleet's reliefs at vehicle time ``t_s`` (s) (the module docstring's rule).

    Args:
        t_s: now (vehicle s).
        on_station: the members on the loop and their leave times.
        standby: the spares on the ground or holding (not yet launched).
        takeover_s: from arriving at the loop to holding the slot (s).
        under_way: spare sysid -> the member it is flying in for (launched spares).
        passed_over: spares left out (they did not launch when booked).
        lead_s: a spare is booked to be in the slot this long before the member must leave
            (s), so a launch a control step late is not a late relief.
        returns_s: the rotation: a member that leaves is a spare again this long after its
            leave time (s: the flight home and the turnaround), ``return_transit_s`` (s)
            from the loop; None: the plan counts only the spares there are now.

    Raises:
        ValueError: a sysid given twice (as two members, two spares, or both).
    """
    under_way = dict(under_way or {})
    ids = [m.sysid for m in on_station] + [s.sysid for s in standby] + list(under_way)
    if len(ids) != len(set(ids)):
        raise ValueError(f"a sysid is given twice: {sorted(ids)}")
    members = sorted(on_station, key=lambda m: (m.leave_t_s, m.sysid))
    by_member = {m: s for s, m in under_way.items()}
    free = sorted((s for s in standby if s.sysid not in passed_over), key=lambda s: s.sysid)
    if returns_s is not None:  # every member on station comes back as a spare after it left
        free += [
            Standby(m.sysid, m.leave_t_s + returns_s, return_transit_s)
            for m in members
            if not m.lost  # a lost member does not come back
        ]
    booked: dict[int, Relief] = {}
    for m in members:  # rule 1
        s_id = by_member.get(m.sysid)
        if s_id is not None:
            booked[m.sysid] = Relief(m.sysid, s_id, -math.inf, -math.inf, m.leave_t_s, 0.0, True)
    for m in members:  # rule 1a: a lost member's slot is open now
        if m.lost and m.sysid not in booked:
            mine = [s for s in free if s.sysid != m.sysid]
            if mine:
                spare = min(mine, key=lambda s: (max(s.ready_t_s, t_s) + s.transit_s, s.sysid))
                free.remove(spare)
                booked[m.sysid] = _relief(t_s, m, spare, takeover_s, lead_s)
    on_time = _on_time(t_s, members, free, booked, takeover_s, lead_s)  # rule 2
    horizon_s = t_s + (returns_s if returns_s is not None else math.inf)
    free, on_time = _late_first(t_s, members, free, booked, on_time, horizon_s, takeover_s,
                                lead_s)  # fmt: skip
    for r in on_time.values():
        free = [s for s in free if s.sysid != r.spare]
        booked[r.member] = r
    for m in members:  # rule 4: the members still without a spare get what is left
        if m.sysid in booked:
            continue
        spare = _first(t_s, [s for s in free if s.sysid != m.sysid])
        if spare is not None:
            free.remove(spare)
            booked[m.sysid] = _relief(t_s, m, spare, takeover_s, lead_s)
    reliefs = [
        booked.get(m.sysid) or Relief(m.sysid, None, math.inf, math.inf, m.leave_t_s, math.inf)
        for m in members
    ]
    return Plan(tuple(reliefs), tuple(sorted(passed_over)))


def _late_first(
    t_s: float,
    members: list[OnStation],
    free: list[Standby],
    booked: dict[int, Relief],
    on_time: dict[int, Relief],
    horizon_s: float,
    takeover_s: float,
    lead_s: float,
) -> tuple[list[Standby], dict[int, Relief]]:
    """Rule 3: a member no spare can relieve on time (by (leave time, sysid)) takes the
    first spare, booked into ``booked``, if that loses no on-time relief of a member leaving
    by ``horizon_s`` (s); returns the spares still free and the on-time reliefs of rule 2
    on them."""
    for m in members:
        if m.sysid in booked or m.sysid in on_time:
            continue
        spare = _first(t_s, [s for s in free if s.sysid != m.sysid])
        if spare is None or not _relief(t_s, m, spare, takeover_s, lead_s).late:
            continue  # only a member no spare can relieve on time
        rest = [s for s in free if s is not spare]
        trial = _on_time(t_s, members, rest, {**booked, m.sysid: None}, takeover_s, lead_s)
        if _soon(trial, horizon_s) == _soon(on_time, horizon_s):
            free = rest
            booked[m.sysid] = _relief(t_s, m, spare, takeover_s, lead_s)
            on_time = trial
    return free, on_time


def _first(t_s: float, spares: list[Standby]) -> Standby | None:
    """The spare that can be on the loop first (``max(ready, now) + transit``; a tie goes to
    the lower sysid), or None."""
    return min(spares, key=lambda s: (max(s.ready_t_s, t_s) + s.transit_s, s.sysid), default=None)


def _soon(on_time: dict[int, Relief], horizon_s: float) -> int:
    """How many of the on-time reliefs ``on_time`` are of members leaving by ``horizon_s``."""
    return sum(1 for r in on_time.values() if r.leave_t_s <= horizon_s)


def _on_time(
    t_s: float,
    members: list[OnStation],
    free: list[Standby],
    booked: dict,
    takeover_s: float,
    lead_s: float,
) -> dict[int, Relief]:
    """Rule 2 on ``free``: the members not in ``booked``, by (leave time, sysid), each the
    spare that can be on the loop first if that one is on time (member sysid -> relief)."""
    left, out = list(free), {}
    for m in members:
        if m.sysid in booked:
            continue
        spare = _first(t_s, [s for s in left if s.sysid != m.sysid])  # not its own return
        if spare is None:
            continue
        r = _relief(t_s, m, spare, takeover_s, lead_s)
        if not r.late:
            left.remove(spare)
            out[m.sysid] = r
    return out


class NoLaunchWatch:
    """Spares that did not launch when booked: a spare still waiting ``grace_s`` (s) after
    its booked launch fell due is passed over from then on (until it no longer shares that
    it waits). Fed each plan with :meth:`see`; :attr:`passed_over` goes back into
    :func:`plan`."""

    def __init__(self, grace_s: float = LAUNCH_GRACE_S) -> None:
        """Nobody passed over yet."""
        self.grace_s = grace_s
        self.passed_over: frozenset[int] = frozenset()
        self._due_since: dict[int, float] = {}  # spare -> when its launch first fell due

    def see(self, t_s: float, plan_now: Plan, waiting: set[int]) -> tuple[int, ...]:
        """Check ``plan_now`` at ``t_s`` (s) against the spares that share they are still
        ``waiting``; returns the spares passed over by this call (ascending)."""
        due = {
            r.spare
            for r in plan_now.reliefs
            if r.spare is not None and not r.under_way and r.launch_t_s <= t_s
        }
        self._due_since = {s: self._due_since.get(s, t_s) for s in due if s in waiting}
        new = sorted(s for s, t0 in self._due_since.items() if t_s - t0 > self.grace_s)
        self.passed_over = (self.passed_over & waiting) | frozenset(new)
        for s in new:
            del self._due_since[s]
        return tuple(new)


def _relief(t_s: float, m: OnStation, spare: Standby, takeover_s: float, lead_s: float) -> Relief:
    """Member ``m``'s relief by ``spare``: launch, in the slot, lateness (s)."""
    want = m.leave_t_s - lead_s - takeover_s - spare.transit_s
    launch = max(want, spare.ready_t_s, t_s)
    on_station_t = launch + spare.transit_s + takeover_s
    late = max(0.0, on_station_t - m.leave_t_s)
    return Relief(m.sysid, spare.sysid, launch, on_station_t, m.leave_t_s, late)
