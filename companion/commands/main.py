"""``companion`` command line: one sub-command per module in :mod:`companion.commands`.

Each command module exposes ``register(subparsers)`` which adds its parser and sets
``func(args) -> int``. Exit status 2 means bad input (one line on stderr, no traceback).
A command line naming a sub-command imports only that module (a companion process does not
load the simulator, the report or the web server); ``companion --help`` imports them all.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from companion import __version__
from companion.contracts.argv import join_negative_values
from companion.contracts.errors import UserError

# Sub-commands, in the order ``companion --help`` lists them.
COMMANDS: tuple[str, ...] = (
    "fleet",
    "simulate",
    "campaign",
    "report",
    "export",
    "run",
    "upload",
    "alert",
    "dashboard",
    "keygen",
    "plan",
    "guarantee",
    "zenoh-router",
)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The top-level argument parser with every sub-command registered (``only``: just that
    one, for a command line that names it)."""
    parser = argparse.ArgumentParser(
        prog="companion",
        description="Coordinated perimeter patrol in wind with minimum-time alert response.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS if only is None else (only,):
        importlib.import_module(f"companion.commands.{name.replace('-', '_')}").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the ``companion`` command line; returns the process exit status."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    args = parser.parse_args(join_negative_values(parser, argv))
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"companion {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
