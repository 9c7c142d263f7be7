"""How a relieving spare flies in to its member's slot (docs/energy.md, "Reliefs"): to its
lane and along it to where it turns in behind the slot, or, where no lane point fits (within
its lane, inside the loop), straight to the loop; and when the steering law takes it.

Part of :class:`companion.agent.relief.duty.Duty`, whose ``__init__`` sets the state these
methods share (``_aim``, ``_in_lane``, ``_laned``, ``_turn_sign``, ``_reaim``,
``_capture``, ``_launch_pos``, ``_hold_left_rad``, ``_hold_heading_rad``) and the mission's
figures (``sensor_m``, ``lane_m``, ``meet_behind_m``, ``early_s``, ``wait_factor``,
``max_u``). Positions complex m, angles rad, times s.
"""

from __future__ import annotations

import math

import numpy as np

from companion.agent.relief.join import (
    away_sign,
    dot,
    fly_to,
    full_turn_clear,
    lane_target,
    meet_point,
    onto_lane,
    turn_signs,
)
from companion.agent.relief.states import DutyStep
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_pi
from companion.guidance.steering import Gains, slot_speed_offset
from companion.guidance.virtual import phase_gap_rad

CAPTURE_SPACINGS = 0.75  # ... and nearer its member's slot than this many splay spacings L/N
LANE_REACH_M = 30.0  # this near the lane point it flew to, it rides the lane (m)
LANE_LOOKAHEAD_S = 3.0  # riding the lane it steers for the lane point this far ahead (s)
CLIMB_OUT_M = 100.0  # a climb-out that took it this far from its launch point: aim again (m)
HOLD_MARGIN_S = 5.0  # a full turn in its lane leaves it this far ahead of its turn-in (s)


class FlyIn:
    """A relieving spare's way in to its member's slot (see the module docstring)."""

    def _behind(self, slot_phase_rad: float, patrol: Patrol) -> float:
        """Where a relieving spare turns in from its lane (rad): ``meet_behind_m`` behind its
        member's slot at ``slot_phase_rad`` (rad). Its sensor first reaches the loop beside
        it, behind the member's, as it turns in."""
        return slot_phase_rad - TWO_PI * self.meet_behind_m / patrol.length_m

    def _meet(
        self, pos_m: complex, heading_rad: float, behind_rad: float, patrol: Patrol
    ) -> tuple[complex, float] | None:
        """The lane point (m) it flies to from ``pos_m`` (m) heading ``heading_rad`` (rad) to
        ride its lane to the turn-in point now at ``behind_rad`` (rad), from outside and with
        the traffic, at least ``early_s`` before that point is there, and how much earlier
        still (s); of those, the one that puts it in the slot soonest, each second early
        costing ``wait_factor`` more in the lane (``join.meet_point``); or None."""
        return meet_point(pos_m, heading_rad, behind_rad, patrol, self.max_u,
                          lane_m=self.lane_m, early_s=self.early_s, clear_m=self.sensor_m,
                          wait_factor=self.wait_factor)  # fmt: skip

    def _meet_loop(
        self, pos_m: complex, heading_rad: float, behind_rad: float, patrol: Patrol, within: bool
    ) -> tuple[complex, float] | None:
        """Where no lane point fits, the point (m) where it meets the point now at
        ``behind_rad`` (rad; the turn-in point moved back by its sensor radius), and how much
        earlier it would be there (s); or None. Inside the loop (``within``): the point its
        sensor radius inside the loop beside that one as it gets there, so its sensor first
        reaches the loop behind its member whatever its angle to the loop (met up to a
        second early: the plan's resolution). Within its lane: the loop point, from outside
        if it can."""
        if within:
            return meet_point(pos_m, heading_rad, behind_rad, patrol, self.max_u, outside=False,
                              lane_m=-self.sensor_m)  # fmt: skip
        found = meet_point(pos_m, heading_rad, behind_rad, patrol, self.max_u)
        if found is None:
            found = meet_point(pos_m, heading_rad, behind_rad, patrol, self.max_u, outside=False)
        return found

    def _captured(self, along_m: float | None, patrol: Patrol, others: list, ahead: bool) -> bool:
        """Near the loop or in its lane: whether the steering law takes it into its member's
        slot from ``along_m`` (m along the loop from the slot; None: not known, it does).
        The law's splay potential with the others held has minima other than the slot (one
        beside each other member): from farther than ``CAPTURE_SPACINGS`` of the spacing it
        flies on to where the slot will be (and, once captured, it stays so within 1.5 times
        that). In its lane, or flying to it, it waits until it is no longer ``ahead`` of where
        it turns in."""
        if along_m is None:
            return True
        lane = self._in_lane or self._aim is not None  # in its lane, or flying to it
        if lane and ahead and not self._capture:
            return False
        spacing_m = patrol.length_m / (len(others) + 1)
        limit = CAPTURE_SPACINGS * spacing_m * (1.5 if self._capture else 1.0)
        self._capture = along_m < limit
        return self._capture

    def _relieving_step(
        self,
        pos_m: complex,
        heading_rad: float,
        patrol: Patrol,
        gains: Gains,
        behind_rad: float,
        own_phase_rad: float,
        turn_in: bool,
        within: bool,
    ) -> DutyStep:
        """Fly to its lane and ride it to where it turns in behind its member's slot, now at
        ``behind_rad`` (rad): straight to the lane point chosen at its launch (:meth:`_meet`:
        reached ``early_s`` before that point is there, from outside the loop and with the
        traffic, the one that puts it in the slot soonest counting its wait in the lane;
        recomputed each step, it would be one it reaches early once it flies), its
        turns :func:`~companion.agent.relief.join.turn_signs`' (a turn of over 90 deg away
        from the loop unless its sensor stays clear of it); then along the lane
        (``join.lane_target``). Where no lane point fits (it is within its lane or inside
        the loop) it flies straight to the loop point where it meets the turn-in point,
        its airspeed closing the gap along the loop (``own_phase_rad``: where it is along
        it, rad), as a prosecutor's does rejoining. ``turn_in``: it is behind the turn-in
        point, near enough its member's slot to take it."""
        behind = behind_rad
        if self._reaim and not self._in_lane:  # its climb-out is over: chosen again from there
            self._reaim = False
            far = self._launch_pos is not None and abs(pos_m - self._launch_pos) > CLIMB_OUT_M
            found = self._meet(pos_m, heading_rad, behind, patrol) if far else None
            if found is not None:
                self._aim = found[0]
        aim, found = self._aim, None
        if aim is None and not self._in_lane and not within:  # none chosen (nor fitting): each step
            found = self._meet(pos_m, heading_rad, behind, patrol)
            aim = found[0] if found is not None else None
        reached = aim is not None and abs(aim - pos_m) < LANE_REACH_M
        onto = onto_lane(pos_m, heading_rad, patrol, self.lane_m, self.max_u)
        if aim is not None and (reached or onto):
            self._in_lane, self._laned, self._aim = True, True, None  # it got to its lane
        if self._in_lane:
            target, lead = lane_target(patrol, own_phase_rad, behind, self.lane_m, turn_in,
                                       LANE_LOOKAHEAD_S)  # fmt: skip
            held = self._hold_turn(pos_m, heading_rad, patrol, lead, turn_in)
            if held is not None:
                return held
            return self._ride_lane(pos_m, heading_rad, patrol, gains, target, lead)
        if aim is None:  # no lane point fits: the loop itself, its sensor radius further back
            behind -= TWO_PI * self.sensor_m / patrol.length_m  # (it reaches the loop first)
            found = self._meet_loop(pos_m, heading_rad, behind, patrol, within)
            aim = found[0] if found is not None else complex(patrol.point_at_phase(behind))
        u = fly_to(pos_m, heading_rad, aim, patrol, self.max_u)
        h = complex(math.cos(heading_rad), math.sin(heading_rad))
        d = aim - pos_m
        if dot(h, d / abs(d)) < 0.0:
            if self._turn_sign == 0.0:  # chosen as it starts, then held through the turn
                err = np.array([wrap_pi(math.atan2(d.imag, d.real) - heading_rad)])
                radius_m = patrol.airspeed_m_s / self.max_u
                sign = turn_signs(pos_m, h, err, patrol, radius_m, self.sensor_m)
                self._turn_sign = float(sign[0])
            u = self._turn_sign * self.max_u
        else:
            self._turn_sign = 0.0
        v = patrol.airspeed_m_s  # from inside, the plan's (its phase on the loop means nothing)
        if not within:
            v += slot_speed_offset(patrol, gains, phase_gap_rad(own_phase_rad, behind))
        return DutyStep(True, u, v)

    def _hold_turn(
        self, pos_m: complex, heading_rad: float, patrol: Patrol, lead_rad: float, turn_in: bool
    ) -> DutyStep | None:
        """In its lane far ahead of where it turns in (``lead_rad``, rad, from
        :func:`~companion.agent.relief.join.lane_target`): one full turn outward at its
        turn rate, the airspeed the plan's, or None to ride on. Riding, it loses its lead at
        the phase hold's few m/s; a full turn loses about 2 pi turn radii in one turn's
        time. It starts one only where its lead is more than the turn-in point comes on at
        airspeed in a turn's time and ``HOLD_MARGIN_S`` (the wind moves both; should the
        point pass it, it is behind it and closes on it: cheaper than a lap at the phase
        hold's pace, which a worst-case margin cost in a sweep of climb-outs,
        ``tests/test_relief_climb_out.py``), and the turn, drifting in the wind, keeps its
        sensor off the loop by half the lane's margin over it
        (:func:`~companion.agent.relief.join.full_turn_clear`; flown with the sensor's edge
        exactly on it, a turn ends that near the loop); then it turns until its heading has
        come round by 2 pi."""
        v = patrol.airspeed_m_s
        if self._hold_left_rad is not None:  # turning: count what it turned since the last step
            turned = float(wrap_pi(heading_rad - self._hold_heading_rad))
            self._hold_left_rad -= self._turn_sign * turned
            self._hold_heading_rad = heading_rad
            if self._hold_left_rad > 0.0:
                return DutyStep(True, self._turn_sign * self.max_u, v)
            self._hold_left_rad, self._turn_sign = None, 0.0
            return None
        if turn_in:
            return None
        lost_m = v * (TWO_PI / self.max_u + HOLD_MARGIN_S)  # a turn's worth, and the margin
        if lead_rad * patrol.length_m / TWO_PI < lost_m:
            return None
        h = complex(math.cos(heading_rad), math.sin(heading_rad))
        sign = away_sign(pos_m, h, patrol)  # outward
        clear_m = 0.5 * (self.sensor_m + self.lane_m)  # half its lane's margin kept
        if not full_turn_clear(pos_m, heading_rad, sign, patrol, self.max_u, clear_m):
            return None
        self._hold_left_rad, self._hold_heading_rad, self._turn_sign = TWO_PI, heading_rad, sign
        return DutyStep(True, sign * self.max_u, v)

    def _ride_lane(
        self, pos_m: complex, heading_rad: float, patrol: Patrol, gains: Gains,
        target_m: complex, lead_rad: float,
    ) -> DutyStep:  # fmt: skip
        """In its lane (or turning in from it): steered for ``target_m`` (m), its airspeed
        the phase hold's for a lead of ``lead_rad`` (rad) on the point where it turns in
        (:func:`~companion.agent.relief.join.lane_target`, which says where and why). Met
        against the traffic, it turns about away from the loop. Once it turns in, the
        steering law takes it ``TURN_IN_M`` from the loop (from as far out as the lane, the
        law may circle)."""
        u = fly_to(pos_m, heading_rad, target_m, patrol, self.max_u)
        h = complex(math.cos(heading_rad), math.sin(heading_rad))
        if dot(h, target_m - pos_m) < 0.0:  # it met its lane against the traffic: about,
            if self._turn_sign == 0.0:  # away from the loop (chosen as it starts, held)
                self._turn_sign = away_sign(pos_m, h, patrol)
            u = self._turn_sign * self.max_u
        else:
            self._turn_sign = 0.0
        v = patrol.airspeed_m_s + slot_speed_offset(patrol, gains, lead_rad)
        return DutyStep(True, u, v)
