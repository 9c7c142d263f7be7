"""PATROL_STATE version 3: the battery and relief fields (docs/protocol.md, docs/energy.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.contracts.signing import Signing
from companion.group.codec import Decoder, Dropped, EncodeError, encode
from companion.group.dialect import XML_PATH, generate, patrol
from companion.group.messages import Energy, MemberState, Mode, WindRecord

KEY = bytes(range(32))
T0 = 1_700_000_000.0
BASE = dict(pos_m=10 - 5j, wind_est_m_s=0.5 + 4.9j, wind_record=WindRecord(2, 1, 5j, 30.0))


def _pair():
    return Signing(KEY, lambda: T0), Decoder(9, Signing(KEY, lambda: T0))


@pytest.mark.parametrize(
    "energy",
    [
        Energy("on_station", 63.0, 2345.678901, 0),
        Energy("spare", None, 4000.0, 0),
        Energy("relieving", 99.5, 1800.0, 4),
        Energy("home", 21.25, None, 0),
        Energy("on_station", 80.0, 100.0, 12),
        Energy("unavailable", 97.0, None, 0),
    ],
)
def test_energy_round_trips(energy: Energy) -> None:
    signing, dec = _pair()
    mode = Mode.PATROL if energy.role == "on_station" else Mode.SPARE
    st = MemberState(3, 12.5, 1 + 2j, 1.0, mode, "", energy=energy, **BASE)
    got = dec.feed(encode(st, 3, signing))
    assert isinstance(got, MemberState) and got.mode is mode
    e = got.energy
    assert e is not None and (e.role, e.relief_sysid) == (energy.role, energy.relief_sysid)
    if energy.battery_pct is None:
        assert e.battery_pct is None
    else:
        assert e.battery_pct == float(np.float32(energy.battery_pct))
    if energy.t_s is None:
        assert e.t_s is None
    else:
        assert e.t_s == pytest.approx(energy.t_s, abs=1e-6)
    assert got.wind_record == BASE["wind_record"]  # the version-2 fields still arrive


def test_a_state_without_energy_is_sent_as_version_2_with_the_same_bytes() -> None:
    # independent check: pack the version-2 fields by hand with the generated message
    signing, dec = _pair()
    st = MemberState(3, 12.5, 1 + 2j, 1.0, Mode.PATROL, "", **BASE)
    ours = encode(st, 3, None)
    m = patrol.MAVLink_patrol_state_message(
        12_500_000, 1.0, 2.0, 1.0, 0, b"", 2, 10.0, -5.0, 0.5, 4.9, 2, 1, 0.0, 5.0, 30_000_000
    )
    mav = patrol.MAVLink(None, srcSystem=3, srcComponent=191)
    assert ours == bytes(m.pack(mav))
    got = dec.feed(encode(st, 3, signing))
    assert isinstance(got, MemberState) and got.energy is None


def test_a_version_2_receiver_reads_a_version_3_state(tmp_path: Path) -> None:
    # the dialect without the version-3 fields (as before them), generated and used to decode
    old = "".join(
        line for line in XML_PATH.read_text().splitlines(True) if "Version 3:" not in line
    )
    assert "battery_pct" not in old and "wind_t_usec" in old
    path = tmp_path / "patrol_v2.xml"
    path.write_text(old)
    v2 = generate(path)
    energy = Energy("on_station", 50.0, 99.0)
    st = MemberState(3, 12.5, 1 + 2j, 1.0, Mode.PATROL, "", energy=energy, **BASE)
    msg = v2.MAVLink(None).decode(bytearray(encode(st, 3, None)))
    assert msg.get_type() == "PATROL_STATE" and msg.version == 3
    assert (msg.phase, msg.wind_seq, msg.wind_t_usec) == (1.0, 2, 30_000_000)


def test_a_spare_state_is_mode_5_on_the_wire() -> None:
    st = MemberState(10, 1.0, 0j, 0.0, Mode.SPARE, "", energy=Energy("spare", 100.0, 0.0))
    msg = patrol.MAVLink(None).decode(bytearray(encode(st, 10, None)))
    assert msg.mode == patrol.PATROL_MODE_SPARE == 5
    assert msg.relief_role == 2


def test_a_bad_relief_role_on_the_wire_is_malformed() -> None:
    m = patrol.MAVLink_patrol_state_message(
        1, 0.0, 0.0, 0.0, 0, b"", 3, math.nan, math.nan, math.nan, math.nan, 0, 0,
        math.nan, math.nan, 0, 50.0, 0, 9, 0,
    )  # fmt: skip
    mav = patrol.MAVLink(None, srcSystem=3, srcComponent=191)
    got = Decoder(9, None).feed(bytes(m.pack(mav)))
    assert isinstance(got, Dropped) and got.reason == "malformed"


def test_encode_refuses_an_unknown_role_or_sysid() -> None:
    for e in (Energy("tired", 1.0, 1.0), Energy("spare", 1.0, 1.0, 256)):  # type: ignore[arg-type]
        with pytest.raises(EncodeError):
            encode(MemberState(3, 1.0, 0j, 0.0, energy=e), 3, None)
