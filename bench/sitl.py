"""Benchmark of the simulator: real-time factor and CPU use for N vehicles streaming telemetry.

For each N it starts ``python -m sitl_model`` (as fast as it can go, and at the goal
speed-up), attaches one listening client per vehicle (a UDP socket that says hello with a
HEARTBEAT and then drains everything), and reports over a fixed wall-clock window:

- rtf: simulated seconds per wall second (from the simulator's own status lines),
- lag: the simulator's reported lag behind the requested pace (wall s),
- cpu: CPU use of the simulator process (% of one core),
- rx/s: datagrams per wall second the clients received.

Usage: ``PYTHONPATH=. python bench/sitl.py [--window 6] [--n 1 6 24 50]``. Timings depend on
the machine; they are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import selectors
import socket
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sitl_model.codec import Encoder, dialect
from sitl_model.testing import SitlProcess

GOALS = {6: 100.0, 50: 5.0}
STATUS = re.compile(r"sitl t=([\d.]+)s rtf=([\d.]+) lag=([\d.]+)s")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(n: int, speedup: float, window_s: float) -> dict[str, float]:
    """One measurement: N vehicles at ``speedup`` for ``window_s`` wall seconds."""
    proc = SitlProcess(
        "--speedup", str(speedup), "--status-interval", "1", "--no-control", vehicles=n
    )
    sel = selectors.DefaultSelector()
    socks = []
    try:
        hello = Encoder(255, 190).pack(dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))
        for i in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            s.connect(("127.0.0.1", proc.port(i)))
            s.setblocking(False)
            s.send(hello)
            sel.register(s, selectors.EVENT_READ)
            socks.append(s)
        time.sleep(1.0)  # warm-up
        first_status = len(proc.stderr_lines)
        c0, w0, rx = cpu_s(proc.proc.pid), time.monotonic(), 0
        while time.monotonic() - w0 < window_s:
            for key, _ in sel.select(0.1):
                try:
                    while True:
                        key.fileobj.recv(65535)
                        rx += 1
                except BlockingIOError:
                    pass
        wall = time.monotonic() - w0
        cpu = cpu_s(proc.proc.pid) - c0
        stats = [STATUS.search(ln) for ln in proc.stderr_lines[first_status:]]
        stats = [m for m in stats if m]
    finally:
        for s in socks:
            s.close()
        sel.close()
        proc.stop()
    rtfs = [float(m.group(2)) for m in stats[1:]] or [float(m.group(2)) for m in stats]
    return {
        "rtf": sum(rtfs) / max(1, len(rtfs)),
        "lag": float(stats[-1].group(3)) if stats else float("nan"),
        "cpu": 100.0 * cpu / wall,
        "rx": rx / wall,
    }


def main() -> int:
    """Run the table and print it."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[1, 6, 24, 50])
    ap.add_argument("--window", type=float, default=6.0, help="wall s per measurement")
    args = ap.parse_args()
    print(f"sitl bench: {os.cpu_count()} CPUs, window {args.window:g} s wall per row")
    print(f"{'N':>3} {'speedup':>9} {'rtf':>8} {'lag_s':>7} {'cpu_%':>6} {'rx/s':>8}")
    for n in args.n:
        runs = [("max", 1e6)]
        if n in GOALS:
            runs.append((f"{GOALS[n]:g}", GOALS[n]))
        for label, speed in runs:
            r = run(n, speed, args.window)
            lag = "-" if label == "max" else f"{r['lag']:.2f}"  # "max" is behind by design
            print(
                f"{n:>3} {label:>9} {r['rtf']:>8.1f} {lag:>7} {r['cpu']:>6.0f} {r['rx']:>8.0f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
