"""The companion's health to ground stations (issue 49, item 3): its HEARTBEAT as an onboard
controller and ONBOARD_COMPUTER_STATUS once a second, what each field carries, the simulator
forwarding both to its ``--gcs-out``, and a plain pymavlink ground station that sees a killed
companion within 3 s."""

from __future__ import annotations

import contextlib
import itertools
import socket
import threading
import time
from dataclasses import dataclass

import pytest
from pymavlink import mavutil

from companion.process.onboard import (
    LINK_MESH,
    LINK_NETWORK,
    LINK_UART,
    U8_UNUSED,
    U32_UNUSED,
    OnboardStatus,
    kib_s,
)
from sitl_model.codec import dialect
from sitl_model.testing import MavClient, SitlProcess
from tests.fleet_harness import FAST, Companion, free_udp_port

COMPANION_COMPID = 191


# ---- the message, on fake clocks ---------------------------------------------------------
@dataclass
class FakeLink:
    sysid: int | None = 7
    generation: int = 1
    rx: int = 0
    tx: int = 0

    @property
    def traffic_bytes(self) -> tuple[int, int]:
        return self.rx, self.tx


@dataclass
class FakeGroup:
    rx_bytes: int = 0
    tx_bytes: int = 0


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _status(link: FakeLink, group: FakeGroup | None, serial: bool = False):
    wall, cpu = Clock(), Clock()
    cpu.t = 5.0
    vehicle: list[float | None] = [None]
    st = OnboardStatus(
        wall, cpu, link, serial=serial, group=lambda: group, vehicle_s=lambda: vehicle[0]
    )
    return st, wall, cpu, vehicle


def _decoded(msg):
    """The message as a ground station decodes it (packed and parsed by pymavlink)."""
    mav = dialect.MAVLink(None, srcSystem=7, srcComponent=COMPANION_COMPID)
    return mav.decode(bytearray(msg.pack(mav)))


def test_onboard_computer_status_once_a_second_with_load_uptime_link_and_group():
    link, group = FakeLink(), FakeGroup()
    st, wall, cpu, vehicle = _status(link, group)
    (first,) = st.tick()
    assert st.tick() == ()  # not due again at the same instant
    wall.t += 0.5
    assert st.tick() == ()
    wall.t += 0.5  # 1 s after the first
    cpu.t += 0.25  # a quarter of a core
    link.rx, link.tx = 3 * 1024, 1024 + 1  # over that second
    group.rx_bytes, group.tx_bytes = 2000, 300
    vehicle[0] = 1_700_000_000.25
    (second,) = st.tick()
    m = _decoded(second)
    assert m.get_type() == "ONBOARD_COMPUTER_STATUS"
    assert m.uptime == 1000 and m.type == 0
    assert m.time_usec == 1_700_000_000_250_000  # vehicle time once known
    assert m.cpu_cores == [25] + [U8_UNUSED] * 7
    assert m.cpu_combined == [U8_UNUSED] * 10
    assert m.link_type == [LINK_NETWORK, LINK_MESH, 0, 0, 0, 0]
    assert m.link_rx_rate == [3, 2] + [U32_UNUSED] * 4  # KiB/s, rounded up
    assert m.link_tx_rate == [2, 1] + [U32_UNUSED] * 4
    assert m.link_rx_max == [U32_UNUSED] * 6 and m.ram_usage == U32_UNUSED
    assert m.status_flags == 0
    assert _decoded(first).time_usec == 0  # before vehicle time: the uptime (0 us)
    # nothing moved for a second: 0, not the previous figure
    wall.t += 1.0
    m = _decoded(st.tick()[0])
    assert m.link_rx_rate[:2] == [0, 0] and m.cpu_cores[0] == 0 and m.uptime == 2000


def test_a_serial_link_a_reopened_link_and_no_group_yet():
    link = FakeLink(rx=50_000, tx=50_000)  # bytes counted before the status started
    st, wall, _cpu, _v = _status(link, None, serial=True)
    st.tick()
    wall.t += 1.0
    link.generation, link.rx, link.tx = 2, 500, 0  # re-opened: its counts start again
    m = _decoded(st.tick()[0])
    assert m.link_type[0] == LINK_UART
    assert m.link_rx_rate[0] == 1 and m.link_tx_rate[0] == 0
    assert m.link_rx_rate[1] == U32_UNUSED  # no group before the first heartbeat


def test_nothing_before_the_autopilot_is_heard_and_no_burst_after_a_stall():
    link = FakeLink(sysid=None)
    st, wall, _cpu, _v = _status(link, None)
    assert st.tick() == ()
    link.sysid = 3
    assert len(st.tick()) == 1
    wall.t += 10.0  # the process stalled for 10 s: one message, then 1 s on
    assert len(st.tick()) == 1 and st.tick() == ()
    wall.t += 1.0
    assert len(st.tick()) == 1


@pytest.mark.parametrize(
    ("n_bytes", "dt_s", "expected"), [(0, 1.0, 0), (1, 1.0, 1), (1024, 1.0, 1), (1025, 1.0, 2),
                                      (4096, 2.0, 2), (10, 0.0, 0)]
)  # fmt: skip
def test_kib_s_rounds_up(n_bytes, dt_s, expected):
    assert kib_s(n_bytes, dt_s) == expected


# ---- the simulator forwards them to its ground stations ------------------------------------
@pytest.mark.integration
def test_simulator_forwards_the_companions_heartbeat_and_status_to_gcs_out():
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.settimeout(0.2)
    with SitlProcess("--gcs-out", f"127.0.0.1:{gcs.getsockname()[1]}", vehicles=1) as sitl:
        companion = MavClient(sitl.port(0), sysid=1, compid=COMPANION_COMPID)
        try:
            st, *_ = _status(FakeLink(sysid=1), FakeGroup())
            sent = [
                dialect.MAVLink_heartbeat_message(
                    dialect.MAV_TYPE_ONBOARD_CONTROLLER, dialect.MAV_AUTOPILOT_INVALID, 0, 0,
                    dialect.MAV_STATE_ACTIVE, 3,
                ),
                st.tick()[0],
            ]  # fmt: skip
            wire = [companion.enc.pack(m) for m in sent]
            for data in wire:
                companion.send_raw(data)
            got: list[bytes] = []
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline and not set(wire) <= set(got):
                with contextlib.suppress(TimeoutError):
                    got.append(gcs.recv(4096))
            assert set(wire) <= set(got)  # verbatim
        finally:
            companion.close()
            gcs.close()


# ---- a pymavlink ground station notes a killed companion -----------------------------------
DEAD_AFTER_S = 2.5  # the ground station's rule: no heartbeat for 2.5 periods of 1 s


class HeartbeatWatch:
    """A ground station on ``--gcs-out``: the companion's heartbeats and statuses as they
    arrive (wall s), and when it declared the companion dead."""

    def __init__(self, port: int, sysid: int) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", dialect="ardupilotmega")
        self.sysid = sysid
        self.beats: list[float] = []
        self.statuses: list[object] = []
        self.dead_at: float | None = None
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            m = self.conn.recv_match(
                type=["HEARTBEAT", "ONBOARD_COMPUTER_STATUS"], blocking=True, timeout=0.05
            )
            now = time.monotonic()
            if m is not None and (m.get_srcSystem(), m.get_srcComponent()) == (
                self.sysid, COMPANION_COMPID,
            ):  # fmt: skip
                if m.get_type() == "HEARTBEAT":
                    assert m.type == dialect.MAV_TYPE_ONBOARD_CONTROLLER
                    self.beats.append(now)
                    self.dead_at = None
                else:
                    self.statuses.append(m)
            if self.beats and self.dead_at is None and now - self.beats[-1] > DEAD_AFTER_S:
                self.dead_at = now

    def close(self) -> None:
        self._stop.set()
        self._t.join(2.0)
        self.conn.close()


def _wait(cond, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        time.sleep(0.05)


@pytest.mark.integration
def test_a_pymavlink_ground_station_sees_a_killed_companion_within_3_s(tmp_path):
    port = free_udp_port()
    gcs = HeartbeatWatch(port, sysid=1)
    try:
        with SitlProcess("--gcs-out", f"127.0.0.1:{port}", "--speedup", "1") as sitl:
            c = Companion([
                "--connect", f"udpout:127.0.0.1:{sitl.port(0)}", "--mission", str(FAST),
                "--insecure", "--group", f"239.255.14.9:{free_udp_port()}",
                "--log-dir", str(tmp_path / "c1"),
            ])  # fmt: skip
            try:
                _wait(lambda: len(gcs.beats) >= 6 and len(gcs.statuses) >= 4, 60, "no health")
                alive = gcs.beats[1:]  # the first ones may come fast: before the link is up
                gaps = [b - a for a, b in itertools.pairwise(alive)]
                assert max(gaps) < 1.6, gaps  # 1 Hz: the 2.5 s rule never fires while alive
                assert gcs.dead_at is None
                s = gcs.statuses[-1]
                assert s.uptime > 0 and 0 <= s.cpu_cores[0] <= 100
                assert s.link_type[:2] == [LINK_NETWORK, LINK_MESH]
                assert s.link_rx_rate[0] >= 1  # the autopilot's telemetry
                assert s.link_tx_rate[1] >= 1  # its own states to the group
                killed_at = time.monotonic()
                c.kill()
                _wait(lambda: gcs.dead_at is not None, 10, "the companion never declared dead")
                assert gcs.dead_at is not None
                seen_after = gcs.dead_at - killed_at
                print(f"\ncompanion killed: declared dead by the ground station {seen_after:.2f} s "
                      f"later (last gap alive {max(gaps):.2f} s)", end="")  # fmt: skip
                assert seen_after <= 3.0
            finally:
                c.stop()
    finally:
        gcs.close()
