"""The vocabulary of one UAV's part in the reliefs (:mod:`companion.agent.relief.duty`): its
states, the events that change them (only along :data:`DUTY_TABLE`, with
:func:`companion.agent.machine.advance`), and what a step of the duty decides for the Agent."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

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
