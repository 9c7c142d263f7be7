"""Group codec (pure, no sockets): round trips, signing, replay, restart, bad datagrams."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega

from companion.contracts.signing import GROUP_LINK_ID, SIGNING_EPOCH_UNIX_S, Signing
from companion.group.codec import COMPID_COMPANION, Decoder, Dropped, EncodeError, encode
from companion.group.dialect import XML_PATH, generate, patrol
from companion.group.faults import FaultModel
from companion.group.flood import FloodGate
from companion.group.messages import Alert, MemberState, Mode, Track

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
T0 = 1_700_000_000.0  # wall clock (unix s) of the fake clocks


class FakeClock:
    """Wall clock (unix s) that only moves when told to."""

    def __init__(self, t: float = T0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


class MemoryStore:
    """A TimestampStore in memory that records every save."""

    def __init__(self) -> None:
        self.value = 0
        self.saves: list[int] = []

    def load(self) -> int:
        return self.value

    def save(self, timestamp: int) -> None:
        self.value = timestamp
        self.saves.append(timestamp)


def pair(clock: FakeClock | None = None, key: bytes = KEY) -> tuple[Signing, Decoder, FakeClock]:
    clock = clock or FakeClock()
    return Signing(key, clock), Decoder(9, Signing(KEY, clock)), clock


STATES = [
    MemberState(3, 12.5, 100.25 - 40.5j, 1.234, "patrol", ""),
    MemberState(1, 0.0, 0j, 0.0, "prosecuting", "3-12"),
    MemberState(255, 86_400.123456, -12_345.678 + 9_876.5j, 6.28, "rejoining", "x" * 16),
]
ALERTS = [
    Alert("3-12", 120.5 + 33.25j, 3, 1234.5, "new"),
    Alert("4-1", -800.0 - 1.5j, 4, 7.0, "confirmed"),
    Alert("255-375284702", 0j, 255, 99.25, "cleared"),
    Alert("3-12", 120.5 + 33.25j, 6, 1240.0, "bid", 41.75),
    Alert(
        "3-13",
        10.5 + 5.25j,
        3,
        100.0,
        "update",
        track=Track(100.0, 10.5 + 5.25j, 2 + 1j, 2.5, 0.5, 21, "turn", 0.75, 0.125, 2.0),
    ),
]


def f32(x: float) -> float:
    return float(np.float32(x))


# ---- round trips --------------------------------------------------------------------------
@pytest.mark.parametrize("state", STATES)
def test_state_round_trip_within_float32(state: MemberState) -> None:
    signing, dec, _ = pair()
    got = dec.feed(encode(state, state.sysid, signing))
    assert isinstance(got, MemberState)
    assert got.sysid == state.sysid and got.mode == state.mode and got.alert_id == state.alert_id
    assert got.t_s == pytest.approx(state.t_s, abs=1e-6)
    assert got.centre_m.real == f32(state.centre_m.real)
    assert got.centre_m.imag == f32(state.centre_m.imag)
    assert got.phase_rad == f32(state.phase_rad)
    assert dec.counts["accepted"] == 1


@pytest.mark.parametrize("alert", ALERTS)
def test_alert_round_trip_within_float32(alert: Alert) -> None:
    signing, dec, _ = pair()
    got = dec.feed(encode(alert, 200, signing))
    assert isinstance(got, Alert)
    assert (got.alert_id, got.state, got.detector_sysid) == (
        alert.alert_id,
        alert.state,
        alert.detector_sysid,
    )
    assert got.t_s == pytest.approx(alert.t_s, abs=1e-6)
    assert got.site_m == complex(f32(alert.site_m.real), f32(alert.site_m.imag))
    assert got.bid_s == f32(alert.bid_s)


def test_negative_phase_is_sent_wrapped_into_0_2pi() -> None:
    signing, dec, _ = pair()
    got = dec.feed(encode(MemberState(2, 1.0, 0j, -0.5), 2, signing))
    assert isinstance(got, MemberState)
    assert got.phase_rad == pytest.approx(2 * math.pi - 0.5, abs=1e-6)


def test_alert_time_zero_means_time_of_receipt() -> None:
    signing, dec, _ = pair()
    alert = Alert("255-1", 5 + 5j, 255, 0.0)
    got = dec.feed(encode(alert, 255, signing), now_s=321.5)
    assert isinstance(got, Alert) and got.t_s == 321.5
    got = dec.feed(encode(alert, 255, signing))  # no time given: left as 0
    assert isinstance(got, Alert) and got.t_s == 0.0
    stamped = dec.feed(encode(Alert("3-1", 0j, 3, 5.0), 3, signing), now_s=321.5)
    assert isinstance(stamped, Alert) and stamped.t_s == 5.0  # a real time is kept


def test_wire_layout_is_mavlink2_signed_with_group_link_and_dialect_ids() -> None:
    signing, _, _ = pair()
    data = encode(STATES[0], 3, signing, seq=7)
    magic, plen, iflags, _, seq, sysid, compid, lo, hi = struct.unpack_from("<BBBBBBBHB", data)
    assert (magic, iflags, seq, sysid, compid) == (0xFD, 1, 7, 3, COMPID_COMPANION)
    assert lo | hi << 16 == 60200 == patrol.MAVLINK_MSG_ID_PATROL_STATE
    assert len(data) == 10 + plen + 2 + 13
    assert data[-13] == GROUP_LINK_ID
    ts = int.from_bytes(data[-12:-6], "little")
    assert ts == (T0 - SIGNING_EPOCH_UNIX_S) * 100_000  # MAVLink: 10 us units since 2015
    assert patrol.MAVLINK_MSG_ID_PATROL_ALERT == 60201


def test_dialect_ids_do_not_collide_and_xml_validates() -> None:
    assert 60200 not in ardupilotmega.mavlink_map and 60201 not in ardupilotmega.mavlink_map
    pytest.importorskip("lxml")
    generate(XML_PATH, validate=True)  # raises DialectError if mavgen rejects it


# ---- drops --------------------------------------------------------------------------------
def test_unsigned_dropped_by_keyed_decoder_and_accepted_by_insecure_one() -> None:
    _, dec, _ = pair()
    data = encode(STATES[0], 3, None)
    assert dec.feed(data) == Dropped("unsigned", "from sysid 3")
    assert isinstance(Decoder(9, None).feed(data), MemberState)
    assert dec.counts == {**dict.fromkeys(dec.counts, 0), "unsigned": 1}


def test_wrong_key_is_bad_signature() -> None:
    signing, dec, _ = pair(key=OTHER_KEY)
    got = dec.feed(encode(STATES[0], 3, signing))
    assert isinstance(got, Dropped) and got.reason == "bad_signature"
    assert dec.counts["bad_signature"] == 1 and dec.counts["accepted"] == 0


def test_replayed_and_duplicated_packets_are_dropped() -> None:
    signing, dec, _ = pair()
    first = encode(STATES[0], 3, signing)
    second = encode(STATES[0], 3, signing)
    assert isinstance(dec.feed(first), MemberState)
    assert isinstance(dec.feed(second), MemberState)
    for old in (first, second, first):
        got = dec.feed(old)
        assert isinstance(got, Dropped) and got.reason == "replayed"
    assert dec.counts["replayed"] == 3 and dec.counts["accepted"] == 2


def test_every_member_decodes_one_datagram_the_same_and_keeps_its_own_streams() -> None:
    # one datagram read by several members (the in-memory bus): the decoding is memoised,
    # the replay check and the counts stay each member's own
    clock = FakeClock()
    signing = Signing(KEY, clock)
    frame = encode(STATES[0], 3, signing)
    members = [Decoder(s, Signing(KEY, clock)) for s in (1, 2, 4)]
    got = [d.feed(frame) for d in members]
    assert all(isinstance(g, MemberState) and g == got[0] for g in got)
    assert all(d.feed(frame).reason == "replayed" for d in members)
    own = Decoder(3, Signing(KEY, clock))
    assert own.feed(frame).reason == "own"
    bad = bytearray(frame)
    bad[12] ^= 1
    assert all(d.feed(bytes(bad)).reason == "malformed" for d in members)
    assert [d.counts["accepted"] for d in members] == [1, 1, 1]


def test_streams_are_per_sysid_so_interleaved_senders_are_accepted() -> None:
    clock = FakeClock()
    a, b = Signing(KEY, clock), Signing(KEY, clock)
    dec = Decoder(9, Signing(KEY, clock))
    pa = [encode(MemberState(1, i, 0j, 0.0), 1, a) for i in range(3)]
    pb = [encode(MemberState(2, i, 0j, 0.0), 2, b) for i in range(3)]
    for x, y in zip(pa, pb, strict=True):
        assert isinstance(dec.feed(y), MemberState)
        assert isinstance(dec.feed(x), MemberState)


def test_stale_new_stream_is_treated_as_replay() -> None:
    signing, _, _ = pair()
    captured = encode(STATES[0], 3, signing)
    late = Decoder(9, Signing(KEY, FakeClock(T0 + 61)))  # fresh receiver a minute later
    got = late.feed(captured)
    assert isinstance(got, Dropped) and got.reason == "replayed"
    recent = Decoder(9, Signing(KEY, FakeClock(T0 + 59)))
    assert isinstance(recent.feed(captured), MemberState)


def test_forged_packet_with_huge_timestamp_does_not_poison_the_stream() -> None:
    signing, dec, clock = pair()
    assert isinstance(dec.feed(encode(STATES[0], 3, signing)), MemberState)
    forged = bytearray(encode(STATES[0], 3, Signing(OTHER_KEY, FakeClock(T0 + 1e6))))
    assert dec.feed(bytes(forged)).reason == "bad_signature"  # type: ignore[union-attr]
    clock.t += 0.2
    assert isinstance(dec.feed(encode(STATES[0], 3, signing)), MemberState)


def test_other_link_id_is_foreign_link() -> None:
    clock = FakeClock()
    other_link = Signing(KEY, clock, link_id=0)  # e.g. a tool on an autopilot link, same key
    _, dec, _ = pair(clock)
    got = dec.feed(encode(STATES[0], 3, other_link))
    assert isinstance(got, Dropped) and got.reason == "foreign_link"


def test_own_looped_back_packets_are_counted_as_own() -> None:
    signing, dec, _ = pair()
    got = dec.feed(encode(MemberState(9, 1.0, 0j, 0.0), 9, signing))
    assert isinstance(got, Dropped) and got.reason == "own"
    forged_own = encode(MemberState(9, 1.0, 0j, 0.0), 9, Signing(OTHER_KEY, FakeClock()))
    assert dec.feed(forged_own).reason == "bad_signature"  # type: ignore[union-attr]


def test_truncated_datagrams_are_malformed() -> None:
    signing, dec, _ = pair()
    data = encode(ALERTS[3], 6, signing)
    for n in range(len(data)):
        got = dec.feed(data[:n])
        assert isinstance(got, Dropped) and got.reason == "malformed", n
    assert dec.counts["malformed"] == len(data) and dec.counts["accepted"] == 0


def test_every_single_bit_flip_is_dropped_by_the_right_counter() -> None:
    signing, dec, _ = pair()
    data = encode(ALERTS[0], 3, signing)
    for i in range(len(data)):
        for bit in range(8):
            bad = bytearray(data)
            bad[i] ^= 1 << bit
            got = dec.feed(bytes(bad))
            assert isinstance(got, Dropped), (i, bit)
            # header, payload and CRC are covered by framing and CRC; the link id, the
            # timestamp and the signature itself by the signature
            want = "malformed" if i < len(data) - 13 else "bad_signature"
            assert got.reason == want, (i, bit, got)
    assert isinstance(dec.feed(data), Alert)  # the intact packet is still fresh


def test_empty_oversized_and_random_datagrams_are_malformed() -> None:
    signing, dec, _ = pair()
    good = encode(STATES[0], 3, signing)
    rng = np.random.default_rng(5)
    junk = [b"", b"\xfd", good + b"\x00", good * 2, bytes(281), b"\xfd" + bytes(300)]
    for _ in range(500):
        n = int(rng.integers(1, 300))
        raw = bytearray(rng.integers(0, 256, n, dtype=np.uint8).tobytes())
        if rng.random() < 0.5:
            raw[0] = 0xFD  # looks like MAVLink 2
        junk.append(bytes(raw))
    for data in junk:
        got = dec.feed(data)
        assert isinstance(got, Dropped) and got.reason == "malformed", data[:12]
    assert dec.counts["malformed"] == len(junk) and dec.counts["accepted"] == 0


def test_valid_mavlink_of_another_dialect_is_malformed_unknown_id() -> None:
    mav = ardupilotmega.MAVLink(None, srcSystem=3, srcComponent=1)
    mav.signing.secret_key, mav.signing.link_id = KEY, GROUP_LINK_ID
    mav.signing.sign_outgoing, mav.signing.timestamp = True, 10**12
    heartbeat = ardupilotmega.MAVLink_heartbeat_message(1, 3, 0, 0, 0, 3).pack(mav)
    _, dec, _ = pair()
    got = dec.feed(heartbeat)
    assert isinstance(got, Dropped) and got.reason == "malformed" and "unknown" in got.detail


def signed_raw(msg: object, sysid: int = 3) -> bytes:
    mav = patrol.MAVLink(None, srcSystem=sysid, srcComponent=COMPID_COMPANION)
    mav.signing.secret_key, mav.signing.link_id = KEY, GROUP_LINK_ID
    mav.signing.sign_outgoing = True
    mav.signing.timestamp = int((T0 - SIGNING_EPOCH_UNIX_S) * 100_000)
    return bytes(msg.pack(mav))  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "msg",
    [
        patrol.MAVLink_patrol_state_message(1, 0.0, 0.0, 0.0, 7, b""),  # mode out of range
        patrol.MAVLink_patrol_state_message(1, math.nan, 0.0, 0.0, 0, b""),
        patrol.MAVLink_patrol_state_message(1, 0.0, 0.0, math.inf, 0, b""),
        patrol.MAVLink_patrol_state_message(1, 0.0, 0.0, 0.0, 0, b"\xff\xfe"),  # not ASCII
        patrol.MAVLink_patrol_alert_message(1, 0.0, 0.0, 0.0, 3, 6, b"3-1"),  # state 6
        patrol.MAVLink_patrol_alert_message(1, 0.0, 0.0, 0.0, 3, 0, b""),  # no id
        patrol.MAVLink_patrol_alert_message(1, 0.0, 0.0, 0.0, 0, 0, b"3-1"),  # detector 0
        patrol.MAVLink_patrol_alert_message(1, 0.0, math.nan, 0.0, 3, 0, b"3-1"),
    ],
)
def test_signed_packets_with_bad_values_are_malformed(msg: object) -> None:
    dec = Decoder(9, Signing(KEY, FakeClock()))
    got = dec.feed(signed_raw(msg))
    assert isinstance(got, Dropped) and got.reason == "malformed"


def test_a_state_with_a_mode_the_group_does_not_know_is_refused_when_made() -> None:
    """The mode is one of the group's words (companion.group.messages.Mode), from the
    wire to the page; a string is taken as its Mode, anything else raises."""
    assert MemberState(3, 1.0, 0j, 0.0, "rejoining").mode is Mode.REJOINING  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        MemberState(3, 1.0, 0j, 0.0, "lost")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        MemberState(3, 1.0, 0j, 0.0, "virtual")  # type: ignore[arg-type]  # the old word


@pytest.mark.parametrize(
    ("msg", "sysid"),
    [
        (MemberState(3, 1.0, 0j, 0.0), 4),  # someone else's state
        (MemberState(3, -1.0, 0j, 0.0), 3),  # negative time
        (MemberState(3, 1.0, complex(math.nan, 0), 0.0), 3),
        (MemberState(3, 1.0, 0j, 0.0, "patrol", "x" * 17), 3),
        (Alert("", 0j, 3, 1.0), 3),
        (Alert("é-1", 0j, 3, 1.0), 3),
        (Alert("3-1", 0j, 0, 1.0), 3),
        (Alert("3-1", 0j, 3, 1.0, "open"), 3),  # type: ignore[arg-type]
        (Alert("3-1", 1e39 + 0j, 3, 1.0), 3),
        (MemberState(0, 1.0, 0j, 0.0), 0),
    ],
)
def test_encode_refuses_what_the_wire_cannot_carry(msg: object, sysid: int) -> None:
    with pytest.raises(EncodeError):
        encode(msg, sysid, None)  # type: ignore[arg-type]


# ---- timestamps and restarts --------------------------------------------------------------
def test_timestamps_strictly_increase_and_follow_the_wall_clock() -> None:
    clock = FakeClock()
    s = Signing(KEY, clock)
    a, b = s.next_timestamp(), s.next_timestamp()
    assert b == a + 1  # same wall time: last + 1
    clock.t += 10.0
    assert s.next_timestamp() == a + 10 * 100_000
    clock.t -= 100.0  # the wall clock steps back: still increasing
    assert s.next_timestamp() == a + 10 * 100_000 + 1


def test_store_is_written_ahead_about_once_a_minute() -> None:
    clock, store = FakeClock(), MemoryStore()
    s = Signing(KEY, clock, store=store)
    first = s.next_timestamp()
    assert store.saves == [first + 60 * 100_000]  # persisted before the first use
    for _ in range(50):
        clock.t += 1.0
        assert s.next_timestamp() < store.value
    assert len(store.saves) == 1
    clock.t += 15.0
    s.next_timestamp()
    assert len(store.saves) == 2


def test_restarted_sender_is_accepted_but_a_replay_of_its_old_packet_is_not() -> None:
    clock, store = FakeClock(), MemoryStore()
    receiver = Decoder(9, Signing(KEY, FakeClock()))
    before = Signing(KEY, clock, store=store)
    old = [encode(MemberState(3, float(i), 0j, 0.0), 3, before) for i in range(5)]
    for p in old:
        assert isinstance(receiver.feed(p), MemberState)
    # restart: new codec state, same key and store, and the wall clock has gone back 10 min
    clock.t -= 600.0
    after = Signing(KEY, clock, store=store)
    assert isinstance(receiver.feed(encode(MemberState(3, 9.0, 0j, 0.0), 3, after)), MemberState)
    for p in old:
        got = receiver.feed(p)
        assert isinstance(got, Dropped) and got.reason == "replayed"


def test_restart_without_persisted_state_and_a_clock_step_back_is_rejected() -> None:
    """Why the store exists: without it the same restart reuses old timestamps."""
    clock = FakeClock()
    receiver = Decoder(9, Signing(KEY, FakeClock()))
    assert isinstance(receiver.feed(encode(STATES[0], 3, Signing(KEY, clock))), MemberState)
    clock.t -= 600.0
    got = receiver.feed(encode(STATES[0], 3, Signing(KEY, clock)))
    assert isinstance(got, Dropped) and got.reason == "replayed"


def test_received_timestamps_raise_the_senders_own() -> None:
    ahead = Signing(KEY, FakeClock(T0 + 3600))
    lagging_clock = FakeClock()
    lagging = Signing(KEY, lagging_clock)
    dec = Decoder(5, lagging)
    data = encode(STATES[0], 3, ahead)
    assert isinstance(dec.feed(data), MemberState)
    assert lagging.next_timestamp() > int.from_bytes(data[-12:-6], "little")


# ---- fault model (pure part) --------------------------------------------------------------
def test_fault_model_is_seeded_and_counts() -> None:
    def run(seed: int) -> list[list[tuple[float, bytes]]]:
        fm = FaultModel(loss=0.3, jitter_s=0.05, duplicate=0.2, reorder=0.1, seed=seed)
        return [fm.apply(bytes([i]), float(i)) for i in range(200)]

    assert run(1) == run(1) != run(2)
    fm = FaultModel(loss=0.3, jitter_s=0.05, duplicate=0.2, reorder=0.1, seed=1)
    out = [fm.apply(bytes([i % 256]), float(i)) for i in range(2000)]
    copies = sum(len(o) for o in out)
    c = fm.counts
    assert copies == 2000 + c["duplicated"] - c["lost"]
    assert 0.25 < c["lost"] / (2000 + c["duplicated"]) < 0.35
    assert all(0.0 <= due - i <= 0.05 + 0.25 for i, o in enumerate(out) for due, _ in o)


@pytest.mark.parametrize(
    ("kwargs", "copies"), [({"loss": 1.0}, 0), ({"duplicate": 1.0}, 2), ({}, 1)]
)
def test_fault_model_extremes(kwargs: dict[str, float], copies: int) -> None:
    fm = FaultModel(**kwargs)
    assert all(len(fm.apply(b"x", 0.0)) == copies for _ in range(20))


def test_fault_model_rejects_bad_probabilities() -> None:
    with pytest.raises(ValueError):
        FaultModel(loss=1.5)
    with pytest.raises(ValueError):
        FaultModel(jitter_s=-1.0)


# ---- a member flooding beyond its share (companion/group/flood.py) ----------------------------
def test_a_sender_at_its_share_is_never_refused_and_one_at_20x_is_held_to_the_margin() -> None:
    gate = FloodGate(share_hz=1.0, margin=2.0, burst=4.0)
    fair = flood = 0
    for k in range(2000):  # 100 s: member 1 at its share, member 2 at 20x
        t = k * 0.05
        if k % 20 == 0:
            assert not gate.full(1, t)
            gate.take(1, t)
            fair += 1
        if not gate.full(2, t):
            gate.take(2, t)
            flood += 1
    assert fair == 100
    assert flood == pytest.approx(4 + 2.0 * 1.0 * 100, abs=2)  # the burst, then 2x its share


def test_the_decoder_drops_states_beyond_the_share_before_decoding_and_counts_them() -> None:
    clock = FakeClock()
    decoder = Decoder(9, Signing(KEY, clock))
    decoder.limit_floods(FloodGate(share_hz=1.0, margin=2.0, burst=4.0))
    flooder, fair, forger = Signing(KEY, clock), Signing(KEY, clock), Signing(OTHER_KEY, clock)
    got: dict[int, int] = {3: 0, 4: 0}
    for k in range(200):  # 10 s of vehicle time
        t = k * 0.05
        clock.t = T0 + t
        for _ in range(20 if k % 20 == 0 else 0):  # 20 states a second from 3, its share is 1
            out = decoder.feed(encode(MemberState(3, t, 0j, 0.0), 3, flooder), t)
            got[3] += not isinstance(out, Dropped)
        out = decoder.feed(encode(MemberState(3, t, 0j, 0.0), 3, forger), t)  # no key
        assert isinstance(out, Dropped) and out.reason == "bad_signature"
        if k % 20 == 0:
            out = decoder.feed(encode(MemberState(4, t, 0j, 0.0), 4, fair), t)
            assert not isinstance(out, Dropped)  # 4 at its share: all in
            got[4] += 1
    assert got[4] == 10
    assert got[3] == pytest.approx(4 + 2 * 10, abs=2)
    assert decoder.counts["flood"] == 200 - got[3]
    assert decoder.counts["bad_signature"] == 200  # refused as forgeries, not as floods


def test_without_a_gate_there_is_no_flood_count() -> None:
    assert "flood" not in Decoder(9, Signing(KEY, FakeClock())).counts


def _repacked_by_pymavlink(ours: bytes, sysid: int, seq: int) -> bytes:
    """``ours`` decoded by pymavlink and packed again by pymavlink with the same header and
    signing timestamp: the reference encoder's bytes for the same fields."""
    ref = patrol.MAVLink(None).decode(bytearray(ours))
    mav = patrol.MAVLink(None, srcSystem=sysid, srcComponent=COMPID_COMPANION)
    mav.seq = seq
    if ours[2] & 1:  # signed: the same key, link and timestamp
        mav.signing.secret_key = KEY
        mav.signing.link_id = GROUP_LINK_ID
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = int.from_bytes(ours[-12:-6], "little")
    return bytes(ref.pack(mav))


@pytest.mark.parametrize("msg", STATES + ALERTS)
@pytest.mark.parametrize("signed", [False, True])
def test_our_frames_are_pymavlinks_byte_for_byte(msg: MemberState | Alert, signed: bool) -> None:
    """The struct encoder against pymavlink's pack: header, cut payload, CRC, signature."""
    signing = Signing(KEY, FakeClock()) if signed else None
    sysid = msg.sysid if isinstance(msg, MemberState) else 42
    for seq in (0, 1, 200):
        ours = encode(msg, sysid, signing, seq=seq)
        assert ours == _repacked_by_pymavlink(ours, sysid, seq)


@pytest.mark.parametrize("msg", STATES + ALERTS)
def test_our_decoding_agrees_with_pymavlinks_field_by_field(msg: MemberState | Alert) -> None:
    """What our decoder reads equals what pymavlink's decoder reads from the same bytes."""
    signing, dec, _ = pair()
    data = encode(msg, msg.sysid if isinstance(msg, MemberState) else 42, signing)
    ref = patrol.MAVLink(None).decode(bytearray(data))
    got = dec.feed(data)
    if isinstance(msg, MemberState):
        assert isinstance(got, MemberState)
        assert got.t_s == ref.time_usec / 1e6 and got.phase_rad == ref.phase
        assert got.centre_m == complex(ref.centre_north, ref.centre_east)
        assert got.alert_id == ref.alert_id and got.mode == msg.mode
    else:
        assert isinstance(got, Alert)
        assert got.site_m == complex(ref.north, ref.east) and got.bid_s == ref.bid
        assert got.alert_id == ref.alert_id and got.detector_sysid == ref.detector


def test_a_track_with_its_motion_model_goes_as_version_3_and_comes_back() -> None:
    signing, dec, _ = pair()
    tr = Track(100.0, 10.5 + 5.25j, 2 + 1j, 2.5, 0.5, 21, "stop", 0.62, -0.25, 0.5)
    data = encode(Alert("3-13", tr.pos_m, 3, 100.0, "update", track=tr), 3, signing)
    assert patrol.MAVLink(None).decode(bytearray(data)).version == 3
    got = dec.feed(data)
    assert isinstance(got, Alert) and got.track is not None
    assert (got.track.model, got.track.model_p) == ("stop", 0.62)
    assert got.track.turn_rad_s == -0.25 and got.track.manoeuvre_m_s2 == 0.5


def test_a_version_2_track_still_decodes_as_a_constant_velocity_track() -> None:
    # packed by pymavlink with the version-2 fields only, as an older member sends it
    mav = patrol.MAVLink(None, srcSystem=4, srcComponent=COMPID_COMPANION)
    msg = patrol.MAVLink_patrol_alert_message(
        100_000_000, 10.5, 5.25, 0.0, 4, 4, b"4-2", 2, 2.0, 1.0, 2.5, 0.5, 21, 0, 0, 0.0, 0.0
    )
    got = Decoder(9, None).feed(bytes(msg.pack(mav)))
    assert isinstance(got, Alert) and got.track is not None
    assert got.track.vel_m_s == 2 + 1j and got.track.sightings == 21
    assert (got.track.model, got.track.model_p, got.track.manoeuvre_m_s2) == ("cv", 1.0, 0.0)
    assert got.track.sigma_m(110.0) == pytest.approx(math.hypot(2.5, 5.0))


def test_an_unknown_track_model_is_dropped_as_malformed() -> None:
    mav = patrol.MAVLink(None, srcSystem=4, srcComponent=COMPID_COMPANION)
    msg = patrol.MAVLink_patrol_alert_message(
        100_000_000, 10.5, 5.25, 0.0, 4, 4, b"4-2", 3, 2.0, 1.0, 2.5, 0.5, 21, 7, 50, 0.0, 1.0
    )
    got = Decoder(9, None).feed(bytes(msg.pack(mav)))
    assert isinstance(got, Dropped) and got.reason == "malformed"
