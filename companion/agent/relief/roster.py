"""Who takes part in the reliefs, from the mission and the shared states (pure; docs/energy.md).

The plan (:mod:`companion.agent.relief.schedule`) is made from what the members share
(:class:`~companion.group.messages.Energy`). This module turns the states heard into the
plan's inputs, the same way for every member and for the live page, and refuses the states
that must never be booked:

* a state under a system id the mission does not list, as a patrol UAV or as a spare
  (``not_in_mission``): a spare that answers as another sysid (its companion or its
  autopilot set up with the wrong id) or a member claiming to be a spare the mission does
  not have. Its state is left out of the plan entirely (never booked, never planned for);
  the caller counts and logs it.

A patrol UAV's sysid sharing ``spare`` is not refused: a relieved patrol UAV lands, turns
around and is a spare from then on (docs/energy.md, "Reliefs").

Times vehicle s, positions complex m (north + i east), speeds m/s.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from companion.agent.relief.energy import home_time_s
from companion.agent.relief.join import inside
from companion.agent.relief.schedule import (
    LEAD_S,
    NoLaunchWatch,
    OnStation,
    Plan,
    Standby,
    plan,
)
from companion.core.patrol import Patrol
from companion.group.messages import Energy
from companion.mission import Mission
from companion.mission.endurance import opening_note
from companion.mission.model import Battery

LOOP_SAMPLES = 64  # loop points for the farthest-point transits and the flight home
LAND_MARGIN_S = 30.0  # a UAV leaves this much before its battery strictly needs to (s)
TAKEOVER_PERIODS = 2.0  # a take-over is planned to take this many loop periods T ...
CAPTURE_S = 120.0  # ... or, from bases inside a loop longer than their flight, this long (s)
# the rotation's beat leaves this many loop periods more for a current above the mission's,
# and at most this fraction of the usable battery
BEAT_SLACK_PERIODS = 1.0
BEAT_SLACK_FRACTION = 0.05
NOT_IN_MISSION = "not_in_mission"


@dataclass(frozen=True)
class Refusal:
    """A shared state left out of the plan: ``sysid`` as heard, the ``role`` it claimed and
    why (``reason``: :data:`NOT_IN_MISSION`)."""

    sysid: int
    role: str
    reason: str


@dataclass(frozen=True)
class PlanInputs:
    """What :func:`companion.agent.relief.schedule.plan` is given, and what was refused.

    Attributes:
        on_station: the members on the loop and their leave times (vehicle s).
        standby: the spares (waiting, or on their way home to be one again).
        under_way: launched spare sysid -> the member it flies in for (members on station
            only).
        refused: the states left out, in sysid order.
        returns_s: from a member's leave time to its being a spare again (s).
        return_transit_s: from a base to the loop's farthest point at the slowest ground
            speed (s).
        takeover_s: from arriving at the loop to holding the slot, as planned
            (:meth:`Roster.takeover_s`, s).
    """

    on_station: tuple[OnStation, ...]
    standby: tuple[Standby, ...]
    under_way: dict[int, int]
    refused: tuple[Refusal, ...]
    returns_s: float
    return_transit_s: float
    takeover_s: float


class Roster:
    """The mission's side of the reliefs: the fleet's system ids, the bases, the turnaround.

    Args:
        mission: the mission (its ``vehicles.sysids`` and ``vehicles.spares``).
    """

    def __init__(self, mission: Mission) -> None:
        """The fleet of ``mission``: its patrol UAVs and its spares."""
        v = mission.vehicles
        self.patrol_sysids = frozenset(int(s) for s in v.sysids)
        self.spare_sysids = frozenset(int(sp.sysid) for sp in v.spares)
        self.bases: list[complex] = [sp.base_m for sp in v.spares] or [0j]
        self.turnaround_s = max((sp.turnaround_s for sp in v.spares), default=0.0)
        self._home_cache: tuple[Patrol, float] | None = None
        self._back_cache: tuple[Patrol, float] | None = None
        self._takeover_cache: tuple[Patrol, float] | None = None

    def screen(self, sysid: int, energy: Energy) -> Refusal | None:
        """Why the state of ``sysid`` sharing ``energy`` must not be booked, or None."""
        if sysid not in self.patrol_sysids and sysid not in self.spare_sysids:
            return Refusal(int(sysid), str(energy.role), NOT_IN_MISSION)
        return None

    def home_s(self, patrol: Patrol) -> float:
        """The longest flight home from the loop to its nearest base in ``patrol``'s wind
        (s; cached per patrol object)."""
        cached = self._home_cache
        if cached is not None and cached[0] is patrol:
            return cached[1]
        worst = 0.0
        for p in patrol.sample_by_time(LOOP_SAMPLES).tolist():
            base = _nearest(self.bases, p)
            worst = max(worst, home_time_s(p, base, patrol.airspeed_m_s, patrol.wind))
        self._home_cache = (patrol, worst)
        return worst

    def back_s(self, patrol: Patrol) -> float:
        """The longest flight from a base to the loop's farthest point from it at the slowest
        ground speed, ``s0 - |w|`` (s): a spare's transit as the plan books it (cached per
        patrol object: the opening asks for it with the beat at every plan)."""
        cached = self._back_cache
        if cached is not None and cached[0] is patrol:
            return cached[1]
        slow = patrol.airspeed_m_s - abs(patrol.wind.vector)
        back = self._back_s(patrol.sample_by_time(LOOP_SAMPLES), slow)
        self._back_cache = (patrol, back)
        return back

    def takeover_s(self, patrol: Patrol) -> float:
        """How long the plan gives a relief from a spare's transit to its holding the slot
        (s; cached per patrol object). A spare waiting outside the loop meets its slot from
        its lane, on its side of the loop, so it waits for the slot to come round (up to a
        loop period T) and then flies in: ``TAKEOVER_PERIODS`` T. From bases all inside a
        loop whose period is longer than their transit (:meth:`back_s`) a spare meets its
        slot at once, flying straight out to the loop point the slot reaches as it does
        (the slot goes round in T, the spare gets anywhere sooner): ``CAPTURE_S`` for the
        steering law to take it into the slot, or ``TAKEOVER_PERIODS`` T if less. On the
        Wright-Patterson loop (T 25.5 min) two periods are longer than a 50-minute battery."""
        cached = self._takeover_cache
        if cached is not None and cached[0] is patrol:
            return cached[1]
        takeover = TAKEOVER_PERIODS * patrol.period_s
        if patrol.period_s > self.back_s(patrol) and all(inside(b, patrol) for b in self.bases):
            takeover = min(takeover, CAPTURE_S)
        self._takeover_cache = (patrol, takeover)
        return takeover

    def _back_s(self, loop: np.ndarray, slow_m_s: float) -> float:
        return max(float(np.max(np.abs(loop - b))) for b in self.bases) / slow_m_s

    def beat_s(self, patrol: Patrol, battery: Battery) -> float | None:
        """The rotation's beat (s): a UAV that took a member's slot leaves this long after
        that member's planned leave time, unless its battery says sooner; None when the
        battery leaves no beat (< 0).

        Each slot then comes due every beat, whenever its relief arrived, so the members'
        leave times keep the spacing they started with; left to each battery, every relief
        that arrived early (its spare's wait for the slot: 89-262 s) brought that slot's next
        leave time forward, and the leave times bunched (docs/energy.md, "Why"). A spare
        booked for a leave time ``L`` launches no sooner than ``L - lead - take-over -
        transit`` and then has ``usable - home - landing margin`` before its battery says
        go, so with the mission's current (``capacity / endurance``) a beat of ``usable -
        lead - take-over - transit - home - landing margin`` is never later than its
        battery; ``BEAT_SLACK_PERIODS`` more loop periods, at most ``BEAT_SLACK_FRACTION``
        of the usable battery, are kept for a higher current (the ellipse's figures were
        measured with one period, 4.3 % of its 40 usable minutes)."""
        usable = battery.usable_min * 60.0
        slack = min(BEAT_SLACK_PERIODS * patrol.period_s, BEAT_SLACK_FRACTION * usable)
        beat = usable - self.relief_lead_s(patrol) - slack
        beat -= self.home_s(patrol) + LAND_MARGIN_S
        return beat if beat > 0.0 else None

    def spares_needed(self, patrol: Patrol, battery: Battery, on_station: int) -> float | None:
        """How many spares the companions' rotation keeps busy on average (dimensionless),
        or None when ``battery`` leaves no beat: each of the ``on_station`` slots comes due
        once a beat (:meth:`beat_s`), and each relief keeps an airframe off station from its
        booking to its being a spare again: the relief's lead (:meth:`relief_lead_s`), the
        flight home, the landing margin and the turnaround (s). By Little's law that many
        are off station on average, so with fewer spares the rotation falls behind in a long
        run (measured: docs/energy.md, "On bases nobody drew"). The mission loader's bound
        (``companion.mission.endurance``) is the ideal rotation's, below this one."""
        beat = self.beat_s(patrol, battery)
        if beat is None:
            return None
        off = self.relief_lead_s(patrol) + self.home_s(patrol) + LAND_MARGIN_S
        return on_station * (off + self.turnaround_s) / beat

    def relief_lead_s(self, patrol: Patrol) -> float:
        """How long before a leave time a spare is booked, at the latest, to be in the slot
        by then (s): the plan's lead, the take-over (:meth:`takeover_s`) and the transit
        from the farthest base (:meth:`back_s`)."""
        return LEAD_S + self.takeover_s(patrol) + self.back_s(patrol)

    def inputs(
        self,
        t_s: float,
        heard: Iterable[tuple[int, Energy, complex | None]],
        patrol: Patrol,
        lost: Mapping[int, float] | None = None,
    ) -> PlanInputs:
        """The plan's inputs at vehicle time ``t_s`` (s) from the states ``heard``: (sysid,
        what it shares, its position in m or None), in any order; each sysid once.
        ``lost``: the members that fell silent on station, sysid -> the vehicle time of
        their last state (s); each not heard and of the mission is planned for as
        :class:`OnStation` ``lost`` (its slot open now). A member on station whose slot
        another member on station claims (``relief_sysid``: it took the slot) is relieved
        and left out, so no second spare is booked for it in the moment before it leaves."""
        loop = patrol.sample_by_time(LOOP_SAMPLES)
        slow = patrol.airspeed_m_s - abs(patrol.wind.vector)
        returns = self.home_s(patrol) + self.turnaround_s + LAND_MARGIN_S
        back = self._back_s(loop, slow)
        on_station: list[OnStation] = []
        standby: list[Standby] = []
        under_way: dict[int, int] = {}
        refused: list[Refusal] = []
        states = sorted(heard, key=lambda h: h[0])
        heard_ids = {h[0] for h in states}
        claimed = {  # slots taken over: their members are relieved, leaving, not to be booked
            e.relief_sysid
            for sysid, e, _ in states
            if e.role == "on_station" and e.relief_sysid and self.screen(sysid, e) is None
        }
        for sysid, e, pos in states:
            why = self.screen(sysid, e)
            if why is not None:
                refused.append(why)
            elif e.role == "on_station" and sysid in claimed:
                continue  # its relief holds its slot; it leaves as soon as it hears so
            elif e.role == "on_station" and e.t_s is not None:
                on_station.append(OnStation(sysid, e.t_s))
            elif e.role == "spare" and pos is not None:
                far = float(np.max(np.abs(loop - complex(np.complex64(pos)))))
                standby.append(Standby(sysid, e.t_s or 0.0, far / slow))
            elif e.role == "relieving" and e.relief_sysid:
                under_way[sysid] = e.relief_sysid
            elif e.role == "home":  # on its way to be a spare again
                standby.append(Standby(sysid, t_s + returns, back))
        for sysid, last_t_s in sorted((lost or {}).items()):
            ours = sysid in self.patrol_sysids or sysid in self.spare_sysids
            if ours and sysid not in heard_ids:
                on_station.append(OnStation(sysid, last_t_s, lost=True))
        members = {o.sysid for o in on_station}
        under_way = {s: m for s, m in under_way.items() if m in members}
        return PlanInputs(
            tuple(on_station),
            tuple(standby),
            under_way,
            tuple(refused),
            returns,
            back,
            self.takeover_s(patrol),
        )


def _nearest(bases: Sequence[complex], p: complex) -> complex:
    """The base in ``bases`` nearest ``p`` (complex m; the first of equals)."""
    return min(bases, key=lambda b: abs(b - p))


def plan_from(
    t_s: float, got: PlanInputs, patrol: Patrol, watch: NoLaunchWatch
) -> tuple[Plan, dict[int, int]]:
    """The fleet's plan at vehicle time ``t_s`` (s) from the inputs ``got`` (their
    take-over, :meth:`Roster.takeover_s`) on ``patrol``, and the spares ``watch`` passes over:
    planned, shown to the watch, and planned again if the watch passed a spare over then
    (the companions and the live page plan the same way). Returns the plan and the spares
    passed over by this call, each with the member it had been booked for."""

    def planned() -> Plan:
        return plan(
            t_s, got.on_station, got.standby, got.takeover_s, got.under_way, watch.passed_over,
            returns_s=got.returns_s, return_transit_s=got.return_transit_s,
        )  # fmt: skip

    p = planned()
    new = watch.see(t_s, p, {s.sysid for s in got.standby})
    passed = {r.spare: r.member for r in p.reliefs if r.spare is not None and r.spare in new}
    if watch.passed_over != frozenset(p.passed_over):
        p = planned()
    return p, passed


def rotation_note(mission: Mission, duration_s: float) -> str | None:
    """Why a run of ``mission`` for ``duration_s`` (s) can miss reliefs although the loader
    took it, or None: it has a battery and spares, is longer than one battery, and has fewer
    spares than the companions' rotation keeps busy (:meth:`Roster.spares_needed`), or the
    battery leaves no beat on this loop (a relief is booked too far ahead of a leave time)."""
    v = mission.vehicles
    if v.battery is None or not v.spares or duration_s <= v.battery.usable_min * 60.0:
        return None
    roster, patrol = Roster(mission), mission.patrol
    need = roster.spares_needed(patrol, v.battery, v.count)
    if need is None:
        return (
            f"a relief is booked {roster.relief_lead_s(patrol) / 60.0:.1f} min before its "
            f"leave time on this loop (period {patrol.period_s / 60.0:.1f} min) and a "
            f"battery gives {v.battery.usable_min:.1f} min, so the rotation has no beat and "
            'reliefs can come late (docs/energy.md, "Not yet")'
        )
    s, hold = len(v.spares), math.ceil(need - 1e-9)
    if s >= hold:
        return None
    return (
        f"{s} spare{'' if s == 1 else 's'} for {v.count} on station: the companions' rotation "
        f"keeps {need:.2f} busy on average, so it falls behind and misses reliefs in a long "
        f"run; {hold} hold it "
        '(docs/energy.md, "Can the spares keep the patrol up?")'
    )


def run_notes(mission: Mission, duration_s: float, started_full: bool) -> list[str]:
    """What ``companion fleet`` and ``companion simulate`` say before a run of ``mission``
    for ``duration_s`` (s) that will not hold its reliefs as set up (``started_full``: no
    battery given as used): :func:`~companion.mission.endurance.opening_note` and
    :func:`rotation_note`."""
    notes = (opening_note(mission, duration_s, started_full), rotation_note(mission, duration_s))
    return [n for n in notes if n]
