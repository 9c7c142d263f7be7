"""The one place where MAVLink 2 messages become bytes and bytes become messages.

Everything else in :mod:`sitl_model` builds pymavlink message objects (plain data) through
``dialect`` and hands them to an :class:`Encoder`; received datagrams go through
:meth:`Decoder.decode`. The dialect is ArduPilot's ``ardupilotmega`` (a superset of
``common``) in its MAVLink 2 form.

With a :class:`~companion.contracts.signing.FrameCheck` (``--signing-key-file``) an encoder signs
every frame and a decoder accepts only correctly signed, fresh frames; the refused ones are
listed in :attr:`Decoder.rejected` (not counted as bad data).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import ardupilotmega as dialect

if TYPE_CHECKING:  # the signing check is passed in; only its type is named here
    from companion.contracts.signing import FrameCheck, Rejected

__all__ = ["Decoder", "Encoder", "dialect", "one_frame"]

MAV_COMP_ID_AUTOPILOT1 = dialect.MAV_COMP_ID_AUTOPILOT1
MAV_COMP_ID_CAMERA = dialect.MAV_COMP_ID_CAMERA


class Encoder:
    """Packs messages as one MAVLink 2 source (system id, component id) with its own sequence."""

    def __init__(self, sysid: int, compid: int, signing: FrameCheck | None = None) -> None:
        """Encoder for ``sysid``/``compid`` (1..255); signs every frame if ``signing``."""
        self._mav = dialect.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self._signing = signing
        if signing is not None:
            signing.install(self._mav)

    def pack(self, msg: dialect.MAVLink_message) -> bytes:
        """The wire bytes of ``msg`` (consumes one sequence number)."""
        if self._signing is not None:
            self._signing.stamp(self._mav)
        return bytes(msg.pack(self._mav))


class Decoder:
    """Decodes whole UDP datagrams; a datagram never leaves state behind for the next one."""

    def __init__(self, signing: FrameCheck | None = None) -> None:
        """A robust parser: garbage yields ``BAD_DATA`` messages, never an exception.

        With ``signing``, frames that fail its check are refused and listed in
        :attr:`rejected` by the latest :meth:`decode`.
        """
        self._mav = dialect.MAVLink(None)
        self._mav.robust_parsing = True
        self.signing = signing
        self.rejected: list[Rejected] = []
        if signing is not None:
            signing.install(self._mav)

    def decode(self, data: bytes) -> tuple[list[dialect.MAVLink_message], int]:
        """Messages in ``data`` and the number of bad chunks (garbage, CRC or unknown id)."""
        mav = self._mav
        good: list[dialect.MAVLink_message] = []
        bad = 0
        self.rejected = []
        try:
            if one_frame(data):
                # pymavlink's parser, given exactly one whole frame, decodes it (CRC,
                # signature, unpacking) and turns a MAVError into BAD_DATA: the same here,
                # without stepping its state machine through the buffer
                frame = bytearray(data)
                try:
                    msgs = [mav.decode(frame)]
                except dialect.MAVError as exc:
                    msgs = [dialect.MAVLink_bad_data(frame, exc.message)]
            else:
                msgs = mav.parse_buffer(data) or []
        except Exception:  # a malformed packet can still trip pymavlink's unpacking
            msgs = []
            bad += 1
        for m in msgs:
            if isinstance(m, dialect.MAVLink_unknown):
                bad += 1  # an id the dialect lacks: pymavlink returns it without a CRC check
            elif m.get_type() != "BAD_DATA":
                good.append(m)
            elif self.signing is not None and _signature_refusal(m):
                self.rejected.append(self.signing.rejected(m.data))
            else:
                bad += 1
        if mav.buf_len() > 0:  # a truncated packet at the end of the datagram
            bad += 1
        mav.buf = bytearray()
        mav.buf_index = 0
        mav.expected_length = dialect.HEADER_LEN_V1 + 2
        mav.have_prefix_error = False
        return good, bad


def one_frame(data: bytes) -> bool:
    """Whether ``data`` is exactly one MAVLink 2 frame by its header (length and flags)."""
    n = len(data)
    if n < 12 or data[0] != 0xFD or data[2] & ~1:
        return False
    return n == 12 + data[1] + (13 if data[2] & 1 else 0)


def _signature_refusal(m: Any) -> bool:
    """Whether a ``BAD_DATA`` is a whole frame pymavlink refused for its signature."""
    return getattr(m, "reason", "") == "Invalid signature"
