"""The radio between the UAVs and the ground router, as a UDP relay (the edge of
:mod:`sitl_model.radio`).

``python -m sitl_model.radio_relay --listen 127.0.0.1:7500 --to 127.0.0.1:7447 ...``:
every UAV's UDP datagrams to ``--listen`` go to the router at ``--to`` from a socket of
their own (the router sees one address per UAV, as over a radio's IP bridge), the
router's answers go back to the UAV; both directions pass through one
:class:`~sitl_model.radio.RadioLink`, which says when each arrives or that it is lost. The
companions use it as ``--group 'zenoh-client:udp/127.0.0.1:7500?scout=off'`` with a
``companion zenoh-router --listen udp/127.0.0.1:7447``; nothing in the group knows.

One asyncio loop (``add_reader`` on plain non-blocking sockets, ``call_at`` for the
deliveries) on the loop's monotonic clock. Prints ``radio-relay: ready ...`` once it
listens; SIGINT or SIGTERM stop it (exit 0) after writing ``--stats`` (JSON: the spec, the
outcomes, the bytes offered per direction and per second), also rewritten every 5 s.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import signal
import socket
import sys
from dataclasses import asdict
from pathlib import Path

from sitl_model.radio import IPV4_UDP_HEADER_BYTES, LinkSpec, RadioLink

__all__ = ["RadioRelay", "StreamRelay", "main"]

MAX_DATAGRAM = 65_535
STATS_EVERY_S = 5.0
SEGMENT_BYTES = 1460  # a TCP segment on a 1500-byte MTU
RETRANSMIT_S = 0.2  # a lost segment is sent again after this (s): Linux's minimum RTO
TCP_IP_HEADER_BYTES = 40


def _addr(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}")
    return host, int(port)


class RadioRelay:
    """The relay's sockets on one asyncio loop; the link decides every datagram's fate."""

    def __init__(self, link: RadioLink, listen: tuple[str, int], router: tuple[str, int]) -> None:
        """Bind ``listen`` (host, port: the UAVs' side); ``router`` (host, port) is the
        ground router's UDP endpoint. Nothing is read until :meth:`attach`."""
        self.link = link
        self.router = router
        self._air = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._air.bind(listen)
        self._air.setblocking(False)
        self.listen = self._air.getsockname()
        self._ground: dict[tuple[str, int], socket.socket] = {}  # UAV address -> its socket
        self._loop: asyncio.AbstractEventLoop | None = None
        self.send_errors = 0

    def attach(self, loop: asyncio.AbstractEventLoop) -> None:
        """Start reading on ``loop``."""
        self._loop = loop
        loop.add_reader(self._air.fileno(), self._from_uavs)

    def _socket_for(self, uav: tuple[str, int]) -> socket.socket:
        sock = self._ground.get(uav)
        if sock is None:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.connect(self.router)
            sock.setblocking(False)
            self._ground[uav] = sock
            self._loop.add_reader(sock.fileno(), self._from_router, uav, sock)
        return sock

    def _from_uavs(self) -> None:
        while True:
            try:
                data, uav = self._air.recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            sock = self._socket_for(uav)
            self._carry(data, "up", lambda d=data, s=sock: s.send(d))

    def _from_router(self, uav: tuple[str, int], sock: socket.socket) -> None:
        while True:
            try:
                data = sock.recv(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionRefusedError:  # the router is not (yet) listening
                continue
            self._carry(data, "down", lambda d=data, a=uav: self._air.sendto(d, a))

    def _carry(self, data: bytes, direction: str, send) -> None:
        transit = self.link.offer(self._loop.time(), len(data), direction)
        if transit.deliver_s is not None:
            self._loop.call_at(transit.deliver_s, self._send, send)

    def _send(self, send) -> None:
        try:
            send()
        except OSError:  # the far end is gone: lost, as on the air
            self.send_errors += 1

    def stats(self) -> dict:
        """The spec, the outcomes, the bytes offered per second by direction, the UAVs seen."""
        return _stats(self.link, {"send_errors": self.send_errors}, len(self._ground))

    def close(self) -> None:
        """Stop reading and close every socket."""
        for sock in [self._air, *self._ground.values()]:
            if self._loop is not None:
                with contextlib.suppress(ValueError, OSError):
                    self._loop.remove_reader(sock.fileno())
            sock.close()


class StreamRelay:
    """The radio for TCP: a link layer with retransmission (ARQ) carrying byte streams.

    Each connection to ``listen`` is joined to a new one to ``router``; each direction
    reads up to :data:`SEGMENT_BYTES` at a time (a segment: what the stream has queued),
    offers it to the link (``header_bytes`` 40: IPv4 + TCP), and writes it to the far end
    when it arrives; a lost segment is offered again after :data:`RETRANSMIT_S` (air time
    spent again), so the stream arrives whole and in order, late. One segment per direction
    and connection is in flight; every delivered segment is acknowledged by a 40-byte
    segment the other way (air time; its loss is ignored). This is the radio's ARQ, or
    TCP's own recovery, approximated: no congestion window, no fast retransmit.
    """

    def __init__(self, link: RadioLink, listen: tuple[str, int], router: tuple[str, int]) -> None:
        """``listen`` (host, port) for the UAVs; ``router`` (host, port) the ground router."""
        self.link = link
        self.listen = listen
        self.router = router
        self._server: asyncio.Server | None = None
        self._tasks: set[asyncio.Task] = set()
        self.connections = 0
        self.retransmissions = 0

    async def start(self) -> None:
        """Listen."""
        self._server = await asyncio.start_server(self._join, *self.listen)
        self.listen = self._server.sockets[0].getsockname()[:2]

    async def _join(self, uav_r: asyncio.StreamReader, uav_w: asyncio.StreamWriter) -> None:
        try:
            gnd_r, gnd_w = await asyncio.open_connection(*self.router)
        except OSError:
            uav_w.close()
            return
        self.connections += 1
        for task in (self._pump(uav_r, gnd_w, "up"), self._pump(gnd_r, uav_w, "down")):
            t = asyncio.create_task(task)
            self._tasks.add(t)
            t.add_done_callback(self._tasks.discard)

    async def _pump(self, r: asyncio.StreamReader, w: asyncio.StreamWriter, way: str) -> None:
        loop = asyncio.get_running_loop()
        back = "down" if way == "up" else "up"
        try:
            while data := await r.read(SEGMENT_BYTES):
                while (t := self.link.offer(loop.time(), len(data), way)).deliver_s is None:
                    self.retransmissions += 1
                    await asyncio.sleep(RETRANSMIT_S)
                await asyncio.sleep(max(0.0, t.deliver_s - loop.time()))
                w.write(data)
                await w.drain()
                self.link.offer(loop.time(), 0, back)  # the acknowledgement's air time
        except (ConnectionError, OSError):
            pass
        finally:
            w.close()

    def stats(self) -> dict:
        """As :meth:`RadioRelay.stats`, with the retransmissions; ``uavs`` = connections."""
        return _stats(self.link, {"retransmissions": self.retransmissions}, self.connections)

    async def close(self) -> None:
        """Stop listening and end every connection."""
        if self._server is not None:
            self._server.close()
        for t in list(self._tasks):
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)


def _stats(link: RadioLink, outcomes: dict[str, int], uavs: int) -> dict:
    """A relay's figures: the link's spec, its outcomes with the relay's own (``outcomes``),
    the longest backlog (s), datagrams by direction, the UAVs seen, and per second the
    bytes offered and carried and the backlog (s)."""
    c = link.counts
    return {
        "spec": asdict(link.spec),
        "outcomes": dict(c.outcomes, **outcomes),
        "max_backlog_s": round(c.max_backlog_s, 4),
        "datagrams": dict(c.datagrams),
        "uavs": uavs,
        "offered_bytes_per_s": link.per_second(),
        "carried_bytes_per_s": link.carried_per_second(),
        "backlog_s_per_s": link.backlog_per_second(),
    }


def _write(path: Path | None, stats: dict) -> None:
    if path is None:
        return
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(stats))
    os.replace(tmp, path)


async def _serve(relay: RadioRelay | StreamRelay, stats_path: Path | None) -> None:
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    if isinstance(relay, StreamRelay):
        await relay.start()
    else:
        relay.attach(loop)
    print(f"radio-relay: ready {relay.listen[0]}:{relay.listen[1]} -> "
          f"{relay.router[0]}:{relay.router[1]}", flush=True)  # fmt: skip
    try:
        while not stop.is_set():
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), STATS_EVERY_S)
            _write(stats_path, relay.stats())
    finally:
        done = relay.close()
        if done is not None:
            await done
        _write(stats_path, relay.stats())


def main(argv: list[str] | None = None) -> int:
    """``python -m sitl_model.radio_relay``; exit 0 on SIGINT/SIGTERM, 2 on bad input."""
    p = argparse.ArgumentParser(
        prog="python -m sitl_model.radio_relay",
        description="A radio-like UDP link (rate, delay, loss) between UAVs and a router.",
    )
    p.add_argument("--listen", type=_addr, required=True, metavar="HOST:PORT")
    p.add_argument("--to", type=_addr, required=True, metavar="HOST:PORT", help="the router")
    p.add_argument("--rate-bytes-s", type=float, default=12_500.0, help="bytes/s (12500)")
    p.add_argument("--delay-ms", type=float, default=50.0, help="one-way delay (50 ms)")
    p.add_argument("--loss", type=float, default=0.10, help="loss probability (0.10)")
    p.add_argument("--limit", type=int, default=1000, help="datagrams queued at most")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument(
        "--tcp", action="store_true", help="relay TCP (retransmit what is lost) instead of UDP"
    )
    p.add_argument("--stats", type=Path, metavar="FILE", help="write the counts here (JSON)")
    args = p.parse_args(argv)
    try:
        header = TCP_IP_HEADER_BYTES if args.tcp else IPV4_UDP_HEADER_BYTES
        spec = LinkSpec(args.rate_bytes_s, args.delay_ms / 1000.0, args.loss, args.limit, header)
        link = RadioLink(spec, args.seed)
        relay = (StreamRelay if args.tcp else RadioRelay)(link, args.listen, args.to)
    except (ValueError, OSError) as exc:
        print(f"radio-relay: {exc}", file=sys.stderr)
        return 2
    asyncio.run(_serve(relay, args.stats))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
