"""The wires of the in-memory engine: the sockets of a UDP run replaced by queues.

:class:`MemoryConn` stands in for a companion's pymavlink connection, :class:`VehiclePort`
for a simulated vehicle's UDP endpoint, :class:`GroupBus` and :class:`BusSocket` for the
group's multicast socket; :func:`fleet_key` derives the signing key of a simulated fleet.
The engine that steps them is :mod:`companion.sim.inmemory.engine`.

An autopilot link carries bytes (``objects=False``: packed by one side, parsed by the
other, as over UDP; needed for link signing) or message objects (``objects=True``): what
nobody reads as bytes crosses as the object a decoder would return
(:func:`sitl_model.codec.as_received`: the header, float32 fields), so both sides read the
same values for a fraction of the cost. :class:`Stopwatch` adds up the time spent on the
wires (packing, parsing, passing on).
"""

from __future__ import annotations

import hashlib
import time
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
    as_received,
    one_frame,
)
from sitl_model.link import VehicleLink

__all__ = ["BusSocket", "GroupBus", "MemoryConn", "Stopwatch", "VehiclePort", "fleet_key"]


def fleet_key(seed: int) -> bytes:
    """A 32-byte signing key derived from ``seed`` (a simulation needs no secret)."""
    return hashlib.sha256(f"companion in-memory fleet key {seed}".encode()).digest()


class Stopwatch:
    """Seconds (``perf_counter``) spent on the wires, added up by every port and connection."""

    def __init__(self) -> None:
        """Nothing counted yet."""
        self.s = 0.0


# ---- the autopilot link ----------------------------------------------------------------------
class _PassingMAVLink(mav.MAVLink):
    """A pymavlink ``MAVLink`` whose :meth:`send` passes the message object on, as its
    receiver would decode it, instead of packing it (an unsigned in-memory link)."""

    def send(self, mavmsg: Any, force_mavlink1: bool = False) -> None:
        """Pass a copy of ``mavmsg`` to the connection (the sender may keep the original)."""
        m = as_received(mavmsg, self.srcSystem, self.srcComponent, self.seq, copy=True)
        self.file.write_message(m)
        self.seq = (self.seq + 1) % 256
        self.total_packets_sent += 1


class MemoryConn:
    """What :class:`AutopilotLink` uses of a pymavlink connection, over a :class:`VehiclePort`.

    ``mav`` packs what the companion sends (``mav.send`` writes the bytes here, they are
    queued to the vehicle), or with ``objects`` passes the message object on;
    :meth:`recv_msg` parses the datagrams the vehicle sent, one message at a time, with the
    same pymavlink parser as a socket connection, or returns the objects it passed on.
    """

    fd = None  # not selectable: the engine drives the runner

    def __init__(
        self,
        port: VehiclePort,
        source_system: int,
        source_component: int,
        objects: bool = False,
        stopwatch: Stopwatch | None = None,
    ) -> None:
        """A new connection to ``port`` (it becomes a peer once it sends a valid message)."""
        self.port = None  # AutopilotLink looks for a serial port here
        self._vehicle = port
        kind = _PassingMAVLink if objects else mav.MAVLink
        self.mav = kind(self, srcSystem=source_system, srcComponent=source_component)
        self.mav.robust_parsing = True
        self.inbox: deque[Any] = deque()  # datagrams (bytes) or message objects
        self._ready: deque[Any] = deque()
        self.closed = False
        self.deaf = False  # a frozen process: what arrives is lost
        self._watch = stopwatch or Stopwatch()

    @property
    def pending(self) -> bool:
        """Whether a message is waiting to be received."""
        return bool(self.inbox or self._ready)

    def write(self, data: bytes | bytearray) -> None:
        """Bytes from the companion (one MAVLink frame) to the vehicle."""
        if not self.closed:
            self._vehicle.inbox.append((self, bytes(data)))

    def write_message(self, msg: Any) -> None:
        """A message object from the companion to the vehicle (the object path)."""
        if not self.closed:
            self._vehicle.inbox.append((self, msg))

    def deliver(self, data: Any) -> None:
        """One datagram (bytes) or message object from the vehicle."""
        if not self.closed and not self.deaf:
            self.inbox.append(data)

    def recv_msg(self) -> Any:
        """The next message received, or None."""
        ready = self._ready
        if ready:
            return ready.popleft()
        inbox = self.inbox
        if not inbox:
            return None
        t0 = time.perf_counter()
        try:
            while inbox:
                data = inbox.popleft()
                if not isinstance(data, bytes):
                    return data  # passed on as an object
                if one_frame(data):
                    # pymavlink's parser, for a datagram holding exactly one whole frame,
                    # calls decode() on it (CRC, signature, unpacking) and turns a MAVError
                    # into BAD_DATA: the same, without stepping its state machine byte by byte
                    try:
                        return self.mav.decode(bytearray(data))
                    except mav.MAVError as exc:
                        return mav.MAVLink_bad_data(bytearray(data), exc.message)
                ready.extend(self.mav.parse_buffer(data) or ())
                if ready:
                    return ready.popleft()
            return None
        finally:
            self._watch.s += time.perf_counter() - t0

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
    message gets the telemetry; replies go to the requester only. With ``objects`` (no
    signing) messages cross as objects both ways (the module docstring).
    """

    def __init__(
        self,
        link: VehicleLink,
        check: Callable[[], FrameCheck | None],
        objects: bool = False,
        stopwatch: Stopwatch | None = None,
    ) -> None:
        """Encoders (autopilot, camera) and a decoder for ``link``; ``check`` makes signing.

        Raises:
            ValueError: ``objects`` with signing (a signature needs the bytes).
        """
        self.link = link
        frame_check = check()
        if objects and frame_check is not None:
            raise ValueError("a signed link carries bytes: objects=False")
        self.objects = objects
        self.enc = Encoder(link.sysid, MAV_COMP_ID_AUTOPILOT1, frame_check)
        self.cam = Encoder(link.sysid, MAV_COMP_ID_CAMERA, frame_check)
        self.decoder = Decoder(frame_check)
        self.peers: dict[Any, None] = {}  # insertion-ordered set
        self.inbox: list[tuple[Any, Any]] = []  # (peer, datagram bytes or message object)
        self.watch = stopwatch or Stopwatch()

    def connect(self, source_system: int, source_component: int) -> MemoryConn:
        """A new companion connection (the ``opener`` of an AutopilotLink)."""
        return MemoryConn(self, source_system, source_component, self.objects, self.watch)

    def send(self, msg: Any, peer: Any = None, camera: bool = False) -> None:
        """Pack ``msg`` once (or pass it on) and give it to ``peer`` (None: every peer)."""
        t0 = time.perf_counter()
        enc = self.cam if camera else self.enc
        data = enc.pass_on(msg) if self.objects else enc.pack(msg)
        self.watch.s += time.perf_counter() - t0
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
        watch, perf = self.watch, time.perf_counter
        for peer, data in inbox:
            if not isinstance(data, bytes):  # an object passed on
                msgs = [data]
            else:
                t0 = perf()
                msgs, bad = decoder.decode(data)
                watch.s += perf() - t0
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
