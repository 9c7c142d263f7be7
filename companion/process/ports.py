"""What the Runner's components may read of the things around them, as small protocols
(the autopilot link is :class:`companion.link.connection.AutopilotLink` in a run, a fake in
the tests)."""

from __future__ import annotations

from typing import Protocol


class LinkState(Protocol):
    """What a component reads of the autopilot link: who is at the other end and the link's
    counts. Components never send through it (they return what to send,
    :mod:`companion.process.sender`)."""

    sysid: int | None  # the autopilot's MAVLink system id (None: not heard yet)
    autopilot: int | None  # its HEARTBEAT's MAV_AUTOPILOT (None: not heard yet)
    counts: dict[str, int]  # rx, tx, reconnects, ...
    silent_s: float | None  # wall s without a heartbeat when the link was last lost
    last_outage_s: float | None  # wall s of the last outage, once the autopilot is heard again
    rates_hz: dict[str, float]  # the streams asked for (message name -> Hz), once it is up
