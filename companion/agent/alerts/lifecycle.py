"""The alert lifecycle and the UAV's own mode as transition tables (pure; no I/O, no clocks).

Two small state machines, each one table of the legal ``(before, after)`` pairs, each pair
with the cause that takes it. :func:`transition` is the only way from one state to another:
it returns the new state, or raises :class:`IllegalTransitionError` for a pair not in its table.
Staying in a state is not a transition (the table has no ``(s, s)`` pairs).

Alert status (one :class:`~companion.agent.records.AlertRecord` per distinct alert, kept by
every companion; never on the wire):

=========== =================================================================================
state       meaning
=========== =================================================================================
queued      waiting for a prosecutor (in (time, id) order)
bidding     the "fastest" policy collects the free members' bids
tasked      a member was chosen and is not yet seen away for it
under_way   its prosecutor flies to it (this UAV, or a member seen prosecuting it)
done        cleared (the site checked, the operator's cancel), or refused by the fence
=========== =================================================================================

A record starts ``queued``; ``done`` is final. A confirmation (the intruder seen again) sends
an open alert back to ``queued`` for the next UAV.

Own mode (one per UAV; ``AgentOutput.mode``; shared on the group as "patrol", "prosecuting"
and "virtual"):

=========== =================================================================================
state       meaning
=========== =================================================================================
patrol      on the loop, steered by the time-splay law
prosecuting flying the minimum-time path to an alert's site, sharing its virtual particle
rejoining   flying back into its slot, still sharing its virtual particle
=========== =================================================================================
"""

from __future__ import annotations

from enum import StrEnum
from typing import TypeVar, overload


class IllegalTransitionError(RuntimeError):
    """A state change its table does not allow: a bug in the caller ("we broke the
    protocol"), not bad input, so not a ``companion.contracts.errors.UserError``.

    Attributes:
        before: the state it was in.
        after: the state asked for.
    """

    def __init__(self, before: StrEnum, after: StrEnum) -> None:
        """Name the machine and both states in the message."""
        super().__init__(
            f"illegal {type(before).__name__} transition {before.value!r} -> {after.value!r}"
        )
        self.before = before
        self.after = after


class AlertStatus(StrEnum):
    """Where one alert is in its prosecution (see the module's table)."""

    QUEUED = "queued"
    BIDDING = "bidding"
    TASKED = "tasked"
    UNDER_WAY = "under_way"
    DONE = "done"


class OwnMode(StrEnum):
    """What this UAV is doing (see the module's table); the value is ``AgentOutput.mode``."""

    PATROL = "patrol"
    PROSECUTING = "prosecuting"
    REJOINING = "rejoining"


_Q, _B, _T, _U, _D = (
    AlertStatus.QUEUED,
    AlertStatus.BIDDING,
    AlertStatus.TASKED,
    AlertStatus.UNDER_WAY,
    AlertStatus.DONE,
)

# (before, after) -> what takes it
ALERT_TRANSITIONS: dict[tuple[AlertStatus, AlertStatus], str] = {
    (_Q, _B): "the fastest policy opens its auction",
    (_Q, _T): "tasked to another member (or an earlier report of its site takes over)",
    (_Q, _U): "tasked to this UAV, or a member seen prosecuting it",
    (_Q, _D): "cleared, a report of its site cleared, or refused by the fence",
    (_B, _Q): "confirmed: bid again for the next UAV",
    (_B, _T): "the auction chose another member",
    (_B, _U): "the auction chose this UAV, or a member seen prosecuting it",
    (_B, _D): "cleared, or a report of its site cleared",
    (_T, _Q): "the tasked member never left or left the formation, or confirmed",
    (_T, _U): "the tasked member (or another) seen prosecuting it",
    (_T, _D): "cleared, or a report of its site cleared",
    (_U, _Q): "its prosecutor confirmed the intruder (hand-off) or left the formation",
    (_U, _D): "cleared: the site checked, the operator's cancel",
}

_P, _X, _R = OwnMode.PATROL, OwnMode.PROSECUTING, OwnMode.REJOINING

MODE_TRANSITIONS: dict[tuple[OwnMode, OwnMode], str] = {
    (_P, _X): "tasked to an alert",
    (_X, _R): "the intruder re-detected, the path's end, or the alert cleared by another",
    (_R, _P): "back in its slot (or timed out), or at once under rejoin 'direct'",
}

OPEN = frozenset({_Q, _B, _T, _U})  # not done
WAITING = frozenset({_Q, _B})  # in the queue, no prosecutor
TAKEN = frozenset({_T, _U})  # a prosecutor chosen

_TABLES: dict[type, dict] = {AlertStatus: ALERT_TRANSITIONS, OwnMode: MODE_TRANSITIONS}

S = TypeVar("S", AlertStatus, OwnMode)


@overload
def transition(before: AlertStatus, after: AlertStatus) -> AlertStatus: ...
@overload
def transition(before: OwnMode, after: OwnMode) -> OwnMode: ...
def transition(before: S, after: S) -> S:
    """The state after a change from ``before`` to ``after``, checked against its table.

    Args:
        before: the current state (an :class:`AlertStatus` or an :class:`OwnMode`).
        after: the state asked for, of the same machine.

    Returns:
        ``after``, when ``(before, after)`` is in the machine's table.

    Raises:
        IllegalTransitionError: the pair is not in the table (staying put included).
        TypeError: the states are not both of one machine.
    """
    table = _TABLES.get(type(before))
    if table is None or type(after) is not type(before):
        raise TypeError(f"not states of one machine: {before!r}, {after!r}")
    if (before, after) not in table:
        raise IllegalTransitionError(before, after)
    return after
