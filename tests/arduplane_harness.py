"""One real ArduPlane SITL instance for the link tests, and a serial cable to it.

:func:`arduplane` starts an instance of the mission's first vehicle (``--wipe``, free ports,
the fleet's command line) and connects a ground station on SERIAL0, which lets it run;
:class:`SerialCable` is ``socat`` between its SERIAL1 and a pseudo-terminal at a fixed path
(:mod:`companion.sim.firmware.serial_relay`), pulled (SIGTERM: the node is gone), plugged
again, cut (SIGSTOP: the node stays, nothing flows) and mended (SIGCONT).
Everything started here is stopped by its own pid.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymavlink import mavutil

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.mission import load_mission
from companion.sim.arduplane import sitl
from companion.sim.arduplane.sitl import InstanceSpec
from companion.sim.firmware.serial_relay import find_socat, relay_argv, serial_url, wait_for_link


@dataclass
class Instance:
    """A running instance: its spec, process and ground-station link on SERIAL0."""

    spec: InstanceSpec
    popen: subprocess.Popen
    gcs: Any

    def wait_heartbeat(self, timeout_s: float = 30.0) -> Any:
        """The instance's first autopilot HEARTBEAT on SERIAL0."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            m = self.gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if m is not None and m.get_srcSystem() == self.spec.sysid and m.type != 6:
                return m
        raise AssertionError("no heartbeat from ArduPlane SITL on SERIAL0")

    def setup_signing(self, key: bytes) -> None:
        """SETUP_SIGNING with ``key`` (32 bytes) on SERIAL0, the timestamp now, as a ground
        station provisions an aircraft (docs/companion.md)."""
        stamp = int((time.time() - 1420070400) * 1e5)
        self.gcs.mav.setup_signing_send(self.spec.sysid, 1, list(key), stamp)


def _stop(popen: subprocess.Popen) -> None:
    if popen.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(popen.pid, signal.SIGTERM)
        try:
            popen.wait(5.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(popen.pid, signal.SIGKILL)
            popen.wait()


@contextlib.contextmanager
def arduplane(out: Path, mission_path: Path, speedup: float = 1.0) -> Iterator[Instance]:
    """One instance of the mission's first vehicle under ``out``, a ground station on SERIAL0."""
    binary = sitl.find_binary(None)
    mission = load_mission(mission_path)
    spec = sitl.instance_specs(mission, sitl.free_base(1), out)[0]
    spec.workdir.mkdir(parents=True, exist_ok=True)
    log = open(out / "arduplane.log", "w")  # noqa: SIM115 - closed below
    popen = subprocess.Popen(
        sitl.instance_argv(binary, spec, speedup, SIM_EPOCH_UNIX_S),
        cwd=spec.workdir,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )
    gcs = None
    try:
        end = time.monotonic() + 20.0
        while gcs is None:
            try:
                gcs = mavutil.mavlink_connection(
                    f"tcp:127.0.0.1:{spec.ports.serial0}", source_system=255, retries=0
                )
            except OSError:
                assert popen.poll() is None, (out / "arduplane.log").read_text()
                assert time.monotonic() < end, "ArduPlane SITL does not listen on SERIAL0"
                time.sleep(0.1)
        inst = Instance(spec, popen, gcs)
        inst.wait_heartbeat()
        yield inst
    finally:
        if gcs is not None:
            gcs.close()
        _stop(popen)
        log.close()


class SerialCable:
    """socat between an instance's SERIAL1 and a pseudo-terminal reached at ``link``."""

    def __init__(self, link: Path, tcp_port: int) -> None:
        self.link = link
        self.url = serial_url(link)
        self._argv = relay_argv(find_socat(), link, tcp_port)
        self.popen: subprocess.Popen | None = None
        self.plug()

    def plug(self) -> None:
        """A new relay, a new pseudo-terminal at the same path (re-plugged)."""
        self.popen = subprocess.Popen(self._argv, stderr=subprocess.DEVNULL)
        wait_for_link(self.link, lambda: self.popen.poll() is None)

    def pull(self) -> None:
        """Stop the relay: it removes the link, the node is gone once the companion lets go."""
        if self.popen is not None:
            self.popen.send_signal(signal.SIGCONT)  # a cut wire can be pulled too
            self.popen.terminate()
            self.popen.wait(5.0)
            self.popen = None

    def cut(self) -> None:
        """Pause the relay: the node stays, nothing flows."""
        assert self.popen is not None
        self.popen.send_signal(signal.SIGSTOP)

    def mend(self) -> None:
        """Let the relay run again."""
        assert self.popen is not None
        self.popen.send_signal(signal.SIGCONT)

    def close(self) -> None:
        """Stop the relay, whatever its state."""
        if self.popen is not None and self.popen.poll() is None:
            self.popen.send_signal(signal.SIGCONT)
            self.popen.kill()
            self.popen.wait()
        self.popen = None


def cpu_s(pid: int) -> float:
    """User + system CPU time (s) process ``pid`` has used so far (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


KEY = bytes(range(1, 33))  # the link key the tests provision
WRONG_KEY = bytes(range(101, 133))
