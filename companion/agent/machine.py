"""State machines written as tables (pure), as h11's ``_state.py`` does.

A machine is one dict ``{(state, event): next state}``. :func:`advance` is the only way from
one state to the next: it looks the pair up, and a pair not in the table raises
:class:`IllegalTransitionError`. Two machines use it: an alert's status
(:mod:`companion.agent.alerts.lifecycle`) and a UAV's own mode (:mod:`companion.agent.modes`).

RULE: every change of state names the event that causes it, and the table says where the
event leads from the current state. An event the table does not list for the current state
is a bug in the caller ("we broke the protocol"), never bad input, so the error is not a
:class:`~companion.contracts.errors.UserError`. Staying in a state is a row of the table
like any other (``(UNDER_WAY, SEEN_UNDER_WAY) -> UNDER_WAY``), never implied.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum
from typing import TypeVar

S = TypeVar("S", bound=StrEnum)
Ev = TypeVar("Ev", bound=StrEnum)


class IllegalTransitionError(RuntimeError):
    """An event the table does not allow in the current state.

    Attributes:
        state: the state it was in.
        event: the event that was not allowed there.
    """

    def __init__(self, state: StrEnum, event: StrEnum) -> None:
        """Name the machine, the state and the event in the message."""
        super().__init__(
            f"illegal {type(state).__name__} event {event.value!r} in state {state.value!r}"
        )
        self.state = state
        self.event = event


def advance(table: Mapping[tuple[S, Ev], S], state: S, event: Ev) -> S:
    """The state after ``event`` in ``state``, by ``table``.

    Raises:
        IllegalTransitionError: ``(state, event)`` is not in the table.
        TypeError: ``state`` or ``event`` is not of the table's enumerations (a plain
            string, or a state of another machine that happens to share its value).
    """
    state_kind, event_kind = (type(x) for x in next(iter(table)))
    if type(state) is not state_kind or type(event) is not event_kind:
        raise TypeError(f"not a state and an event of this machine: {state!r}, {event!r}")
    try:
        return table[(state, event)]
    except KeyError:
        raise IllegalTransitionError(state, event) from None
