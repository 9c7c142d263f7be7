"""Reading a real autopilot's MAVLink link (ArduPlane or PX4 SITL): the messages waiting from
its autopilot component, shared by the bring-ups and the world process; closing a bring-up's
links."""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav


def autopilot_messages(conn: Any, sysid: int, limit: int | None = None) -> Iterator[Any]:
    """The messages waiting on ``conn`` (a pymavlink connection) from autopilot ``sysid``
    (component 1), in order, until none is waiting or the link fails; at most ``limit``
    messages read (the others' included) when given, so a busy link cannot hold the caller."""
    read = 0
    while limit is None or read < limit:
        read += 1
        try:
            m = conn.recv_msg()
        except (OSError, mav.MAVError):
            return
        if m is None:
            return
        if m.get_srcSystem() == sysid and m.get_srcComponent() == 1:
            yield m


def close_links(vehicles: Iterable[Any]) -> None:
    """Close each vehicle's ``conn`` (a pymavlink connection, or None) and set it to None."""
    for v in vehicles:
        if v.conn is not None:
            with contextlib.suppress(OSError):
                v.conn.close()
            v.conn = None
