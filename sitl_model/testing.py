"""Helpers for tests and benchmarks that run the real simulator over loopback UDP.

:class:`SitlProcess` starts ``python -m sitl_model`` on free ports and always stops it;
:class:`MavClient` is a minimal MAVLink 2 peer (one UDP socket, the simulator's own codec)
for precise protocol tests. Wall-clock waits here are test plumbing, not simulator logic.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from companion.contracts.simulator import PORT_SPACING
from sitl_model.codec import Decoder, Encoder, dialect
from sitl_model.server import free_base_port

REPO = Path(__file__).resolve().parents[1]


class SitlProcess:
    """A running ``python -m sitl_model`` (use as a context manager or call :meth:`stop`)."""

    def __init__(
        self,
        *args: str,
        vehicles: int = 1,
        ready_timeout_s: float = 20.0,
        prefix: tuple[str, ...] = (),
    ) -> None:
        """Start with ``--vehicles`` (unless a mission gives it), free ports and ``args``,
        after ``prefix`` (e.g. ``ip netns exec NS``)."""
        self.base_port = free_base_port(vehicles)
        cmd = [*prefix, sys.executable, "-m", "sitl_model", "--base-port", str(self.base_port)]
        if "--mission" not in args:
            cmd += ["--vehicles", str(vehicles)]
        cmd += list(args)
        env = dict(os.environ, PYTHONPATH=str(REPO))
        self.proc = subprocess.Popen(
            cmd,
            cwd=REPO,
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.stderr_lines: list[str] = []
        self.stdout_lines: list[str] = []
        self._threads = [
            threading.Thread(target=self._pump, args=(self.proc.stderr, self.stderr_lines)),
            threading.Thread(target=self._pump, args=(self.proc.stdout, self.stdout_lines)),
        ]
        for t in self._threads:
            t.daemon = True
            t.start()
        deadline = time.monotonic() + ready_timeout_s
        while not any("vehicle(s)" in ln for ln in self.stderr_lines):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError("simulator did not start: " + "".join(self.stderr_lines))
            time.sleep(0.02)

    @staticmethod
    def _pump(stream: Any, sink: list[str]) -> None:
        for raw in iter(stream.readline, b""):
            sink.append(raw.decode("utf-8", "replace"))

    def port(self, index: int) -> int:
        """UDP port of vehicle ``index`` (0-based)."""
        return self.base_port + PORT_SPACING * index

    def control(self, line: str, timeout_s: float = 5.0) -> str:
        """Send one control line on stdin and return the reply line."""
        n = len(self.stdout_lines)
        self.proc.stdin.write((line + "\n").encode())
        self.proc.stdin.flush()
        deadline = time.monotonic() + timeout_s
        while len(self.stdout_lines) <= n:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no reply to {line!r}")
            time.sleep(0.01)
        return self.stdout_lines[n].strip()

    def stop(self, timeout_s: float = 10.0) -> int:
        """SIGTERM, wait, kill if needed; returns the exit status."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for t in self._threads:
            t.join(2.0)
        for f in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if f:
                f.close()
        return self.proc.returncode

    def __enter__(self) -> SitlProcess:
        """Context manager entry."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Always stop the process."""
        self.stop()


class MavClient:
    """A MAVLink 2 peer of one simulated vehicle (system 255, component 190 by default)."""

    def __init__(self, port: int, sysid: int = 255, compid: int = 190) -> None:
        """Connect a UDP socket to ``127.0.0.1:port`` and say hello with a HEARTBEAT."""
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(("127.0.0.1", port))
        self.enc = Encoder(sysid, compid)
        self.dec = Decoder()
        self.pending: list[Any] = []
        self.send(dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))

    def send(self, msg: Any) -> None:
        """Pack and send one message."""
        self.sock.send(self.enc.pack(msg))

    def send_raw(self, data: bytes) -> None:
        """Send arbitrary bytes."""
        self.sock.send(data)

    def recv(self, timeout_s: float) -> list[Any]:
        """Messages received within ``timeout_s`` (at least one datagram waited for)."""
        self.sock.settimeout(timeout_s)
        out = self.pending
        self.pending = []
        try:
            data = self.sock.recv(65535)
            out += self.dec.decode(data)[0]
            self.sock.setblocking(False)
            while True:
                out += self.dec.decode(self.sock.recv(65535))[0]
        except (TimeoutError, BlockingIOError):
            pass
        return out

    def drain(self) -> None:
        """Discard everything received so far."""
        self.pending = []
        self.sock.setblocking(False)
        try:
            while True:
                self.sock.recv(65535)
        except BlockingIOError:
            pass

    def collect(self, duration_s: float) -> list[Any]:
        """Every message received during the next ``duration_s`` wall seconds."""
        out: list[Any] = []
        deadline = time.monotonic() + duration_s
        while (left := deadline - time.monotonic()) > 0:
            out += self.recv(min(left, 0.05))
        return out

    def match(
        self,
        mtype: str | tuple[str, ...],
        timeout_s: float = 5.0,
        cond: Callable[[Any], bool] | None = None,
    ) -> Any:
        """The first message of ``mtype`` satisfying ``cond``; ``TimeoutError`` if none."""
        types = (mtype,) if isinstance(mtype, str) else mtype
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {types} within {timeout_s} s")
            msgs = self.recv(min(left, 0.2))
            for k, m in enumerate(msgs):
                if m.get_type() in types and (cond is None or cond(m)):
                    self.pending = msgs[k + 1 :] + self.pending
                    return m

    def command_long(self, command: int, *params: float, target: int = 1) -> Any:
        """Send COMMAND_LONG and return its COMMAND_ACK."""
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.send(dialect.MAVLink_command_long_message(target, 1, command, 0, *p))
        return self.match("COMMAND_ACK", cond=lambda m: m.command == command)

    def close(self) -> None:
        """Close the socket."""
        self.sock.close()
