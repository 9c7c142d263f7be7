"""The group over Zenoh: a datagram socket that publishes and subscribes one key expression.

:class:`ZenohSocket` has the four methods :class:`companion.group.transport.Group` asks of its
socket (``sendto``, ``recv``, ``fileno``, ``close``), so the group, the codec and the Runner
do not know whether the bytes cross multicast or Zenoh. Each datagram is one Zenoh sample
whose payload is the signed MAVLink 2 packet, opaque to Zenoh: signing stays end to end and
a router in between can neither forge nor replay a state the codec would accept.

Zenoh delivers samples on its own threads; the callback only writes the payload into a
local ``AF_UNIX`` datagram socket pair (one datagram per sample, non-blocking: when the
pair's buffer is full the sample is dropped and counted, as a full UDP receive buffer
drops), and the Runner's ``selectors`` loop reads the other end. Nothing of ours runs on
Zenoh's threads but that one ``send``.

:func:`open_router` is a Zenoh router in this process (``companion zenoh-router``): the
endpoints across subnets and, for clients, the path every sample takes.
"""

from __future__ import annotations

import atexit
import socket
import threading
import weakref

import zenoh

from companion.contracts.errors import UserError
from companion.group.address import ZenohGroup

__all__ = ["ZenohSocket", "open_router"]

# An AF_UNIX datagram pair queues what the sender's SO_SNDBUF allows: measured on Linux,
# 278 states of 95 bytes with the default, 2731 with 1 MiB (about 9 s of 60 members at 5 Hz).
_BUF_BYTES = 1 << 20
# Sessions still open at exit are closed first. (With zenoh-python's default indirect
# callbacks a forgotten session hung the exit, measured: its non-daemon Python thread; the
# subscriber here is direct, and a session closed at exit leaves nothing to chance.)
_OPEN: weakref.WeakSet[ZenohSocket] = weakref.WeakSet()


@atexit.register
def _close_left_open() -> None:
    for sock in list(_OPEN):
        sock.close()


def _config(items: dict[str, str]) -> zenoh.Config:
    config = zenoh.Config()
    for path, value in items.items():
        config.insert_json5(path, value)
    return config


def _open(items: dict[str, str], what: str) -> zenoh.Session:
    try:
        return zenoh.open(_config(items))
    except zenoh.ZError as exc:
        raise UserError(f"cannot open the Zenoh session ({what}): {exc}") from None


class ZenohSocket:
    """One Zenoh session publishing and subscribing ``where.key_expr``, seen as a socket.

    ``overflow`` counts samples dropped because the local pair's buffer was full.
    """

    def __init__(self, where: ZenohGroup) -> None:
        """Open the session (``UserError`` if Zenoh refuses the configuration or an
        endpoint); 0.03-0.5 s measured."""
        self.where = where
        self.overflow = 0
        self._lock = threading.Lock()  # the callback's send against close
        self._rx, self._tx = socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)
        for s in (self._rx, self._tx):
            s.setblocking(False)
        self._tx.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, _BUF_BYTES)
        self._rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _BUF_BYTES)
        try:
            self._session = _open(where.config(), str(where))
            self._pub = self._session.declare_publisher(
                where.key_expr, congestion_control=zenoh.CongestionControl.DROP, express=True
            )
            # direct: the callback runs on Zenoh's own thread (no Python thread of Zenoh's
            # that a forgotten session would keep alive past the interpreter's exit)
            handler = zenoh.handlers.Callback(self._deliver, indirect=False)
            self._sub = self._session.declare_subscriber(where.key_expr, handler)
            _OPEN.add(self)
        except BaseException:
            self._rx.close()
            self._tx.close()
            raise

    def _deliver(self, sample: zenoh.Sample) -> None:
        """Zenoh's thread: the payload into the local pair (dropped and counted if full)."""
        data = sample.payload.to_bytes()
        with self._lock:
            if self._tx.fileno() < 0:
                return
            try:
                self._tx.send(data)
            except OSError:  # full (BlockingIOError), or too large for the pair
                self.overflow += 1

    def sendto(self, data: bytes, _address: object = None) -> int:
        """Publish one datagram (the address is the multicast socket's; unused here).

        Raises ``OSError`` if Zenoh refuses it, as a socket would (the group counts it).
        """
        try:
            self._pub.put(data)
        except zenoh.ZError as exc:
            raise OSError(str(exc)) from None
        return len(data)

    def recv(self, bufsize: int) -> bytes:
        """The next datagram received (at most ``bufsize`` bytes); ``BlockingIOError`` if none."""
        return self._rx.recv(bufsize)

    def fileno(self) -> int:
        """The descriptor that is readable when a datagram waits (for selectors)."""
        return self._rx.fileno()

    def close(self) -> None:
        """Undeclare, close the session (Zenoh's threads stop), then the local pair; a second
        call does nothing."""
        if self not in _OPEN:
            return
        _OPEN.discard(self)
        try:
            self._sub.undeclare()
            self._pub.undeclare()
            self._session.close()
        finally:
            with self._lock:
                self._tx.close()
            self._rx.close()

    def __enter__(self) -> ZenohSocket:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_router(listen: tuple[str, ...], connect: tuple[str, ...] = ()) -> zenoh.Session:
    """A Zenoh router in this process, listening on ``listen`` and linked to the routers at
    ``connect`` (Zenoh endpoints); close the returned session to stop it.

    Multicast scouting is off: the peers and clients reach it by its endpoints.
    """
    import json

    items = {
        "mode": json.dumps("router"),
        "listen/endpoints": json.dumps(list(listen)),
        "connect/endpoints": json.dumps(list(connect)),
        "scouting/multicast/enabled": "false",
    }
    return _open(items, "router on " + ",".join(listen))
