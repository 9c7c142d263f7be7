"""The wires of the in-memory engine: the sockets of a UDP run replaced by queues.

:class:`MemoryConn` stands in for a companion's pymavlink connection, :class:`VehiclePort`
for a simulated vehicle's UDP endpoint, :class:`GroupBus` and :class:`BusSocket` for the
group's multicast socket; :func:`fleet_key` derives the signing key of a simulated fleet.
The engine that steps them is :mod:`companion.sim.inmemory.engine`.
"""

from __future__ import annotations

import hashlib
from collections import deque
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.signing import FrameCheck
from sitl_model.codec import (
    MAV_COMP_ID_AUTOPILOT1,
    MAV_COMP_ID_CAMERA,
    Decoder,
    Encoder,
    one_frame,
)
from sitl_model.link import VehicleLink

__all__ = ["BusSocket", "GroupBus", "MemoryConn", "VehiclePort", "fleet_key"]


def fleet_key(seed: int) -> bytes:
    """A 32-byte signing key derived from ``seed`` (a simulation needs no secret)."""
    return hashlib.sha256(f"companion in-memory fleet key {seed}".encode()).digest()


# ---- the autopilot link ----------------------------------------------------------------------
class MemoryConn:
    """What :class:`AutopilotLink` uses of a pymavlink connection, over a :class:`VehiclePort`.

    ``mav`` packs what the companion sends (``mav.send`` writes the bytes here, they are
    queued to the vehicle); :meth:`recv_msg` parses the datagrams the vehicle sent, one
    message at a time, with the same pymavlink parser as a socket connection.
    """

    fd = None  # not selectable: the engine drives the runner

    def __init__(self, port: VehiclePort, source_system: int, source_component: int) -> None:
        """A new connection to ``port`` (it becomes a peer once it sends a valid message)."""
        self.port = None  # AutopilotLink looks for a serial port here
        self._vehicle = port
        self.mav = mav.MAVLink(self, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True
        self.inbox: deque[bytes] = deque()
        self._ready: deque[Any] = deque()
        self.closed = False
        self.deaf = False  # a frozen process: what arrives is lost

    @property
    def pending(self) -> bool:
        """Whether a message is waiting to be received."""
        return bool(self.inbox or self._ready)

    def write(self, data: bytes | bytearray) -> None:
        """Bytes from the companion (one MAVLink frame) to the vehicle."""
        if not self.closed:
            self._vehicle.inbox.append((self, bytes(data)))

    def deliver(self, data: bytes) -> None:
        """One datagram from the vehicle."""
        if not self.closed and not self.deaf:
            self.inbox.append(data)

    def recv_msg(self) -> Any:
        """The next message received, or None."""
        ready = self._ready
        if ready:
            return ready.popleft()
        inbox = self.inbox
        while inbox:
            data = inbox.popleft()
            one = one_frame(data)
            if one:
                # pymavlink's parser, for a datagram holding exactly one whole frame, calls
                # decode() on it (CRC, signature, unpacking) and turns a MAVError into
                # BAD_DATA: the same, without feeding the parser's state machine byte by byte
                try:
                    return self.mav.decode(bytearray(data))
                except mav.MAVError as exc:
                    return mav.MAVLink_bad_data(bytearray(data), exc.message)
            ready.extend(self.mav.parse_buffer(data) or ())
            if ready:
                return ready.popleft()
        return None

    def close(self) -> None:
        """Close: nothing more is sent or received."""
        self.closed = True
        self.inbox.clear()
        self._ready.clear()


class Sink:
    """A peer that keeps nothing (a ground station whose replies are not read)."""

    closed = False

    def deliver(self, data: bytes) -> None:
        """Drop a datagram."""


class VehiclePort:
    """Vehicle ``index``'s end of the link: the simulator's codec around its VehicleLink.

    What its UDP socket is to :class:`sitl_model.server.Server`: every peer that sent a valid
    message gets the telemetry; replies go to the requester only.
    """

    def __init__(self, link: VehicleLink, check: Callable[[], FrameCheck | None]) -> None:
        """Encoders (autopilot, camera) and a decoder for ``link``; ``check`` makes signing."""
        self.link = link
        frame_check = check()
        self.enc = Encoder(link.sysid, MAV_COMP_ID_AUTOPILOT1, frame_check)
        self.cam = Encoder(link.sysid, MAV_COMP_ID_CAMERA, frame_check)
        self.decoder = Decoder(frame_check)
        self.peers: dict[Any, None] = {}  # insertion-ordered set
        self.inbox: list[tuple[Any, bytes]] = []

    def connect(self, source_system: int, source_component: int) -> MemoryConn:
        """A new companion connection (the ``opener`` of an AutopilotLink)."""
        return MemoryConn(self, source_system, source_component)

    def send(self, msg: Any, peer: Any = None, camera: bool = False) -> None:
        """Pack ``msg`` once and give it to ``peer`` (None: every peer)."""
        data = (self.cam if camera else self.enc).pack(msg)
        c = self.link.counters
        if peer is not None:
            peer.deliver(data)
            c.tx += 1
            return
        for p in self.peers:
            p.deliver(data)
            c.tx += 1

    def process(self, now_s: float) -> list[tuple[str, dict[str, Any]]]:
        """Decode and handle what the peers sent; mission events (name, fields) out."""
        if not self.inbox:
            return []
        link, decoder = self.link, self.decoder
        inbox, self.inbox = self.inbox, []
        for peer, data in inbox:
            msgs, bad = decoder.decode(data)
            link.counters.bad += bad
            link.tm.errors_comm[link.index] += bad
            for r in decoder.rejected:
                setattr(link.counters, r.reason, getattr(link.counters, r.reason) + 1)
            if not msgs and not decoder.rejected:
                continue
            if peer not in self.peers and not peer.closed:
                self.peers[peer] = None
            for m in msgs:
                for reply, to in link.handle(m, peer, now_s):
                    self.send(reply, to)
        self.forget_closed()
        mp = link.missions
        events, mp.events = list(mp.events), []
        return events

    def forget_closed(self) -> None:
        """Stop sending to closed connections (a UDP server would send into the void)."""
        if any(p.closed for p in self.peers):
            self.peers = {p: None for p in self.peers if not p.closed}


# ---- the group ---------------------------------------------------------------------------
class GroupBus:
    """The multicast group in memory: datagrams sent during a step reach the others after it.

    Delivery is in sender order; a member does not receive its own datagrams (the UDP group
    loops them back and the decoder drops them as ``own``).
    """

    def __init__(self) -> None:
        """An empty group."""
        self.members: dict[int, BusSocket] = {}
        self._in_flight: list[tuple[int, bytes]] = []

    def join(self, sysid: int) -> BusSocket:
        """The socket of member ``sysid``."""
        sock = BusSocket(self, sysid)
        self.members[sysid] = sock
        return sock

    def post(self, sysid: int, data: bytes) -> None:
        """A datagram sent by ``sysid`` (delivered by :meth:`deliver`)."""
        self._in_flight.append((sysid, data))

    def deliver(self) -> None:
        """Everything posted since the last call, to every other open member."""
        if not self._in_flight:
            return
        flying, self._in_flight = self._in_flight, []
        members = list(self.members.values())
        for sender, data in flying:
            for m in members:
                if m.sysid != sender and not m.deaf:
                    m.inbox.append(data)


class BusSocket:
    """What :class:`Group` uses of its UDP socket, on a :class:`GroupBus`."""

    def __init__(self, bus: GroupBus, sysid: int) -> None:
        """Member ``sysid``'s socket."""
        self.bus = bus
        self.sysid = sysid
        self.inbox: deque[bytes] = deque()
        self.deaf = False

    def sendto(self, data: bytes, _address: Any) -> int:
        """Post one datagram to the group."""
        self.bus.post(self.sysid, data)
        return len(data)

    def recv(self, _size: int) -> bytes:
        """The next datagram (BlockingIOError when none is waiting)."""
        if not self.inbox:
            raise BlockingIOError
        return self.inbox.popleft()

    def fileno(self) -> int:
        """No descriptor (-1): the engine tells the runner when to read."""
        return -1

    def close(self) -> None:
        """Leave the group."""
        self.inbox.clear()
        if self.bus.members.get(self.sysid) is self:
            del self.bus.members[self.sysid]


# ---- the engine --------------------------------------------------------------------------
