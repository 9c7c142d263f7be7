"""``companion zenoh-router``: a Zenoh router in a Python process, for the group across subnets.

Listens on ``--listen`` (Zenoh endpoints, e.g. ``tcp/0.0.0.0:7447``) and links to the
routers at ``--connect``. Peers (``--group zenoh:tcp/ROUTER:7447``) meet through it and then
also talk directly where unicast reaches; clients (``--group zenoh-client:...``) send every
sample through it. It never sees the fleet key: the group's datagrams are signed end to end
and it forwards them as opaque payloads. Prints ``zenoh-router: ready ...`` once it listens;
SIGINT/SIGTERM close it (exit 0).
"""

from __future__ import annotations

import argparse
import signal
import sys

from companion.group.address import parse_endpoint


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``zenoh-router`` sub-command."""
    p = sub.add_parser(
        "zenoh-router",
        help="run a Zenoh router for the group across subnets (docs/protocol.md)",
        description="A Zenoh router: the meeting point of the group's Zenoh peers across "
        "subnets and the path of its clients. It forwards the signed datagrams unread.",
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="endpoint to listen on (repeatable; default tcp/0.0.0.0:7447)",
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="another router to link to (repeatable)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Open the router; serve until SIGINT/SIGTERM, then close it (exit 0)."""
    listen = tuple(parse_endpoint(e, "--listen") for e in args.listen) or ("tcp/0.0.0.0:7447",)
    connect = tuple(parse_endpoint(e, "--connect") for e in args.connect)
    stop = {signal.SIGINT, signal.SIGTERM}
    signal.pthread_sigmask(signal.SIG_BLOCK, stop)  # before Zenoh's threads start: they inherit it
    from companion.group.zenoh_socket import open_router

    session = open_router(listen, connect)  # UserError: exit 2 with one line
    try:
        print(
            f"zenoh-router: ready, zid {session.zid()}, listening on {','.join(listen)}",
            flush=True,
        )
        got = signal.sigwait(stop)
        print(f"zenoh-router: {signal.Signals(got).name}, closing", file=sys.stderr, flush=True)
    finally:
        session.close()
    return 0
