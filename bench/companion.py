"""Companion benchmark: telemetry-to-setpoint latency and CPU per companion.

Starts ``sitl_model`` with the six-UAV test mission at 1x (real time) and six
``companion run`` processes over loopback UDP, lets them fly for ``--seconds`` of wall
time, stops them with SIGTERM and reads each one's final status line:

* latency: wall time from reading a telemetry datagram to sending the setpoint computed
  from it (median and 99th percentile, ms);
* CPU: process CPU time per wall second since the link came up (% of one core).

Usage: ``PYTHONPATH=. python bench/companion.py [--seconds 60] [--speedup 1]``
Goals: p99 under 5 ms and under 5 % of one core per companion at 1x with 6 UAVs.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from sitl_model.server import free_base_port
from sitl_model.testing import SitlProcess

MISSION = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"


def main() -> int:
    """Run the benchmark and print one row per companion and a summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="wall seconds of flight")
    ap.add_argument("--speedup", type=float, default=1.0, help="simulator speed-up")
    ap.add_argument("--profile", default="turn-rate", choices=("turn-rate", "bank", "heading"))
    args = ap.parse_args()
    base = free_base_port(6)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        gport = s.getsockname()[1]
    env = dict(os.environ, PYTHONPATH=str(REPO))
    out = Path(tempfile.mkdtemp(prefix="bench-companion-"))
    procs = []
    for i in range(6):
        err = open(out / f"c{i + 1}.err", "w")  # noqa: SIM115 - closed below
        procs.append(
            (
                subprocess.Popen(
                    [
                        sys.executable,
                        "-m",
                        "companion",
                        "run",
                        "--connect",
                        f"udpout:127.0.0.1:{base + 10 * i}",
                        "--mission",
                        str(MISSION),
                        "--insecure",
                        "--profile",
                        args.profile,
                        "--group",
                        f"239.255.14.77:{gport}",
                    ],
                    cwd=REPO,
                    env=env,
                    stdout=subprocess.DEVNULL,
                    stderr=err,
                ),
                err,
            )
        )
    time.sleep(3.0)
    sitl = SitlProcess(
        "--mission", str(MISSION), "--speedup", str(args.speedup), "--base-port", str(base)
    )
    try:
        time.sleep(args.seconds)
    finally:
        for p, _ in procs:
            p.send_signal(signal.SIGTERM)
        codes = [p.wait(15) for p, _ in procs]
        for _, err in procs:
            err.close()
        sitl.stop()
    print(
        f"companion bench: {os.cpu_count()} CPUs, {args.seconds:g} s wall, speed-up "
        f"{args.speedup:g}, profile {args.profile}, load average {os.getloadavg()[0]:.1f}"
    )
    print(" sysid  setpoints  sp/s  lat_p50_ms  lat_p99_ms  cpu_%  exit")
    p50s, p99s, cpus = [], [], []
    for i in range(6):
        text = (out / f"c{i + 1}.err").read_text()
        final = [ln for ln in text.splitlines() if ln.startswith("companion final")]
        if not final:
            print(f"{i + 1:6d}  no final status line (exit {codes[i]})")
            continue
        ln = final[-1]
        lat = re.search(r"lat_ms=([\d.]+)/([\d.]+)", ln)
        cpu = re.search(r"cpu_pct=([\d.]+)", ln)
        sp = re.search(r"setpoints=(\d+)", ln)
        rate = re.search(r"sp/s=([\d.]+)", ln)
        p50, p99 = (float(lat.group(1)), float(lat.group(2))) if lat else (float("nan"),) * 2
        c = float(cpu.group(1)) if cpu else float("nan")
        p50s.append(p50)
        p99s.append(p99)
        cpus.append(c)
        print(
            f"{i + 1:6d}  {int(sp.group(1)) if sp else 0:9d}  {rate.group(1) if rate else '-':>4}"
            f"  {p50:10.2f}  {p99:10.2f}  {c:5.2f}  {codes[i]:4d}"
        )
    if p99s:
        print(
            f"median p50 {sorted(p50s)[len(p50s) // 2]:.2f} ms, worst p99 {max(p99s):.2f} ms, "
            f"worst CPU {max(cpus):.2f} % of one core (goals: p99 < 5 ms, CPU < 5 %)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
