"""MAVLink 2 signing (pure): the signing state and the check of received frames.

One module for every signed link: the group (:mod:`companion.group.codec`), the companion's
autopilot link (:mod:`companion.link.connection`, ``companion upload``) and the simulator's
vehicle endpoints (:mod:`sitl_model.codec`, :mod:`sitl_model.server`). No sockets and no
clock reads: the wall clock is injected (``clock() -> unix seconds``); key files are read by
:mod:`companion.group.keys` (an edge).

* :class:`Signing` is one endpoint's signing state: the 32-byte key, the link id and the
  strictly increasing timestamp (10 us units since 2015-01-01 UTC). An optional
  :class:`TimestampStore` keeps a persisted upper bound so a restarted sender starts above
  every timestamp it ever used (see ``docs/protocol.md``).
* :class:`FrameCheck` checks the frames one endpoint receives.

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

import functools
import hashlib
import hmac
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal, Protocol, get_args

__all__ = [
    "ACCEPT_UNSIGNED",
    "COMPANION_LINK_ID",
    "GROUP_LINK_ID",
    "LEASE",
    "NEW_STREAM_WINDOW",
    "REJECT_REASONS",
    "SIGNING_EPOCH_UNIX_S",
    "VEHICLE_LINK_ID",
    "FrameCheck",
    "RejectReason",
    "Rejected",
    "Signing",
    "TimestampStore",
    "signing_time",
]

# MAVLink signing timestamps: 10 us units since 2015-01-01 00:00:00 UTC.
SIGNING_EPOCH_UNIX_S = 1_420_070_400
SIGNING_UNITS_PER_S = 100_000
# A stream seen for the first time is accepted only if its timestamp is at most this far
# behind the receiver's own (MAVLink's rule, one minute).
NEW_STREAM_WINDOW = 60 * SIGNING_UNITS_PER_S
# A sender persists an upper bound this far ahead of the timestamp it uses, so it writes the
# state file about once a minute, not per packet.
LEASE = 60 * SIGNING_UNITS_PER_S

# Signing link ids, one per kind of link.
GROUP_LINK_ID = 80  # the group ('P'); see docs/protocol.md
COMPANION_LINK_ID = 0  # the companion's frames to its autopilot (its only link)
VEHICLE_LINK_ID = 1  # a simulated vehicle's port (ArduPilot: the serial channel)

MSG_ID_RADIO_STATUS = 109
MSG_ID_RADIO = 166
ACCEPT_UNSIGNED: frozenset[int] = frozenset({MSG_ID_RADIO_STATUS, MSG_ID_RADIO})

MAGIC_V2 = 0xFD
IFLAG_SIGNED = 0x01
HEADER_LEN = 10  # MAVLink 2
CRC_LEN = 2
SIGNATURE_LEN = 13  # link id (1) + timestamp (6) + signature (6)
SIGNATURE_MEMO = 1024  # signatures remembered (a step's group datagrams, many times over)

RejectReason = Literal["unsigned", "bad_signature", "replayed"]
REJECT_REASONS: tuple[RejectReason, ...] = get_args(RejectReason)


class TimestampStore(Protocol):
    """Persistence of a sender's signing-timestamp upper bound (10 us units since 2015)."""

    def load(self) -> int:
        """The persisted upper bound, 0 if there is none yet."""
        ...

    def save(self, timestamp: int) -> None:
        """Persist ``timestamp`` durably before it is relied on."""
        ...


def signing_time(unix_s: float) -> int:
    """A wall-clock time (unix s) as a MAVLink signing timestamp (10 us since 2015), >= 0."""
    return max(0, int((unix_s - SIGNING_EPOCH_UNIX_S) * SIGNING_UNITS_PER_S))


class Signing:
    """MAVLink 2 signing state shared by a process's encoder and decoder.

    Outgoing timestamps follow MAVLink's rule, ``max(last + 1, wall clock)``, where ``last``
    also rises to every valid timestamp received. With a ``store``, the sender starts
    strictly above the persisted bound and persists ``timestamp + LEASE`` before it uses a
    timestamp at or above the bound, so no timestamp is ever reused after a restart, even if
    the wall clock has gone back.
    """

    def __init__(
        self,
        key: bytes,
        clock: Callable[[], float],
        *,
        link_id: int = GROUP_LINK_ID,
        store: TimestampStore | None = None,
    ) -> None:
        """Signing with the 32-byte fleet ``key``; ``clock()`` returns wall time (unix s)."""
        if len(key) != 32:
            raise ValueError(f"a MAVLink signing key is 32 bytes, got {len(key)}")
        if not 0 <= link_id <= 255:
            raise ValueError(f"link id must be 0..255, got {link_id}")
        self.key = bytes(key)
        self.link_id = link_id
        self._clock = clock
        self._store = store
        self._bound = store.load() if store is not None else 0
        self.last = self._bound  # last timestamp used or validly received

    def now(self) -> int:
        """The current signing time: the later of the wall clock and the last timestamp."""
        return max(self.last, signing_time(self._clock()))

    def next_timestamp(self) -> int:
        """A fresh outgoing timestamp, strictly above every earlier one (persisting first)."""
        ts = max(self.last + 1, signing_time(self._clock()))
        if self._store is not None and ts >= self._bound:
            self._bound = ts + LEASE
            self._store.save(self._bound)
        self.last = ts
        return ts

    def observe(self, timestamp: int) -> None:
        """A valid timestamp was received: never send below it (MAVLink's rule)."""
        self.last = max(self.last, timestamp)

    def signature(self, packet_without_signature: bytes) -> bytes:
        """The 6-byte signature of everything up to and including link id and timestamp."""
        return _signature(self.key, bytes(packet_without_signature))


@functools.lru_cache(maxsize=SIGNATURE_MEMO)
def _signature(key: bytes, packet_without_signature: bytes) -> bytes:
    """MAVLink 2's signature, memoised: a pure function of the key and the bytes, and every
    member of an in-memory fleet checks each group datagram with the same key."""
    return hashlib.sha256(key + packet_without_signature).digest()[:6]


@dataclass(frozen=True)
class Rejected:
    """A frame refused by the signing check: why, and who it claims to come from."""

    reason: RejectReason
    sysid: int
    compid: int
    msg_id: int


def _header(frame: bytes | bytearray) -> tuple[bool, bool, int, int, int]:
    """(MAVLink 2, signed, sysid, compid, msg id) of a frame (zeros where it is too short)."""
    if len(frame) >= HEADER_LEN and frame[0] == MAGIC_V2:
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
        if not (v2 and signed) or len(frame) < HEADER_LEN + CRC_LEN + SIGNATURE_LEN:
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
