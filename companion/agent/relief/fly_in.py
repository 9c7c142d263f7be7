"""How a relieving spare flies in to its member's slot (pure; docs/energy.md, "Reliefs"): to
its lane and along it to where it turns in behind the slot, or, where no lane point fits
(within its lane, inside the loop), straight to the loop; and when the steering law takes it.

Functions over a :class:`~companion.agent.relief.records.Relieving` record, one handler per
stage it flies (:data:`FLY_IN`: ``to_lane``, ``to_loop``, ``in_lane``, ``full_turn``); the
stage changes along :data:`~companion.agent.relief.states.RELIEVING_TABLE`, the stage's
record made as it is entered. The duty decides first whether it is captured
(:func:`captured`); :func:`fly_in` is its step when it is not. Positions complex m, angles
rad, times s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from companion.agent.fix import Fix
from companion.agent.relief.figures import Figures
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
from companion.agent.relief.records import (
    Captured,
    Committed,
    Flight,
    FullTurn,
    InLane,
    Relieving,
    Stage,
    ToLane,
    ToLoop,
)
from companion.agent.relief.states import DutyStep, RelievingEvent, RelievingStage
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_pi
from companion.guidance.steering import Gains, slot_speed_offset
from companion.guidance.virtual import phase_gap_rad

CAPTURE_SPACINGS = 0.75  # ... and nearer its member's slot than this many splay spacings L/N
LANE_REACH_M = 30.0  # this near the lane point it flew to, it rides the lane (m)
LANE_LOOKAHEAD_S = 3.0  # riding the lane it steers for the lane point this far ahead (s)
CLIMB_OUT_M = 100.0  # a climb-out that took it this far from its launch point: aim again (m)
HOLD_MARGIN_S = 5.0  # a full turn in its lane leaves it this far ahead of its turn-in (s)

_LANE_STAGES = (RelievingStage.IN_LANE, RelievingStage.FULL_TURN)


@dataclass(frozen=True)
class Approach:
    """One step of a relieving spare flying in, not captured.

    Attributes:
        fix: where it is (its ``patrol`` the loop it flies to).
        gains: the steering law's gains (its phase hold).
        behind_rad: where it turns in, ``meet_behind_m`` behind its member's slot (rad).
        turn_in: it is behind that point, near enough the slot to take it.
        within: it is inside the loop (no lane point fits).
    """

    fix: Fix
    gains: Gains
    behind_rad: float
    turn_in: bool
    within: bool


def behind_rad(fig: Figures, slot_phase_rad: float, patrol: Patrol) -> float:
    """Where a relieving spare turns in from its lane (rad): ``meet_behind_m`` behind its
    member's slot at ``slot_phase_rad`` (rad). Its sensor first reaches the loop beside it,
    behind the member's, as it turns in."""
    return slot_phase_rad - TWO_PI * fig.meet_behind_m / patrol.length_m


def meet(fig: Figures, fix: Fix, behind: float) -> tuple[complex, float] | None:
    """The lane point (m) it flies to from ``fix`` to ride its lane to the turn-in point now
    at ``behind`` (rad), from outside and with the traffic, at least ``early_s`` before that
    point is there, and how much earlier still (s); of those, the one that puts it in the
    slot soonest, each second early costing ``wait_factor`` more in the lane
    (``join.meet_point``); or None."""
    return meet_point(fix.pos_m, fix.heading_rad, behind, fix.patrol, fig.max_u,
                      lane_m=fig.lane_m, early_s=fig.early_s, clear_m=fig.sensor_m,
                      wait_factor=fig.wait_factor)  # fmt: skip


def meet_loop(fig: Figures, fix: Fix, behind: float, within: bool) -> tuple[complex, float] | None:
    """Where no lane point fits, the point (m) where it meets the point now at ``behind``
    (rad; the turn-in point moved back by its sensor radius), and how much earlier it would
    be there (s); or None. Inside the loop (``within``): the point its sensor radius inside
    the loop beside that one as it gets there, so its sensor first reaches the loop behind
    its member whatever its angle to the loop (met up to a second early: the plan's
    resolution). Within its lane: the loop point, from outside if it can."""
    pos_m, heading_rad, patrol = fix.pos_m, fix.heading_rad, fix.patrol
    if within:
        return meet_point(pos_m, heading_rad, behind, patrol, fig.max_u, outside=False,
                          lane_m=-fig.sensor_m)  # fmt: skip
    found = meet_point(pos_m, heading_rad, behind, patrol, fig.max_u)
    if found is None:
        found = meet_point(pos_m, heading_rad, behind, patrol, fig.max_u, outside=False)
    return found


def flight_of(stage: Stage) -> Flight | None:
    """The flight a stage record shares (None while it is committed)."""
    return None if isinstance(stage, Committed) else stage.flight


def aim_of(stage: Stage) -> complex | None:
    """The lane point a stage keeps (flying to it, or captured on the way), or None."""
    return stage.aim_m if isinstance(stage, ToLane | Captured) else None


def captured(
    rel: Relieving, flight: Flight, along_m: float | None, patrol: Patrol, others: int, ahead: bool
) -> bool:
    """Near the loop or in its lane: whether the steering law takes it into its member's
    slot from ``along_m`` (m along the loop from the slot; None: not known, it does), with
    ``others`` members in the formation besides. The law's splay potential with the others
    held has minima other than the slot (one beside each other member): from farther than
    ``CAPTURE_SPACINGS`` of the spacing it flies on to where the slot will be (and, once
    captured, it stays so within 1.5 times that). In its lane, or flying to it, it waits
    until it is no longer ``ahead`` of where it turns in."""
    if along_m is None:
        return True
    stage = rel.stage.record
    lane = rel.stage.state in _LANE_STAGES or aim_of(stage) is not None  # in it, or to it
    if lane and ahead and not flight.capture:
        return False
    spacing_m = patrol.length_m / (others + 1)
    limit = CAPTURE_SPACINGS * spacing_m * (1.5 if flight.capture else 1.0)
    flight.capture = along_m < limit
    return flight.capture


def capture(rel: Relieving, flight: Flight) -> None:
    """The steering law takes it from here (it keeps the lane point it flew to, if any)."""
    if rel.stage.state is not RelievingStage.CAPTURED:
        rel.go(RelievingEvent.CAPTURE, Captured(flight, aim_of(rel.stage.record)))


def release(rel: Relieving, flight: Flight) -> None:
    """No longer captured: on to the lane point it kept, or with none."""
    stage = rel.stage.record
    if isinstance(stage, Captured):
        fly_for(rel, flight, stage.aim_m)


def fly_for(rel: Relieving, flight: Flight, aim_m: complex | None) -> None:
    """Flying (airborne, out of its hold, or let go by the law): to the lane point ``aim_m``
    (m) it keeps, or with none."""
    if aim_m is not None:
        rel.go(RelievingEvent.AIM, ToLane(flight, aim_m))
    else:
        rel.go(RelievingEvent.NO_AIM, ToLoop(flight))


def fly_in(rel: Relieving, fig: Figures, a: Approach) -> DutyStep:
    """Fly to its lane and ride it to where it turns in behind its member's slot, now at
    ``a.behind_rad`` (rad): straight to the lane point chosen at its launch (:func:`meet`:
    reached ``early_s`` before that point is there, from outside the loop and with the
    traffic, the one that puts it in the slot soonest counting its wait in the lane;
    recomputed each step, it would be one it reaches early once it flies), its turns
    :func:`~companion.agent.relief.join.turn_signs`' (a turn of over 90 deg away from the
    loop unless its sensor stays clear of it); then along the lane (``join.lane_target``).
    Where no lane point fits (it is within its lane or inside the loop) it flies straight
    to the loop point where it meets the turn-in point, its airspeed closing the gap along
    the loop, as a prosecutor's does rejoining. Not captured, flying (any stage but
    ``committed``, ``taking_off`` and ``captured``)."""
    stage = rel.stage.record
    assert isinstance(stage, ToLane | ToLoop | InLane | FullTurn)
    flight = stage.flight
    if flight.reaim and rel.stage.state not in _LANE_STAGES:  # its climb-out is over:
        flight.reaim = False  # the lane point chosen again from there
        far = abs(a.fix.pos_m - flight.launch_pos_m) > CLIMB_OUT_M
        found = meet(fig, a.fix, a.behind_rad) if far else None
        if found is not None:
            rel.go(RelievingEvent.AIM, ToLane(flight, found[0]))
    return FLY_IN[rel.stage.state](rel, fig, a)


def _to_lane(rel: Relieving, fig: Figures, a: Approach) -> DutyStep:
    """Straight to the lane point it keeps, until it reaches it (or meets its lane)."""
    stage = rel.stage.record
    assert isinstance(stage, ToLane)
    if _reached(fig, a.fix, stage.aim_m):
        return _enter_lane(rel, stage.flight, fig, a)
    return _fly_to_point(stage.flight, fig, a, stage.aim_m, a.behind_rad)


def _to_loop(rel: Relieving, fig: Figures, a: Approach) -> DutyStep:
    """No lane point kept: the one that fits now, or, none fitting, the loop point where it
    meets the turn-in point less its sensor radius (it reaches the loop first)."""
    stage = rel.stage.record
    assert isinstance(stage, ToLoop)
    aim = None
    if not a.within:
        found = meet(fig, a.fix, a.behind_rad)
        aim = found[0] if found is not None else None
    if aim is not None and _reached(fig, a.fix, aim):
        return _enter_lane(rel, stage.flight, fig, a)
    behind = a.behind_rad
    if aim is None:  # no lane point fits: the loop itself, its sensor radius further back
        patrol = a.fix.patrol
        behind -= TWO_PI * fig.sensor_m / patrol.length_m
        found = meet_loop(fig, a.fix, behind, a.within)
        aim = found[0] if found is not None else complex(patrol.point_at_phase(behind))
    return _fly_to_point(stage.flight, fig, a, aim, behind)


def _reached(fig: Figures, fix: Fix, aim_m: complex) -> bool:
    """Whether it is at its lane point ``aim_m`` (m), or must turn onto the lane now."""
    reached = abs(aim_m - fix.pos_m) < LANE_REACH_M
    return reached or onto_lane(fix.pos_m, fix.heading_rad, fix.patrol, fig.lane_m, fig.max_u)


def _enter_lane(rel: Relieving, flight: Flight, fig: Figures, a: Approach) -> DutyStep:
    """It got to its lane: it rides it from this step."""
    rel.go(RelievingEvent.REACH_LANE, InLane(flight))
    flight.laned = True
    return _in_lane(rel, fig, a)


def _in_lane(rel: Relieving, fig: Figures, a: Approach) -> DutyStep:
    """In its lane far ahead of where it turns in: one full turn outward at its turn rate,
    the airspeed the plan's; else it rides the lane (:func:`_ride_lane`). Riding, it loses
    its lead at the phase hold's few m/s; a full turn loses about 2 pi turn radii in one
    turn's time. It starts one only where its lead is more than the turn-in point comes on
    at airspeed in a turn's time and ``HOLD_MARGIN_S`` (the wind moves both; should the
    point pass it, it is behind it and closes on it: cheaper than a lap at the phase hold's
    pace, which a worst-case margin cost in a sweep of climb-outs,
    ``tests/test_relief_climb_out.py``), and the turn, drifting in the wind, keeps its
    sensor off the loop by half the lane's margin over it
    (:func:`~companion.agent.relief.join.full_turn_clear`; flown with the sensor's edge
    exactly on it, a turn ends that near the loop); then it turns until its heading has
    come round by 2 pi (:func:`_full_turn`)."""
    stage = rel.stage.record
    assert isinstance(stage, InLane)
    flight, fix, patrol = stage.flight, a.fix, a.fix.patrol
    target, lead = _lane_target(fig, a)
    v = patrol.airspeed_m_s
    if a.turn_in:
        return _ride_lane(flight, fig, a, target, lead)
    lost_m = v * (TWO_PI / fig.max_u + HOLD_MARGIN_S)  # a turn's worth, and the margin
    if lead * patrol.length_m / TWO_PI < lost_m:
        return _ride_lane(flight, fig, a, target, lead)
    h = complex(math.cos(fix.heading_rad), math.sin(fix.heading_rad))
    sign = away_sign(fix.pos_m, h, patrol)  # outward
    clear_m = 0.5 * (fig.sensor_m + fig.lane_m)  # half its lane's margin kept
    if not full_turn_clear(fix.pos_m, fix.heading_rad, sign, patrol, fig.max_u, clear_m):
        return _ride_lane(flight, fig, a, target, lead)
    rel.go(RelievingEvent.TURN_FULL, FullTurn(flight, TWO_PI, fix.heading_rad))
    flight.turn_sign = sign
    return DutyStep(True, sign * fig.max_u, v)


def _full_turn(rel: Relieving, fig: Figures, a: Approach) -> DutyStep:
    """Turning a full turn in its lane: count what it turned since the last step; at 2 pi
    it rides the lane again."""
    stage = rel.stage.record
    assert isinstance(stage, FullTurn)
    flight, heading_rad = stage.flight, a.fix.heading_rad
    turned = float(wrap_pi(heading_rad - stage.heading_rad))
    stage.left_rad -= flight.turn_sign * turned
    stage.heading_rad = heading_rad
    if stage.left_rad > 0.0:
        return DutyStep(True, flight.turn_sign * fig.max_u, a.fix.patrol.airspeed_m_s)
    flight.turn_sign = 0.0
    rel.go(RelievingEvent.TURNED, InLane(flight))
    target, lead = _lane_target(fig, a)
    return _ride_lane(flight, fig, a, target, lead)


def _lane_target(fig: Figures, a: Approach) -> tuple[complex, float]:
    """What it steers for in its lane (m) and its lead on the turn-in point (rad)."""
    return lane_target(a.fix.patrol, a.fix.loop_phase_rad, a.behind_rad, fig.lane_m, a.turn_in,
                       LANE_LOOKAHEAD_S)  # fmt: skip


def _ride_lane(
    flight: Flight, fig: Figures, a: Approach, target_m: complex, lead_rad: float
) -> DutyStep:
    """In its lane (or turning in from it): steered for ``target_m`` (m), its airspeed the
    phase hold's for a lead of ``lead_rad`` (rad) on the point where it turns in
    (:func:`~companion.agent.relief.join.lane_target`, which says where and why). Met
    against the traffic, it turns about away from the loop. Once it turns in, the steering
    law takes it ``TURN_IN_M`` from the loop (from as far out as the lane, the law may
    circle)."""
    fix, patrol = a.fix, a.fix.patrol
    u = fly_to(fix.pos_m, fix.heading_rad, target_m, patrol, fig.max_u)
    h = complex(math.cos(fix.heading_rad), math.sin(fix.heading_rad))
    if dot(h, target_m - fix.pos_m) < 0.0:  # it met its lane against the traffic: about,
        if flight.turn_sign == 0.0:  # away from the loop (chosen as it starts, held)
            flight.turn_sign = away_sign(fix.pos_m, h, patrol)
        u = flight.turn_sign * fig.max_u
    else:
        flight.turn_sign = 0.0
    v = patrol.airspeed_m_s + slot_speed_offset(patrol, a.gains, lead_rad)
    return DutyStep(True, u, v)


def _fly_to_point(
    flight: Flight, fig: Figures, a: Approach, aim_m: complex, behind: float
) -> DutyStep:
    """Straight to ``aim_m`` (m), a turn of over 90 deg the way
    :func:`~companion.agent.relief.join.turn_signs` says (chosen as it starts, held through
    the turn); its airspeed closing its gap along the loop on ``behind`` (rad), or from
    inside the loop the plan's (its phase on the loop means nothing there)."""
    fix, patrol = a.fix, a.fix.patrol
    pos_m, heading_rad = fix.pos_m, fix.heading_rad
    u = fly_to(pos_m, heading_rad, aim_m, patrol, fig.max_u)
    h = complex(math.cos(heading_rad), math.sin(heading_rad))
    d = aim_m - pos_m
    if dot(h, d / abs(d)) < 0.0:
        if flight.turn_sign == 0.0:  # chosen as it starts, then held through the turn
            err = np.array([wrap_pi(math.atan2(d.imag, d.real) - heading_rad)])
            radius_m = patrol.airspeed_m_s / fig.max_u
            sign = turn_signs(pos_m, h, err, patrol, radius_m, fig.sensor_m)
            flight.turn_sign = float(sign[0])
        u = flight.turn_sign * fig.max_u
    else:
        flight.turn_sign = 0.0
    v = patrol.airspeed_m_s
    if not a.within:
        v += slot_speed_offset(patrol, a.gains, phase_gap_rad(fix.loop_phase_rad, behind))
    return DutyStep(True, u, v)


FLY_IN: dict[RelievingStage, Callable[[Relieving, Figures, Approach], DutyStep]] = {
    RelievingStage.TO_LANE: _to_lane,
    RelievingStage.TO_LOOP: _to_loop,
    RelievingStage.IN_LANE: _in_lane,
    RelievingStage.FULL_TURN: _full_turn,
}
"""The step of each stage it flies, not captured."""
