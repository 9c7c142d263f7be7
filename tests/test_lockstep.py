"""Lockstep (``sitl-model --lockstep``): the pure gate, its inputs from the vehicle link, the
command line, and the real simulator held by a peer that answers (or not) over loopback.

The gate's contract: a vehicle is waited for only in GUIDED, once it has a controlling peer
(a setpoint since it entered GUIDED), for its latest position report, at most the bound; a
silent vehicle times out once per episode and is then not waited for until it answers.
"""

from __future__ import annotations

import itertools
import json
import time

import pytest

from sitl_model.cli import build, build_parser
from sitl_model.codec import dialect as d
from sitl_model.lockstep import DEFAULT_WAIT_BOUND_S, LockstepGate, WaitTimeout
from sitl_model.testing import MavClient, SitlProcess

G = [True, True, True]


# ---- the pure gate -----------------------------------------------------------------------
def test_nobody_is_waited_for_before_a_controlling_peer_exists():
    gate = LockstepGate(3, 0.5)
    for i in range(3):
        gate.position_sent(i, 0.0)
    assert gate.waiting_for(G) == []
    assert gate.blocked(10.0, G) == (False, [])  # no bound is ever hit either
    assert gate.timeouts == 0


def test_a_live_vehicle_holds_the_step_until_its_setpoint():
    gate = LockstepGate(3, 0.5)
    gate.setpoint(1)  # vehicle 1 has a controller; 0 and 2 have none
    for i in range(3):
        gate.position_sent(i, 1.0)
    assert gate.waiting_for(G) == [1]
    assert gate.blocked(1.2, G) == (True, [])
    assert gate.next_deadline_s(G) == pytest.approx(1.5)
    gate.setpoint(1)
    assert gate.blocked(1.3, G) == (False, [])
    assert gate.waited_s == pytest.approx(0.1)  # held from 1.2 to 1.3 (wall s)
    assert gate.next_deadline_s(G) is None


def test_the_earliest_deadline_is_the_oldest_pending_report():
    gate = LockstepGate(3, 0.5)
    for i in range(3):
        gate.setpoint(i)
    gate.position_sent(2, 4.0)
    gate.position_sent(0, 4.2)
    assert gate.waiting_for(G) == [0, 2]
    assert gate.next_deadline_s(G) == pytest.approx(4.5)


def test_a_silent_vehicle_times_out_once_per_episode_and_rejoins_on_its_next_setpoint():
    gate = LockstepGate(2, 0.5)
    gate.setpoint(0)
    gate.setpoint(1)
    gate.position_sent(0, 0.0)
    gate.position_sent(1, 0.0)
    gate.setpoint(1)  # 1 answers, 0 is silent
    assert gate.blocked(0.49, [True, True]) == (True, [])
    held, out = gate.blocked(0.5, [True, True])
    assert not held and out == [WaitTimeout(0, 0.5)]
    assert gate.timeouts == 1
    # the silent one is not waited for again: later reports go out, no hold, no new timeout
    for k in range(1, 20):
        gate.position_sent(0, 0.5 + 0.01 * k)
        gate.position_sent(1, 0.5 + 0.01 * k)
        gate.setpoint(1)
        assert gate.blocked(10.0 + k, [True, True]) == (False, [])
    assert gate.timeouts == 1
    # a late setpoint ends the episode: waited for again, and a second silence is a new one
    gate.setpoint(0)
    gate.position_sent(0, 50.0)
    assert gate.blocked(50.1, [True, True]) == (True, [])
    assert gate.blocked(50.6, [True, True])[1] == [WaitTimeout(0, pytest.approx(0.6))]
    assert gate.timeouts == 2


def test_out_of_guided_is_not_waited_for_and_needs_a_new_setpoint_after_guided():
    gate = LockstepGate(1, 0.5)
    gate.setpoint(0)
    gate.position_sent(0, 0.0)
    assert gate.blocked(0.1, [False]) == (False, [])  # a pilot took it (LOITER)
    gate.position_sent(0, 0.2)
    # GUIDED again: its companion has not resumed yet, so the report is not waited for
    assert gate.blocked(0.3, [True]) == (False, [])
    assert gate.blocked(5.0, [True]) == (False, [])
    assert gate.timeouts == 0
    gate.setpoint(0)  # resumed
    gate.position_sent(0, 5.1)
    assert gate.blocked(5.2, [True]) == (True, [])


@pytest.mark.parametrize("bound", [0.0, -1.0, float("nan"), float("inf")])
def test_the_bound_must_be_a_positive_time(bound):
    with pytest.raises(ValueError, match="lockstep wait bound"):
        LockstepGate(2, bound)


# ---- its inputs: the vehicle link counts setpoints; the command line -------------------------
def _args(*extra: str):
    return build_parser().parse_args(["--vehicles", "2", "--no-control", *extra])


def test_the_link_counts_every_new_setpoint_and_nothing_else():
    _, links, _ = build(_args())
    link = links[0]
    peer = ("127.0.0.1", 1)

    def rate(t_ms: int, target: int = 1):
        return d.MAVLink_set_attitude_target_message(
            t_ms, target, 1, 0xC3, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.1, 0.0
        )

    heading = d.MAVLink_command_long_message(1, 1, 43002, 0, 0, 90, 0, 0, 0, 0, 0)
    mode = d.MAVLink_command_long_message(1, 1, 176, 0, 1, 15, 0, 0, 0, 0, 0)
    # rate, a keep-alive repeat of it, heading, a mode command, vehicle 2's (foreign here),
    # the first rate again (new: only a repeat of the setpoint just before is not), a new rate
    for m in (rate(100), rate(100), heading, mode, rate(100, target=2), rate(100), rate(200)):
        link.handle(m, peer, 0.0)
    assert link.setpoints_rx == 4
    assert links[1].setpoints_rx == 0


def test_cli_lockstep_flags():
    _, _, cfg = build(_args())
    assert not cfg.lockstep and cfg.lockstep_wait_s == DEFAULT_WAIT_BOUND_S
    _, _, cfg = build(_args("--lockstep", "--lockstep-wait", "2"))
    assert cfg.lockstep and cfg.lockstep_wait_s == 2.0
    for bad in ("0", "-1", "nan"):
        with pytest.raises(ValueError, match="--lockstep-wait"):
            build(_args("--lockstep", "--lockstep-wait", bad))


# ---- the real simulator held by one answering (then silent) peer --------------------------
def _positions(client: MavClient, wall_s: float) -> list[int]:
    """time_boot_ms of every GLOBAL_POSITION_INT received during ``wall_s``."""
    return [m.time_boot_ms for m in client.collect(wall_s) if m.get_type() == "GLOBAL_POSITION_INT"]


def _turn(client: MavClient, time_boot_ms: int = 0) -> None:
    """A turn-rate setpoint stamped with the report it answers (as ``companion run`` does:
    a field-for-field repeat would be a keep-alive, not an answer)."""
    client.send(
        d.MAVLink_set_attitude_target_message(
            time_boot_ms, 1, 1, 0xC3, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.05, 0.0
        )
    )


@pytest.mark.integration
def test_simulator_waits_for_the_answer_then_times_out_once_and_loiters(tmp_path):
    """As fast as possible (speedup 1e6) but lockstepped: the world stops at each position
    report until the peer's setpoint; a silent peer costs one bound (1 s), one timeout and
    one event, then the vehicle runs free and loiters after GUID_TIMEOUT as without lockstep."""
    events = tmp_path / "events.jsonl"
    args = ("--speedup", "1e6", "--lockstep", "--lockstep-wait", "1", "--events-log", str(events))
    args += ("--param", "SIM_RATE_OK=1")  # fly the body-rate setpoints (ArduPlane ignores them)
    with SitlProcess(*args, "--status-interval", "0.5") as sitl:
        client = MavClient(sitl.port(0))
        try:
            _turn(client)  # now a controlling peer
            seen = _positions(client, 0.3)
            assert seen, "no position report"
            # answer every report: each answer releases exactly one more 0.2 s of flight
            answered = [max(seen)]
            for _ in range(5):
                client.drain()
                last_sent = answered[-1]
                _turn(client, last_sent)
                answered += _positions(client, 0.15)
            steps = sorted(set(answered))
            assert len(steps) >= 4
            assert all(b - a == 200 for a, b in itertools.pairwise(steps)), steps
            # a keep-alive (the last setpoint again) answers nothing: still held
            _turn(client, last_sent)
            # held: no answer for 0.5 s (under the 1 s bound), the clock does not move
            client.drain()
            held = _positions(client, 0.5)
            assert held == [], held
            # silent past the bound: the simulator goes on alone, once
            t0 = time.monotonic()
            later = _positions(client, 2.0)
            assert later and max(later) - steps[-1] > 3000  # far ahead: free again
            assert time.monotonic() - t0 >= 1.9
        finally:
            client.close()
        time.sleep(0.6)
        status = [ln for ln in sitl.stderr_lines if ln.startswith("sitl t=")]
    assert "lockstep_timeouts=1 " in status[-1], status[-1]
    evs = [json.loads(ln) for ln in events.read_text().splitlines()]
    timeouts = [e for e in evs if e["event"] == "lockstep_wait_timeout"]
    assert len(timeouts) == 1 and timeouts[0]["sysid"] == 1
    assert timeouts[0]["waited_wall_s"] >= 1.0
    # (a GUIDED timeout may also come first, at 3 s, if the peer connects late)
    loiter = [e for e in evs if e["event"] == "guided_timeout" and e["t_s"] > timeouts[0]["t_s"]]
    assert loiter, evs  # GUID_TIMEOUT later, simulated
    assert loiter[0]["t_s"] - timeouts[0]["t_s"] <= 3.0 + 0.05
