"""Options that several sub-commands share (argparse only)."""

from __future__ import annotations

import argparse
import math

from companion.contracts.argv import add_battery_used_option

__all__ = ["add_battery_used_option"]  # shared with sitl-model (contracts/argv.py)

ON_CONFIRM_CHOICES = ("track", "chain")


def battery_used(
    args: argparse.Namespace, sysids: tuple[int, ...]
) -> tuple[tuple[int, float], ...]:
    """``--battery-used`` as given, each sysid checked against the mission's vehicles
    ``sysids`` (spares included). Raises :class:`UserError` for one the mission lacks."""
    from companion.contracts.errors import UserError

    for sysid, mah in args.battery_used:
        if sysid not in sysids:
            raise UserError(f"--battery-used {sysid}={mah:g}: the mission has no vehicle {sysid}")
    return tuple(args.battery_used)


def add_alert_options(p: argparse.ArgumentParser) -> None:
    """``--policy`` and ``--on-confirm``: how every companion answers an alert."""
    p.add_argument(
        "--policy", choices=("next", "fastest"), default="next", help="alert tasking policy"
    )
    p.add_argument(
        "--on-confirm",
        choices=ON_CONFIRM_CHOICES,
        default="track",
        help="what the UAV that sees the intruder it flies to does: track (stays over it "
        "while the others splay as N - 1; default) or chain (the paper's: hands it to the "
        "next UAV)",
    )


GROUP_HELP = (
    "the group: ADDR:PORT for UDP multicast (default %(default)s), or "
    "zenoh[:ENDPOINT,...][?key=KEYEXPR&listen=ENDPOINT,...&scout=off] for Zenoh in peer "
    "mode (scouting finds the LAN's peers; the endpoints, e.g. tcp/10.0.1.1:7447, reach a "
    "router or peers across subnets), or zenoh-client:ENDPOINT,... (all through the router); "
    "see docs/protocol.md"
)


def add_group_options(p: argparse.ArgumentParser) -> None:
    """``--group`` (multicast ``ADDR:PORT`` or ``zenoh:...``) and ``--group-iface ADDR``, as
    every group client takes them."""
    from companion.group.address import DEFAULT_ADDRESS, DEFAULT_PORT
    from companion.group.transport import DEFAULT_IFACE

    p.add_argument(
        "--group", default=f"{DEFAULT_ADDRESS}:{DEFAULT_PORT}", metavar="WHERE", help=GROUP_HELP
    )
    p.add_argument(
        "--group-iface",
        default=DEFAULT_IFACE,
        metavar="ADDR",
        help="multicast only: IPv4 address of the group's interface (default %(default)s, "
        "loopback)",
    )


def _budget_bytes_s(text: str) -> float:
    """``--group-budget``'s value: bytes/s, finite and > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be finite and > 0 bytes/s, got {text!r}")
    return value


def add_budget_option(p: argparse.ArgumentParser) -> None:
    """``--group-budget BYTES_PER_S``: the group's state budget (docs/protocol.md,
    "Bandwidth budget"); absent: 5 states/s per member, the member time-out as given."""
    p.add_argument(
        "--group-budget",
        type=_budget_bytes_s,
        default=None,
        metavar="BYTES_PER_S",
        help="the group's state budget, bytes/s for all members together (e.g. 10000 on a "
        "100 kbit/s link, room left for alerts): each member's state rate falls as the group "
        "grows, the member time-out follows it, states beyond a sender's share are dropped "
        "(default: none, 5 states/s each; every member of a fleet must use the same; "
        "docs/protocol.md)",
    )
