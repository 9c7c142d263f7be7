"""The one place where MAVLink 2 messages become bytes and bytes become messages.

Everything else in :mod:`sitl_model` builds pymavlink message objects (plain data) through
``dialect`` and hands them to an :class:`Encoder`; received datagrams go through
:func:`decode_datagram`. The dialect is ArduPilot's ``ardupilotmega`` (a superset of
``common``) in its MAVLink 2 form.
"""

from __future__ import annotations

import os

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import ardupilotmega as dialect

__all__ = ["Decoder", "Encoder", "dialect"]

MAV_COMP_ID_AUTOPILOT1 = dialect.MAV_COMP_ID_AUTOPILOT1
MAV_COMP_ID_CAMERA = dialect.MAV_COMP_ID_CAMERA


class Encoder:
    """Packs messages as one MAVLink 2 source (system id, component id) with its own sequence."""

    def __init__(self, sysid: int, compid: int) -> None:
        """Encoder for ``sysid``/``compid`` (1..255)."""
        self._mav = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)

    def pack(self, msg: dialect.MAVLink_message) -> bytes:
        """The wire bytes of ``msg`` (consumes one sequence number)."""
        return bytes(msg.pack(self._mav))


class Decoder:
    """Decodes whole UDP datagrams; a datagram never leaves state behind for the next one."""

    def __init__(self) -> None:
        """A robust parser: garbage yields ``BAD_DATA`` messages, never an exception."""
        self._mav = dialect.MAVLink(None)
        self._mav.robust_parsing = True

    def decode(self, data: bytes) -> tuple[list[dialect.MAVLink_message], int]:
        """Messages in ``data`` and the number of bad chunks (garbage, CRC or unknown id)."""
        mav = self._mav
        good: list[dialect.MAVLink_message] = []
        bad = 0
        try:
            msgs = mav.parse_buffer(data) or []
        except Exception:  # a malformed packet can still trip pymavlink's unpacking
            msgs = []
            bad += 1
        for m in msgs:
            if m.get_type() == "BAD_DATA":
                bad += 1
            else:
                good.append(m)
        if mav.buf_len() > 0:  # a truncated packet at the end of the datagram
            bad += 1
        mav.buf = bytearray()
        mav.buf_index = 0
        mav.expected_length = dialect.HEADER_LEN_V1 + 2
        mav.have_prefix_error = False
        return good, bad
