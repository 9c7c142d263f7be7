"""Where the perimeter sits in an autopilot's stored mission (pure, no I/O).

ArduPilot reserves mission item 0 for home: whatever item 0 an upload sends is overwritten
by home, a download returns home there (a NAV_WAYPOINT at the home location) and AUTO never
flies it. PX4 and other autopilots store item 0 as sent. The autopilot is told apart by the
``autopilot`` field (MAV_AUTOPILOT) of its HEARTBEAT, so one rule serves ``companion upload``
(where to put the perimeter) and ``companion run`` without ``--mission`` (which items form
the loop).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, TypeVar

MAV_AUTOPILOT_GENERIC = 0
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_AUTOPILOT_PX4 = 12
NAV_WAYPOINT = 16  # MAV_CMD_NAV_WAYPOINT


class _Item(Protocol):
    seq: int
    command: int
    x: int
    y: int


ItemT = TypeVar("ItemT", bound=_Item)


def home_in_item0(autopilot: int | None) -> bool:
    """Whether an autopilot of this MAV_AUTOPILOT type keeps home in mission item 0."""
    return autopilot == MAV_AUTOPILOT_ARDUPILOTMEGA


def first_seq(autopilot: int | None) -> int:
    """The mission seq of the perimeter's first waypoint: 1 after ArduPilot's home, else 0."""
    return 1 if home_in_item0(autopilot) else 0


def convention(autopilot: int | None) -> str:
    """A short name of the autopilot's mission convention, for reports."""
    if home_in_item0(autopilot):
        return "ArduPilot: item 0 is home"
    if autopilot == MAV_AUTOPILOT_PX4:
        return "PX4: no home item"
    if autopilot is None:
        return "unknown autopilot: no home item"
    return f"autopilot type {autopilot}: no home item"


def loop_items(items: Sequence[ItemT], autopilot: int | None) -> list[ItemT]:
    """The stored items that form the patrol loop: every NAV_WAYPOINT with a position
    (lat/lon not both 0), without item 0 when it is ArduPilot's home."""
    skip = 0 if home_in_item0(autopilot) else -1
    return [
        it
        for it in items
        if it.seq != skip and it.command == NAV_WAYPOINT and (it.x != 0 or it.y != 0)
    ]
