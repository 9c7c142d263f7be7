"""Fuzz datagrams for the simulator's vehicle ports and the companions' group (pure).

One seeded ``numpy.random.Generator`` in, datagrams (bytes) out; no sockets, no clock. The
classes (the name each datagram is counted under):

* ``random`` random bytes, 1-2048 long; ``empty`` a zero-length datagram; ``huge`` 2 KiB up
  to 65,507 bytes (the largest UDP payload over IPv4), random bytes or a frame tiled.
* ``valid`` a well-formed MAVLink 2 (or 1) frame with random field values and a correct CRC;
  ``multi`` several (mutated) frames in one datagram.
* mutations of a valid frame: ``flip`` (1-8 bits of the payload flipped, CRC left stale),
  ``length`` (length byte changed), ``truncated``, ``extended`` (random bytes appended),
  ``crc`` (CRC changed), ``magic`` (start byte changed), ``msgid`` (message id changed);
  ``signature`` a MAVLink 2 frame with the signed flag, a correct CRC and a bogus 13-byte
  signature block (half of them on the group's link id).
* ``replay`` (group only) a genuine signed group datagram captured on the wire, resent as
  it was or with one byte changed.

Frames for the simulator are common messages (HEARTBEAT, COMMAND_LONG/INT,
SET_ATTITUDE_TARGET, SET_MODE, MISSION_*, PARAM_*, REQUEST_DATA_STREAM, TIMESYNC); for the
group, the group dialect's PATROL_STATE and PATROL_ALERT plus a few common ones.

Safety: the autopilot link is unsigned, so a frame with a correct CRC is a command the
simulator obeys. Every datagram for the simulator is therefore decoded with the
simulator's own decoder before it is returned; each message that decodes must be
addressed to a system id that is not a vehicle, or be read-only (:data:`READ_ONLY`).
A datagram that fails the check is replaced by another (counted in ``replaced``). The group
is signed, so nothing sent to it without the key can be accepted.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Sequence
from typing import Literal

import numpy as np
from pymavlink.dialects.v10 import ardupilotmega as v1
from pymavlink.generator.mavcrc import x25crc

from companion.contracts.signing import GROUP_LINK_ID, SIGNATURE_LEN
from companion.group.dialect import patrol
from sitl_model.codec import Decoder, dialect

Dest = Literal["sim", "group"]

MAX_UDP = 65_507  # largest UDP payload over IPv4 (bytes)
SIM_TYPES = (
    "HEARTBEAT", "COMMAND_LONG", "COMMAND_INT", "SET_ATTITUDE_TARGET", "SET_MODE",
    "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_REQUEST_INT", "MISSION_REQUEST_LIST",
    "MISSION_ACK", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT", "PARAM_SET",
    "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "REQUEST_DATA_STREAM", "TIMESYNC",
)  # fmt: skip
GROUP_COMMON_TYPES = ("HEARTBEAT", "COMMAND_LONG", "SET_ATTITUDE_TARGET", "PARAM_SET")
# messages a vehicle only answers (no state change): allowed to any target system
READ_ONLY = frozenset({"HEARTBEAT", "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "TIMESYNC"})
WEIGHTS = {
    "random": 0.14, "empty": 0.03, "huge": 0.01, "valid": 0.13, "multi": 0.04,
    "flip": 0.10, "length": 0.08, "truncated": 0.08, "extended": 0.06, "crc": 0.08,
    "magic": 0.06, "msgid": 0.06, "signature": 0.07, "replay": 0.06,
}  # fmt: skip
MUTATIONS = ("flip", "length", "truncated", "extended", "crc", "magic", "msgid")


def _classes(module, names: Sequence[str]) -> list[type]:
    return [getattr(module, f"MAVLink_{n.lower()}_message") for n in names]


def _target_offset(cls: type) -> int | None:
    """Byte offset of ``target_system`` in the wire payload of ``cls``, None if it has none."""
    if "target_system" not in cls.ordered_fieldnames:
        return None
    tokens = []
    num = ""
    for ch in cls.unpacker.format[1:]:
        if ch.isdigit():
            num += ch
        else:
            tokens.append(num + ch)
            num = ""
    k = cls.ordered_fieldnames.index("target_system")
    return struct.calcsize("<" + "".join(tokens[:k]))


def frame(
    cls: type,
    payload: bytes,
    *,
    sysid: int,
    compid: int,
    seq: int,
    mavlink1: bool = False,
    signature: bytes | None = None,
) -> bytes:
    """A MAVLink frame of message ``cls`` carrying ``payload`` with a correct CRC; with a
    13-byte ``signature`` block (MAVLink 2 only) the signed flag is set and the block appended
    as it is (a bogus signature unless the caller computed it)."""
    if mavlink1:
        header = bytes([0xFE, len(payload), seq, sysid, compid, cls.id])
    else:
        iflags = 0x01 if signature is not None else 0
        header = struct.pack(
            "<BBBBBBBHB", 0xFD, len(payload), iflags, 0, seq, sysid, compid, cls.id & 0xFFFF,
            cls.id >> 16,
        )  # fmt: skip
    crc = x25crc(header[1:] + payload)
    crc.accumulate(bytes([cls.crc_extra]))
    return header + payload + struct.pack("<H", crc.crc) + (signature or b"")


class FuzzGenerator:
    """Datagrams of the classes above for the simulator (``"sim"``) or the group."""

    def __init__(
        self,
        seed: int,
        vehicle_sysids: Sequence[int],
        captured: Sequence[bytes] = (),
    ) -> None:
        """``captured``: genuine group datagrams for the ``replay`` class (none: no replays)."""
        self.rng = np.random.default_rng(seed)
        self.vehicles = frozenset(vehicle_sysids)
        self.captured = list(captured)
        self.sim_classes = _classes(dialect, SIM_TYPES)
        self.group_classes = [
            patrol.MAVLink_patrol_state_message,
            patrol.MAVLink_patrol_alert_message,
            *_classes(dialect, GROUP_COMMON_TYPES),
        ]
        self.v1_size = {c.id: c.unpacker.size for c in _classes(v1, SIM_TYPES)}
        self.offsets = {c.id: _target_offset(c) for c in self.sim_classes + self.group_classes}
        self.foreign = [s for s in range(1, 256) if s not in self.vehicles]
        self._foreign_set = frozenset(self.foreign)
        self.decoder = Decoder()
        self.replaced = 0  # datagrams for the simulator that decoded to a command, replaced
        self.valid_to_sim: Counter[str] = Counter()  # frames the simulator decodes, by type

    # ---- one datagram ----------------------------------------------------------------------
    def datagram(self, dest: Dest) -> tuple[str, bytes]:
        """One datagram for ``dest`` and its class."""
        kinds = [k for k in WEIGHTS if k != "replay" or (dest == "group" and self.captured)]
        p = np.array([WEIGHTS[k] for k in kinds])
        while True:
            kind = str(self.rng.choice(kinds, p=p / p.sum()))
            data = self._make(kind, dest)
            if dest == "group" or self._safe_for_sim(data):
                return kind, data
            self.replaced += 1

    def _make(self, kind: str, dest: Dest) -> bytes:
        rng = self.rng
        if kind == "random":
            return rng.bytes(int(rng.integers(1, 2049)))
        if kind == "empty":
            return b""
        if kind == "huge":
            n = int(np.exp(rng.uniform(np.log(2048), np.log(MAX_UDP))))
            if rng.random() < 0.2:
                n = MAX_UDP
            if rng.random() < 0.5:
                return rng.bytes(n)
            unit = b"".join(self._mutated(dest) for _ in range(4))
            return (unit * (n // max(1, len(unit)) + 1))[:n]
        if kind == "valid":
            return self._valid(dest)
        if kind == "signature":
            return self._valid(dest, signed=True)
        if kind == "multi":
            return b"".join(self._mutated(dest) for _ in range(int(rng.integers(2, 9))))
        if kind == "replay":
            data = bytearray(self.captured[int(rng.integers(len(self.captured)))])
            if rng.random() < 0.5:
                data[int(rng.integers(len(data)))] ^= int(rng.integers(1, 256))
            return bytes(data)
        return self._mutate(kind, self._valid(dest))

    def _mutated(self, dest: Dest) -> bytes:
        kind = str(self.rng.choice(("valid", "signature", *MUTATIONS)))
        if kind in ("valid", "signature"):
            return self._valid(dest, signed=kind == "signature")
        return self._mutate(kind, self._valid(dest))

    def _valid(self, dest: Dest, signed: bool = False) -> bytes:
        """A well-formed frame with random field values (for the simulator: safe, see above);
        ``signed``: MAVLink 2 with a bogus signature block (half of them on the group's link)."""
        rng = self.rng
        classes = self.sim_classes if dest == "sim" else self.group_classes
        cls = classes[int(rng.integers(len(classes)))]
        mavlink1 = not signed and cls.id in self.v1_size and rng.random() < 0.3
        size = self.v1_size[cls.id] if mavlink1 else cls.unpacker.size
        off = self.offsets[cls.id]
        patch = dest == "sim" and off is not None and cls.msgname not in READ_ONLY
        if not mavlink1 and rng.random() < 0.3:  # MAVLink 2 drops trailing zeros: shorter is legal
            size = int(rng.integers(off + 1 if patch else 1, size + 1))
        payload = bytearray(rng.bytes(size))
        if patch:
            payload[off] = self.foreign[int(rng.integers(len(self.foreign)))]
        signature = None
        if signed:
            block = bytearray(rng.bytes(SIGNATURE_LEN))
            if rng.random() < 0.5:
                block[0] = GROUP_LINK_ID
            signature = bytes(block)
        return frame(
            cls,
            bytes(payload),
            sysid=int(rng.integers(1, 256)),
            compid=int(rng.integers(0, 256)),
            seq=int(rng.integers(0, 256)),
            mavlink1=mavlink1,
            signature=signature,
        )

    def _mutate(self, kind: str, f: bytes) -> bytes:
        rng = self.rng
        data = bytearray(f)
        hdr = 6 if data[0] == 0xFE else 10
        if kind == "flip":
            end = max(hdr + 1, len(data) - 2)
            for _ in range(int(rng.integers(1, 9))):
                data[int(rng.integers(hdr, end))] ^= 1 << int(rng.integers(8))
        elif kind == "length":
            data[1] = (data[1] + int(rng.integers(1, 256))) % 256
        elif kind == "truncated":
            del data[int(rng.integers(0, len(data))) :]
        elif kind == "extended":
            data += rng.bytes(int(rng.integers(1, 300)))
        elif kind == "crc":
            data[-1 - int(rng.integers(2))] ^= int(rng.integers(1, 256))
        elif kind == "magic":
            data[0] = int(rng.choice([b for b in range(256) if b != data[0]]))
        elif kind == "msgid":
            if hdr == 6:
                data[5] = int(rng.integers(0, 256))
            else:
                data[7:10] = rng.bytes(3)
        return bytes(data)

    # ---- safety ----------------------------------------------------------------------------
    def _safe_for_sim(self, data: bytes) -> bool:
        """True if every message the simulator would decode from ``data`` is harmless."""
        if 0xFD not in data and 0xFE not in data:
            return True  # no start byte: no frame
        msgs, _ = self.decoder.decode(data)
        for m in msgs:
            if isinstance(m, dialect.MAVLink_unknown):  # an id it does not know: ignored
                continue
            name = m.get_type()
            if name not in READ_ONLY and getattr(m, "target_system", 0) not in self._foreign_set:
                return False
        for m in msgs:
            self.valid_to_sim[m.get_type()] += 1
        return True


def plan(
    n: int, gen: FuzzGenerator, n_vehicles: int, group_share: float
) -> list[tuple[Dest, int, str, bytes]]:
    """``n`` datagrams: (destination, vehicle index or -1 for the group, class, bytes)."""
    out: list[tuple[Dest, int, str, bytes]] = []
    for _ in range(n):
        if gen.rng.random() < group_share:
            kind, data = gen.datagram("group")
            out.append(("group", -1, kind, data))
        else:
            kind, data = gen.datagram("sim")
            out.append(("sim", int(gen.rng.integers(n_vehicles)), kind, data))
    return out
