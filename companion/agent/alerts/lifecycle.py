"""An alert's status as a table keyed by (status, event) (pure; :mod:`companion.agent.machine`).

Every companion keeps one :class:`~companion.agent.alerts.record.AlertRecord` per distinct
alert; its status is never on the wire. A record starts ``queued``; ``done`` is final.

=========== =================================================================================
status      meaning
=========== =================================================================================
queued      waiting for a prosecutor (in (time, id) order)
bidding     the "fastest" policy collects the free members' bids
tasked      a member was chosen and is not yet seen away for it
under_way   its prosecutor flies to it (this UAV, or a member seen prosecuting it)
tracked     a member stays over the intruder (policy track), out of the formation
done        cleared (the site checked, the operator's cancel), or refused by the fence
=========== =================================================================================

================= ================================================================ ==========
event             what happened                                                    from
================= ================================================================ ==========
auction_opened    the "fastest" policy opens its auction                            Q
tasked            tasked to another member (the policy's choice)                    Q B
tasked_self       tasked to this UAV: under way at once                             Q B
seen_under_way    a member is seen prosecuting it                                   Q B T U
taken_over_tasked an earlier report of its site replaces it, with that tasking      Q
taken_over_away   ... with that prosecutor under way                                Q
confirmed         seen again by its sender: the next UAV takes it (hand-off)        Q B T U
task_lapsed       the tasked member was never seen away for it                     T
prosecutor_lost   its prosecutor, tasked member or tracker left the formation       T U K
tracking_seen     a member is seen tracking it                                      Q B T U K
cleared           the site checked and clear, a report of it cleared, the operator  Q B T U K
lost              its tracker lost it, or it left the fence                         Q B T U K
refused           the geofence rules the site out                                   Q B
================= ================================================================ ==========

Where each event leads is :data:`ALERT_TABLE`; any other (status, event) pair raises.
"""

from __future__ import annotations

from enum import StrEnum

from companion.agent.machine import IllegalTransitionError, advance

__all__ = [
    "ALERT_TABLE",
    "OPEN",
    "TAKEN",
    "WAITING",
    "AlertEvent",
    "AlertStatus",
    "IllegalTransitionError",
    "next_status",
]


class AlertStatus(StrEnum):
    """Where one alert is in its prosecution (see the module's table)."""

    QUEUED = "queued"
    BIDDING = "bidding"
    TASKED = "tasked"
    UNDER_WAY = "under_way"
    TRACKED = "tracked"
    DONE = "done"


class AlertEvent(StrEnum):
    """What moves an alert's status (see the module's table)."""

    AUCTION_OPENED = "auction_opened"
    TASKED = "tasked"
    TASKED_SELF = "tasked_self"
    SEEN_UNDER_WAY = "seen_under_way"
    TAKEN_OVER_TASKED = "taken_over_tasked"
    TAKEN_OVER_AWAY = "taken_over_away"
    CONFIRMED = "confirmed"
    TASK_LAPSED = "task_lapsed"
    PROSECUTOR_LOST = "prosecutor_lost"
    TRACKING_SEEN = "tracking_seen"
    CLEARED = "cleared"
    LOST = "lost"
    REFUSED = "refused"


_Q, _B, _T, _U, _K, _D = (
    AlertStatus.QUEUED,
    AlertStatus.BIDDING,
    AlertStatus.TASKED,
    AlertStatus.UNDER_WAY,
    AlertStatus.TRACKED,
    AlertStatus.DONE,
)
_E = AlertEvent

ALERT_TABLE: dict[tuple[AlertStatus, AlertEvent], AlertStatus] = {
    (_Q, _E.AUCTION_OPENED): _B,
    (_Q, _E.TASKED): _T,
    (_B, _E.TASKED): _T,
    (_Q, _E.TASKED_SELF): _U,
    (_B, _E.TASKED_SELF): _U,
    (_Q, _E.SEEN_UNDER_WAY): _U,
    (_B, _E.SEEN_UNDER_WAY): _U,
    (_T, _E.SEEN_UNDER_WAY): _U,
    (_U, _E.SEEN_UNDER_WAY): _U,  # another member now seen prosecuting it
    (_Q, _E.TAKEN_OVER_TASKED): _T,
    (_Q, _E.TAKEN_OVER_AWAY): _U,
    (_Q, _E.CONFIRMED): _Q,  # a confirmation heard before the alert itself
    (_B, _E.CONFIRMED): _Q,  # bid again for the next UAV
    (_T, _E.CONFIRMED): _Q,
    (_U, _E.CONFIRMED): _Q,  # the hand-off
    (_T, _E.TASK_LAPSED): _Q,
    (_T, _E.PROSECUTOR_LOST): _Q,
    (_U, _E.PROSECUTOR_LOST): _Q,
    (_K, _E.PROSECUTOR_LOST): _Q,
    **{(s, _E.TRACKING_SEEN): _K for s in (_Q, _B, _T, _U, _K)},
    **{(s, _E.CLEARED): _D for s in (_Q, _B, _T, _U, _K)},
    **{(s, _E.LOST): _D for s in (_Q, _B, _T, _U, _K)},
    (_Q, _E.REFUSED): _D,
    (_B, _E.REFUSED): _D,
}

OPEN = frozenset({_Q, _B, _T, _U, _K})  # not done
WAITING = frozenset({_Q, _B})  # in the queue, no prosecutor
TAKEN = frozenset({_T, _U, _K})  # a prosecutor (or tracker) chosen


def next_status(status: AlertStatus, event: AlertEvent) -> AlertStatus:
    """The status after ``event`` (:data:`ALERT_TABLE`); raises
    :class:`IllegalTransitionError` for a pair not in it."""
    return advance(ALERT_TABLE, status, event)
