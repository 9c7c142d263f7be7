"""The operator as a member of the group (system id 255): an alert sent as copies, its
default id, and the vehicle time heard from the members. Used by ``companion alert`` and by
the dashboard's operator actions. Wall-clock waits here are operator plumbing, not flight
logic.
"""

from __future__ import annotations

import selectors
import time

from companion.contracts.signing import SIGNING_EPOCH_UNIX_S
from companion.group.codec import OPERATOR_SYSID
from companion.group.messages import Alert, MemberState
from companion.group.transport import Group

MAX_DISTANCE_M = 100_000.0  # an alert further than this from the origin is a typo


def send_copies(group: Group, alert: Alert, repeat: int, interval_s: float) -> int:
    """Send ``alert`` ``repeat`` times, ``interval_s`` (s) apart, with the same id and time
    (members merge repeats by id, so a lossy network still delivers it); datagrams sent.

    Used by ``companion alert`` and by the dashboard's operator actions.
    """
    before = group.stats["sent"]
    for i in range(repeat):
        if i:
            time.sleep(interval_s)
        group.send_alert(alert)
    return group.stats["sent"] - before


def listen_for_alert(group: Group, alert_id: str, listen_s: float) -> Alert | None:
    """Listen up to ``listen_s`` (s) for a message of alert ``alert_id`` (the members repeat
    the alerts they know); the first heard (not a bid), or None."""
    deadline = time.monotonic() + listen_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)
        while (left := deadline - time.monotonic()) > 0:
            sel.select(left)
            for msg in group.receive():
                if isinstance(msg, Alert) and msg.alert_id == alert_id and msg.state != "bid":
                    return msg
    return None


def default_alert_id(unix_s: float) -> str:
    """``"255-<seconds since 2015-01-01>"``: unique per operator second, 13 characters."""
    return f"{OPERATOR_SYSID}-{max(0, int(unix_s) - SIGNING_EPOCH_UNIX_S)}"


def listen_for_vehicle_time(group: Group, listen_s: float) -> tuple[float, int | None]:
    """Listen up to ``listen_s`` (s) for a member state; (vehicle time now s, its sysid).

    Returns ``(0.0, None)`` when no member was heard: time 0 = "on receipt".
    """
    if listen_s <= 0:
        return 0.0, None
    deadline = time.monotonic() + listen_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)
        while (left := deadline - time.monotonic()) > 0:
            sel.select(left)
            heard = time.monotonic()
            for msg in group.receive():
                if isinstance(msg, MemberState) and msg.t_s > 0:
                    return msg.t_s + (time.monotonic() - heard), msg.sysid
    return 0.0, None
