"""Fuzzing bench: random and mutated datagrams at the simulator's ports and the group
during a fleet run.

Run from the repository root (under the shared lock on a shared machine)::

    flock /tmp/heavy.lock python bench/fuzz.py [--datagrams 100000] [--rate 2000] \\
        [--speedup 20] [--seed 1] [--mission FILE] [--out DIR]

It starts a fleet with the test harness (``tests/fleet_harness.py``: the real simulator and
six real ``companion run`` processes on a fresh fleet key; the harness is what the fleet
tests use, it stops every process even on failure and exposes each process's stderr, the
group address and the simulator's control line, which ``companion fleet`` does not), on
the mission without its intruders (so no UAV leaves its slot on purpose), captures a few
genuine group datagrams for the ``replay`` class, waits until the formation has held
splay < 2 deg and centre < 5 m for 20 simulated s, then sends the datagrams of
:mod:`bench.fuzzgen` at ``--rate`` per wall second, spread over every vehicle's port and
the group address. Then it prints: the classes sent, the processes alive, each companion's
setpoints per simulated second before and during the fuzz (counted in its
``autopilot.tlog``), the splay and centre errors over the fuzz (truth log), the group's
drop counters and the simulator's counters. Exit status 1 if a process died or exited
non-zero, or the formation lost convergence (splay >= 2 deg or centre >= 5 m) during the
fuzz; 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import json
import socket
import struct
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[1]
if not __package__:  # run as a script: sys.path[0] is bench/, whose companion.py would shadow
    sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"]

from bench.fuzzgen import FuzzGenerator, plan
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.mission import load_mission
from tests.fleet_harness import (
    FAST,
    SPEEDUP,
    Fleet,
    companion_cli,
    group_listener,
    last_truth_time,
    measures,
    start_fleet,
    status_field,
)

SPLAY_MAX_DEG = 2.0
CENTRE_MAX_M = 5.0
HOLD_S = 20.0  # simulated s the formation must have held before the fuzz starts
NOMINAL_RATE_HZ = 10.0  # setpoints per simulated second (companion --rate-hz default)
DROP_REASONS = ("malformed", "unsigned", "bad_signature", "replayed", "foreign_link", "own")
SIM_COUNTERS = ("rx", "bad", "foreign", "refused", "unsupported")


@dataclass
class FuzzResult:
    """What a fuzz run measured (times in simulated s, rates in setpoints per simulated s)."""

    datagrams: int
    classes: dict[str, dict[str, int]]  # destination -> class -> count
    valid_to_sim: dict[str, int]  # frames with a correct CRC the simulator decodes, by type
    replaced: int  # candidate datagrams for the simulator refused by the safety check
    send_wall_s: float
    send_errors: int
    t_converged_s: float
    t_fuzz_s: tuple[float, float]  # simulated time at the first and last datagram
    alive: dict[str, bool]  # process -> alive after the fuzz
    exit_codes: list[int]  # companions c1..c6, then the simulator (SIGTERM at the end)
    rate_before: list[float]
    rate_during: list[float]
    splay_before_deg: float
    centre_before_m: float
    splay_during_deg: float
    centre_during_m: float
    drops_before: list[dict[str, int]]
    drops_after: list[dict[str, int]]
    sim_before: dict[str, int]
    sim_after: dict[str, int]
    notes: list[str] = field(default_factory=list)

    @property
    def group_drop_increase(self) -> dict[str, int]:
        """Drops by reason summed over the companions, during the fuzz (own excluded)."""
        tot: Counter[str] = Counter()
        for b, a in zip(self.drops_before, self.drops_after, strict=True):
            for r in DROP_REASONS[:-1]:
                tot[r] += a.get(r, 0) - b.get(r, 0)
        return dict(tot)

    @property
    def converged(self) -> bool:
        """Splay and centre errors stayed under the convergence bounds during the fuzz."""
        return self.splay_during_deg < SPLAY_MAX_DEG and self.centre_during_m < CENTRE_MAX_M

    @property
    def all_alive(self) -> bool:
        """Every process alive after the fuzz and exiting 0 on SIGTERM."""
        return all(self.alive.values()) and all(c == 0 for c in self.exit_codes)


# ---- fleet plumbing -------------------------------------------------------------------------
def quiet_mission(mission: Path, out: Path) -> Path:
    """A copy of ``mission`` without intruders (nobody leaves its slot on purpose)."""
    doc = yaml.safe_load(mission.read_text())
    scenario = doc.get("scenario") or {}
    scenario.pop("intruders", None)
    doc["scenario"] = scenario
    path = out / f"{mission.stem}_quiet.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    load_mission(path)  # the copy must still be a valid mission
    return path


def group_of(fleet: Fleet) -> tuple[str, int]:
    """The group's multicast address and port (from the companions' command lines)."""
    args = list(fleet.companions[0].proc.args)
    addr, port = args[args.index("--group") + 1].rsplit(":", 1)
    return addr, int(port)


def capture_group(group: tuple[str, int], n: int, timeout_s: float) -> list[bytes]:
    """Up to ``n`` genuine datagrams heard on the group within ``timeout_s`` wall s."""
    sock = group_listener(f"{group[0]}:{group[1]}")
    out: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    try:
        sock.settimeout(0.1)
        while len(out) < n and time.monotonic() < deadline:
            try:
                out.append(sock.recv(2048))
            except TimeoutError:
                continue
    finally:
        sock.close()
    return out


def sim_counters(fleet: Fleet) -> tuple[float, dict[str, int]]:
    """The simulator's simulated time (s) and counters, asked on its control line now."""
    line = fleet.sitl.control("status")
    t_s = float(status_field(line, "t").rstrip("s"))
    return t_s, {k: int(status_field(line, k)) for k in SIM_COUNTERS}


def companion_drops(lines: list[str], final: bool) -> dict[str, int]:
    """The group drop counters of the latest (or the final) status line, {} if none yet."""
    tag = "companion final " if final else "companion sysid="
    status = [ln for ln in lines if ln.startswith(tag)]
    return json.loads(status_field(status[-1], "drops")) if status else {}


def wait_converged(fleet: Fleet, mission: Path, timeout_s: float) -> float:
    """Until splay < 2 deg and centre < 5 m have held for :data:`HOLD_S`; since when (sim s)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(2.0)
        if fleet.sitl.proc.poll() is not None:
            raise RuntimeError("simulator exited before the formation converged")
        try:
            m, _ = measures(fleet.out, mission)
        except (ValueError, IndexError, KeyError):  # truth log still empty
            continue
        if len(m.t_s) < 2:
            continue
        t_last = float(m.t_s[-1])
        conv = m.convergence_time_s(t_last)
        if conv is not None and t_last - conv >= HOLD_S:
            return conv
    raise TimeoutError(f"formation did not converge within {timeout_s:.0f} wall s")


def send(
    datagrams: list[tuple[str, int, str, bytes]],
    ports: list[int],
    group: tuple[str, int],
    rate_per_s: float,
) -> tuple[float, int]:
    """Send every datagram at ``rate_per_s`` per wall s; (wall s taken, send errors)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    errors = 0
    try:
        sock.bind(("127.0.0.1", 0))
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack("B", 1))
        batch = max(1, int(rate_per_s / 200))  # pace in 5 ms slices
        t0 = time.perf_counter()
        for k, (dest, index, _kind, data) in enumerate(datagrams):
            if k % batch == 0:
                _drain(sock)  # the simulator answers valid frames: do not let them pile up
                ahead = t0 + k / rate_per_s - time.perf_counter()
                if ahead > 0:
                    time.sleep(ahead)
            addr = group if dest == "group" else ("127.0.0.1", ports[index])
            try:
                sock.sendto(data, addr)
            except OSError:
                errors += 1
        return time.perf_counter() - t0, errors
    finally:
        sock.close()


def _drain(sock: socket.socket) -> None:
    sock.setblocking(False)
    try:
        while True:
            sock.recv(65535)
    except (BlockingIOError, InterruptedError, ConnectionRefusedError):
        pass
    finally:
        sock.setblocking(True)


# ---- analysis -------------------------------------------------------------------------------
def setpoint_rate(tlog: Path, t0_s: float, t1_s: float) -> float:
    """Setpoints per simulated second the companion sent in [t0_s, t1_s) (its tlog)."""
    if not tlog.is_file() or t1_s <= t0_s:
        return 0.0
    log = mavutil.mavlink_connection(str(tlog))
    n = 0
    while (m := log.recv_match(type=["SET_ATTITUDE_TARGET", "COMMAND_INT"])) is not None:
        if t0_s <= m._timestamp - SIM_EPOCH_UNIX_S < t1_s:
            n += 1
    log.close()
    return n / (t1_s - t0_s)


def formation(out: Path, mission: Path, t0_s: float, t1_s: float) -> tuple[float, float]:
    """Largest splay error (deg) and centre error (m) of the truth log in [t0_s, t1_s]."""
    m, _ = measures(out, mission)
    sel = (m.t_s >= t0_s) & (m.t_s <= t1_s)
    if not np.any(sel):
        return float("nan"), float("nan")
    return float(np.max(m.splay_deg[sel])), float(np.max(m.centre_m[sel]))


# ---- the run --------------------------------------------------------------------------------
def run_fuzz(
    out: Path,
    mission: Path = FAST,
    *,
    datagrams: int = 100_000,
    rate_per_s: float = 2000.0,
    speedup: float = SPEEDUP,
    seed: int = 1,
    group_share: float = 0.5,
    tail_s: float = 10.0,
    converge_timeout_s: float = 120.0,
    baseline: bool = False,
) -> FuzzResult:
    """Start a fleet, wait for convergence, fuzz, measure; every process is stopped.

    ``baseline``: send nothing, wait as long as sending would take (the control run).
    """
    out.mkdir(parents=True, exist_ok=True)
    quiet = quiet_mission(mission, out)
    sysids = list(load_mission(quiet).vehicles.sysids)
    key = out / "fleet.key"
    made = companion_cli("keygen", str(key))
    if made.returncode != 0:
        raise RuntimeError(f"companion keygen failed: {made.stderr.strip()}")
    fleet = start_fleet(out, quiet, key_file=key, speedup=speedup)
    try:
        group = group_of(fleet)
        ports = [fleet.port(i) for i in range(len(sysids))]
        captured = capture_group(group, 200, timeout_s=30.0)
        gen = FuzzGenerator(seed, sysids, captured)
        queue = [] if baseline else plan(datagrams, gen, len(sysids), group_share)
        t_conv = wait_converged(fleet, quiet, converge_timeout_s)
        drops_before = [companion_drops(c.lines, final=False) for c in fleet.companions]
        t0, sim_before = sim_counters(fleet)
        if baseline:
            wall, errors = datagrams / rate_per_s, 0
            time.sleep(wall)
        else:
            wall, errors = send(queue, ports, group, rate_per_s)
        if fleet.sitl.proc.poll() is None:
            t1, _ = sim_counters(fleet)
            fleet.wait_sim_time(t1 + tail_s, timeout_s=60.0)
        else:  # died: judge what it logged
            t1 = last_truth_time(out / "truth.csv")
        alive = {f"c{i + 1}": c.proc.poll() is None for i, c in enumerate(fleet.companions)}
        alive["sitl"] = fleet.sitl.proc.poll() is None
        _, sim_after = sim_counters(fleet) if alive["sitl"] else (0.0, {})
    finally:
        codes = fleet.stop()
    drops_after = [companion_drops(c.lines, final=True) for c in fleet.companions]
    t_end = t1 + tail_s
    before0 = max(t_conv, t0 - max(t_end - t0, HOLD_S))
    tlogs = [out / f"c{i + 1}" / "autopilot.tlog" for i in range(len(fleet.companions))]
    splay_b, centre_b = formation(out, quiet, before0, t0)
    splay_d, centre_d = formation(out, quiet, t0, t_end)
    classes: dict[str, Counter[str]] = {"sim": Counter(), "group": Counter()}
    for dest, _i, kind, _data in queue:
        classes[dest][kind] += 1
    return FuzzResult(
        datagrams=len(queue),
        classes={k: dict(sorted(v.items())) for k, v in classes.items()},
        valid_to_sim=dict(gen.valid_to_sim.most_common()),
        replaced=gen.replaced,
        send_wall_s=wall,
        send_errors=errors,
        t_converged_s=t_conv,
        t_fuzz_s=(t0, t1),
        alive=alive,
        exit_codes=codes,
        rate_before=[setpoint_rate(p, before0, t0) for p in tlogs],
        rate_during=[setpoint_rate(p, t0, t1) for p in tlogs],
        splay_before_deg=splay_b,
        centre_before_m=centre_b,
        splay_during_deg=splay_d,
        centre_during_m=centre_d,
        drops_before=drops_before,
        drops_after=drops_after,
        sim_before=sim_before,
        sim_after=sim_after,
    )


def print_report(r: FuzzResult, speedup: float) -> None:
    """The figures, one block per question."""
    t0, t1 = r.t_fuzz_s
    print(
        f"fuzz: {r.datagrams} datagrams in {r.send_wall_s:.1f} wall s "
        f"({r.datagrams / max(r.send_wall_s, 1e-9):.0f}/s), send errors {r.send_errors}, "
        f"speed-up {speedup:g}, simulated {t0:.1f}-{t1:.1f} s "
        f"(converged from {r.t_converged_s:.1f} s)"
    )
    for dest, cls in r.classes.items():
        total = sum(cls.values())
        print(f"  to {dest:5s} {total:6d}: " + ", ".join(f"{k} {v}" for k, v in cls.items()))
    n_valid = sum(r.valid_to_sim.values())
    print(
        f"  frames with a correct CRC the simulator decodes: {n_valid}, every one addressed to a "
        f"non-vehicle system id or read-only ({len(r.valid_to_sim)} types; "
        f"{r.replaced} candidates refused by the safety check)"
    )
    alive = ", ".join(f"{k} {'alive' if v else 'DEAD'}" for k, v in r.alive.items())
    print(f"processes: {alive}; exit codes on SIGTERM {r.exit_codes}")
    fmt = " ".join(f"{x:.1f}" for x in r.rate_before)
    print(f"control rate before (setpoints per simulated s, c1..c6): {fmt}")
    fmt = " ".join(f"{x:.1f}" for x in r.rate_during)
    print(
        f"control rate during: {fmt}  (min {min(r.rate_during):.1f}, "
        f"{100 * min(r.rate_during) / NOMINAL_RATE_HZ:.0f} % of nominal {NOMINAL_RATE_HZ:g})"
    )
    print(
        f"formation before: splay {r.splay_before_deg:.2f} deg, centre {r.centre_before_m:.2f} m; "
        f"during (+{t1 - t0:.0f} s and tail): splay max {r.splay_during_deg:.2f} deg, "
        f"centre max {r.centre_during_m:.2f} m -> "
        f"{'converged' if r.converged else 'LOST CONVERGENCE'}"
    )
    inc = r.group_drop_increase
    print("group drops during the fuzz, summed over the companions: " + json.dumps(inc))
    for i, (b, a) in enumerate(zip(r.drops_before, r.drops_after, strict=True)):
        print(f"  c{i + 1}: before {json.dumps(b)} final {json.dumps(a)}")
    if r.sim_after:
        diff = {k: r.sim_after[k] - r.sim_before[k] for k in SIM_COUNTERS}
        print("simulator counters during the fuzz: " + json.dumps(diff))


def main(argv: list[str] | None = None) -> int:
    """Parse arguments, run, print; the exit status."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--datagrams", type=int, default=100_000, help="how many to send")
    p.add_argument("--rate", type=float, default=2000.0, help="datagrams per wall second")
    p.add_argument("--speedup", type=float, default=SPEEDUP, help="simulator speed-up")
    p.add_argument("--seed", type=int, default=1, help="seed of the datagram generator")
    p.add_argument("--group-share", type=float, default=0.5, help="fraction sent to the group")
    p.add_argument("--mission", type=Path, default=FAST, help="mission YAML (intruders dropped)")
    p.add_argument("--out", type=Path, help="run folder to keep (default: a temporary one)")
    p.add_argument(
        "--baseline",
        action="store_true",
        help="control run: send nothing, wait as long as sending would take",
    )
    a = p.parse_args(argv)
    if a.datagrams < 0 or not a.rate > 0 or not a.speedup > 0 or not 0 <= a.group_share <= 1:
        msg = "need --datagrams >= 0, --rate > 0, --speedup > 0, 0 <= --group-share <= 1"
        print(f"fuzz: {msg}", file=sys.stderr)
        return 2
    if not a.mission.is_file():
        print(f"fuzz: no mission file {a.mission}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        out = a.out if a.out is not None else Path(tmp)
        r = run_fuzz(
            out,
            a.mission,
            datagrams=a.datagrams,
            rate_per_s=a.rate,
            speedup=a.speedup,
            seed=a.seed,
            group_share=a.group_share,
            baseline=a.baseline,
        )
        if a.baseline:
            print("BASELINE: nothing was sent; the same windows measured without fuzzing")
        print_report(r, a.speedup)
    return 0 if r.all_alive and r.converged else 1


if __name__ == "__main__":
    sys.exit(main())
