"""MAVLink routers for the tests: one autopilot link (TCP) shared by several UDP clients.
:class:`UdpRouter` in this process, as ``mavlink-routerd`` with a TCP endpoint and a UDP
server endpoint; :class:`MavproxyRouter`, ``mavproxy.py --master tcp:... --out udpin:...``
as docs/gcs.md gives it.

:class:`UdpRouter` sends the autopilot's bytes to every client heard so far and a client's
datagrams to the autopilot. It forwards bytes, not frames: each client's pymavlink parser
joins a frame split across two datagrams. One thread; :meth:`UdpRouter.close` stops it and
closes its sockets.
"""

from __future__ import annotations

import contextlib
import os
import selectors
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path


class UdpRouter:
    """Routes between ``tcp:127.0.0.1:tcp_port`` and UDP clients of :attr:`port`.

    Attributes:
        port: the UDP port the clients send to (``udpout:127.0.0.1:PORT``).
        clients: the clients heard, by address.
    """

    def __init__(self, tcp_port: int, connect_timeout_s: float = 20.0) -> None:
        """Connect to the autopilot (retrying until ``connect_timeout_s``) and start."""
        deadline = time.monotonic() + connect_timeout_s
        while True:
            try:
                self._tcp = socket.create_connection(("127.0.0.1", tcp_port), timeout=1.0)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        self._tcp.setblocking(False)
        self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._udp.bind(("127.0.0.1", 0))
        self._udp.setblocking(False)
        self.port = self._udp.getsockname()[1]
        self.clients: dict[tuple[str, int], None] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self._tcp, selectors.EVENT_READ, "tcp")
        sel.register(self._udp, selectors.EVENT_READ, "udp")
        with sel:
            while not self._stop.is_set():
                for key, _ in sel.select(0.1):
                    if key.data == "tcp":
                        self._from_autopilot()
                    else:
                        self._from_clients()

    def _from_autopilot(self) -> None:
        try:
            data = self._tcp.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        if not data:
            self._stop.set()  # the autopilot closed its end
            return
        for addr in list(self.clients):
            with contextlib.suppress(OSError):
                self._udp.sendto(data, addr)

    def _from_clients(self) -> None:
        while True:
            try:
                data, addr = self._udp.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ICMP port unreachable from a client gone
                continue
            self.clients[addr] = None
            with contextlib.suppress(BlockingIOError):
                self._tcp.sendall(data)

    def close(self) -> None:
        """Stop and close both sockets."""
        self._stop.set()
        self._thread.join(2.0)
        self._tcp.close()
        self._udp.close()


class MavproxyRouter:
    """``mavproxy.py --master tcp:127.0.0.1:TCP_PORT --out udpin:... --out udpin:...
    --streamrate -1`` as the router (docs/gcs.md): one UDP server port per client.

    Attributes:
        ports: the clients' ports (each ``udpin`` output serves the last address heard).
    """

    def __init__(self, mavproxy: str, tcp_port: int, workdir: Path, clients: int = 2) -> None:
        """Start MAVProxy (its logs under ``workdir``); it connects to the autopilot itself."""
        self.ports = [_free_udp_port() for _ in range(clients)]
        outs = [f"--out=udpin:127.0.0.1:{p}" for p in self.ports]
        workdir.mkdir(parents=True, exist_ok=True)
        self._log = open(workdir / "mavproxy.log", "w")  # noqa: SIM115 - closed in close()
        self.proc = subprocess.Popen(
            [mavproxy, f"--master=tcp:127.0.0.1:{tcp_port}", *outs, "--streamrate=-1",
             "--non-interactive", "--default-modules=", f"--state-basedir={workdir}"],
            cwd=workdir, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True,
        )  # fmt: skip

    def close(self) -> None:
        """Stop MAVProxy (by its own process group)."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(5.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._log.close()


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]
