"""Where the group is: a UDP multicast group or a Zenoh key expression (pure: text in, data out).

``--group`` takes either form (docs/protocol.md, Transport):

* ``ADDR:PORT`` -- UDP multicast, e.g. ``239.255.14.1:14600`` (the default);
* ``zenoh[:ENDPOINT,...][?key=KEYEXPR&listen=ENDPOINT,...&scout=off]`` -- Zenoh in peer
  mode: multicast scouting finds the peers of the LAN, the ENDPOINTs (``tcp/10.0.1.1:7447``,
  a router or a peer) are connected as well, which carries the group across subnets;
* ``zenoh-client:ENDPOINT,...[?...]`` -- Zenoh in client mode: everything goes through the
  router(s) at the endpoints.

Both carry the same signed MAVLink 2 datagrams; the codec and the group never know which.
"""

from __future__ import annotations

import ipaddress
import json
import re
from dataclasses import dataclass

from companion.contracts.errors import UserError

__all__ = [
    "CLIENT_CONNECT_TIMEOUT_MS",
    "DEFAULT_ADDRESS",
    "DEFAULT_KEY_EXPR",
    "DEFAULT_PORT",
    "GroupAddress",
    "MulticastGroup",
    "ZenohGroup",
    "parse_endpoint",
    "parse_group",
]

DEFAULT_ADDRESS = "239.255.14.1"  # administratively scoped (RFC 2365), site-local
DEFAULT_PORT = 14600
DEFAULT_KEY_EXPR = "patrol/group"
ZENOH_MODES = ("peer", "client")
CLIENT_CONNECT_TIMEOUT_MS = 30_000  # a client retries its routers this long at start (ms)
_ENDPOINT = re.compile(r"^(tcp|udp|tls|quic|ws)/(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(\d{1,5})$")
_CHUNK = re.compile(r"^[A-Za-z0-9_.~+-]+$")  # a key-expression chunk without wildcards


@dataclass(frozen=True)
class MulticastGroup:
    """A UDP multicast group: IPv4 multicast ``address`` and UDP ``port``."""

    address: str = DEFAULT_ADDRESS
    port: int = DEFAULT_PORT

    def __str__(self) -> str:
        return f"{self.address}:{self.port}"


@dataclass(frozen=True)
class ZenohGroup:
    """A Zenoh group: the session's mode, endpoints and the one key expression it uses.

    ``connect`` and ``listen`` are Zenoh endpoints (``tcp/HOST:PORT``); ``scouting`` is
    Zenoh's multicast scouting (peers of one LAN find each other without endpoints).
    """

    mode: str = "peer"
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    key_expr: str = DEFAULT_KEY_EXPR
    scouting: bool = True

    def __str__(self) -> str:
        head = "zenoh" if self.mode == "peer" else "zenoh-client"
        text = head + (":" + ",".join(self.connect) if self.connect else "")
        query = []
        if self.key_expr != DEFAULT_KEY_EXPR:
            query.append(f"key={self.key_expr}")
        if self.listen:
            query.append("listen=" + ",".join(self.listen))
        if not self.scouting:
            query.append("scout=off")
        return text + ("?" + "&".join(query) if query else "")

    def config(self) -> dict[str, str]:
        """The Zenoh configuration as ``{json5 path: json5 value}`` (``Config.insert_json5``).

        A client keeps trying its router(s) for :data:`CLIENT_CONNECT_TIMEOUT_MS` when the
        session opens (Zenoh's default for a client: 10 s; twelve clients opening at once
        through a 100 kbit/s radio queue their handshakes for seconds, and one failed to open
        within 10 s, measured).
        """
        out = {
            "mode": json.dumps(self.mode),
            "connect/endpoints": json.dumps(list(self.connect)),
            "scouting/multicast/enabled": json.dumps(self.scouting),
        }
        if self.mode == "client":
            out["connect/timeout_ms"] = json.dumps(CLIENT_CONNECT_TIMEOUT_MS)
        if self.listen:
            out["listen/endpoints"] = json.dumps(list(self.listen))
        return out


GroupAddress = MulticastGroup | ZenohGroup


def parse_group(text: str) -> GroupAddress:
    """``--group`` text -> a :class:`MulticastGroup` or a :class:`ZenohGroup`; ``UserError``
    naming the option and what was expected if it is neither."""
    m = re.match(r"^(zenoh|zenoh-client)(?::|(?=\?)|$)", text)
    if m is not None:
        return _parse_zenoh(text, "peer" if m.group(1) == "zenoh" else "client", text[m.end() :])
    return _parse_multicast(text)


def _parse_multicast(text: str) -> MulticastGroup:
    addr, sep, port_text = text.rpartition(":")
    if not sep or not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise UserError(
            f"--group {text!r}: expected ADDR:PORT (e.g. 239.255.14.1:14600) or "
            "zenoh[:ENDPOINT,...] (e.g. zenoh:tcp/10.0.1.1:7447)"
        )
    try:
        ip = ipaddress.IPv4Address(addr)
    except ValueError:
        raise UserError(f"--group {text!r}: {addr!r} is not an IPv4 address") from None
    if not ip.is_multicast:
        raise UserError(f"--group {text!r}: {addr} is not a multicast address (224.0.0.0/4)")
    return MulticastGroup(addr, int(port_text))


def parse_endpoint(text: str, where: str) -> str:
    """One Zenoh endpoint ``PROTO/HOST:PORT`` (tcp, udp, tls, quic, ws), checked;
    ``UserError`` naming ``where`` (the option) otherwise."""
    m = _ENDPOINT.match(text)
    if m is None or not 0 <= int(m.group(3)) <= 65535:
        raise UserError(
            f"{where}: {text!r} is not a Zenoh endpoint (expected PROTO/HOST:PORT, "
            "e.g. tcp/10.0.1.1:7447)"
        )
    return text


def _endpoints(value: str, where: str) -> tuple[str, ...]:
    return tuple(parse_endpoint(e, where) for e in value.split(",") if e)


def _parse_zenoh(text: str, mode: str, rest: str) -> ZenohGroup:
    where = f"--group {text!r}"
    body, _, query = rest.partition("?")
    connect = _endpoints(body, where)
    key, scouting = DEFAULT_KEY_EXPR, True
    listen: tuple[str, ...] = ()
    for item in (q for q in query.split("&") if q):
        name, eq, value = item.partition("=")
        if not eq:
            raise UserError(f"{where}: {item!r}: expected NAME=VALUE (key, listen, scout)")
        if name == "key":
            chunks = value.split("/")
            if not value or not all(_CHUNK.match(c) for c in chunks):
                raise UserError(
                    f"{where}: key={value!r}: expected a key expression without wildcards, "
                    "e.g. patrol/blue"
                )
            key = value
        elif name == "listen":
            listen = _endpoints(value, where)
        elif name == "scout":
            if value not in ("on", "off"):
                raise UserError(f"{where}: scout={value!r}: expected on or off")
            scouting = value == "on"
        else:
            raise UserError(f"{where}: unknown setting {name!r} (expected key, listen, scout)")
    if mode == "client" and not connect and not scouting:
        raise UserError(f"{where}: a client needs a router: give ENDPOINT or scout=on")
    return ZenohGroup(mode, connect, listen, key, scouting)
