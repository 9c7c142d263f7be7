"""The autopilot link over a serial device: a pseudo-terminal pair stands in for the cable.

pymavlink opens ``/dev/...,BAUD`` URLs with pyserial, which it does not require itself: a
fresh install without it could not open a serial port ("No module named 'serial'"). Here the
companion's real :class:`~companion.link.connection.AutopilotLink` opens the slave end of a
pty at 921600 baud and an autopilot is played on the master end with pymavlink's encoder.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.connection import AutopilotLink
from companion.process.loop import Poller

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(not hasattr(os, "openpty"), reason="no pseudo-terminals here"),
]


def _read_frames(fd: int, parser: mav.MAVLink, within_s: float) -> list:
    """Every MAVLink message the companion wrote to the master end within ``within_s``."""
    got: list = []
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            got.extend(parser.parse_buffer(os.read(fd, 4096)) or [])
    return got


def test_a_serial_device_opens_and_carries_mavlink_both_ways() -> None:
    """The link opens a serial device, hears the autopilot's heartbeat on it, learns its
    system id, and its own heartbeat comes back over the same wire."""
    master, slave = os.openpty()
    link = None
    try:
        link = AutopilotLink(f"{os.ttyname(slave)},921600", clock=time.monotonic)
        autopilot = mav.MAVLink(None, srcSystem=7, srcComponent=1)
        hb = autopilot.heartbeat_encode(
            mav.MAV_TYPE_FIXED_WING, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 15, 4
        )
        heard: list = []
        end = time.monotonic() + 5.0
        while not heard and time.monotonic() < end:
            os.write(master, hb.pack(autopilot))
            time.sleep(0.05)
            heard = [m for m in link.receive() if m.get_type() == "HEARTBEAT"]
        assert heard, "no heartbeat read from the serial device"
        assert link.sysid == 7
        link.tick()  # the companion's own heartbeat goes out on the wire
        parser = mav.MAVLink(None)
        parser.robust_parsing = True
        sent = _read_frames(master, parser, 1.0)
        assert any(m.get_type() == "HEARTBEAT" and m.get_srcSystem() == 7 for m in sent)
    finally:
        if link is not None:
            link.close()
        os.close(master)
        os.close(slave)


# ---- a cable that can be pulled, a wire that can be cut -------------------------------------
class Cable:
    """A serial cable played with a pseudo-terminal: the companion opens ``path`` (a symbolic
    link to the slave end, as udev's /dev/serial/by-id/... names a USB adapter) and an
    autopilot (system 7) on the master end sends a HEARTBEAT every 0.1 s and reads whatever
    comes. ``pull()`` closes the master and removes the link (the node is gone),
    ``plug()`` makes a new pair at the same path; ``cut()`` stops both directions with the
    node kept (the far end reads and writes nothing), ``mend()`` lets them flow again."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.master: int | None = None
        self.slave: int | None = None
        self.flowing = True
        self.read_bytes = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ap = mav.MAVLink(None, srcSystem=7, srcComponent=1)
        self.plug()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def plug(self) -> None:
        master, slave = os.openpty()
        with self._lock:
            self.master, self.slave = master, slave
            self.path.unlink(missing_ok=True)
            self.path.symlink_to(os.ttyname(slave))
        os.close(slave)  # only the companion holds the slave end from now on
        self.slave = None

    def pull(self) -> None:
        with self._lock:
            self.path.unlink(missing_ok=True)
            if self.master is not None:
                os.close(self.master)
            self.master = None

    def cut(self) -> None:
        self.flowing = False

    def mend(self) -> None:
        self.flowing = True

    def _run(self) -> None:
        hb = self._ap.heartbeat_encode(
            mav.MAV_TYPE_FIXED_WING, mav.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 15, 4
        )
        while not self._stop.wait(0.1):
            with self._lock:
                fd = self.master
                if fd is None or not self.flowing:
                    continue
                with contextlib.suppress(OSError):
                    os.write(fd, hb.pack(self._ap))
                    while select.select([fd], [], [], 0)[0]:
                        self.read_bytes += len(os.read(fd, 4096))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.pull()


def _serve(link: AutopilotLink, poller: Poller, seconds: float) -> list[str]:
    """The companion's loop (as Runner.run: select, receive, tick) for ``seconds`` of wall
    time; what the link's supervision said."""
    said: list[str] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if "link" in poller.poll(0.05, None):
            link.receive()
        state = link.tick()
        if state is not None:
            said.append(state)
    return said


@pytest.fixture
def cable(tmp_path):
    c = Cable(tmp_path / "ttyAP")
    yield c
    c.close()


def test_a_pulled_cable_is_lost_at_once_reopened_without_spinning_and_never_printed(
    cable, capfd
):
    """The device node vanishes: the link is lost at once (not after its time-out), the
    companion's loop uses almost no CPU while the node is gone (pymavlink's own serial
    reconnect spun a full core here, see docs/companion.md), pymavlink's "Device ... is dead"
    never reaches stdout, and the re-plugged device is re-opened by itself: the outage's
    length is measured on the companion's own clock."""
    link = AutopilotLink(f"{cable.path},921600", link_timeout_s=3.0, retry_s=0.5)
    poller = Poller(link)
    try:
        _serve(link, poller, 1.0)
        assert link.up and link.sysid == 7
        cable.pull()
        t_pull = time.monotonic()
        cpu0 = time.thread_time()
        said = _serve(link, poller, 3.0)
        cpu_s = time.thread_time() - cpu0
        assert said == ["lost"]
        assert link.silent_s is not None and link.silent_s < 1.0  # at once, not after 3 s
        assert link.counts["device_lost"] == 1
        assert link.fileno() is None  # nothing left to select on
        assert cpu_s < 0.3, f"{cpu_s:.2f} s of CPU in 3 s with the device gone"
        cable.plug()
        t_plug = time.monotonic()
        _serve(link, poller, 2.0)
        assert link.up, "the re-plugged device was not re-opened"
        assert link.counts["reconnects"] >= 2  # tried while it was gone, then opened
        assert link.last_outage_s == pytest.approx(t_plug - t_pull, abs=0.8)
    finally:
        link.close()
        poller.close()
    out = capfd.readouterr().out
    assert "is dead" not in out and "reopened" not in out, out


def test_a_cut_wire_is_the_time_out_alone_and_the_device_stays_open(cable, capfd):
    """The node stays but nothing flows: the link is lost after its time-out, the device is
    not re-opened (closing a pseudo-terminal's last slave hangs its master up), writes that
    no one reads never block (they are dropped and counted), and when the wire is mended the
    link comes back with the outage's length on the companion's clock."""
    link = AutopilotLink(f"{cable.path},921600", link_timeout_s=1.5, retry_s=0.5)
    poller = Poller(link)
    try:
        _serve(link, poller, 1.0)
        assert link.up
        cable.cut()
        t_cut = time.monotonic()
        said = _serve(link, poller, 2.5)
        assert said == ["lost"]
        assert link.silent_s == pytest.approx(1.5, abs=0.3)
        t0 = time.monotonic()
        for _ in range(2000):  # about 40 kB that no one reads: the buffers fill
            link.statustext("companion 7: nobody hears this")
        assert time.monotonic() - t0 < 2.0
        assert link.conn.dropped_bytes > 0
        assert link.counts["reconnects"] == 0 and link.counts["device_lost"] == 0
        cable.mend()
        t_mend = time.monotonic()
        _serve(link, poller, 1.5)
        assert link.up
        assert link.last_outage_s == pytest.approx(t_mend - t_cut, abs=0.6)
    finally:
        link.close()
        poller.close()
    assert "is dead" not in capfd.readouterr().out
