"""The autopilot link over a serial device: a pseudo-terminal pair stands in for the cable.

pymavlink opens ``/dev/...,BAUD`` URLs with pyserial, which it does not require itself: a
fresh install without it could not open a serial port ("No module named 'serial'"). Here the
companion's real :class:`~companion.link.connection.AutopilotLink` opens the slave end of a
pty at 921600 baud and an autopilot is played on the master end with pymavlink's encoder.
"""

from __future__ import annotations

import os
import select
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.connection import AutopilotLink

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(not hasattr(os, "openpty"), reason="no pseudo-terminals here"),
]


def _read_frames(fd: int, parser: mav.MAVLink, within_s: float) -> list:
    """Every MAVLink message the companion wrote to the master end within ``within_s``."""
    got: list = []
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            got.extend(parser.parse_buffer(os.read(fd, 4096)) or [])
    return got


def test_a_serial_device_opens_and_carries_mavlink_both_ways() -> None:
    """The link opens a serial device, hears the autopilot's heartbeat on it, learns its
    system id, and its own heartbeat comes back over the same wire."""
    master, slave = os.openpty()
    link = None
    try:
        link = AutopilotLink(f"{os.ttyname(slave)},921600", clock=time.monotonic)
        autopilot = mav.MAVLink(None, srcSystem=7, srcComponent=1)
        hb = autopilot.heartbeat_encode(
            mav.MAV_TYPE_FIXED_WING, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 15, 4
        )
        heard: list = []
        end = time.monotonic() + 5.0
        while not heard and time.monotonic() < end:
            os.write(master, hb.pack(autopilot))
            time.sleep(0.05)
            heard = [m for m in link.receive() if m.get_type() == "HEARTBEAT"]
        assert heard, "no heartbeat read from the serial device"
        assert link.sysid == 7
        link.tick()  # the companion's own heartbeat goes out on the wire
        parser = mav.MAVLink(None)
        parser.robust_parsing = True
        sent = _read_frames(master, parser, 1.0)
        assert any(m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 7 for m in sent)
    finally:
        if link is not None:
            link.close()
        os.close(master)
        os.close(slave)
