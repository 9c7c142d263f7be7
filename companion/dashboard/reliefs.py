"""The reliefs' part of the live page (pure: no I/O, no clock; docs/energy.md, "Reliefs").

A mission with a battery and spares has reliefs. :class:`ReliefView` holds what the page
shows of them, from the members' shared states (their :class:`~companion.group.messages.Energy`)
alone:

* each member's battery (%), relief role and time to leave (on station) or to ready (a
  spare), and its relief in the plan;
* the spares and their state, and the reliefs under way;
* the fleet's plan, computed here exactly as the members compute it
  (:mod:`companion.agent.relief.roster`, :mod:`companion.agent.relief.schedule`) from the same
  shared states: who relieves whom, when it launches, when it holds the slot;
* the reliefs that will be late: one standing warning per member whose relief is predicted
  late, updated in place as the prediction changes (:attr:`ReliefView.warnings`), logged
  ``relief_late`` once when it is first raised (before it is late) until that member leaves
  the station;
* a state under a sysid the mission does not list: shown as refused and never planned
  with; counted and logged when that sysid is first refused (and again only after a
  picture in which it was not);
* the events of a member's role change (:data:`RELIEF_EVENTS`).

Times are vehicle seconds (the members' clocks), passed in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from companion.agent.relief.roster import Roster, plan_from
from companion.agent.relief.schedule import NoLaunchWatch, Plan, Relief
from companion.core.patrol import Patrol
from companion.group.messages import Energy
from companion.mission import Mission

__all__ = ["RELIEF_EVENTS", "SPARE_STATIONS", "ReliefView", "finite"]

SPARE_STATIONS = {  # a member out of the formation for the reliefs, by its relief role
    "spare": "spare",  # waiting on the ground or holding
    "unavailable": "spare",  # a spare that could not take off (still on its base)
    "relieving": "climbing_out",  # launched, flying in to a member's slot
    "home": "going_home",  # relieved, flying home to land
    "on_station": "spare",  # not yet flying its slot (a state between two roles)
}
RELIEF_EVENTS = {  # (old role, new role) -> (event kind, text after "UAV <sysid> ")
    ("spare", "relieving"): ("relief_launched", "launched to relieve UAV {m}"),
    ("relieving", "on_station"): ("relief_in_slot", "in UAV {m}'s slot: on station"),
    ("relieving", "spare"): ("relief_stood_down", "stood down: another spare relieves UAV {m}"),
    ("relieving", "home"): ("relief_stood_down", "turned back: another spare relieves UAV {m}"),
    ("relieving", "unavailable"): ("relief_no_takeoff", "did not take off: unavailable"),
    ("on_station", "home"): ("relieved", "left the loop for home"),
    ("home", "spare"): ("relief_landed", "landed: a spare again"),
}

Heard = Sequence[tuple[int, Energy, complex | None]]
"""The members heard now, each ``(sysid, its energy, its reported position or None)``."""
EventLog = Callable[..., None]
"""How an event is logged: ``log(kind, text, **fields)``."""


class ReliefView:
    """The reliefs' picture for the live page (see the module doc).

    Args:
        mission: the mission, or None; reliefs are on when it has a battery and spares.
        log: how the page logs an event, ``log(kind, text, **fields)``.

    Attributes:
        warnings: member sysid -> its standing "relief late" warning (JSON-ready).
        refused: sysid -> why its relief state is never planned with (not in the mission),
            for the members refused now.
        refused_count: relief states refused, counted once per sysid while it stays refused.
    """

    def __init__(self, mission: Mission | None, log: EventLog) -> None:
        """No reliefs planned yet."""
        self._roster: Roster | None = None  # None: no reliefs in this mission
        if mission is not None and mission.vehicles.battery is not None and mission.vehicles.spares:
            self._roster = Roster(mission)
        self._watch = NoLaunchWatch()
        self._log = log
        self._late_said: set[int] = set()  # members whose late relief was logged this stint
        self.warnings: dict[int, dict[str, Any]] = {}
        self.refused: dict[int, str] = {}
        self.refused_count = 0

    @property
    def enabled(self) -> bool:
        """Whether the mission has reliefs (a battery and spares)."""
        return self._roster is not None

    def role_change(self, sysid: int, old: Energy | None, new: Energy | None) -> None:
        """Log the event of member ``sysid``'s relief role going from ``old`` to ``new``
        (:data:`RELIEF_EVENTS`; nothing for a change not listed there)."""
        if old is None or new is None or old.role == new.role:
            return
        got = RELIEF_EVENTS.get((old.role, new.role))
        if got is None:
            return
        member = new.relief_sysid or old.relief_sysid
        kind, text = got
        self._log(kind, f"UAV {sysid} " + text.format(m=member), sysid=sysid,
                  member_sysid=member)  # fmt: skip

    def picture(
        self, t_s: float | None, heard: Heard, patrol: Patrol | None
    ) -> tuple[dict[str, Any], Plan | None]:
        """The reliefs' picture at vehicle time ``t_s`` (s; None: nothing heard yet) from the
        members ``heard`` now, and the plan (None: reliefs off or nothing to plan on).
        Refuses (and logs once) a state whose sysid the mission does not list and updates
        the late warnings."""
        out: dict[str, Any] = {"enabled": self.enabled, "plan": [], "spares": [],
                               "under_way": [], "refused": [],
                               "refused_count": self.refused_count}  # fmt: skip
        if self._roster is None or patrol is None or t_s is None:
            return out, None
        got = self._roster.inputs(t_s, heard, patrol)
        refused = {r.sysid: r for r in got.refused}
        for s, why in refused.items():
            if s not in self.refused:
                self.refused_count += 1
                self._log("relief_refused", f"UAV {s} refused as {why.role}: not in the "
                          "mission", sysid=s, reason=why.reason)  # fmt: skip
        self.refused = {s: r.reason for s, r in refused.items()}
        p, _ = plan_from(t_s, got, patrol, self._watch)
        out["plan"] = [relief_json(r, t_s) for r in p.reliefs]
        self._warn_late(p, t_s, {s for s, e, _ in heard if e.role == "on_station"})
        for s, e, _ in heard:
            if s in refused:
                out["refused"].append({"sysid": s, "role": e.role, "reason": refused[s].reason})
            elif e.role in ("spare", "unavailable", "home", "relieving"):
                out["spares"].append(energy_json(s, e, t_s) | {"booked_for": _booked(p, s)})
            if s not in refused and e.role == "relieving" and e.relief_sysid:
                out["under_way"].append({"spare_sysid": s, "member_sysid": e.relief_sysid})
        out["refused_count"] = self.refused_count
        return out, p

    def of_vehicle(self, sysid: int, e: Energy, t_s: float, p: Plan | None) -> dict[str, Any]:
        """A member's battery and relief as its vehicle's entry shows them, at vehicle time
        ``t_s`` (s), with its relief in the plan ``p`` when it is on station."""
        out = energy_json(sysid, e, t_s) | {"refused": self.refused.get(sysid)}
        mine = p.of_member(sysid) if p is not None and e.role == "on_station" else None
        out["relief"] = None if mine is None else relief_json(mine, t_s)
        return out

    def _warn_late(self, p: Plan, t_s: float, on_station: set[int]) -> None:
        """One standing warning per member whose relief the plan ``p`` predicts late, updated
        in place at vehicle time ``t_s`` (s); logged once when first raised while the member
        is in ``on_station`` (the members that share that role now)."""
        late = {r.member: r for r in p.reliefs if r.late and not r.under_way}
        for m in [m for m in self.warnings if m not in late]:
            del self.warnings[m]
        self._late_said &= on_station  # a member that left the station may warn again
        for m, r in late.items():
            how = "no spare" if r.spare is None else f"{r.late_s:.0f} s late by UAV {r.spare}"
            text = f"UAV {m}: relief {how}"
            w = self.warnings.get(m)
            if w is None:
                w = self.warnings[m] = {"kind": "relief_late", "member_sysid": m,
                                        "since_t_s": t_s}  # fmt: skip
            w.update(spare_sysid=r.spare, late_s=finite(r.late_s, 1),
                     leave_in_s=round(r.leave_t_s - t_s, 1), t_s=t_s, text=text)  # fmt: skip
            if m not in self._late_said:
                self._late_said.add(m)
                self._log("relief_late", text, sysid=m, spare_sysid=r.spare or 0,
                          late_s=finite(r.late_s, 1))  # fmt: skip


def finite(x: float, digits: int) -> float | None:
    """``x`` rounded to ``digits``, None if it is not finite (JSON has no inf)."""
    return round(x, digits) if math.isfinite(x) else None


def energy_json(sysid: int, e: Energy, t_s: float) -> dict[str, Any]:
    """What a member shares about its battery and the reliefs, with the time left until
    its role's time (on station: until it must leave; a spare: until it is ready) at
    vehicle time ``t_s`` (s)."""
    until = None if e.t_s is None else round(e.t_s - t_s, 1)
    return {
        "sysid": sysid,
        "role": e.role,
        "battery_pct": _pct(e.battery_pct),
        "leave_in_s": until if e.role == "on_station" else None,
        "ready_in_s": max(0.0, until) if e.role == "spare" and until is not None else None,
        "relief_sysid": e.relief_sysid or None,
    }


def relief_json(r: Relief, t_s: float) -> dict[str, Any]:
    """One relief of the plan, times from vehicle time ``t_s`` (s); None: never (no spare)
    or already (under way)."""
    return {
        "member_sysid": r.member,
        "spare_sysid": r.spare,
        "under_way": r.under_way,
        "leave_in_s": round(r.leave_t_s - t_s, 1),
        "launch_in_s": None if r.under_way else finite(r.launch_t_s - t_s, 1),
        "in_slot_in_s": None if r.under_way else finite(r.on_station_t_s - t_s, 1),
        "late": r.late,
        "late_s": finite(r.late_s, 1),
    }


def _pct(pct: float | None) -> float | None:
    """A shared battery charge (%) as shown: None when unknown or out of 0-100 %."""
    if pct is None or not 0.0 <= pct <= 100.0:
        return None
    return round(pct, 1)


def _booked(p: Plan, sysid: int) -> int | None:
    """The member the plan ``p`` books spare ``sysid`` for, or None."""
    r = p.of_spare(sysid)
    return None if r is None else r.member
