"""MAVLink 2 signing on the companion <-> autopilot link (issue 7).

Pure tests of :class:`companion.contracts.signing.FrameCheck` against frames signed by pymavlink
(a third-party signer), then the real simulator started with ``--signing-key-file`` and real
``companion run --link-key-file`` processes: the signed companion steers the vehicle, while
unsigned, wrong-key and replayed commands from a third party are ignored and counted, and
companions without the key or with a wrong one stop with a clear message.
"""

from __future__ import annotations

import csv
import json
import time
from pathlib import Path

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav
from test_companion_lifecycle import wait_for

from companion.contracts.signing import LEASE, FrameCheck, Signing, signing_time
from companion.link.connection import link_signing
from sitl_model.testing import MavClient, SitlProcess
from tests.fleet_harness import FAST, Companion, companion_cli, free_udp_port

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

KEY = bytes(range(32))
WRONG = bytes(range(1, 33))
LOITER = 12  # ArduPlane custom mode


class Clock:
    """A settable wall clock (unix s)."""

    def __init__(self, t: float) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def signer(
    key: bytes | None, sysid: int = 255, compid: int = 190, link_id: int = 7, ts: int = 0
) -> mav.MAVLink:
    """A pymavlink MAVLink packer, signing with ``key`` (None: unsigned) from timestamp ``ts``."""
    m = mav.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        m.signing.secret_key = key
        m.signing.link_id = link_id
        m.signing.sign_outgoing = True
        m.signing.timestamp = ts or signing_time(time.time())
    return m


def set_mode(custom_mode: int) -> mav.MAVLink_message:
    return mav.MAVLink_command_long_message(
        1, 1, mav.MAV_CMD_DO_SET_MODE, 0, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom_mode,
        0, 0, 0, 0, 0,
    )  # fmt: skip


def request_version() -> mav.MAVLink_message:
    return mav.MAVLink_command_long_message(
        1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
        0, 0, 0, 0, 0, 0,
    )  # fmt: skip


def frame(packer: mav.MAVLink, msg: mav.MAVLink_message) -> bytes:
    return bytes(msg.pack(packer))


# ---- pure: the frame check -----------------------------------------------------------------
def test_frame_check_accepts_signed_and_refuses_unsigned_wrong_key_replayed_and_stale():
    now = Clock(1_800_000_000.0)
    check = FrameCheck(Signing(KEY, now, link_id=1))
    hb = mav.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)
    good = signer(KEY, ts=signing_time(now.t) - 100)
    f1, f2 = frame(good, hb), frame(good, hb)
    assert check.verdict(f1) is None
    check.accept(f1)
    assert check.verdict(f1) == "replayed"  # the same bytes again
    assert check.verdict(f2) is None  # the next timestamp of the stream
    assert check.verdict(frame(signer(None), hb)) == "unsigned"
    assert check.verdict(frame(signer(WRONG), hb)) == "bad_signature"
    v1 = mav.MAVLink(None, srcSystem=255, srcComponent=190)
    assert check.verdict(hb.pack(v1, force_mavlink1=True)) == "unsigned"  # MAVLink 1
    # a new stream must be at most a minute behind our own signing time
    old = signing_time(now.t) - LEASE - 10
    assert check.verdict(frame(signer(KEY, sysid=9, ts=old), hb)) == "replayed"
    assert check.verdict(frame(signer(KEY, sysid=9, ts=old + 20), hb)) is None
    # a tampered payload fails the signature
    bad = bytearray(f2)
    bad[12] ^= 1
    assert check.verdict(bytes(bad)) == "bad_signature"


def test_a_forged_far_future_frame_does_not_lock_the_real_sender_out():
    """pymavlink's own check records a stream's timestamp before verifying the signature."""
    check = FrameCheck(Signing(KEY, time.time, link_id=1))
    m = mav.MAVLink(None)
    m.robust_parsing = True
    check.install(m)
    hb = mav.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)
    forged = frame(signer(WRONG, ts=2**47), hb)  # same stream (255, 190, 7), far future
    real = frame(signer(KEY), hb)
    out = m.parse_buffer(forged + real) or []
    assert [x.get_type() for x in out] == ["BAD_DATA", "HEARTBEAT"]
    assert check.rejected(out[0].data).reason == "bad_signature"
    assert check.counts["accepted"] == 1 and check.counts["bad_signature"] == 1


def test_unsigned_radio_status_is_accepted_like_ardupilot():
    check = FrameCheck(Signing(KEY, time.time, link_id=1))
    m = mav.MAVLink(None)
    m.robust_parsing = True
    check.install(m)
    radio = mav.MAVLink_radio_status_message(200, 190, 90, 10, 5, 0, 0)
    cmd = set_mode(LOITER)
    out = m.parse_buffer(frame(signer(None), radio) + frame(signer(None), cmd)) or []
    assert [x.get_type() for x in out] == ["RADIO_STATUS", "BAD_DATA"]
    assert check.rejected(out[1].data).reason == "unsigned"


def test_link_timestamps_persist_apart_from_the_group_and_start_above_the_bound(tmp_path):
    key_file = tmp_path / "link.key"
    key_file.write_text(KEY.hex())
    key_file.chmod(0o600)
    first = link_signing(key_file, 3, state_dir=tmp_path)
    m = mav.MAVLink(None, srcSystem=3, srcComponent=191)
    first.install(m)
    first.stamp(m)
    sent = [m.signing.timestamp]
    frame(m, mav.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3))
    first.stamp(m)
    sent.append(m.signing.timestamp)
    assert sent[1] > sent[0] and first.signing.link_id == 0
    states = sorted(p.name for p in tmp_path.glob("*signing-ts"))
    assert len(states) == 1 and states[0].endswith(".sysid3.link-signing-ts"), states
    again = link_signing(key_file, 3, state_dir=tmp_path)  # a restarted companion
    assert again.signing.next_timestamp() > sent[1] + LEASE // 2


def test_key_files_open_to_others_are_refused_by_every_command(tmp_path):
    key_file = tmp_path / "link.key"
    key_file.write_text(KEY.hex())
    key_file.chmod(0o644)
    from sitl_model.cli import main as sitl_main

    assert sitl_main(["--vehicles", "1", "--signing-key-file", str(key_file)]) == 2
    for args in (
        ["run", "--connect", "udpout:127.0.0.1:9", "--mission", str(FAST), "--insecure"],
        ["upload", str(FAST), "--connect", "udpout:127.0.0.1:9"],
    ):
        r = companion_cli(*args, "--link-key-file", str(key_file))
        assert r.returncode == 2, r.stderr
        assert "chmod 600" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


# ---- the real simulator and companions -------------------------------------------------------
@pytest.fixture(scope="module")
def signed_sim(tmp_path_factory):
    """One signing vehicle at 10x with truth and events logs; the key files beside them."""
    out = tmp_path_factory.mktemp("link_signing")
    for name, key in (("link.key", KEY), ("wrong.key", WRONG)):
        (out / name).write_text(key.hex() + "\n")
        (out / name).chmod(0o600)
    sim = SitlProcess(
        "--speedup", "10",
        "--signing-key-file", str(out / "link.key"),
        "--truth-log", str(out / "truth.csv"),
        "--events-log", str(out / "events.jsonl"),
        "--status-interval", "1",
    )  # fmt: skip
    try:
        assert any("link signing on" in ln for ln in sim.stderr_lines)
        yield sim, out
    finally:
        assert sim.stop() == 0


def rejects(sim: SitlProcess) -> dict[str, int]:
    """The simulator's signing counters (from the status control line)."""
    fields = dict(f.split("=", 1) for f in sim.control("status").split() if "=" in f)
    return {k: int(fields[k]) for k in ("unsigned", "bad_signature", "replayed")}


def truth_modes(out: Path, since_s: float) -> set[str]:
    with open(out / "truth.csv") as fh:
        return {r["mode"] for r in csv.DictReader(fh) if r["mode"] and float(r["t_s"]) >= since_s}


def sim_time(out: Path) -> float:
    with open(out / "truth.csv") as fh:
        rows = [ln for ln in fh.read().splitlines()[1:] if ln.count(",") == 11]
    return float(rows[-1].split(",")[0])


def acks_after(them: MavClient, data: bytes, wait_s: float) -> list[int]:
    """A third party on the vehicle's port sends ``data`` (bytes made by pymavlink); the
    commands of the COMMAND_ACKs it hears within ``wait_s`` (it reads signed frames without
    checking them, having no key)."""
    them.drain()
    them.send_raw(data)
    return [m.command for m in them.collect(wait_s) if m.get_type() == "COMMAND_ACK"]


def companion_args(sim: SitlProcess, *extra: str) -> list[str]:
    return [
        "--connect", f"udpout:127.0.0.1:{sim.port(0)}",
        "--mission", str(FAST),
        "--sysid", "1",
        "--insecure",
        "--group", f"239.255.14.11:{free_udp_port()}",
        *extra,
    ]  # fmt: skip


def test_signed_companion_steers_and_forged_commands_are_ignored(signed_sim):
    sim, out = signed_sim
    log = out / "c_signed"
    c = Companion(
        companion_args(
            sim, "--link-key-file", str(out / "link.key"), "--state-dir", str(out),
            "--log-dir", str(log), "--status-interval", "1",
        )
    )  # fmt: skip
    them = MavClient(sim.port(0))  # its hello HEARTBEAT is unsigned: counted before we start
    try:
        wait_for(lambda: any("auth=commanding" in ln for ln in c.lines), 20, "no command")
        t_commanding = sim_time(out)
        before = rejects(sim)
        # unsigned, and signed with the wrong key: LOITER is never acknowledged nor flown
        assert acks_after(them, frame(signer(None), set_mode(LOITER)), 1.0) == []
        assert acks_after(them, frame(signer(WRONG), set_mode(LOITER)), 1.0) == []
        # a correctly signed request is answered once; the same bytes replayed are not
        req = frame(signer(KEY), request_version())
        assert acks_after(them, req, 2.0) == [mav.MAV_CMD_REQUEST_MESSAGE]
        assert acks_after(them, req, 1.0) == []
        after = rejects(sim)
        assert {k: after[k] - before[k] for k in after} == {
            "unsigned": 1, "bad_signature": 1, "replayed": 1,
        }  # fmt: skip
        wait_for(lambda: sim_time(out) > t_commanding + 20, 10, "simulation stalled")
        assert truth_modes(out, t_commanding) == {"GUIDED"}
        final = [ln for ln in c.lines if "auth=" in ln][-1]
        assert "auth=commanding" in final and "ap_mode=GUIDED" in final
        t_stop = sim_time(out)
    finally:
        them.close()
        code = c.stop()
    assert code == 0
    # the vehicle flew the companion's setpoints: it turned, and GUIDED never timed out
    with open(out / "truth.csv") as fh:
        rows = [r for r in csv.DictReader(fh) if t_commanding <= float(r["t_s"]) <= t_stop]
    assert max(abs(float(r["turn_rate_deg_s"])) for r in rows) > 2.0
    events = [json.loads(ln) for ln in (out / "events.jsonl").read_text().splitlines()]
    names = [e["event"] for e in events if t_commanding <= e["t_s"] <= t_stop]
    assert "guided_timeout" not in names and "link_rejected" in names
    # a frame captured from the companion's own (signed) stream, replayed after it stopped
    tl = mavutil.mavlink_connection(str(log / "autopilot.tlog"))
    captured = []
    while (m := tl.recv_match(type="COMMAND_LONG")) is not None:
        if m.get_srcComponent() == 191:
            captured.append(bytes(m.get_msgbuf()))
    tl.close()
    assert captured and all(f[2] & 1 for f in captured)  # signed frames in the tlog
    them = MavClient(sim.port(0))
    try:
        before = rejects(sim)["replayed"]
        assert acks_after(them, captured[0], 1.0) == []
        assert rejects(sim)["replayed"] == before + 1
    finally:
        them.close()


@pytest.mark.parametrize(
    ("key", "message"),
    [
        (None, "signs its MAVLink frames and answered none of our commands"),
        ("wrong.key", "no valid heartbeat from the autopilot"),
    ],
)
def test_companion_without_the_key_stops_with_a_clear_message(signed_sim, key, message):
    sim, out = signed_sim
    extra = ("--link-key-file", str(out / key), "--state-dir", str(out)) if key else ()
    before = rejects(sim)
    c = Companion(companion_args(sim, *extra))
    try:
        c.proc.wait(20)
    finally:
        code = c.stop()
    text = "".join(c.lines)
    assert code == 2, text
    last = c.lines[-1]
    assert last.startswith("companion run: error: ") and message in last, text
    assert "--link-key-file" in last
    if key:
        assert "bad_signature" in last
    after = rejects(sim)
    grew = "bad_signature" if key else "unsigned"
    assert after[grew] > before[grew]


def test_upload_with_the_link_key(signed_sim):
    sim, out = signed_sim
    r = companion_cli(
        "upload", str(FAST), "--connect", f"udpout:127.0.0.1:{sim.port(0)}", "--sysid", "1",
        "--link-key-file", str(out / "link.key"), "--listen-s", "10",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "sysid 1: uploaded 16 waypoints, verified" in r.stdout
    r = companion_cli(
        "upload", str(FAST), "--connect", f"udpout:127.0.0.1:{sim.port(0)}", "--sysid", "1",
        "--link-key-file", str(out / "wrong.key"), "--listen-s", "1",
    )  # fmt: skip
    assert r.returncode == 2
    assert "no autopilot heard" in r.stderr and "bad_signature" in r.stderr, r.stderr
    assert r.stderr.rstrip().endswith("wrong key?)"), r.stderr


def test_a_signed_upload_to_an_autopilot_that_does_not_sign_says_so(tmp_path):
    """The documented refusal (docs/companion.md, "Link signing"): every frame unsigned, so
    the autopilot does not sign; not "wrong key?"."""
    key = tmp_path / "link.key"
    key.write_text(KEY.hex() + "\n")
    key.chmod(0o600)
    sim = SitlProcess("--speedup", "10")
    try:
        r = companion_cli(
            "upload", str(FAST), "--connect", f"udpout:127.0.0.1:{sim.port(0)}", "--sysid",
            "1", "--link-key-file", str(key), "--listen-s", "2",
        )  # fmt: skip
    finally:
        assert sim.stop() == 0
    assert r.returncode == 2, r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert "no autopilot heard" in last and "unsigned" in last, last
    assert "the autopilot does not sign its frames: set its key with SETUP_SIGNING" in last
    assert "wrong key" not in last
