"""``companion dashboard``: the live patrol page, a passive member of the signed group.

Joins the group (never sends a state), serves the page and its JSON API (see
``docs/dashboard.md`` and :mod:`companion.dashboard.server`), and signs with the fleet key
only the alerts and cancels the operator asks for (system id 255, like ``companion alert``).
Bound to 127.0.0.1 by default; bound to any other address it requires a token (``--token``,
or one generated and printed at start). Runs until SIGINT or SIGTERM, then exits 0.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import secrets
import signal
import sys
import time

from companion.commands.options import add_group_options
from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import parse_group
from companion.group.codec import COMPID_OPERATOR, OPERATOR_SYSID, Decoder
from companion.group.keys import load_key, signing_from_key_file
from companion.group.transport import open_group
from companion.mission import load_mission


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``dashboard`` sub-command."""
    p = sub.add_parser(
        "dashboard",
        help="live patrol page: map, UAVs, alerts, gauges; raise and cancel alerts",
        description="Listen to the signed patrol group and serve a live web page of the "
        "patrol (and GET /api/state for scripts). The operator can raise an alert by clicking "
        "the map and cancel an open one; they are signed with the fleet key.",
    )
    add_group_options(p)
    p.add_argument("--key-file", required=True, metavar="FILE", help="fleet signing key")
    p.add_argument(
        "--state-dir",
        metavar="DIR",
        help="where to keep the operator's signing-timestamp state (default: by the key)",
    )
    p.add_argument("--mission", metavar="FILE", help="mission YAML: loop, outline, origin")
    p.add_argument("--port", type=int, default=8080, help="HTTP port (default 8080; 0 = any)")
    p.add_argument(
        "--bind", default="127.0.0.1", metavar="ADDR", help="HTTP address (default 127.0.0.1)"
    )
    p.add_argument(
        "--token",
        metavar="T",
        help="required on every request (generated and printed when bound off loopback)",
    )
    p.add_argument(
        "--member-timeout-s",
        type=float,
        default=3.0,
        metavar="S",
        help="wall seconds of silence after which a UAV is shown lost (default 3)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Check the options, join the group and serve until SIGINT/SIGTERM."""
    from companion.dashboard.model import FleetView
    from companion.dashboard.server import Dashboard, is_loopback

    where = parse_group(args.group)
    if not 0 <= args.port <= 65535:
        raise UserError(f"--port {args.port}: expected 0..65535")
    if not (math.isfinite(args.member_timeout_s) and args.member_timeout_s > 0):
        raise UserError("--member-timeout-s must be > 0")
    loopback = is_loopback(args.bind)
    token = args.token
    if token is not None and (len(token) < 16 or not token.isascii() or not token.isprintable()):
        raise UserError("--token: at least 16 printable ASCII characters")
    if token is None and not loopback:
        token = secrets.token_urlsafe(24)
    mission = load_mission(args.mission) if args.mission else None
    key = load_key(args.key_file)
    listen_signing = Signing(key, time.time)  # verification only: never sends
    send_signing = signing_from_key_file(args.key_file, OPERATOR_SYSID, state_dir=args.state_dir)
    group_kw = {"iface": args.group_iface, "compid": COMPID_OPERATOR}
    listener = open_group(where, OPERATOR_SYSID, listen_signing, **group_kw)
    # hear every sender, the operator's own alerts (ours or `companion alert`'s) included
    listener.decoder = Decoder(None, listen_signing)
    # The sender's socket is joined too; nothing reads it, so the kernel keeps at most its
    # receive buffer of the group's traffic and drops the rest.
    sender = open_group(where, OPERATOR_SYSID, send_signing, **group_kw)
    view = FleetView(mission, member_timeout_s=args.member_timeout_s)
    dash = Dashboard(view, mission, listener, sender, token=token, loopback_only_hosts=loopback)
    try:
        asyncio.run(_serve(dash, args.bind, args.port, token, str(where)))
    finally:
        listener.close()
        sender.close()
    return 0


async def _serve(dash, host: str, port: int, token: str | None, group: str) -> None:
    """Serve ``dash`` on ``host:port`` until SIGINT or SIGTERM."""
    from aiohttp import web

    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    runner = web.AppRunner(dash.app, handle_signals=False, access_log=None, shutdown_timeout=2.0)
    await runner.setup()
    try:
        site = web.TCPSite(runner, host, port, reuse_address=True)
        try:
            await site.start()
        except OSError as exc:
            raise UserError(f"cannot serve on {host}:{port}: {exc.strerror or exc}") from None
        bound = runner.addresses[0][1] if runner.addresses else port
        shown = f"[{host}]" if ":" in host else host
        url = f"http://{shown}:{bound}/" + (f"?token={token}" if token else "")
        print(f"dashboard: {url} (group {group}; Ctrl-C stops)", flush=True)
        if token and not dash.loopback_only_hosts:
            print("dashboard: bound off loopback: every request needs the token", flush=True)
        await stop.wait()
    finally:
        await runner.cleanup()
    print("dashboard: stopped", file=sys.stderr, flush=True)
