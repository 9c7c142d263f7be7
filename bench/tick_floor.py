"""The floor under a companion's control tick in its own process: what its MAVLink and group
traffic costs before any control is computed (issue 46's goal: at most 0.4 ms a tick).

One process, no control step, the traffic of one companion of the demo (the ellipse, 6 UAVs,
10 Hz) for ``--ticks`` ticks, each part timed alone on this process's CPU clock:

* ``telemetry``: one datagram a tick from the simulator holding that tick's messages at the
  rates the companion asks of ArduPlane (``companion.process.config.telemetry_rates_hz``)
  and the simulator's defaults for the rest, received and parsed by pymavlink as the
  companion's link does (``mavutil`` over UDP: ``recv_msg`` until empty); the sender's own
  cost is measured apart and taken off;
* ``setpoint``: one SET_ATTITUDE_TARGET a tick, packed by pymavlink and sent over UDP;
* ``group in``: the states of the five others at 5 Hz (2.5 signed datagrams a tick), each
  received over UDP and checked and decoded by the group's codec (signature included);
* ``group out``: the own state at 5 Hz, encoded, signed and sent.

Their sum is the cost of a tick's traffic alone, on an otherwise idle process; the demo's
companions pay it and the control step (``bench/speed.py``'s in-memory figure) and the
scheduling of eight processes on the machine's cores on top.

    python bench/tick_floor.py [--ticks 3000]
"""

from __future__ import annotations

import argparse
import math
import os
import socket
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repo before bench/

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as d

from companion.contracts.signing import Signing
from companion.group.codec import Decoder, encode
from companion.group.messages import MemberState
from companion.process.config import telemetry_rates_hz
from sitl_model.telemetry import DEFAULT_RATES_HZ

RATE_HZ = 10.0  # the control rate: one tick per position message
OTHERS = 5  # the demo's other members
STATE_HZ = 5.0  # each member's state broadcast
KEY = bytes(range(32))


def _message(name: str, t_ms: int) -> object:
    """A message of type ``name`` with plausible values at ``t_ms`` (boot ms)."""
    build = {
        "HEARTBEAT": lambda: d.MAVLink_heartbeat_message(1, 3, 217, 15, 4, 3),
        "SYS_STATUS": lambda: d.MAVLink_sys_status_message(
            1, 1, 1, 500, 12600, 1500, 80, 0, 0, 0, 0, 0, 0
        ),
        "GPS_RAW_INT": lambda: d.MAVLink_gps_raw_int_message(
            t_ms * 1000, 3, -353632610, 1491652300, 684000, 121, 65535, 2500, 9000, 10
        ),
        "GLOBAL_POSITION_INT": lambda: d.MAVLink_global_position_int_message(
            t_ms, -353632610, 1491652300, 684000, 100000, 1200, -2100, 5, 27000
        ),
        "LOCAL_POSITION_NED": lambda: d.MAVLink_local_position_ned_message(
            t_ms, 120.5, -240.25, -100.0, 12.0, -21.0, 0.05
        ),
        "ATTITUDE": lambda: d.MAVLink_attitude_message(t_ms, 0.31, 0.02, 4.71, 0.01, 0.0, 0.2),
        "VFR_HUD": lambda: d.MAVLink_vfr_hud_message(18.0, 24.2, 270, 55, 100.0, 0.1),
        "HOME_POSITION": lambda: d.MAVLink_home_position_message(
            -353632610, 1491652300, 584000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0
        ),
        "EXTENDED_SYS_STATE": lambda: d.MAVLink_extended_sys_state_message(0, 2),
        "SYSTEM_TIME": lambda: d.MAVLink_system_time_message(1_700_000_000_000_000, t_ms),
        "WIND": lambda: d.MAVLink_wind_message(135.0, 6.0, 0.0),
        "MISSION_CURRENT": lambda: d.MAVLink_mission_current_message(0),
        "BATTERY_STATUS": lambda: d.MAVLink_battery_status_message(
            0, 1, 3, 32767, [12600] + [65535] * 9, 1500, 800, 900, 80
        ),
    }
    return build[name]()


def telemetry_datagrams(ticks: int) -> list[bytes]:
    """One datagram per tick with that tick's messages (packed as the simulator packs them)."""
    rates = dict(DEFAULT_RATES_HZ)
    rates.update(telemetry_rates_hz(RATE_HZ))
    mav = d.MAVLink(None, srcSystem=1, srcComponent=1)
    out = []
    for k in range(ticks):
        t_ms = 100 * k
        frames = b""
        for name, hz in rates.items():
            every = max(1, round(RATE_HZ / hz))
            if k % every == 0:
                frames += _message(name, t_ms).pack(mav)
        out.append(frames)
    return out


def _cpu(fn, *args) -> float:
    """CPU seconds of this process spent in ``fn(*args)``."""
    t0 = time.process_time()
    fn(*args)
    return time.process_time() - t0


def _udp_pair() -> tuple[socket.socket, tuple[str, int]]:
    """A sending socket and a free loopback address."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    addr = probe.getsockname()
    probe.close()
    return socket.socket(socket.AF_INET, socket.SOCK_DGRAM), addr


def telemetry_ms(ticks: int) -> tuple[float, float]:
    """(CPU ms a tick to receive and parse a tick's telemetry, messages a tick)."""
    grams = telemetry_datagrams(ticks)
    tx, addr = _udp_pair()
    conn = mavutil.mavlink_connection(f"udpin:{addr[0]}:{addr[1]}", source_system=255)
    conn.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    count = 0

    def both() -> None:
        nonlocal count
        for g in grams:
            tx.sendto(g, addr)
            while conn.recv_msg() is not None:
                count += 1

    cpu_both = _cpu(both)
    t0 = time.process_time()  # the sender's part, taken off
    for g in grams:
        tx.sendto(g, addr)
    cpu_send = time.process_time() - t0
    while conn.recv_msg() is not None:
        pass
    conn.close()
    tx.close()
    return 1000.0 * (cpu_both - cpu_send) / ticks, count / ticks


def setpoint_ms(ticks: int) -> float:
    """CPU ms a tick to pack and send one SET_ATTITUDE_TARGET."""
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    conn = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{rx.getsockname()[1]}", source_system=7, source_component=191
    )

    def send() -> None:
        for k in range(ticks):
            h = 0.5 * (0.1 + 1e-4 * k)
            conn.mav.set_attitude_target_send(
                100 * k, 1, 1, 0b00000111, [math.cos(h), math.sin(h), 0.0, 0.0], 0, 0, 0, 0.5
            )

    ms = 1000.0 * _cpu(send) / ticks
    conn.close()
    rx.close()
    return ms


def group_ms(ticks: int) -> tuple[float, float]:
    """(CPU ms a tick for the others' states in, for the own state out)."""
    n_in = round(ticks * OTHERS * STATE_HZ / RATE_HZ)
    n_out = round(ticks * STATE_HZ / RATE_HZ)
    senders = {s: Signing(KEY, time.time) for s in range(2, 2 + OTHERS)}
    grams = []
    for k in range(n_in):
        s = 2 + k % OTHERS
        st = MemberState(
            s, 1000.0 + 0.2 * k, 10.0 - 5.0j, (0.01 * k) % 6.28, "patrol", "", pos_m=300 + 40j
        )
        grams.append(encode(st, s, senders[s]))
    tx, addr = _udp_pair()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(addr)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 24)
    rx.setblocking(False)
    decoder = Decoder(1, Signing(KEY, time.time))
    for g in grams:  # queued first: only the receipt is timed
        tx.sendto(g, addr)

    def receive() -> None:
        for _ in grams:
            decoder.feed(rx.recv(2048))

    cpu_in = _cpu(receive)
    if decoder.counts["accepted"] != n_in:
        raise SystemExit(f"group: not every state was accepted: {decoder.counts}")
    own = Signing(KEY, time.time)
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send() -> None:
        for k in range(n_out):
            st = MemberState(1, 1000.0 + 0.2 * k, 10.0 - 5.0j, 0.5, "patrol", "", pos_m=1 + 2j)
            sink.sendto(encode(st, 1, own), addr)

    cpu_out = _cpu(send)
    for sock in (tx, rx, sink):
        sock.close()
    return 1000.0 * cpu_in / ticks, 1000.0 * cpu_out / ticks


def main() -> int:
    """Print each part's CPU ms a tick and their sum."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ticks", type=int, default=3000, help="control ticks (10 Hz) to time")
    args = p.parse_args()
    ticks = args.ticks
    tel, per_tick = telemetry_ms(ticks)
    sp = setpoint_ms(ticks)
    g_in, g_out = group_ms(ticks)
    rows = [
        (f"telemetry in ({per_tick:.1f} messages a tick)", tel),
        ("setpoint out (SET_ATTITUDE_TARGET)", sp),
        (f"group in ({OTHERS} members at {STATE_HZ:g} Hz, signed)", g_in),
        (f"group out (own state at {STATE_HZ:g} Hz, signed)", g_out),
    ]
    print(f"a companion's traffic alone, CPU ms a tick ({ticks} ticks at {RATE_HZ:g} Hz)")
    for name, ms in rows:
        print(f"  {name:<52} {ms:7.3f}")
    print(f"  {'sum':<52} {sum(ms for _, ms in rows):7.3f}")
    print(f"  load average now: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
