"""The one place where MAVLink 2 messages become bytes and bytes become messages.

Everything else in :mod:`sitl_model` builds pymavlink message objects (plain data) through
``dialect`` and hands them to an :class:`Encoder`; received datagrams go through
:meth:`Decoder.decode`. The dialect is ArduPilot's ``ardupilotmega`` (a superset of
``common``) in its MAVLink 2 form.

With a :class:`~companion.contracts.signing.FrameCheck` (``--signing-key-file``) an encoder signs
every frame and a decoder accepts only correctly signed, fresh frames; the refused ones are
listed in :attr:`Decoder.rejected` (not counted as bad data).

Where nobody reads the bytes (the in-memory engine, unsigned), :meth:`Encoder.pass_on` and
:func:`as_received` stand for a pack and a decode: the message object itself crosses, with
the header a decode would give it and its fields as the wire carries them (``float``
fields rounded to float32, ``char`` fields cut to their length), so the receiver reads the
same values as from the frame, bit for bit.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable
from operator import itemgetter
from typing import TYPE_CHECKING, Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import ardupilotmega as dialect

if TYPE_CHECKING:  # the signing check is passed in; only its type is named here
    from companion.contracts.signing import FrameCheck, Rejected

__all__ = ["Decoder", "Encoder", "as_received", "dialect", "one_frame"]

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
        mav = self._mav
        if self._signing is not None:
            self._signing.stamp(mav)
        data = bytes(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256  # what MAVLink.send does after packing
        return data

    def pass_on(self, msg: dialect.MAVLink_message) -> dialect.MAVLink_message:
        """``msg`` as the receiver of :meth:`pack`'s frame would decode it, without the frame
        (consumes one sequence number; changes ``msg`` in place, see :func:`as_received`).

        Raises:
            ValueError: this encoder signs (a signature needs the bytes).
        """
        if self._signing is not None:
            raise ValueError("a signed link carries bytes: use pack()")
        mav = self._mav
        seq = mav.seq
        mav.seq = (seq + 1) % 256
        return as_received(msg, mav.srcSystem, mav.srcComponent, seq)


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


class _WirePlan:
    """What the wire does to the fields of one message type (see :func:`as_received`)."""

    __slots__ = ("chars", "float_arrays", "floats", "get_floats", "pack", "rest", "unpack")

    def __init__(self, cls: type) -> None:
        # array_lengths is in wire order (ordered_fieldnames), fieldtypes in fieldnames order
        length = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
        floats: list[str] = []
        self.float_arrays: list[tuple[str, struct.Struct]] = []
        self.chars: list[tuple[str, int]] = []
        for name, typ in zip(cls.fieldnames, cls.fieldtypes, strict=True):
            n = length[name]
            if typ == "float" and n:
                self.float_arrays.append((name, struct.Struct(f"<{n}f")))
            elif typ == "float":
                floats.append(name)
            elif typ == "char":
                self.chars.append((f"_{name}_raw", n))
        self.floats = tuple(floats)
        self.get_floats = itemgetter(*floats) if len(floats) > 1 else _one(floats)
        packer = struct.Struct(f"<{len(floats)}f")
        self.pack, self.unpack = packer.pack, packer.unpack
        self.rest = bool(self.float_arrays or self.chars)


def _one(names: list[str]) -> Callable[[dict[str, Any]], tuple[Any, ...]]:
    """A getter of the values of at most one name, as a tuple (what itemgetter gives two)."""
    if not names:
        return lambda _d: ()
    name = names[0]
    return lambda d: (d[name],)


_PLANS: dict[type, _WirePlan] = {}
_Header = dialect.MAVLink_header


def as_received(
    msg: dialect.MAVLink_message, sysid: int, compid: int, seq: int, copy: bool = False
) -> dialect.MAVLink_message:
    """``msg`` as a MAVLink 2 decoder would return it from the unsigned frame that
    ``sysid``/``compid`` packs with sequence number ``seq``: the header (source, sequence;
    no length, CRC or frame), every ``float`` field rounded to float32 and every ``char``
    field cut to its length, as pymavlink's pack and decode leave them. Integer fields are
    passed as they are (the simulator and the companion give ints in range).

    Args:
        msg: a pymavlink message object, as its constructor made it (never packed).
        sysid, compid: the sender's system and component ids.
        seq: the frame's sequence number (0-255).
        copy: leave ``msg`` unchanged and return a new object (a sender that keeps what
            it sent); False changes ``msg`` in place (its header's source and sequence,
            its fields) and returns it.
    """
    cls = type(msg)
    plan = _PLANS.get(cls)
    if plan is None:
        plan = _PLANS[cls] = _WirePlan(cls)
    if copy:
        new = object.__new__(cls)
        new.__dict__.update(msg.__dict__)
        msg = new
        msg._header = _Header(cls.id, 0, 0, 0, seq, sysid, compid)
    else:  # the header its constructor made, (msgId, 0, 0, 0, 0, 0, 0)
        h = msg._header
        h.seq, h.srcSystem, h.srcComponent = seq, sysid, compid
    if plan.floats:
        fields = msg.__dict__
        values = plan.unpack(plan.pack(*plan.get_floats(fields)))
        fields.update(zip(plan.floats, values, strict=False))  # as many: strict costs 0.4 us
    if plan.rest:
        _arrays_and_chars(msg, plan)
    return msg


def _arrays_and_chars(msg: dialect.MAVLink_message, plan: _WirePlan) -> None:
    """:func:`as_received`'s float arrays (float32) and texts (cut to their length)."""
    for name, packer in plan.float_arrays:
        values = getattr(msg, name)[: packer.size // 4]
        setattr(msg, name, list(packer.unpack(packer.pack(*values))))
    for raw_name, n in plan.chars:
        raw = getattr(msg, raw_name)
        if len(raw) > n:  # cut as the frame cuts it (shorter texts read the same)
            text_name = raw_name[1:-4]
            raw = raw[:n].rstrip(b"\x00")
            setattr(msg, raw_name, raw)
            setattr(msg, text_name, raw.split(b"\x00", 1)[0].decode("ascii", errors="replace"))
