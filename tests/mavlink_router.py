"""A MAVLink router for the tests: one autopilot link (TCP) shared by several UDP clients,
as ``mavlink-routerd`` with a TCP endpoint and a UDP server endpoint, or ``mavproxy.py
--master tcp:... --out udpin:...`` (docs/gcs.md).

Bytes from the autopilot go to every client heard so far; a client's datagrams go to the
autopilot. It forwards bytes, not frames: each client's pymavlink parser joins a frame split
across two datagrams. One thread; :meth:`UdpRouter.close` stops it and closes its sockets.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time


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
