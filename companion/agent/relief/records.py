"""The data of one UAV's part in the reliefs, one record per state and stage (pure; h11's
readers keyed by state).

A :class:`Staged` holds a table machine's state and the record of that state. The only way
to another state is :meth:`Staged.go`: the event is looked up in the machine's table
(:func:`companion.agent.machine.advance`; an event the table does not allow raises
:class:`~companion.agent.machine.IllegalTransitionError`) and the record of the state it
leads to is given with it, made by the transition that enters that state; the record of the
state left is dropped. Each record names its state (``STATE``), so a record of the wrong
state is refused too.

The duty's four states (:data:`~companion.agent.relief.states.DUTY_TABLE`):

* :class:`OnStation` -- its leave time and the rotation's, whom it relieved, who flew in
  for it, the reliefs it said were late;
* :class:`Spare` -- on the ground or holding, when it is charged;
* :class:`Relieving` -- whom it relieves, and its stage
  (:data:`~companion.agent.relief.states.RELIEVING_TABLE`): :class:`Committed`,
  :class:`TakingOff`, :class:`ToLane`, :class:`ToLoop`, :class:`InLane`,
  :class:`FullTurn`, :class:`Captured`; from its launch on they share its :class:`Flight`;
* :class:`GoingHome` -- its stage (:data:`~companion.agent.relief.states.HOME_TABLE`):
  :class:`Riding`, :class:`Crossing`, :class:`OutToLane`, :class:`StraightHome`.

Times vehicle s, positions complex m, angles rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, ClassVar, Generic, Protocol, TypeVar

from companion.agent.machine import advance
from companion.agent.relief.states import (
    HOME_TABLE,
    RELIEVING_TABLE,
    DutyState,
    HomeEvent,
    HomeStage,
    RelievingEvent,
    RelievingStage,
)
from companion.group.messages import Energy

S = TypeVar("S", bound=StrEnum)


class _Record(Protocol):
    """A record names the state it is the record of."""

    STATE: ClassVar[Any]


R = TypeVar("R", bound=_Record)


class Staged(Generic[S, R]):
    """A state of a table machine with that state's record (see the module docstring).

    Args:
        table: the machine, ``{(state, event): next state}``.
        record: the record of the state it starts in (its ``STATE``).
    """

    def __init__(self, table: dict[tuple[S, Any], S], record: R) -> None:
        """Start in ``record``'s state."""
        self._table = table
        self._record = record

    @property
    def state(self) -> S:
        """The state it is in (the record's)."""
        state: S = self._record.STATE
        return state

    @property
    def record(self) -> R:
        """The record of the state it is in."""
        return self._record

    def go(self, event: StrEnum, record: R) -> None:
        """Change state by ``event`` (the table's), into ``record``, the new state's record;
        the old record is dropped.

        Raises:
            IllegalTransitionError: the table has no ``event`` from this state.
            TypeError: ``record`` is not the record of the state ``event`` leads to.
        """
        state = advance(self._table, self.state, event)
        if record.STATE is not state:
            raise TypeError(f"a {type(record).__name__} is not the record of {state.value!r}")
        self._record = record


# ---- on station, spare --------------------------------------------------------------------
@dataclass
class OnStation:
    """On the loop, in the formation.

    Attributes:
        relieved: the member whose slot it took, shared ``CLAIM_S`` after it did; else None.
        in_slot_t_s: when it took that slot (s).
        leave_t_s: when it must leave (s; None until its battery is known).
        beat_t_s: after a relief, its slot's next turn in the rotation (s).
        opening_steps: a staggered opening's first stint: this many beats / N early.
        opening_floor_s: ... and not before this (s; set at its first plan).
        late_said: spares whose late relief of it it has said (0: no spare at all).
        relievers: members heard flying in for it, this stint.
    """

    STATE: ClassVar[DutyState] = DutyState.ON_STATION
    relieved: int | None = None
    in_slot_t_s: float = -math.inf
    leave_t_s: float | None = None
    beat_t_s: float | None = None
    opening_steps: int = 0
    opening_floor_s: float | None = None
    late_said: set[int] = field(default_factory=set)
    relievers: set[int] = field(default_factory=set)

    def energy(self, battery_pct: float | None) -> Energy:
        """What it shares with ``battery_pct`` (%) left: its leave time, whom it relieved."""
        return Energy("on_station", battery_pct, self.leave_t_s, self.relieved or 0)


@dataclass
class Spare:
    """On the ground (``grounded``) or holding, waiting to be booked.

    Attributes:
        grounded: on the ground (no setpoint); else orbiting its holding point.
        ready_t_s: when it is charged (s; inf: out of the rotation).
        uncharged: past ``ready_t_s`` still short of the launch charge: unavailable.
    """

    STATE: ClassVar[DutyState] = DutyState.SPARE
    grounded: bool
    ready_t_s: float = 0.0
    uncharged: bool = False

    def energy(self, battery_pct: float | None) -> Energy:
        """What it shares with ``battery_pct`` (%) left: when it is ready, or that it is
        ``unavailable`` (out of the rotation, or short of charge)."""
        if math.isinf(self.ready_t_s) or self.uncharged:
            return Energy("unavailable", battery_pct, None, 0)
        return Energy("spare", battery_pct, self.ready_t_s, 0)


# ---- relieving ----------------------------------------------------------------------------
@dataclass
class Flight:
    """A relieving spare's flight from its launch on, shared by its stages after
    :class:`Committed`.

    Attributes:
        launch_t_s: when it launched (s).
        launch_pos_m: where (m).
        slot_since_t_s: since when it holds its member's slot (s), None if it does not.
        capture: the steering law flies it into the slot (with hysteresis).
        turn_sign: a big turn's direction, held through it (+1 right, -1 left; 0 none).
        laned: it has been in its lane: it turns in before the law takes it.
        reaim: its climb-out is over: choose the lane point again at the next step.
    """

    launch_t_s: float
    launch_pos_m: complex
    slot_since_t_s: float | None = None
    capture: bool = False
    turn_sign: float = 0.0
    laned: bool = False
    reaim: bool = False


@dataclass
class Committed:
    """Booked: it waits for its member's slot to come round.

    Attributes:
        since_t_s: when it was booked (s).
        grounded: on the ground (the spare's); else holding.
        ready_t_s: the spare's ready time, should it stand down (s).
    """

    STATE: ClassVar[RelievingStage] = RelievingStage.COMMITTED
    since_t_s: float
    grounded: bool
    ready_t_s: float


@dataclass
class TakingOff:
    """Asked its autopilot to take off at ``takeoff_pos_m`` (m); airborne once it moves.
    ``aim_m``: the lane point chosen at its launch (m), or None."""

    STATE: ClassVar[RelievingStage] = RelievingStage.TAKING_OFF
    flight: Flight
    takeoff_pos_m: complex
    aim_m: complex | None


@dataclass
class ToLane:
    """Flying straight to its lane point ``aim_m`` (m)."""

    STATE: ClassVar[RelievingStage] = RelievingStage.TO_LANE
    flight: Flight
    aim_m: complex


@dataclass
class ToLoop:
    """No lane point kept: the one that fits is chosen each step, or, none fitting (within
    its lane, inside the loop), the loop point where it meets its slot."""

    STATE: ClassVar[RelievingStage] = RelievingStage.TO_LOOP
    flight: Flight


@dataclass
class InLane:
    """Riding its lane to where it turns in behind its member's slot."""

    STATE: ClassVar[RelievingStage] = RelievingStage.IN_LANE
    flight: Flight


@dataclass
class FullTurn:
    """A full turn outward in its lane: ``left_rad`` (rad) still to turn, its heading at the
    last step ``heading_rad`` (rad); the direction is its flight's ``turn_sign``."""

    STATE: ClassVar[RelievingStage] = RelievingStage.FULL_TURN
    flight: Flight
    left_rad: float
    heading_rad: float


@dataclass
class Captured:
    """The steering law flies it into its member's slot. ``aim_m``: the lane point it flew
    to when captured, flown to again should the law let it go (m), or None."""

    STATE: ClassVar[RelievingStage] = RelievingStage.CAPTURED
    flight: Flight
    aim_m: complex | None


InFlight = TakingOff | ToLane | ToLoop | InLane | FullTurn | Captured
Stage = Committed | InFlight
"""A relieving spare's stage records."""


@dataclass
class Relieving:
    """Flying in (or about to) for ``member``, which must leave at ``leave_of_member_s`` (s);
    ``stage``: where it is on its way in."""

    STATE: ClassVar[DutyState] = DutyState.RELIEVING
    member: int
    leave_of_member_s: float
    stage: Staged[RelievingStage, Stage]

    @classmethod
    def committed(cls, member: int, leave_of_member_s: float, first: Committed) -> Relieving:
        """Booked for ``member`` at ``first.since_t_s``: its first stage, :class:`Committed`.

        Raises:
            TypeError: another stage's record.
        """
        if not isinstance(first, Committed):
            raise TypeError(f"a relief starts committed, not with a {type(first).__name__}")
        return cls(member, leave_of_member_s, Staged(RELIEVING_TABLE, first))

    def go(self, event: RelievingEvent, record: Stage) -> None:
        """Its next stage, by ``event`` (:data:`RELIEVING_TABLE`), with its record."""
        self.stage.go(event, record)

    def energy(self, battery_pct: float | None) -> Energy:
        """What it shares with ``battery_pct`` (%) left: whom it flies in for (booked)."""
        return Energy("relieving", battery_pct, None, self.member or 0)


# ---- going home ---------------------------------------------------------------------------
@dataclass
class Riding:
    """Relieved by ``behind``: it rides the loop until ``until_s`` (s, its leave time),
    dropping back behind it; it last looked for a crossing at ``cross_t_s`` (s)."""

    STATE: ClassVar[HomeStage] = HomeStage.RIDING
    until_s: float
    behind: int
    cross_t_s: float = -math.inf


@dataclass
class Crossing:
    """Flying to ``point_m`` (m), where it crosses the loop behind a member."""

    STATE: ClassVar[HomeStage] = HomeStage.CROSSING
    point_m: complex


@dataclass
class OutToLane:
    """Straight out to its lane, its sensor off the loop beside it."""

    STATE: ClassVar[HomeStage] = HomeStage.OUT


@dataclass
class StraightHome:
    """Straight to the nearest base, where it lands."""

    STATE: ClassVar[HomeStage] = HomeStage.STRAIGHT


HomeRecord = Riding | Crossing | OutToLane | StraightHome
"""A relieved UAV's stage records."""


@dataclass
class GoingHome:
    """Out of the formation, on its way to land; ``stage``: how it leaves the loop."""

    STATE: ClassVar[DutyState] = DutyState.HOME
    stage: Staged[HomeStage, HomeRecord]

    @classmethod
    def starting(cls, first: HomeRecord) -> GoingHome:
        """Its way home, starting with ``first``: :class:`Riding` (relieved by a spare) or
        :class:`StraightHome` (at its leave time, or turned back on its way in).

        Raises:
            TypeError: another stage's record.
        """
        if first.STATE not in (HomeStage.RIDING, HomeStage.STRAIGHT):
            raise TypeError(f"a way home does not start with a {type(first).__name__}")
        return cls(Staged(HOME_TABLE, first))

    def go(self, event: HomeEvent, record: HomeRecord) -> None:
        """Its next stage, by ``event`` (:data:`HOME_TABLE`), with its record."""
        self.stage.go(event, record)

    def energy(self, battery_pct: float | None) -> Energy:
        """What it shares with ``battery_pct`` (%) left."""
        return Energy("home", battery_pct, None, 0)


DutyRecord = OnStation | Spare | Relieving | GoingHome
"""A duty state's record."""
