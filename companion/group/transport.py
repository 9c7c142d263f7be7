"""The group's socket edge: signed patrol messages over UDP multicast or Zenoh.

One :class:`Group` per companion process, on one :class:`DatagramSocket`: the multicast
socket opened here, or a :class:`~companion.group.zenoh_socket.ZenohSocket`
(:func:`open_group` picks by the ``--group`` address); the group above it is the same.
On multicast it joins the group on one interface
(loopback by default: ``IP_MULTICAST_IF`` and ``IP_MULTICAST_LOOP=1``, TTL 1), shares the
port with the other companions on the host (``SO_REUSEADDR``/``SO_REUSEPORT``), and is
non-blocking: put :meth:`Group.fileno` in a selector and call :meth:`Group.receive` when it
is readable. Encoding, checks and counting are in :mod:`companion.group.codec`; faults for
tests in :mod:`companion.group.faults`, applied on send here and nowhere else.
"""

from __future__ import annotations

import heapq
import ipaddress
import socket
import struct
import sys
import time
from collections.abc import Callable
from typing import Protocol

from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import DEFAULT_ADDRESS, DEFAULT_PORT, GroupAddress, ZenohGroup
from companion.group.codec import COMPID_COMPANION, MAX_DATAGRAM, Decoder, Dropped, Received, encode
from companion.group.faults import FaultModel
from companion.group.flood import FloodGate
from companion.group.messages import Alert, MemberState

__all__ = [
    "DEFAULT_ADDRESS",
    "DEFAULT_IFACE",
    "DEFAULT_PORT",
    "DatagramSocket",
    "Group",
    "open_group",
]

DEFAULT_IFACE = "127.0.0.1"
# The receive buffer asked for (Linux doubles it, up to net.core.rmem_max). The default
# 208 KiB held 256 signed states (about 830 bytes each as the kernel counts them, measured):
# under a second of a 60-member group, a quarter of a second of an alert storm, while the
# companion is descheduled. 1 MiB holds about 2,500.
RECEIVE_BUFFER_BYTES = 1 << 20


class DatagramSocket(Protocol):
    """What a :class:`Group` needs of its socket: the multicast UDP socket, a
    :class:`~companion.group.zenoh_socket.ZenohSocket` or the in-memory engine's bus."""

    def sendto(self, data: bytes, address: tuple[str, int], /) -> int:
        """Send one datagram (``OSError`` if it cannot leave)."""
        ...

    def recv(self, bufsize: int, /) -> bytes:
        """The next datagram; ``BlockingIOError`` when none is waiting."""
        ...

    def fileno(self) -> int:
        """Readable when a datagram is waiting (for selectors)."""
        ...

    def close(self) -> None:
        """Release the socket."""
        ...


def open_group(
    where: GroupAddress, sysid: int, signing: Signing | None, *, iface: str = DEFAULT_IFACE, **kw
) -> Group:
    """The group at ``where`` (``--group``, :func:`companion.group.address.parse_group`):
    a multicast socket joined on ``iface`` (IPv4 address), or a Zenoh session (``iface`` is
    then unused: the endpoints say where). ``kw`` are :class:`Group`'s other options."""
    if isinstance(where, ZenohGroup):
        from companion.group.zenoh_socket import ZenohSocket  # loads zenoh only when asked

        return Group(sysid, signing, sock=ZenohSocket(where), **kw)
    return Group(sysid, signing, address=where.address, port=where.port, iface=iface, **kw)


class Group:
    """A member's end of the multicast group: sends states and alerts, receives the others'.

    ``stats`` holds the decoder's counts (``accepted`` and each drop reason; ``flood`` once
    :meth:`limit_floods` was called), ``sent``, ``send_errors`` and, with a fault model,
    ``lost``, ``duplicated`` and ``reordered``; ``tx_bytes`` and ``rx_bytes`` the datagram
    bytes sent and received (every datagram read, dropped or not).
    """

    def __init__(
        self,
        sysid: int,
        signing: Signing | None,
        *,
        address: str = DEFAULT_ADDRESS,
        port: int = DEFAULT_PORT,
        iface: str = DEFAULT_IFACE,
        ttl: int = 1,
        loop: bool = True,
        compid: int = COMPID_COMPANION,
        faults: FaultModel | None = None,
        clock: Callable[[], float] = time.monotonic,
        sock: DatagramSocket | None = None,
    ) -> None:
        """Join ``address:port`` on the interface with IPv4 address ``iface``.

        Args:
            sysid: this member's MAVLink system id (1..255); its own packets are dropped.
            signing: the fleet key's signing state, or None for an insecure group.
            ttl: multicast hops (1: the local network only).
            loop: deliver our datagrams to other sockets on this host (needed on loopback).
            faults: optional faults applied to every outgoing datagram.
            clock: monotonic time (s) used only to schedule faulty sends.
            sock: an already open socket-like object (``sendto``, ``recv`` raising
                ``BlockingIOError`` when empty, ``fileno``, ``close``) instead of joining
                the multicast group: a Zenoh session (:func:`open_group`) or the in-memory
                engine's bus (:mod:`companion.sim.inmemory`).
        """
        self.sysid = sysid
        self.compid = compid
        self.signing = signing
        self.address = (address, port)
        self.decoder = Decoder(sysid, signing)
        self.faults = faults
        self._clock = clock
        self._seq = 0
        self._pending: list[tuple[float, int, bytes]] = []  # (due s, order, datagram)
        self._order = 0
        self.tx_bytes = 0  # datagram bytes sent and received (ONBOARD_COMPUTER_STATUS)
        self.rx_bytes = 0
        self._sent = 0
        self._send_errors = 0
        self._sock = sock if sock is not None else _open_socket(address, port, iface, ttl, loop)

    # ---- sending ------------------------------------------------------------------------
    def send_state(self, state: MemberState) -> None:
        """Broadcast this member's state (the state's sysid must be ours)."""
        self._send(state)

    def send_alert(self, alert: Alert) -> None:
        """Broadcast an alert (new, confirmed, cleared or a bid)."""
        self._send(alert)

    def _send(self, msg: Received) -> None:
        data = encode(msg, self.sysid, self.signing, compid=self.compid, seq=self._seq)
        self._seq = (self._seq + 1) % 256
        if self.faults is None:
            self._transmit(data)
            return
        for due, copy in self.faults.apply(data, self._clock()):
            heapq.heappush(self._pending, (due, self._order, copy))
            self._order += 1
        self.flush()

    def flush(self) -> None:
        """Send the delayed datagrams whose time has come (called by send and receive)."""
        now = self._clock()
        while self._pending and self._pending[0][0] <= now:
            self._transmit(heapq.heappop(self._pending)[2])

    def next_due_s(self) -> float | None:
        """When the next delayed datagram is due (the clock's s), None if none is waiting."""
        return self._pending[0][0] if self._pending else None

    def _transmit(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self.address)
            self._sent += 1
            self.tx_bytes += len(data)
        except OSError:  # full buffer, no route: the group is best effort
            self._send_errors += 1

    # ---- receiving ----------------------------------------------------------------------
    def limit_floods(self, gate: FloodGate) -> None:
        """Refuse each sender's states beyond its share under the budget (``gate``), before
        decoding them; ``stats`` then counts them as ``flood``."""
        self.decoder.limit_floods(gate)

    def receive(self, now_s: float | None = None) -> list[Received]:
        """Drain the socket; the accepted states and alerts, in arrival order.

        ``now_s`` (vehicle s) stamps alerts sent with time 0 (operator alerts).
        """
        self.flush()
        out: list[Received] = []
        while True:
            try:
                data = self._sock.recv(MAX_DATAGRAM + 1)  # one more: oversize shows
            except (BlockingIOError, InterruptedError):
                break
            self.rx_bytes += len(data)
            got = self.decoder.feed(data, now_s)
            if not isinstance(got, Dropped):
                out.append(got)
        return out

    @property
    def stats(self) -> dict[str, int]:
        """Counters: decoder outcomes, ``sent``, ``send_errors`` and fault counts."""
        out = dict(self.decoder.counts, sent=self._sent, send_errors=self._send_errors)
        if self.faults is not None:
            out.update(self.faults.counts)
        return out

    def fileno(self) -> int:
        """The socket's descriptor, for selectors (readable = call :meth:`receive`)."""
        return self._sock.fileno()

    def close(self) -> None:
        """Leave the group and close the socket (delayed datagrams are discarded)."""
        self._pending.clear()
        self._sock.close()

    def __enter__(self) -> Group:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _open_socket(address: str, port: int, iface: str, ttl: int, loop: bool) -> socket.socket:
    """A non-blocking UDP socket bound to the group's port and joined on ``iface``."""
    try:
        ipaddress.IPv4Address(iface)
    except ValueError:
        raise UserError(f"--group-iface {iface!r}: expected the interface's IPv4 address") from None
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        if hasattr(socket, "SO_REUSEPORT"):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        # On Linux, binding to the group address keeps other groups' traffic on this port out.
        sock.bind((address if sys.platform.startswith("linux") else "", port))
        group = socket.inet_aton(address) + socket.inet_aton(iface)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, group)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(iface))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1 if loop else 0)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack("B", ttl))
        sock.setblocking(False)
    except OSError as exc:
        sock.close()
        raise UserError(
            f"cannot join multicast group {address}:{port} on interface {iface}: "
            f"{exc.strerror or exc}"
        ) from None
    return sock
