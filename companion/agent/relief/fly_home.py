"""How a relieved UAV leaves the loop for home (docs/energy.md, "Reliefs", home): it drops
back behind its relief, then leaves by a way out (straight out to its lane, its way on to
its base off the loop), or crosses the loop behind a member, or at its leave time flies
straight home. Its sensor so starts no member's pass early (the revisit is counted start to
start).

Part of :class:`companion.agent.relief.duty.Duty`, whose ``__init__`` sets the state these
methods share (``_ride_until_s``, ``_ride_behind``, ``_out_first``, ``_cross_m``,
``_cross_t_s``) and the mission's figures (``sensor_m``, ``lane_m``, ``count``,
``max_u``, ``airspeed_m_s``). Positions complex m, angles rad, times s.
"""

from __future__ import annotations

from companion.agent.neighbours import Neighbours
from companion.agent.relief.fly_in import LANE_REACH_M
from companion.agent.relief.join import crossing, fly_to, loop_frame, slot_phase, way_out
from companion.agent.relief.roster import LAND_MARGIN_S
from companion.agent.relief.states import DutyStep
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.group.messages import Mode
from companion.guidance.formation import splay_command
from companion.guidance.steering import Gains, slot_speed_offset, speed_holds_phase
from companion.guidance.virtual import phase_gap_rad

DROP_SENSORS = 1.5  # relieved, it drops this many sensor radii behind its relief to leave
DROP_REACH_M = 10.0  # ... and is that far back within this (m)
CROSS_MARGIN_S = 2.0  # crossing the loop home, its sensor is off it this long before the next
CROSS_EVERY_S = 1.0  # riding with no way out, it looks for a crossing this often (s)


class FlyHome:
    """A relieved UAV's way off the loop (see the module docstring)."""

    def _way_home(
        self,
        t_s: float,
        pos_m: complex,
        heading_rad: float,
        heard: Neighbours,
        patrol: Patrol,
        gains: Gains,
        base: complex,
    ) -> DutyStep | None:
        """Its step while it rides the loop, crosses it or flies out to its lane; None once
        it flies straight to ``base`` (m)."""
        if self._ride_until_s is not None:
            v, back = self._drop_back(t_s, pos_m, heard, patrol, gains)
            due = t_s >= self._ride_until_s
            radius_m = patrol.airspeed_m_s / self.max_u
            out = not due and back and way_out(pos_m, base, patrol, self.lane_m, self.sensor_m,
                                               radius_m)  # fmt: skip
            if (due or back) and not out and t_s - self._cross_t_s >= CROSS_EVERY_S:
                self._cross_t_s = t_s  # no way out: home across the loop, behind a member?
                self._cross_m = self._crossing(t_s, pos_m, heading_rad, heard, patrol, base)
            if not due and not out and self._cross_m is None:
                centre, phase = patrol.centre_and_phase(pos_m, heading_rad)
                u = splay_command(patrol, gains, pos_m, heading_rad, float(phase),
                                  complex(centre), [], self.max_u)  # fmt: skip
                return DutyStep(True, u, v)
            self._ride_until_s, self._ride_behind, self._out_first = None, None, out
        if self._cross_m is not None:
            if abs(self._cross_m - pos_m) > LANE_REACH_M:
                u = fly_to(pos_m, heading_rad, self._cross_m, patrol, self.max_u)
                return DutyStep(True, u, self.airspeed_m_s)
            self._cross_m, self._out_first = None, True  # and out across the loop
        if self._out_first:  # straight out to its lane, its sensor off the loop beside it
            near, _, n = loop_frame(pos_m, patrol)
            if abs(pos_m - near) < self.lane_m:
                u = fly_to(pos_m, heading_rad, pos_m + 2.0 * self.lane_m * n, patrol, self.max_u)
                return DutyStep(True, u, self.airspeed_m_s)
            self._out_first = False
        return None

    def _drop_back(
        self, t_s: float, pos_m: complex, heard: Neighbours, patrol: Patrol, gains: Gains
    ) -> tuple[float, bool]:
        """Relieved and riding the loop at ``pos_m`` (m): its airspeed (m/s), the phase
        hold's for a slot ``DROP_SENSORS`` sensor radii (at most half the spacing L/N)
        behind its relief, and whether it is that far back (within ``DROP_REACH_M``). Its
        relief unheard, or its airspeed not holding the phase (the mean-centre form), it
        rides at the plan's airspeed and is back."""
        relief = heard.table.get(self._ride_behind) if self._ride_behind is not None else None
        if relief is None or not speed_holds_phase(gains):
            return patrol.airspeed_m_s, True
        target = slot_phase(relief, t_s, patrol) - TWO_PI * self._drop_m(patrol) / patrol.length_m
        gap = phase_gap_rad(patrol.phase_of_point(pos_m), target)  # + ahead of it
        v = patrol.airspeed_m_s + slot_speed_offset(patrol, gains, gap)
        return v, gap * patrol.length_m / TWO_PI <= DROP_REACH_M

    def _drop_m(self, patrol: Patrol) -> float:
        """How far behind its relief a relieved UAV drops back before it leaves (m):
        ``DROP_SENSORS`` sensor radii, at most half the spacing L/N."""
        return min(DROP_SENSORS * self.sensor_m, 0.5 * patrol.length_m / self.count)

    def _crossing(
        self,
        t_s: float,
        pos_m: complex,
        heading_rad: float,
        heard: Neighbours,
        patrol: Patrol,
        base_m: complex,
    ) -> complex | None:
        """Relieved with no way out (back behind its relief, or at its leave time): the loop
        point (m) where it crosses the loop home behind a member
        (:func:`~companion.agent.relief.join.crossing`: its drop-back distance after the last
        member, its sensor off the loop before the next one's reaches it), if that gets it
        home at most half the landing margin later than flying straight; else None."""
        members = [slot_phase(n, t_s, patrol) for n in heard.table.values()
                   if n.state.mode is Mode.PATROL]  # fmt: skip
        slow_m_s = patrol.airspeed_m_s - abs(patrol.wind.vector)  # its slowest ground speed
        behind_s = self._drop_m(patrol) / slow_m_s
        clear_s = 2.0 * self.sensor_m / slow_m_s + CROSS_MARGIN_S
        found = crossing(pos_m, heading_rad, base_m, members, patrol, behind_s, clear_s,
                         self.lane_m, self.sensor_m, self.max_u)  # fmt: skip
        if found is None:
            return None
        point, flight = found
        straight_s = abs(base_m - pos_m) / slow_m_s
        home_s = flight + abs(base_m - point) / slow_m_s
        return point if home_s <= straight_s + 0.5 * LAND_MARGIN_S else None
