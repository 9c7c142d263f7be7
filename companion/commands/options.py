"""Options that several sub-commands share (argparse only)."""

from __future__ import annotations

import argparse
import math
from dataclasses import fields
from typing import TYPE_CHECKING, Any, TypeVar

from companion.agent.config import AGENT_OPTIONS, AgentConfig
from companion.contracts.argv import add_battery_used_option
from companion.contracts.errors import UserError
from companion.contracts.options import OptionError, option_flag
from companion.link.config import LINK_OPTIONS, LinkConfig

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

__all__ = ["add_battery_used_option"]  # shared with sitl-model (contracts/argv.py)


def battery_used(
    args: argparse.Namespace, sysids: tuple[int, ...]
) -> tuple[tuple[int, float], ...]:
    """``--battery-used`` as given, each sysid checked against the mission's vehicles
    ``sysids`` (spares included). Raises :class:`UserError` for one the mission lacks."""
    for sysid, mah in args.battery_used:
        if sysid not in sysids:
            raise UserError(f"--battery-used {sysid}={mah:g}: the mission has no vehicle {sysid}")
    return tuple(args.battery_used)


def add_record_options(
    p: argparse.ArgumentParser, record: type[DataclassInstance], names: tuple[str, ...]
) -> None:
    """One option per field in ``names`` of the configuration ``record`` (a frozen dataclass
    whose fields carry a :func:`~companion.contracts.options.spec`), built from the field's
    declaration: its default, its meaning and unit as the help, its choices (a bad one is
    argparse's usage error); a number's bounds are checked by :func:`record_from_args`."""
    declared = {f.name: f for f in fields(record)}
    for name in names:
        f = declared[name]
        meta = f.metadata
        unit = f"{meta['unit']}; " if meta["unit"] else ""
        if meta["choices"] is not None:
            p.add_argument(
                option_flag(name),
                choices=meta["choices"],
                default=f.default,
                help=f"{meta['doc']} (default %(default)s)",
            )
            continue
        number = int if isinstance(f.default, int) else float
        p.add_argument(
            option_flag(name),
            type=number,
            default=f.default,
            metavar=(meta["unit"] or "N").upper(),
            help=f"{meta['doc']} ({unit}default %(default)s)",
        )


R = TypeVar("R", bound="DataclassInstance")


def record_from_args(
    record: type[R], args: argparse.Namespace, names: tuple[str, ...], **more: Any
) -> R:
    """The configuration ``record`` of the options ``names`` as parsed and the fields
    ``more`` (the others at their defaults). Raises :class:`UserError` naming the flag of a
    value out of its bounds."""
    try:
        return record(**{name: getattr(args, name) for name in names}, **more)
    except OptionError as exc:
        raise UserError(f"{option_flag(exc.field)} {exc.why}") from None


def add_agent_options(p: argparse.ArgumentParser) -> None:
    """``--policy``, ``--on-confirm``, ``--max-prosecutors``, ``--member-timeout-s``: the
    :class:`~companion.agent.config.AgentConfig` fields in
    :data:`~companion.agent.config.AGENT_OPTIONS`, as every companion of a run takes them."""
    add_record_options(p, AgentConfig, AGENT_OPTIONS)


def agent_config(args: argparse.Namespace) -> AgentConfig:
    """The :class:`~companion.agent.config.AgentConfig` of :func:`add_agent_options`' options
    as parsed (the others at their defaults; :class:`UserError` for a value out of bounds)."""
    return record_from_args(AgentConfig, args, AGENT_OPTIONS)


def add_link_options(p: argparse.ArgumentParser, names: tuple[str, ...] = LINK_OPTIONS) -> None:
    """``--profile`` (and ``--rate-hz``): the :class:`~companion.link.config.LinkConfig`
    fields in ``names``."""
    add_record_options(p, LinkConfig, names)


def link_config(
    args: argparse.Namespace, names: tuple[str, ...] = LINK_OPTIONS, adapt: bool = True
) -> LinkConfig:
    """The :class:`~companion.link.config.LinkConfig` of :func:`add_link_options`' options
    ``names`` as parsed, ``adapt`` as given (:class:`UserError` for a value out of bounds)."""
    return record_from_args(LinkConfig, args, names, adapt=adapt)


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
