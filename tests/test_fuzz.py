"""Fuzzing: the bugs ``bench/fuzz.py`` found, each pinned by its minimal datagram, the fuzz
generator's safety rule, and a bounded fuzz of a real fleet run (``bench.fuzz.run_fuzz``
with 5,000 datagrams at the simulator's ports and the group)."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from bench.fuzz import NOMINAL_RATE_HZ, run_fuzz
from bench.fuzzgen import READ_ONLY, FuzzGenerator
from sitl_model.cli import build, build_parser
from sitl_model.codec import Decoder
from sitl_model.testing import SitlProcess
from tests.fleet_harness import FAST, SPEEDUP, report, status_field

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

# A MAVLink 2 header with a message id no dialect defines (0xFFFFFF), no payload, CRC 0; and
# the same in MAVLink 1 (id 255). pymavlink returns an "UNKNOWN" message for them without
# any CRC check, so random bytes after a start byte used to count as valid messages.
UNKNOWN_V2 = bytes.fromhex("fd000000000101ffffff0000")
UNKNOWN_V1 = bytes.fromhex("fe00000101ff0000")


@pytest.mark.parametrize("data", [UNKNOWN_V2, UNKNOWN_V1])
def test_unknown_message_id_is_bad_data_not_a_message(data: bytes) -> None:
    assert Decoder().decode(data) == ([], 1)


def test_garbage_with_an_unknown_id_does_not_make_its_sender_a_peer() -> None:
    """Before the fix the simulator took the sender of UNKNOWN_V2 as a peer (rx += 1) and
    streamed telemetry to it: twelve bytes from a spoofed address bought a telemetry stream."""
    with SitlProcess("--vehicles", "1") as sitl, socket.socket(type=socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        s.sendto(UNKNOWN_V2, ("127.0.0.1", sitl.port(0)))
        deadline = time.monotonic() + 5.0
        while sum(int(status_field(line := sitl.control("status"), k)) for k in ("rx", "bad")) < 1:
            assert time.monotonic() < deadline, line
            time.sleep(0.05)
        assert (status_field(line, "bad"), status_field(line, "rx")) == ("1", "0"), line
        assert status_field(line, "peers") == "0", line
        s.settimeout(0.5)
        with pytest.raises(TimeoutError):
            s.recv(4096)  # no telemetry for the garbage's sender


def _simulation():
    args = build_parser().parse_args(["--mission", str(FAST)])
    sim, links, _cfg = build(args)
    return sim, links


def test_generator_never_sends_the_simulator_a_command_it_would_obey() -> None:
    """The autopilot link is unsigned: every frame with a correct CRC the generator sends a
    vehicle port must be read-only or addressed to a system id that is not a vehicle. Fed
    through a vehicle's link in memory, 3,000 of them change nothing: the fuzzed simulation
    flies exactly like an untouched twin, with the same modes, mission and parameters."""
    gen = FuzzGenerator(11, range(1, 7))
    dec = Decoder()
    fuzzed, links = _simulation()
    twin, _ = _simulation()
    n_valid = 0
    for k in range(3000):
        _kind, data = gen.datagram("sim")
        for m in dec.decode(data)[0]:
            n_valid += 1
            assert m.get_type() in READ_ONLY or getattr(m, "target_system", 0) > 6, m
            links[k % 6].handle(m, ("127.0.0.1", 9), 0.0)
        if k % 10 == 0:
            fuzzed.step()
            twin.step()
    assert n_valid > 500  # the check is not vacuous: many well-formed frames were handled
    assert np.array_equal(fuzzed.state.pos_m, twin.state.pos_m)
    assert [a.mode for a in fuzzed.autopilots] == [a.mode for a in twin.autopilots]
    assert [lk.missions.version for lk in links] == [0] * 6
    assert fuzzed.params.version == twin.params.version


@pytest.mark.slow
def test_bounded_fuzz_during_a_fleet_run(tmp_path) -> None:
    """5,000 random and mutated datagrams at the six vehicle ports and the group while the
    fleet flies: every process survives, the formation stays converged, each companion
    keeps at least 90 % of its 10 setpoints per simulated second, and the garbage is
    counted by the group's decoders and the simulator."""
    r = run_fuzz(tmp_path, datagrams=5000, rate_per_s=2000.0, seed=7, speedup=SPEEDUP)
    inc = r.group_drop_increase
    report(
        "fuzz",
        {
            "wall_s": round(r.send_wall_s, 2),
            "t_fuzz_s": r.t_fuzz_s,
            "alive": r.alive,
            "exit_codes": r.exit_codes,
            "rate_before": r.rate_before,
            "rate_during": r.rate_during,
            "splay_during_deg": r.splay_during_deg,
            "centre_during_m": r.centre_during_m,
            "group_drops": inc,
            "sim_bad": r.sim_after.get("bad", 0) - r.sim_before.get("bad", 0),
        },
    )
    assert r.all_alive, (r.alive, r.exit_codes)
    assert r.splay_during_deg < 2.0 and r.centre_during_m < 5.0
    assert min(r.rate_during) >= 0.9 * NOMINAL_RATE_HZ, r.rate_during
    # the group's garbage was read and dropped by every companion, for the right reasons
    # (a replayed copy of a member's own datagram is counted as "own" by that member)
    expected = sum(r.classes["group"].values()) - r.classes["group"].get("replay", 0)
    reasons = ("malformed", "unsigned", "bad_signature", "replayed", "foreign_link")
    for before, after in zip(r.drops_before, r.drops_after, strict=True):
        dropped = sum(after.get(k, 0) - before.get(k, 0) for k in reasons)
        assert dropped >= 0.9 * expected, (before, after)
    assert inc["bad_signature"] > 0 and inc["replayed"] > 0
    assert r.sim_after["bad"] - r.sim_before["bad"] >= sum(r.classes["sim"].values()) // 2
