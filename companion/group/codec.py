"""Group wire codec (pure): member states and alerts <-> signed MAVLink 2 datagrams.

Bytes in, events out, no sockets and no clock reads: the wall clock used for signing
timestamps is injected (``clock() -> unix seconds``), vehicle time arrives in the messages.

* :func:`encode` turns a :class:`MemberState` or :class:`Alert` into one datagram (one
  MAVLink 2 packet of the ``patrol.xml`` dialect), signed with the fleet key.
* :class:`Decoder` turns one received datagram into a :class:`MemberState`, an
  :class:`Alert`, or a :class:`Dropped` with the reason, and counts each outcome.

Both work on the bytes with ``struct`` and the CRC directly (:class:`_Layout`, read from the
dialect's generated classes: field order, payload format, CRC extra): the same bytes as
pymavlink's ``pack`` and the same fields as its ``decode`` (``tests/test_group_codec.py``
checks both against pymavlink), at a fraction of their cost; signing is one SHA-256 a
datagram.
* The signing state (key, link id, timestamps) is :class:`companion.contracts.signing.Signing`,
  shared with the autopilot link and the simulator.

Check order on receipt: framing and CRC (``malformed``), signature present (``unsigned``),
signature valid (``bad_signature``), group link id (``foreign_link``), own system id
(``own``), timestamp newer than the stream's last (``replayed``), payload values
(``malformed``). The stream table is updated only by packets that pass the signature check,
so a forged packet cannot poison it (pymavlink's own ``check_signature`` records the
timestamp before it checks the signature, which is why the check is done here).
"""

from __future__ import annotations

import functools
import hashlib
import hmac
import math
import struct
from dataclasses import dataclass, replace
from typing import Any, Literal, get_args

from companion.contracts.signing import (
    CRC_LEN,
    GROUP_LINK_ID,
    HEADER_LEN,
    IFLAG_SIGNED,
    MAGIC_V2,
    NEW_STREAM_WINDOW,
    SIGNATURE_LEN,
    Signing,
)
from companion.group.dialect import patrol as dialect
from companion.group.flood import FloodGate
from companion.group.messages import (
    MODELS,
    RELIEF_ROLES,
    Alert,
    AlertState,
    Energy,
    MemberState,
    Mode,
    Track,
    WindRecord,
)

__all__ = [
    "ALERT_ID_MAX",
    "COMPID_COMPANION",
    "COMPID_OPERATOR",
    "DROP_REASONS",
    "MAX_DATAGRAM",
    "OPERATOR_SYSID",
    "Decoder",
    "DropReason",
    "Dropped",
    "EncodeError",
    "Received",
    "encode",
]

COMPID_COMPANION = 191  # MAV_COMP_ID_ONBOARD_COMPUTER
COMPID_OPERATOR = 190  # MAV_COMP_ID_MISSIONPLANNER (a ground station)
OPERATOR_SYSID = 255  # the operator's `companion alert`, like a GCS
ALERT_ID_MAX = 16  # characters (char[16] on the wire)

MAX_DATAGRAM = HEADER_LEN + 255 + CRC_LEN + SIGNATURE_LEN  # 280 bytes

STATE_VERSION = 2  # PATROL_STATE format sent (extension fields; 1 = without them)
ENERGY_VERSION = 3  # PATROL_STATE with the battery and relief fields (only when shared)
ALERT_VERSION = 2  # PATROL_ALERT format with a track (extension fields; 1 = without them)
MODEL_VERSION = 3  # PATROL_ALERT with the track's motion model (model, turn, manoeuvre)
MODES: tuple[Mode, ...] = tuple(Mode)  # PATROL_MODE values 0, 1, 2
ALERT_STATES: tuple[AlertState, ...] = get_args(AlertState)  # PATROL_ALERT_STATE 0..3

DropReason = Literal["unsigned", "bad_signature", "replayed", "malformed", "own", "foreign_link"]
DROP_REASONS: tuple[DropReason, ...] = get_args(DropReason)
# a state beyond its sender's share under a budget: counted only by a decoder with a gate
FLOOD = "flood"
Received = MemberState | Alert
_STATE_ID = dialect.MAVLINK_MSG_ID_PATROL_STATE

try:  # pymavlink's own CRC (CRC-16/MCRF4XX) where it has it, its Python one otherwise
    from fastcrc.crc16 import mcrf4xx as _mcrf4xx
except ImportError:  # pragma: no cover - fastcrc is installed with pymavlink

    def _mcrf4xx(data: bytes, crc: int = 0xFFFF) -> int:  # type: ignore[misc]
        return int(dialect.x25crc(data).crc)


_HEADER = struct.Struct("<BBBBBBBHB")  # MAVLink 2: magic, len, flags, seq, sys, comp, id
_CRC = struct.Struct("<H")
_SIGN_TS = struct.Struct("<BQ")  # link id, timestamp (its low 6 bytes are sent)


class _Layout:
    """One message of the dialect on the wire, read from its generated pymavlink class: the
    id, the CRC extra and the payload's ``struct`` format in wire order, with the fields'
    declared order mapped to it (pymavlink sorts the base fields by size)."""

    def __init__(self, cls: Any) -> None:
        self.msg_id: int = cls.id
        self.crc_extra: int = cls.crc_extra
        self.payload: struct.Struct = cls.unpacker
        self.names: list[str] = list(cls.fieldnames)
        # wire position -> declared position, and back
        self.to_wire = [self.names.index(n) for n in cls.ordered_fieldnames]
        self.from_wire = [list(cls.ordered_fieldnames).index(n) for n in self.names]
        self.identity = self.to_wire == list(range(len(self.names)))

    def pack_payload(self, values: tuple) -> bytes:
        """The payload of the fields in declared order, MAVLink 2's trailing zeros cut (one
        byte at least)."""
        if not self.identity:
            values = tuple(values[i] for i in self.to_wire)
        return self.payload.pack(*values).rstrip(b"\x00") or b"\x00"

    def unpack_payload(self, payload: bytes) -> tuple:
        """The fields in declared order from a (possibly cut) payload, zero-padded as
        pymavlink does; text fields as their bytes."""
        size = self.payload.size
        if len(payload) < size:
            payload = payload + bytes(size - len(payload))
        got = self.payload.unpack(payload[:size])
        return got if self.identity else tuple(got[i] for i in self.from_wire)


_STATE = _Layout(dialect.MAVLink_patrol_state_message)
_ALERT = _Layout(dialect.MAVLink_patrol_alert_message)
_KNOWN = {_STATE.msg_id: _STATE, _ALERT.msg_id: _ALERT}


def _frame(
    layout: _Layout, values: tuple, sysid: int, compid: int, seq: int, signing: Signing | None
) -> bytes:
    """One MAVLink 2 frame of ``layout`` with ``values`` (declared order): header, payload
    (trailing zeros cut), CRC with the CRC extra, and with ``signing`` the link id, a fresh
    timestamp and the 6-byte signature (pymavlink's ``pack``, byte for byte)."""
    payload = layout.pack_payload(values)
    mid = layout.msg_id
    flags = IFLAG_SIGNED if signing is not None else 0
    body = _HEADER.pack(
        MAGIC_V2, len(payload), flags, 0, seq, sysid, compid, mid & 0xFFFF, mid >> 16
    )
    body += payload
    crc = _mcrf4xx(body[1:] + bytes((layout.crc_extra,)), 0xFFFF)
    body += _CRC.pack(crc)
    if signing is None:
        return body
    body += _SIGN_TS.pack(signing.link_id, signing.next_timestamp())[:7]
    return body + hashlib.sha256(signing.key + body).digest()[:6]


# The last datagrams' states are kept (see :func:`_state_of`): every member of an in-memory
# fleet receives each datagram, the same bytes, from one bus.
UNPACKED_MEMO = 256  # datagrams


class EncodeError(ValueError):
    """We were asked to send something the wire format cannot carry (our bug, not the peer's)."""


@dataclass(frozen=True)
class Dropped:
    """A datagram that was not accepted: why (one of :data:`DROP_REASONS`) and details."""

    reason: DropReason | Literal["flood"]
    detail: str


# ---- encoding ----------------------------------------------------------------------------
def encode(
    msg: Received,
    sysid: int,
    signing: Signing | None,
    *,
    compid: int = COMPID_COMPANION,
    seq: int = 0,
) -> bytes:
    """One datagram carrying ``msg`` from ``sysid``/``compid``; unsigned if ``signing`` is None.

    Times become microseconds (``t_s`` must be >= 0; an alert with ``t_s == 0`` means
    "unknown, use the time of receipt"), positions float32 metres, the phase float32 radians
    in [0, 2 pi). Raises :class:`EncodeError` for values the format cannot carry.
    """
    if not 1 <= sysid <= 255:
        raise EncodeError(f"sysid must be 1..255, got {sysid}")
    if not 0 <= compid <= 255:
        raise EncodeError(f"compid must be 0..255, got {compid}")
    if isinstance(msg, MemberState):
        if msg.sysid != sysid:
            raise EncodeError(f"state of sysid {msg.sysid} sent as sysid {sysid}")
        if msg.mode not in MODES:
            raise EncodeError(f"unknown mode {msg.mode!r}")
        _finite("phase_rad", msg.phase_rad)
        phase = math.fmod(msg.phase_rad, 2 * math.pi)
        layout = _STATE
        values: tuple = (
            _usec(msg.t_s),
            _f32("centre north", msg.centre_m.real),
            _f32("centre east", msg.centre_m.imag),
            phase + 2 * math.pi if phase < 0 else phase,
            MODES.index(msg.mode),
            _alert_id(msg.alert_id, allow_empty=True),
            *_state_v2(msg),
        )
    elif isinstance(msg, Alert):
        if msg.state not in ALERT_STATES:
            raise EncodeError(f"unknown alert state {msg.state!r}")
        if not 1 <= msg.detector_sysid <= 255:
            raise EncodeError(f"detector sysid must be 1..255, got {msg.detector_sysid}")
        layout = _ALERT
        values = (
            _usec(msg.t_s),
            _f32("site north", msg.site_m.real),
            _f32("site east", msg.site_m.imag),
            _f32("bid_s", msg.bid_s),
            msg.detector_sysid,
            ALERT_STATES.index(msg.state),
            _alert_id(msg.alert_id, allow_empty=False),
            *_alert_track(msg),
        )
    else:
        raise EncodeError(f"cannot send a {type(msg).__name__}")
    return _frame(layout, values, sysid, compid, seq % 256, signing)


def _alert_track(msg: Alert) -> tuple:
    """The version-2 extension fields of PATROL_ALERT (the track), or version 0 without one."""
    tr = msg.track
    if tr is None:
        return (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0.0, 0.0)
    if tr.t_s != msg.t_s or tr.pos_m != msg.site_m:
        raise EncodeError("an alert's track must be at the report's time and site")
    if not 0 <= tr.sightings <= 0xFFFF:
        raise EncodeError(f"sightings must be 0..65535, got {tr.sightings}")
    v3 = tr.manoeuvre_m_s2 != 0.0 or tr.model != "cv" or tr.turn_rad_s != 0.0
    return (
        MODEL_VERSION if v3 else ALERT_VERSION,
        _f32("velocity north", tr.vel_m_s.real),
        _f32("velocity east", tr.vel_m_s.imag),
        _f32("pos_sigma", tr.pos_sigma_m),
        _f32("vel_sigma", tr.vel_sigma_m_s),
        int(tr.sightings),
        *_track_model(tr),
    )


def _track_model(tr: Track) -> tuple:
    """The version-3 fields of a track (its motion model); a version-2 track (no manoeuvre,
    constant velocity) is sent as version 2."""
    if tr.model not in MODELS:
        raise EncodeError(f"unknown track model {tr.model!r}")
    pct = tr.model_p * 100.0
    return (
        MODELS.index(tr.model),
        round(min(max(pct, 0.0), 100.0)) if math.isfinite(pct) else 0,
        _f32("track turn", tr.turn_rad_s),
        _f32("track manoeuvre", tr.manoeuvre_m_s2),
    )


def _state_v2(msg: MemberState) -> tuple:
    """The version-2 extension fields of PATROL_STATE (position, wind estimate, agreed wind)."""
    nan = math.nan
    pos = msg.pos_m
    est = msg.wind_est_m_s
    rec = msg.wind_record
    if pos is not None:
        _f32("pos north", pos.real)
        _f32("pos east", pos.imag)
    if est is not None and not (math.isfinite(est.real) and math.isfinite(est.imag)):
        est = None  # an invalid estimate is not shared
    if rec is None:
        rec_fields: tuple = (0, 0, nan, nan, 0)
    else:
        if not (0 <= rec.seq <= 0xFFFF and 0 <= rec.proposer <= 255):
            raise EncodeError(f"wind record {rec.seq}/{rec.proposer} out of range")
        t_eff = 0 if not math.isfinite(rec.t_eff_s) else _usec(max(rec.t_eff_s, 0.0))
        rec_fields = (
            rec.seq,
            rec.proposer,
            _f32("wind north", rec.wind_m_s.real),
            _f32("wind east", rec.wind_m_s.imag),
            t_eff,
        )
    return (
        STATE_VERSION if msg.energy is None else ENERGY_VERSION,
        pos.real if pos is not None else nan,
        pos.imag if pos is not None else nan,
        est.real if est is not None else nan,
        est.imag if est is not None else nan,
        *rec_fields,
        *_state_v3(msg.energy),
    )


def _state_v3(energy: Energy | None) -> tuple:
    """The version-3 extension fields of PATROL_STATE (battery, relief), all 0 without them:
    MAVLink 2 drops trailing zero bytes, so a state without energy is sent as before."""
    if energy is None:
        return (0.0, 0, 0, 0)
    if energy.role not in RELIEF_ROLES:
        raise EncodeError(f"unknown relief role {energy.role!r}")
    if not 0 <= energy.relief_sysid <= 255:
        raise EncodeError(f"relief sysid must be 0..255, got {energy.relief_sysid}")
    pct = energy.battery_pct
    t = energy.t_s
    return (
        math.nan if pct is None else _f32("battery_pct", pct),
        0 if t is None else _usec(max(t, 0.0)),
        RELIEF_ROLES.index(energy.role) + 1,
        int(energy.relief_sysid),
    )


def _usec(t_s: float) -> int:
    _finite("t_s", t_s)
    if not 0 <= t_s < 2**63 / 1e6:
        raise EncodeError(f"t_s must be >= 0 s (vehicle time), got {t_s!r}")
    return round(t_s * 1e6)


def _f32(name: str, value: float) -> float:
    _finite(name, value)
    if abs(value) > 3.0e38:
        raise EncodeError(f"{name} does not fit a float32: {value!r}")
    return float(value)


def _finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise EncodeError(f"{name} must be finite, got {value!r}")


def _alert_id(text: str, *, allow_empty: bool) -> bytes:
    raw = text.encode("ascii", errors="replace")
    if not text.isascii() or not text.isprintable() or len(raw) > ALERT_ID_MAX:
        raise EncodeError(f"alert id must be at most {ALERT_ID_MAX} printable ASCII: {text!r}")
    if not raw and not allow_empty:
        raise EncodeError("an alert needs an id")
    return raw


# ---- decoding ----------------------------------------------------------------------------
class Decoder:
    """Checks and decodes received datagrams (one MAVLink 2 packet each); counts outcomes.

    ``counts`` maps ``"accepted"`` and each of :data:`DROP_REASONS` to a number of datagrams.
    With ``signing`` None the decoder is insecure: it accepts unsigned packets and ignores
    signatures (no replay check either).
    """

    def __init__(
        self,
        own_sysid: int | None,
        signing: Signing | None,
        *,
        link_id: int = GROUP_LINK_ID,
    ) -> None:
        """Decoder for the member ``own_sysid`` (its looped-back packets are dropped)."""
        self.own_sysid = own_sysid
        self.signing = signing
        self.link_id = link_id
        self.streams: dict[tuple[int, int, int], int] = {}  # (sysid, compid, link) -> last ts
        self.counts: dict[str, int] = {"accepted": 0, **dict.fromkeys(DROP_REASONS, 0)}
        self.gate: FloodGate | None = None

    def limit_floods(self, gate: FloodGate) -> None:
        """From now on refuse a sender's states beyond its share (``gate``), counted as
        ``flood``: checked before the state is decoded, after its signature, so a forged
        frame never spends a member's share (:mod:`companion.group.flood`)."""
        self.gate = gate
        self.counts.setdefault(FLOOD, 0)

    def feed(self, datagram: bytes, now_s: float | None = None) -> Received | Dropped:
        """Decode one datagram; ``now_s`` (vehicle s) stamps alerts sent with time 0."""
        out = self._check(bytes(datagram), now_s)
        self.counts["accepted" if not isinstance(out, Dropped) else out.reason] += 1
        return out

    def _check(self, data: bytes, now_s: float | None) -> Received | Dropped:
        frame = _frame_of(data)  # what the bytes alone say, once per datagram for all members
        if isinstance(frame, Dropped):
            return frame
        msgid, sysid, compid, signed, end, crc_error = frame
        gate, gate_t = self.gate, now_s
        if gate is None or gate_t is None or msgid != _STATE_ID or sysid == self.own_sysid:
            gate = None
        elif gate.full(sysid, gate_t) and self._genuine(data, signed):
            return Dropped("flood", f"state from sysid {sysid} beyond its share")
        if crc_error:
            return Dropped("malformed", crc_error)
        layout = _KNOWN[msgid]
        stream: tuple[int, int, int] | None = None
        ts = 0
        if self.signing is not None:
            if not signed:
                return Dropped("unsigned", f"from sysid {sysid}")
            body, sig = data[:-6], data[-6:]
            if not hmac.compare_digest(self.signing.signature(body), sig):
                return Dropped("bad_signature", f"from sysid {sysid}")
            link = data[-SIGNATURE_LEN]
            ts = int.from_bytes(data[-12:-6], "little")
            if link != self.link_id:
                return Dropped("foreign_link", f"link id {link} from sysid {sysid}")
            stream = (sysid, compid, link)
        if sysid == self.own_sysid:
            return Dropped("own", "looped back")
        if stream is not None and self.signing is not None:
            last = self.streams.get(stream)
            if last is not None and ts <= last:
                return Dropped("replayed", f"timestamp {ts} <= {last} of stream {stream}")
            if last is None and ts + NEW_STREAM_WINDOW < self.signing.now():
                return Dropped("replayed", f"new stream {stream} more than 60 s old")
        out: Received | Dropped
        if layout is _STATE:
            out = _state_of(data)  # the same datagram gives the same state, whoever reads it
        else:
            out = _alert_of(layout.unpack_payload(data[HEADER_LEN:end]), sysid, now_s)
        if isinstance(out, Dropped):
            return out
        if stream is not None and self.signing is not None:
            self.streams[stream] = ts
            self.signing.observe(ts)
        if gate is not None and gate_t is not None:
            gate.take(sysid, gate_t)
        return out

    def _genuine(self, data: bytes, signed: bool) -> bool:
        """Whether a datagram is signed with the fleet key on the group's link (True on an
        insecure group): only then is a state beyond its share counted as a flood."""
        if self.signing is None:
            return True
        if not signed or data[-SIGNATURE_LEN] != self.link_id:
            return False
        return hmac.compare_digest(self.signing.signature(data[:-6]), data[-6:])


@functools.lru_cache(maxsize=UNPACKED_MEMO)
def _frame_of(data: bytes) -> tuple[int, int, int, bool, int, str] | Dropped:
    """What one datagram's bytes say before any key or stream is consulted: (message id,
    sysid, component id, signed, payload end, "" or why its CRC is wrong), or why it is no
    frame of ours. Memoised: a pure function of the bytes, and N - 1 members of an in-memory
    fleet check every datagram (the same bytes object, its hash computed once)."""
    if not HEADER_LEN + CRC_LEN <= len(data) <= MAX_DATAGRAM:
        return Dropped("malformed", f"datagram of {len(data)} bytes")
    magic, plen, iflags, _cflags, _seq, sysid, compid, id_lo, id_hi = _HEADER.unpack_from(data)
    msgid = id_lo | id_hi << 16
    if magic != MAGIC_V2:
        return Dropped("malformed", f"not MAVLink 2 (start byte 0x{magic:02x})")
    if iflags & ~IFLAG_SIGNED:
        return Dropped("malformed", f"unknown incompatibility flags 0x{iflags:02x}")
    signed = bool(iflags & IFLAG_SIGNED)
    expected = HEADER_LEN + plen + CRC_LEN + (SIGNATURE_LEN if signed else 0)
    if len(data) != expected:
        return Dropped("malformed", f"length {len(data)}, header says {expected}")
    layout = _KNOWN.get(msgid)
    if layout is None:
        return Dropped("malformed", f"unknown message id {msgid}")
    if sysid == 0:
        return Dropped("malformed", "system id 0")
    end = HEADER_LEN + plen
    crc = _CRC.unpack_from(data, end)[0]
    want = _mcrf4xx(data[1:end] + bytes((layout.crc_extra,)), 0xFFFF)
    error = "" if crc == want else (
        f"invalid MAVLink CRC in msgID {msgid} 0x{crc:04x} should be 0x{want:04x}"
    )  # fmt: skip
    return msgid, sysid, compid, signed, end, error


@functools.lru_cache(maxsize=UNPACKED_MEMO)
def _state_of(data: bytes) -> MemberState | Dropped:
    """The member state a checked PATROL_STATE datagram carries, or why its values are bad;
    memoised: a pure function of the bytes (no receive time), and N - 1 members of an
    in-memory fleet read every datagram."""
    plen = data[1]
    return _member_state(_STATE.unpack_payload(data[HEADER_LEN : HEADER_LEN + plen]), data[5])


def _complex_or_none(north: float, east: float) -> complex | None:
    """``north + i east``, or None when either is not finite (NaN = not shared)."""
    if math.isfinite(north) and math.isfinite(east):
        return complex(north, east)
    return None


def _text(raw: bytes) -> str | None:
    """A char[16] field as pymavlink gives it (up to the first NUL, ASCII, anything else
    replaced), or None when that is not printable ASCII."""
    text = raw.split(b"\x00", 1)[0].decode("ascii", errors="replace")
    return text if text.isascii() and text.isprintable() else None


def _member_state(f: tuple, sysid: int) -> MemberState | Dropped:
    """PATROL_STATE's fields (declared order) as a :class:`MemberState`, or why not."""
    (t_us, c_n, c_e, phase, mode, raw_id, version, pos_n, pos_e, est_n, est_e,
     w_seq, w_prop, w_n, w_e, w_t_us, pct, r_t_us, role, r_sysid) = f  # fmt: skip
    text = _text(raw_id)
    if text is None:
        return Dropped("malformed", "alert id is not printable ASCII")
    if not (math.isfinite(c_n) and math.isfinite(c_e) and math.isfinite(phase)):
        return Dropped("malformed", f"bad PATROL_STATE values from sysid {sysid}")
    if mode >= len(MODES):
        return Dropped("malformed", f"bad PATROL_STATE values from sysid {sysid}")
    pos = est = rec = None
    if version >= STATE_VERSION:
        pos = _complex_or_none(pos_n, pos_e)
        est = _complex_or_none(est_n, est_e)
        w = _complex_or_none(w_n, w_e)
        if w is not None:
            rec = WindRecord(w_seq, w_prop, w, w_t_us / 1e6 if w_t_us else -math.inf)
    energy = None
    if version >= ENERGY_VERSION:
        if not 1 <= role <= len(RELIEF_ROLES):
            return Dropped("malformed", f"relief role {role} from sysid {sysid}")
        energy = Energy(
            RELIEF_ROLES[role - 1],
            pct if math.isfinite(pct) else None,
            r_t_us / 1e6 if r_t_us else None,
            r_sysid,
        )
    return MemberState(
        sysid=sysid,
        t_s=t_us / 1e6,
        centre_m=complex(c_n, c_e),
        phase_rad=phase,
        mode=MODES[mode],
        alert_id=text,
        pos_m=pos,
        wind_est_m_s=est,
        wind_record=rec,
        energy=energy,
    )


def _alert_of(f: tuple, sysid: int, now_s: float | None) -> Alert | Dropped:
    """PATROL_ALERT's fields (declared order) as an :class:`Alert`, or why not; ``now_s``
    (vehicle s) stamps an alert sent with time 0."""
    (t_us, north, east, bid, detector, state, raw_id, version, vel_n, vel_e, pos_sigma,
     vel_sigma, sightings, model, model_pct, turn, manoeuvre) = f  # fmt: skip
    text = _text(raw_id)
    if text is None:
        return Dropped("malformed", "alert id is not printable ASCII")
    if not (math.isfinite(north) and math.isfinite(east) and math.isfinite(bid)):
        return Dropped("malformed", f"bad PATROL_ALERT values from sysid {sysid}")
    if state >= len(ALERT_STATES):
        return Dropped("malformed", f"bad PATROL_ALERT values from sysid {sysid}")
    if not text or detector == 0:
        return Dropped("malformed", f"PATROL_ALERT without id or detector from sysid {sysid}")
    t_s = t_us / 1e6
    if t_us == 0 and now_s is not None:
        t_s = float(now_s)
    site = complex(north, east)
    track = None
    if version >= ALERT_VERSION:
        # finite or not, a track is decoded as sent: the agent refuses a bad one and counts it
        track = Track(t_s, site, complex(vel_n, vel_e), pos_sigma, vel_sigma, sightings)
        if version >= MODEL_VERSION:
            if model >= len(MODELS):
                return Dropped("malformed", f"bad PATROL_ALERT track model from sysid {sysid}")
            # as sent, finite or not: the agent refuses a bad one and counts it
            track = replace(
                track,
                model=MODELS[model],
                model_p=model_pct / 100.0,
                turn_rad_s=turn,
                manoeuvre_m_s2=manoeuvre,
            )
    return Alert(
        alert_id=text,
        site_m=site,
        detector_sysid=detector,
        t_s=t_s,
        state=ALERT_STATES[state],
        bid_s=bid,
        track=track,
    )
