"""Options that several sub-commands share (argparse only)."""

from __future__ import annotations

import argparse

ON_CONFIRM_CHOICES = ("track", "chain")


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
