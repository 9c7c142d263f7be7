"""The in-memory engine's two wires: MAVLink messages packed and parsed (as over UDP) or
passed on as the objects a decoder would return (sitl_model.codec.as_received). The objects
carry the values the bytes carry, so a mission flies the same both ways."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from companion.report.summary import write_report
from companion.sim.inmemory import Engine, EngineConfig
from sitl_model.codec import Decoder, Encoder, as_received
from sitl_model.codec import dialect as d

REPO = Path(__file__).resolve().parents[1]
FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"


def _messages() -> list:
    """Messages of every kind that cross a vehicle link: float fields with values float32
    cannot hold, float arrays, a text longer than its field, int arrays, extensions."""
    third = 1.0 / 3.0
    return [
        d.MAVLink_attitude_message(123456, third, -math.pi, 2.0 / 3.0, 1e-9, 1e30, -0.1),
        d.MAVLink_set_attitude_target_message(
            0,
            1,
            1,
            0b00000111,
            [math.cos(0.1), math.sin(0.1) * third, 0.0, 0.3],
            0.0,
            0.0,
            0.123456789,
            0.5,
        ),
        d.MAVLink_command_long_message(1, 1, 43002, 0, 1.0, 271.123456789, 2.5, 0, 0, 0, 0),
        d.MAVLink_statustext_message(4, b"x" * 60 + b"beyond the field"),
        d.MAVLink_param_value_message(b"SIM_WIND_SPD", 5.123456789, 9, 80, 3),
        d.MAVLink_battery_status_message(
            0,
            0,
            0,
            32767,
            [15000, 65535, 65535, 65535, 65535, 65535, 65535, 65535, 65535, 65535],
            1234,
            567,
            89,
            70,
            3600,
            1,
            [0, 0, 0, 0],
            0,
            0,
        ),
        d.MAVLink_global_position_int_message(
            1000, 398000000, -840000000, 350000, 100000, -123, 456, 0, 35999
        ),
        d.MAVLink_vfr_hud_message(19.87654321, 24.1234567, 271, 50, 350.000001, 0.0),
        d.MAVLink_wind_message(180.0000001, 5.55555555, 0.0),
        d.MAVLink_heartbeat_message(1, 3, 217, 15, 4, 3),
    ]


def test_an_object_passed_on_reads_as_the_decoded_frame_field_for_field() -> None:
    enc, dec = Encoder(3, 1), Decoder()
    passer = Encoder(3, 1)
    for seq, msg in enumerate(_messages()):
        frame = enc.pack(msg)
        (decoded,), bad = dec.decode(frame)
        assert bad == 0
        passed = passer.pass_on(msg)
        assert passed.get_type() == decoded.get_type()
        assert passed.to_dict() == decoded.to_dict(), msg.get_type()
        for name in decoded.get_fieldnames():  # the same Python values, bit for bit
            assert repr(getattr(passed, name)) == repr(getattr(decoded, name)), name
        for k in ("srcSystem", "srcComponent", "seq", "msgId", "incompat_flags"):
            assert getattr(passed.get_header(), k) == getattr(decoded.get_header(), k), k
        assert passed.get_seq() == seq


def test_a_copy_leaves_the_senders_message_as_it_was() -> None:
    msg = _messages()[0]
    roll = msg.roll
    copy = as_received(msg, 1, 191, 7, copy=True)
    assert msg.roll == roll and copy.roll != roll  # 1/3 is not a float32
    assert copy.get_srcComponent() == 191 and msg.get_srcComponent() == 0


def test_a_signing_encoder_refuses_to_pass_objects() -> None:
    from companion.contracts.signing import FrameCheck, Signing

    enc = Encoder(1, 1, FrameCheck(Signing(bytes(32), lambda: 1.8e9)))
    with pytest.raises(ValueError, match="bytes"):
        enc.pass_on(_messages()[0])
    with pytest.raises(ValueError, match="signed"):
        EngineConfig(FAST, wire="objects", link_signing=True)


@pytest.mark.contract
def test_objects_and_bytes_fly_the_same_mission_to_the_same_measures(tmp_path) -> None:
    """The fast ellipse with gusts and GPS noise through the decoy's alert (240 s), once
    with bytes and once with objects: the same truth, events and measures, byte for byte."""
    params = {"SIM_WIND_TURB": 1.5, "SIM_GPS_NOISE": 1.0}
    outs = {}
    for wire in ("bytes", "objects"):
        out = tmp_path / wire
        with Engine(EngineConfig(FAST, out, params=params, wire=wire)) as e:
            e.run(240.0)
            assert e.cfg.objects == (wire == "objects")
            if wire == "objects":  # nothing was packed: the wires only passed objects on
                assert all(p.enc._mav.total_packets_sent == 0 for p in e.ports)
        write_report(out, plots=False)
        outs[wire] = out
    metrics = {w: json.loads((o / "metrics.json").read_text()) for w, o in outs.items()}
    assert metrics["bytes"]["alerts_raised"] >= 1  # the decoy was flown to
    assert metrics["objects"] == metrics["bytes"]
    for f in ("truth.csv", "events.jsonl", "sim_events.jsonl"):
        assert (outs["objects"] / f).read_bytes() == (outs["bytes"] / f).read_bytes(), f
