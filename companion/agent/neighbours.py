"""The formation as one companion hears it (pure): the members' last shared states.

A :class:`Neighbours` keeps each member's last :class:`~companion.group.messages.MemberState`
with its local receipt time (vehicle s), drops a member silent for ``member_timeout_s``
(judged by receipt time, so clocks need not agree), and extrapolates a member's phase at the
nominal rate from its last state. One of the seams of :class:`companion.agent.agent.Agent`: who is
there; what the Agent does about a member that joins or leaves is its own business.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_2pi
from companion.group.messages import OUT_OF_FORMATION, MemberState, Mode
from companion.guidance.steering import XTRACK_SAT_M

ON_LOOP_M = XTRACK_SAT_M  # distance (m) over which a member's phase turns from position to course


@dataclass
class Neighbour:
    state: MemberState
    rx_t_s: float


@dataclass(frozen=True)
class RosterChange:
    """What one :meth:`Neighbours.expire` found, each in ascending sysid order except
    ``dropped`` (in the order heard): the members timed out now, the members new since the
    last call, and the members gone since the last call."""

    dropped: tuple[int, ...]
    joined: tuple[int, ...]
    lost: tuple[int, ...]


class Neighbours:
    """The other members' last states, by sysid.

    Args:
        sysid: this UAV's system id (its own state, echoed back, is ignored).
        member_timeout_s: silence after which a member leaves the formation (s).
    """

    def __init__(self, sysid: int, member_timeout_s: float) -> None:
        """Nobody heard yet."""
        self.sysid = int(sysid)
        self.member_timeout_s = member_timeout_s
        self.table: dict[int, Neighbour] = {}  # the same dict for the object's lifetime
        self._members: set[int] = set()
        # sysid -> (the state, the patrol, its position's phase rad, its distance m, the
        # weight of that phase in the steering's, its nearest loop point's canonical course)
        self._point_phase: dict[int, tuple[MemberState, Patrol, float, float, float, float]] = {}
        # the members whose last state is off the perimeter (neither on patrol nor a spare):
        # usually none, so the per-step questions below need not look at every member
        self._away: set[int] = set()

    def hear(self, state: MemberState, rx_t_s: float) -> bool:
        """Keep a member's state received at local time ``rx_t_s`` (s); False for our own."""
        if state.sysid == self.sysid:
            return False
        self.table[state.sysid] = Neighbour(state, rx_t_s)
        if state.mode in (Mode.PATROL, Mode.SPARE):
            self._away.discard(state.sysid)
        else:
            self._away.add(state.sysid)
        return True

    def expire(self, t_s: float) -> RosterChange:
        """Drop the members silent for more than ``member_timeout_s`` at ``t_s`` (s), and
        report who joined and who left since the last call."""
        dropped = tuple(s for s, n in self.table.items() if t_s - n.rx_t_s > self.member_timeout_s)
        for sysid in dropped:
            del self.table[sysid]
            self._point_phase.pop(sysid, None)
            self._away.discard(sysid)
        current = set(self.table)
        change = RosterChange(
            dropped, tuple(sorted(current - self._members)), tuple(sorted(self._members - current))
        )
        self._members = current
        return change

    def phases(self, t_s: float, period_s: float, on_patrol: bool = False) -> dict[int, float]:
        """Each member's time-phase (rad) extrapolated to ``t_s`` (s) at the nominal rate of a
        loop of period ``period_s`` (s), the members in the formation (a tracker is not);
        ``on_patrol``: only the members on patrol."""
        return {
            s: n.state.phase_at(n.state.t_s + (t_s - n.rx_t_s), period_s)
            for s, n in self.table.items()
            if (n.state.mode is Mode.PATROL if on_patrol else n.state.mode not in OUT_OF_FORMATION)
        }

    def others(self, t_s: float, period_s: float) -> list[tuple[float, complex]]:
        """(phase rad, centre m) of every member in the formation at ``t_s`` (s), for the
        splay law (a tracker is out of it: the others splay without it)."""
        return [
            (n.state.phase_at(n.state.t_s + (t_s - n.rx_t_s), period_s), n.state.centre_m)
            for n in self.table.values()
            if n.state.mode not in OUT_OF_FORMATION
        ]

    def in_formation(self) -> int:
        """How many members are in the formation (a tracker or a spare is not)."""
        return sum(1 for n in self.table.values() if n.state.mode not in OUT_OF_FORMATION)

    def positions_phases(self, t_s: float, patrol: Patrol) -> list[float]:
        """Every member's time-phase (rad) at ``t_s`` (s) read from where it is along the loop
        (:meth:`Patrol.phase_of_point` of its shared position), extrapolated at the nominal
        rate; the shared (course) phase for a member away or not sharing its position."""
        out = []
        for s, n in self.table.items():
            st = n.state
            if st.mode in OUT_OF_FORMATION:
                continue  # out of the formation
            age = t_s - n.rx_t_s
            along = self._along(s, patrol)
            if along is None:
                out.append(st.phase_at(st.t_s + age, patrol.period_s))
            else:
                out.append(float(wrap_2pi(along[0] + TWO_PI * age / patrol.period_s)))
        return out

    def steering_phases(self, t_s: float, patrol: Patrol) -> list[tuple[float, complex]]:
        """(phase rad, centre m) of every member at ``t_s`` (s) for the steering's phase term:
        the position phase of a member on the loop, its shared course phase far from it,
        blended by ``exp(-(d / ON_LOOP_M)^2)`` of its distance ``d`` from the loop.

        On the loop the course phase is ill-conditioned on long edges (docs/companion.md);
        off it, while the formation acquires, the course phases are the paper's law's own:
        with position phases there, six aircraft loitering near one another read as one
        cluster and the phase term drove all six out of the fence (a fleet start)."""
        # the arithmetic of MemberState.phase_at and _along inlined (the same operations in
        # the same order, so the same bits): this loop runs over every member every step
        out = []
        period = patrol.period_s
        placed = self._point_phase
        for s, n in self.table.items():
            st = n.state
            if st.mode in OUT_OF_FORMATION:
                continue  # out of the formation
            age = t_s - n.rx_t_s
            course = float((st.phase_rad + TWO_PI * ((st.t_s + age) - st.t_s) / period) % TWO_PI)
            if st.mode is Mode.PATROL and st.pos_m is not None:
                c = placed.get(s)
                if c is None or c[0] is not st or c[1] is not patrol:
                    c = self._place(s, st, patrol)
                pos = c[2] + TWO_PI * age / period
                course = float((course + c[4] * math.remainder(pos - course, TWO_PI)) % TWO_PI)
            out.append((course, st.centre_m))
        return out

    def _along(self, sysid: int, patrol: Patrol) -> tuple[float, float] | None:
        """(phase rad, distance m) of a member's shared position against ``patrol``, once
        per received state; None for a member away or not sharing its position."""
        st = self.table[sysid].state
        if st.mode is not Mode.PATROL or st.pos_m is None:
            return None
        cached = self._point_phase.get(sysid)
        if cached is None or cached[0] is not st or cached[1] is not patrol:
            cached = self._place(sysid, st, patrol)
        return cached[2], cached[3]

    def _place(
        self, sysid: int, st: MemberState, patrol: Patrol
    ) -> tuple[MemberState, Patrol, float, float, float, float]:
        """Place a member's shared position on ``patrol`` once per received state: (the
        state, the patrol, its phase rad, its distance m, the weight of that phase in the
        steering's, ``exp(-(d / ON_LOOP_M)^2)``, the loop point's canonical course rad).
        The search starts where its last state was placed (it moved a few metres since),
        or at the course its shared phase says."""
        last = self._point_phase.get(sysid)
        if last is not None:
            guess = last[5]
        else:
            guess = float(patrol.course_after(st.phase_rad * patrol.period_s / TWO_PI))
        assert st.pos_m is not None
        p = patrol.loop_point(st.pos_m, guess)
        dist = abs(p.offset_m)
        cached = (
            st,
            patrol,
            p.phase_rad,
            dist,
            math.exp(-((dist / ON_LOOP_M) ** 2)),
            p.course_canon_rad,
        )
        self._point_phase[sysid] = cached
        return cached

    def _off_perimeter(self) -> list[tuple[int, MemberState]]:
        """(sysid, state) of the members off the perimeter, in the table's order."""
        if not self._away:
            return []
        return [(s, n.state) for s, n in self.table.items() if s in self._away]

    def away(self) -> dict[int, str]:
        """The members off the perimeter as they share it, each mapped to the alert it flies
        back from (rejoining), or "" (prosecuting, tracking). A spare is not away."""
        return {
            s: st.alert_id if st.mode is Mode.REJOINING else "" for s, st in self._off_perimeter()
        }

    def tracking(self) -> list[tuple[int, str]]:
        """(sysid, alert id) of the members that share they are tracking an intruder."""
        return [(s, st.alert_id) for s, st in self._off_perimeter() if st.mode is Mode.TRACKING]

    def prosecuting(self) -> list[tuple[int, str]]:
        """(sysid, alert id) of the members that share they are prosecuting an alert (flying
        to it or searching for it)."""
        return [
            (s, st.alert_id)
            for s, st in self._off_perimeter()
            if st.mode in (Mode.PROSECUTING, Mode.SEARCHING)
        ]
