"""The vocabulary of one UAV's part in the reliefs (:mod:`companion.agent.relief.duty`): its
states, the events that change them (only along :data:`DUTY_TABLE`, with
:func:`companion.agent.machine.advance`), the stages of two of them (relieving:
:data:`RELIEVING_TABLE`; home: :data:`HOME_TABLE`), and what a step of the duty decides for
the Agent (:class:`DutyResult`). The data each state and stage needs is its record
(:mod:`companion.agent.relief.records`)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

from companion.agent.events import AgentEvent

VehicleCommand = Literal["takeoff", "land"]


class DutyState(StrEnum):
    """This UAV's part in the reliefs (shared as ``Energy.role``)."""

    ON_STATION = "on_station"
    HOME = "home"
    SPARE = "spare"
    RELIEVING = "relieving"


class DutyEvent(StrEnum):
    """What changes a :class:`DutyState`."""

    RELIEVED = "relieved"  # its relief holds the slot, or its leave time came
    LANDED = "landed"
    LAUNCHED = "launched"  # booked, due and charged: committed, taking off
    NOT_AIRBORNE = "not_airborne"  # commanded to take off and still on the ground
    IN_SLOT = "in_slot"
    STOOD_DOWN = "stood_down"  # another spare has its member: not yet flying, a spare again
    TURNED_BACK = "turned_back"  # the same, flying: home, to land and turn around


_O, _H, _S, _R = DutyState.ON_STATION, DutyState.HOME, DutyState.SPARE, DutyState.RELIEVING
DUTY_TABLE: dict[tuple[DutyState, DutyEvent], DutyState] = {
    (_O, DutyEvent.RELIEVED): _H,
    (_H, DutyEvent.LANDED): _S,
    (_S, DutyEvent.LAUNCHED): _R,
    (_R, DutyEvent.NOT_AIRBORNE): _S,
    (_R, DutyEvent.IN_SLOT): _O,
    (_R, DutyEvent.STOOD_DOWN): _S,
    (_R, DutyEvent.TURNED_BACK): _H,
}


class RelievingStage(StrEnum):
    """Where a relieving spare is on its way in to its member's slot (docs/energy.md,
    "Reliefs", relieving)."""

    COMMITTED = "committed"  # booked: waits (on the ground or holding) for the slot to come round
    TAKING_OFF = "taking_off"  # asked its autopilot to take off, not moved yet
    TO_LANE = "to_lane"  # straight to the lane point it keeps (chosen at its launch)
    TO_LOOP = "to_loop"  # none kept: the lane point chosen each step, or the loop if none fits
    IN_LANE = "in_lane"  # riding its lane to the turn-in point, then in at 45 deg
    FULL_TURN = "full_turn"  # far ahead in its lane: one full turn outward
    CAPTURED = "captured"  # the steering law flies it into the slot (or its member is gone)


class RelievingEvent(StrEnum):
    """What changes a :class:`RelievingStage`."""

    TAKE_OFF = "take_off"  # its slot came round, on the ground: the take-off asked for
    AIM = "aim"  # a lane point to fly to: chosen at launch, after its climb-out, or kept
    NO_AIM = "no_aim"  # flying, and no lane point kept
    REACH_LANE = "reach_lane"  # at its lane point, or turning onto the lane where it meets it
    TURN_FULL = "turn_full"  # far ahead in its lane: a full turn outward
    TURNED = "turned"  # the full turn is over
    CAPTURE = "capture"  # the steering law takes it (near the loop and the slot; no member)


_C, _T, _L, _P = (
    RelievingStage.COMMITTED,
    RelievingStage.TAKING_OFF,
    RelievingStage.TO_LANE,
    RelievingStage.TO_LOOP,
)
_I, _F, _X = RelievingStage.IN_LANE, RelievingStage.FULL_TURN, RelievingStage.CAPTURED
_RE = RelievingEvent
RELIEVING_TABLE: dict[tuple[RelievingStage, RelievingEvent], RelievingStage] = {
    (_C, _RE.TAKE_OFF): _T,
    (_C, _RE.AIM): _L,  # a holding spare leaves its hold
    (_C, _RE.NO_AIM): _P,
    (_T, _RE.AIM): _L,  # airborne: it moved
    (_T, _RE.NO_AIM): _P,
    (_L, _RE.AIM): _L,  # chosen again from where its climb-out left it
    (_P, _RE.AIM): _L,
    (_L, _RE.REACH_LANE): _I,
    (_P, _RE.REACH_LANE): _I,
    (_I, _RE.TURN_FULL): _F,
    (_F, _RE.TURNED): _I,
    (_L, _RE.CAPTURE): _X,
    (_P, _RE.CAPTURE): _X,
    (_I, _RE.CAPTURE): _X,
    (_F, _RE.CAPTURE): _X,
    (_X, _RE.AIM): _L,  # no longer captured: on to the lane point it kept
    (_X, _RE.NO_AIM): _P,
}
"""A relieving spare's stages: entered at ``committed`` (:data:`DUTY_TABLE`'s ``launched``);
left for another duty state from any stage (``in_slot``, ``not_airborne``, ``stood_down``,
``turned_back``)."""


class HomeStage(StrEnum):
    """How a relieved UAV leaves the loop for home (docs/energy.md, "Reliefs", home)."""

    RIDING = "riding"  # rides the loop, dropping back behind its relief
    CROSSING = "crossing"  # to the loop point where it crosses the loop behind a member
    OUT = "out"  # straight out to its lane, its sensor off the loop beside it
    STRAIGHT = "straight"  # straight to the nearest base, where it lands


class HomeEvent(StrEnum):
    """What changes a :class:`HomeStage`."""

    WAY_OUT = "way_out"  # back behind its relief, with a way out: out to its lane
    CROSS = "cross"  # no way out, a crossing found
    LEAVE = "leave"  # its leave time, neither: straight home
    CROSSED = "crossed"  # at its crossing point: out to its lane
    CLEAR = "clear"  # in its lane: on to the base


_HR, _HC, _HO, _HS = HomeStage.RIDING, HomeStage.CROSSING, HomeStage.OUT, HomeStage.STRAIGHT
HOME_TABLE: dict[tuple[HomeStage, HomeEvent], HomeStage] = {
    (_HR, HomeEvent.WAY_OUT): _HO,
    (_HR, HomeEvent.CROSS): _HC,
    (_HR, HomeEvent.LEAVE): _HS,
    (_HC, HomeEvent.CROSSED): _HO,
    (_HO, HomeEvent.CLEAR): _HS,
}
"""A relieved UAV's stages: entered at ``riding`` (relieved by a spare) or ``straight`` (at
its leave time, or turned back on its way in); left at ``landed`` from ``straight``."""


@dataclass(frozen=True)
class DutyStep:
    """What :meth:`Duty.step` decided.

    Attributes:
        off_station: the Agent does not patrol: it flies ``turn_rate_rad_s`` at
            ``airspeed_m_s`` and shares its real state as mode ``spare``.
        turn_rate_rad_s: the command off station (rad/s).
        airspeed_m_s: the airspeed off station (m/s).
        hold: on the ground: send the autopilot no setpoint.
        command: ``takeoff`` or ``land`` for the autopilot, or None.
    """

    off_station: bool
    turn_rate_rad_s: float = 0.0
    airspeed_m_s: float = 0.0
    hold: bool = False
    command: VehicleCommand | None = None


ON_STATION = DutyStep(False)


@dataclass(frozen=True)
class DutyResult:
    """What :meth:`Duty.step` returns: its decision and the events of the step, in the order
    they happened (the Agent logs them right after the call).

    Attributes:
        step: the decision.
        events: the step's events (:mod:`companion.agent.relief.events`).
    """

    step: DutyStep
    events: tuple[AgentEvent, ...] = ()


OFF = DutyResult(ON_STATION)
"""The result of a step with the reliefs off, or on station with nothing to say."""
