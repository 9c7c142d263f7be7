"""Twelve UAVs on the paper's ellipse with their group over a radio-like link: the figures.

The link is :mod:`sitl_model.radio_relay` (user space: this kernel has no ``sch_netem``, so
``tc qdisc ... netem`` is refused; docs/protocol.md, "A radio-like link"): 100 kbit/s
shared by both directions, 50 ms one way, 10 % independent loss. The companions are Zenoh
clients reaching one ``companion zenoh-router`` through it; ``--group-budget`` is set so
the star's traffic fits 80 % of the link. Free-running at 1x (the link runs on the wall
clock), so a run takes its duration in wall time plus about a minute.

    python bench/radio_link.py                    # 12 UAVs, 400 s, --group-budget 300
    python bench/radio_link.py --no-budget        # the same without the budget
    python bench/radio_link.py --udp              # Zenoh's UDP link (no retransmission)

Prints one JSON object: metrics.json's cross-track p95 and coverage revisit ratio, the
convergence and settle times, the bytes offered to the link per second against its rate,
each member's last state rate, the exit statuses and the wall time.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.radio_harness import BUDGET_BYTES_S, LINK_RATE_BYTES_S, fly_over_radio


def main() -> int:
    """Fly once and print the figures (exit 0 whatever they are: a bench, not a test)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--uavs", type=int, default=12)
    p.add_argument("--duration", type=float, default=400.0, help="simulated = wall s")
    p.add_argument("--budget", type=float, default=BUDGET_BYTES_S, help="--group-budget, B/s")
    p.add_argument("--no-budget", action="store_true", help="no --group-budget")
    p.add_argument("--rate-bytes-s", type=float, default=LINK_RATE_BYTES_S)
    p.add_argument("--delay-ms", type=float, default=50.0)
    p.add_argument("--loss", type=float, default=0.10)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--udp", action="store_true", help="Zenoh over UDP (no retransmission)")
    p.add_argument("--out", type=Path, help="run folder (default: a temporary one, kept)")
    args = p.parse_args()
    # SIGTERM as Ctrl-C: the harness's finally then stops the fleet, the relay and the router
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    out = args.out or Path(tempfile.mkdtemp(prefix="radio_link-"))
    fig = fly_over_radio(
        out,
        uavs=args.uavs,
        duration_s=args.duration,
        budget_bytes_s=None if args.no_budget else args.budget,
        rate_bytes_s=args.rate_bytes_s,
        delay_ms=args.delay_ms,
        loss=args.loss,
        seed=args.seed,
        udp=args.udp,
    )
    print(json.dumps({"out": str(out), **fig}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
