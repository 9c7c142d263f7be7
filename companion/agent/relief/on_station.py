"""A UAV on station in the reliefs (pure; docs/energy.md, "Reliefs"): when it must leave,
who relieved it, and whether its relief will be late. Functions over its
:class:`~companion.agent.relief.records.OnStation` record. Times vehicle s, battery %, mAh,
A."""

from __future__ import annotations

from companion.agent.events import AgentEvent
from companion.agent.neighbours import Neighbours
from companion.agent.relief.energy import Gauge, leave_time_s
from companion.agent.relief.events import ReliefLate
from companion.agent.relief.figures import Figures
from companion.agent.relief.records import OnStation
from companion.agent.relief.roster import LAND_MARGIN_S, Roster
from companion.agent.relief.schedule import Plan
from companion.core.patrol import Patrol
from companion.group.messages import Mode


def update_leave(
    rec: OnStation, fig: Figures, roster: Roster, gauge: Gauge, t_s: float, patrol: Patrol
) -> None:
    """Its leave time at ``t_s`` (s) into ``rec``: its battery (``gauge``; the mission's
    current until one is reported) to the reserve, less the flight home from the loop's
    farthest point and ``LAND_MARGIN_S``; the slot's next turn in the rotation if sooner, or
    a staggered opening's; unchanged while its battery is unknown."""
    b = fig.battery
    if b is None:
        return
    consumed = gauge.consumed_mah
    if consumed is None and gauge.pct is not None:
        consumed = b.capacity_mah * (1.0 - gauge.pct / 100.0)
    if consumed is None:
        return
    current = gauge.drain.current_a
    if current is None:  # the mission's: the capacity in the endurance
        current = b.capacity_mah / (b.endurance_min * 60.0) * 3.6
    home = roster.home_s(patrol)
    t = leave_time_s(t_s, consumed, b.capacity_mah, b.reserve_mah, current, home, LAND_MARGIN_S)
    if rec.beat_t_s is not None:  # the slot's next turn in the rotation, if sooner
        t = min(t, rec.beat_t_s)
    elif rec.opening_steps:  # a first stint of a staggered opening
        t = _opening_leave_s(rec, fig, roster, t_s, t, patrol)
    rec.leave_t_s = round(t, 6)  # as the wire carries it: every member plans on the same


def _opening_leave_s(
    rec: OnStation,
    fig: Figures,
    roster: Roster,
    t_s: float,
    battery_leave_s: float,
    patrol: Patrol,
) -> float:
    """A first stint's leave time in a ``staggered`` opening (vehicle s; docs/energy.md,
    "The opening"): its steps of ``beat / N`` before ``battery_leave_s``, the time its
    battery says, but not before its first plan (at ``t_s``, the first call) plus the
    relief's lead (a spare booked then is in the slot by then) nor after the battery's
    time. Started together and full, the N patrol UAVs then leave one ``beat / N`` apart in
    ``sysids`` order, as the rotation keeps them, instead of all at once."""
    if rec.opening_floor_s is None:
        rec.opening_floor_s = t_s + roster.relief_lead_s(patrol)
    battery = fig.battery
    beat = roster.beat_s(patrol, battery) if battery else None
    if beat is None:
        return battery_leave_s
    early = rec.opening_steps * beat / len(roster.patrol_sysids)
    return min(battery_leave_s, max(battery_leave_s - early, rec.opening_floor_s))


def relieved_by(rec: OnStation, heard: Neighbours, sysid: int) -> int | None:
    """The member that relieved UAV ``sysid``: one it heard flying in for it this stint
    (kept in ``rec.relievers``) that shares, on patrol, that it holds its slot; or None."""
    for s, n in heard.table.items():  # who has flown in for it, this stint
        e = n.state.energy
        if e is not None and e.role == "relieving" and e.relief_sysid == sysid:
            rec.relievers.add(s)
    return next(
        (
            s
            for s, n in sorted(heard.table.items())
            if s in rec.relievers
            and n.state.mode is Mode.PATROL
            and n.state.energy is not None
            and n.state.energy.role == "on_station"
            and n.state.energy.relief_sysid == sysid
        ),
        None,
    )


def say_late(rec: OnStation, plan: Plan | None, sysid: int, t_s: float) -> list[AgentEvent]:
    """UAV ``sysid``'s relief will be late by ``plan``: said at ``t_s`` (s) once per spare
    (``relief_late``; spare 0: no spare at all), the spares said kept in ``rec``."""
    mine = plan.of_member(sysid) if plan is not None else None
    if mine is None or not mine.late or (mine.spare or 0) in rec.late_said:
        return []
    rec.late_said.add(mine.spare or 0)
    late = None if mine.spare is None else round(mine.late_s, 1)
    return [ReliefLate(t_s=t_s, sysid=sysid, spare_sysid=mine.spare or 0,
                       leave_t_s=round(mine.leave_t_s, 1), late_s=late)]  # fmt: skip
