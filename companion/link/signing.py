"""MAVLink 2 signing of the autopilot link (pure): the check of received frames.

Used on both ends of a companion <-> autopilot link: by :mod:`companion.link.connection`
(and ``companion upload``) on a pymavlink connection, and by the simulator's codec
(:mod:`sitl_model.codec`) for every vehicle endpoint. The signing state itself (32-byte key,
link id, strictly increasing timestamps in 10 us units since 2015-01-01 UTC, optionally
persisted) is the group's :class:`companion.group.codec.Signing`; key files are read by
:mod:`companion.group.keys` (same format and permission checks as the group key).

A received frame is accepted when it is a signed MAVLink 2 frame whose signature is right
for the key and whose timestamp is strictly newer than the last accepted one of its stream
``(system id, component id, link id)``; the first frame of a stream must be at most 60 s
behind our own signing time (MAVLink's rule). The stream table is updated only after the
signature has been verified: pymavlink's own ``check_signature`` records the timestamp
first, so a forged frame with a far-future timestamp would lock the real sender out.
:meth:`FrameCheck.install` puts this check in place of pymavlink's on a ``MAVLink`` object.

Unsigned frames are refused except RADIO_STATUS and RADIO, which a telemetry radio injects
and cannot sign (ArduPilot accepts exactly these unsigned). Rejections are counted by
reason: ``unsigned`` (including MAVLink 1 frames), ``bad_signature``, ``replayed``.
"""

from __future__ import annotations

import hmac
import struct
from dataclasses import dataclass
from typing import Any, Literal, get_args

from companion.group.codec import NEW_STREAM_WINDOW, Signing

__all__ = [
    "ACCEPT_UNSIGNED",
    "COMPANION_LINK_ID",
    "REJECT_REASONS",
    "FrameCheck",
    "RejectReason",
    "Rejected",
]

COMPANION_LINK_ID = 0  # link id of the companion's frames to its autopilot (its only link)
MSG_ID_RADIO_STATUS = 109
MSG_ID_RADIO = 166
ACCEPT_UNSIGNED: frozenset[int] = frozenset({MSG_ID_RADIO_STATUS, MSG_ID_RADIO})

MAGIC_V2 = 0xFD
IFLAG_SIGNED = 0x01
HEADER_LEN_V2 = 10
CRC_LEN = 2
SIGNATURE_LEN = 13  # link id (1) + timestamp (6) + signature (6)

RejectReason = Literal["unsigned", "bad_signature", "replayed"]
REJECT_REASONS: tuple[RejectReason, ...] = get_args(RejectReason)


@dataclass(frozen=True)
class Rejected:
    """A frame refused by the signing check: why, and who it claims to come from."""

    reason: RejectReason
    sysid: int
    compid: int
    msg_id: int


def _header(frame: bytes) -> tuple[bool, bool, int, int, int]:
    """(MAVLink 2, signed, sysid, compid, msg id) of a frame (zeros where it is too short)."""
    if len(frame) >= HEADER_LEN_V2 and frame[0] == MAGIC_V2:
        _m, _l, iflags, _c, _s, sysid, compid, lo, hi = struct.unpack_from("<BBBBBBBHB", frame)
        return True, bool(iflags & IFLAG_SIGNED), sysid, compid, lo | hi << 16
    if len(frame) >= 6 and frame[0] == 0xFE:  # MAVLink 1: never signed
        return False, False, frame[3], frame[4], frame[5]
    return False, False, 0, 0, 0


class FrameCheck:
    """Signature and replay check of the frames one endpoint receives; counts rejections.

    Args:
        signing: the endpoint's signing state (key, link id, timestamps); a valid received
            timestamp raises its timestamp too (MAVLink's rule).
        accept_unsigned: message ids accepted without a (valid) signature.
    """

    def __init__(self, signing: Signing, accept_unsigned: frozenset[int] = ACCEPT_UNSIGNED):
        """A check with an empty stream table and zero counts."""
        self.signing = signing
        self.accept_unsigned = accept_unsigned
        self.streams: dict[tuple[int, int, int], int] = {}  # (sysid, compid, link) -> ts
        self.counts: dict[str, int] = {"accepted": 0, **dict.fromkeys(REJECT_REASONS, 0)}

    def verdict(self, frame: bytes | bytearray) -> RejectReason | None:
        """Why ``frame`` (one whole frame, CRC already checked) is refused; None if it is good.

        Pure: nothing is recorded (see :meth:`accept`).
        """
        v2, signed, sysid, compid, _msg = _header(frame)
        if not (v2 and signed) or len(frame) < HEADER_LEN_V2 + CRC_LEN + SIGNATURE_LEN:
            return "unsigned"
        body, sig = bytes(frame[:-6]), bytes(frame[-6:])
        if not hmac.compare_digest(self.signing.signature(body), sig):
            return "bad_signature"
        link = frame[-SIGNATURE_LEN]
        ts = int.from_bytes(frame[-12:-6], "little")
        last = self.streams.get((sysid, compid, link))
        if last is not None and ts <= last:
            return "replayed"
        if last is None and ts + NEW_STREAM_WINDOW < self.signing.now():
            return "replayed"  # a new stream more than a minute old
        return None

    def accept(self, frame: bytes | bytearray) -> None:
        """Record a frame that passed :meth:`verdict`: its stream's timestamp, our clock."""
        _v2, _signed, sysid, compid, _msg = _header(frame)
        ts = int.from_bytes(frame[-12:-6], "little")
        self.streams[(sysid, compid, frame[-SIGNATURE_LEN])] = ts
        self.signing.observe(ts)
        self.counts["accepted"] += 1

    def rejected(self, frame: bytes | bytearray) -> Rejected:
        """Count a frame that pymavlink refused for its signature and say why."""
        _v2, signed, sysid, compid, msg_id = _header(frame)
        reason: RejectReason = "unsigned"
        if signed:
            reason = self.verdict(frame) or "bad_signature"
        self.counts[reason] += 1
        return Rejected(reason, sysid, compid, msg_id)

    def rejects(self) -> int:
        """Frames refused so far, all reasons."""
        return sum(self.counts[r] for r in REJECT_REASONS)

    # ---- pymavlink hooks --------------------------------------------------------------------
    def check_signature(self, msgbuf: bytearray, src_system: int, src_component: int) -> bool:
        """pymavlink's ``MAVLink.check_signature`` signature: accept and record, or refuse."""
        if self.verdict(msgbuf) is not None:
            return False
        self.accept(msgbuf)
        return True

    def allow_unsigned(self, _mav: Any, msg_id: int) -> bool:
        """pymavlink's ``allow_unsigned_callback``: RADIO_STATUS and RADIO only."""
        return msg_id in self.accept_unsigned

    def install(self, mav: Any) -> None:
        """Sign what ``mav`` (a pymavlink ``MAVLink``) sends and check what it receives.

        Outgoing timestamps are set per frame by :meth:`stamp` (call it before each send).
        """
        mav.signing.secret_key = self.signing.key
        mav.signing.link_id = self.signing.link_id
        mav.signing.sign_outgoing = True
        mav.signing.allow_unsigned_callback = self.allow_unsigned
        mav.signing.timestamp = self.signing.now()
        mav.check_signature = self.check_signature  # ours, in place of pymavlink's

    def stamp(self, mav: Any) -> None:
        """Give ``mav``'s next outgoing frame a fresh timestamp from the signing state.

        pymavlink counts up by one per frame from the last stamp, so frames sent on ``mav``
        directly in between are taken into account.
        """
        self.signing.observe(mav.signing.timestamp - 1)
        mav.signing.timestamp = self.signing.next_timestamp()
