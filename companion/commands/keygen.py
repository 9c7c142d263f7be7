"""``companion keygen FILE``: create a new fleet signing key file (32 random bytes, hex).

The file is created with mode 0600 and never overwritten. Copy it to every companion (and
operator station) of the fleet over a secure channel; ``--key-file FILE`` then signs the
group. Prints the file name and the key's public fingerprint, never the key.
"""

from __future__ import annotations

import argparse

from companion.group.keys import generate_key_file, key_fingerprint


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``keygen`` sub-command."""
    p = sub.add_parser(
        "keygen",
        help="create a new fleet signing key file (mode 600)",
        description="Write 32 random bytes as 64 hex characters to FILE (mode 0600; an "
        "existing file is never overwritten).",
    )
    p.add_argument("file", metavar="FILE", help="the key file to create")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Create the key file; print its name and fingerprint."""
    key = generate_key_file(args.file)
    print(f"wrote {args.file} (fingerprint {key_fingerprint(key)})")
    return 0
