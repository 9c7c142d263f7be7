"""What one process per aircraft costs on this machine, apart from the product: the same
Python work, timed alone and in a lockstep of processes like the fleet's (issue 46).

A companion's control step costs 0.25-0.28 ms a tick in memory (one process) and about
0.5 ms in the demo, where eight processes take turns on two cores (docs/speed.md). This
bench asks whether that excess belongs to the product or to the arrangement: it runs a
synthetic step (``--ops`` reads of objects spread over a pool of ``--pool-mb`` MB, arithmetic
on each) with none of the product's code,

* ``alone``: back to back in one process;
* ``lockstep N``: a hub and ``N`` worker processes on loopback UDP, as the lockstepped
  simulator and its companions: each tick the hub sends every worker one datagram, each
  worker does the step and answers, and the hub starts the next tick once every answer is
  in. Each worker times its own CPU (``time.process_time``) for the step alone and for the
  whole tick (the step, the datagrams and the waits' wake-ups).

It prints, per arrangement, the step's CPU per tick (the median over the workers) and its
ratio to ``alone``, and the whole tick's CPU. Run it on an idle machine: other work moves
the figures as it moves the product's.

    python bench/process_floor.py [--ticks 2000] [--ops 1000] [--pool-mb 1.5]
        [--workers 1,2,6] [--rounds 2]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import socket
import statistics
import sys
import time
from pathlib import Path

HOST = "127.0.0.1"
WAIT_S = 5.0  # wall s the hub waits for a tick's answers before it gives up


class Cell:
    """One object of the pool (two floats, as a message's fields)."""

    __slots__ = ("x", "y")

    def __init__(self, x: float, y: float) -> None:
        """Two values."""
        self.x, self.y = x, y


def pool_of(mb: float) -> list[Cell]:
    """About ``mb`` MB of :class:`Cell` objects (a slotted object and its two floats: about
    104 bytes), shuffled so that neighbours in the list are apart in memory."""
    n = max(1, int(mb * 1e6 / 104))
    cells = [Cell(float(i), 1.0 / (i + 1)) for i in range(n)]
    stride = 7919  # a prime: i -> i * stride mod n permutes the pool unless n is its multiple
    return [cells[(i * stride) % n] for i in range(n)] if n % stride else cells


def step(pool: list[Cell], ops: int, tick: int) -> float:
    """The synthetic control step: ``ops`` reads spread over the pool (-)."""
    n = len(pool)
    acc = 0.0
    j = (tick * 104729) % n
    for _ in range(ops):
        c = pool[j]
        acc += c.x * c.y
        j = (j + 4099) % n
    return acc


def alone(ticks: int, ops: int, pool_mb: float) -> float:
    """CPU ms per step, back to back in this process."""
    pool = pool_of(pool_mb)
    step(pool, ops, 0)
    t0 = time.process_time()
    for k in range(ticks):
        step(pool, ops, k)
    return (time.process_time() - t0) / ticks * 1e3


def _worker(port_q: mp.Queue, out_q: mp.Queue, ops: int, pool_mb: float) -> None:
    """A worker: answer each of the hub's datagrams after one step; report its CPU."""
    pool = pool_of(pool_mb)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((HOST, 0))
    port_q.put(sock.getsockname()[1])
    step_cpu = 0.0
    ticks = 0
    t_start = None
    while True:
        data, hub = sock.recvfrom(64)
        if data == b"end":
            break
        if t_start is None:
            t_start = time.process_time()
        t0 = time.process_time()
        if ops:
            step(pool, ops, ticks)
        step_cpu += time.process_time() - t0
        ticks += 1
        sock.sendto(b"ok", hub)
    total = time.process_time() - (t_start or time.process_time())
    out_q.put((step_cpu, total, ticks))
    sock.close()


def lockstep(workers: int, ticks: int, ops: int, pool_mb: float) -> tuple[float, float]:
    """CPU ms per tick in the workers (medians): the step alone, and the whole tick."""
    ctx = mp.get_context("fork")
    port_q: mp.Queue = ctx.Queue()
    out_q: mp.Queue = ctx.Queue()
    procs = [
        ctx.Process(target=_worker, args=(port_q, out_q, ops, pool_mb)) for _ in range(workers)
    ]
    for p in procs:
        p.start()
    try:
        ports = [port_q.get(timeout=30) for _ in procs]
        hub = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        hub.bind((HOST, 0))
        hub.settimeout(WAIT_S)
        for _ in range(ticks):
            for port in ports:
                hub.sendto(b"tick", (HOST, port))
            for _ in ports:
                hub.recvfrom(64)
        for port in ports:
            hub.sendto(b"end", (HOST, port))
        got = [out_q.get(timeout=30) for _ in procs]
        hub.close()
    finally:
        for p in procs:
            p.join(10)
            if p.is_alive():
                p.kill()
                p.join()
    step_ms = statistics.median(s / n * 1e3 for s, _, n in got)
    tick_ms = statistics.median(t / n * 1e3 for _, t, n in got)
    return step_ms, tick_ms


def main(argv: list[str] | None = None) -> int:
    """Print the table; 0."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ticks", type=int, default=2000)
    p.add_argument("--ops", type=int, default=1000, help="reads per step")
    p.add_argument("--pool-mb", type=float, default=1.5, help="MB the reads are spread over")
    p.add_argument("--workers", default="1,2,6", help="lockstep arrangements (comma list)")
    p.add_argument("--rounds", type=int, default=2, help="every arrangement this many times")
    a = p.parse_args(argv)
    try:
        arrangements = [int(x) for x in a.workers.split(",")]
    except ValueError:
        p.error(f"--workers: expected whole numbers separated by commas, got {a.workers!r}")
    if min(arrangements) < 1 or min(a.ticks, a.ops, a.rounds) < 1 or not a.pool_mb > 0:
        p.error("--workers, --ticks, --ops and --rounds must be at least 1, --pool-mb above 0")
    avg = Path("/proc/loadavg")
    load = " ".join(avg.read_text().split()[:3]) if avg.exists() else "unknown"
    print(f"# {a.ticks} ticks, {a.ops} reads over {a.pool_mb:g} MB; {os.cpu_count()} CPUs, "
          f"load {load}")  # fmt: skip
    rows: dict[str, list[tuple[float, float]]] = {}
    for _ in range(a.rounds):
        ms = alone(a.ticks, a.ops, a.pool_mb)
        rows.setdefault("alone", []).append((ms, ms))
        for n in arrangements:
            rows.setdefault(f"lockstep {n}", []).append(lockstep(n, a.ticks, a.ops, a.pool_mb))
            rows.setdefault(f"lockstep {n}, no step", []).append(lockstep(n, a.ticks, 0, a.pool_mb))
    base = min(s for s, _ in rows["alone"])
    print("| arrangement | step ms/tick (min over rounds) | x alone | whole tick ms |")
    print("|---|---|---|---|")
    for name, got in rows.items():
        s = min(x for x, _ in got)
        t = min(x for _, x in got)
        print(f"| {name} | {s:.3f} | {s / base:.2f} | {t:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
