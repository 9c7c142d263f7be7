"""A fleet whose group crosses a radio-like link: ``companion fleet`` over Zenoh clients
that reach their ground router through :mod:`sitl_model.radio_relay`.

Processes, all started and stopped here by pid: ``companion zenoh-router`` (one TCP
endpoint behind the radio, one on the ground side), the relay (the radio, ``--tcp``: its
link layer retransmits what is lost), and ``companion fleet``
(the simulator and one companion per UAV; its own observer joins on the ground side, off
the radio). Free-running at 1x: the radio's rate and delay are wall-clock, so simulated
time must be wall time too. Used by ``tests/test_radio_link.py`` and
``bench/radio_link.py``; docs/protocol.md, "A radio-like link".
"""

from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from companion.sim.fleet import free_tcp_port
from sitl_model.testing import REPO

PAPER = REPO / "missions" / "ellipse_6uav.yaml"
LINK_RATE_BYTES_S = 12_500.0  # 100 kbit/s
GROUP_SHARE = 0.8  # of the link, for the group (docs/protocol.md: alerts come on top)
JOIN_S = 30  # the link's first seconds: the companions join (each at 5 Hz until it hears)
WINDOW_S = 10  # the budget is judged on means over windows this long (s)
BUDGET_BYTES_S = 300.0  # --group-budget: 12 states of 95 B at 0.263 Hz (docs/protocol.md)


def paper_mission(folder: Path, uavs: int, duration_s: float) -> Path:
    """The paper's ellipse (``missions/ellipse_6uav.yaml``) with ``uavs`` UAVs (sysids 1..N
    on the same start line) and no intruder, lasting ``duration_s`` (s)."""
    text = PAPER.read_text().split("scenario:")[0]
    text = text.replace("count: 6", f"count: {uavs}")
    text = text.replace("sysids: [1, 2, 3, 4, 5, 6]", f"sysids: {list(range(1, uavs + 1))}")
    text = text.replace("name: ellipse_6uav", f"name: ellipse_{uavs}uav_radio")
    path = folder / f"ellipse_{uavs}uav_radio.yaml"
    path.write_text(text + f"scenario:\n  duration_s: {duration_s:g}\n")
    return path


def _python(*args: str) -> list[str]:
    return [sys.executable, *args]


def _stop(proc: subprocess.Popen, timeout_s: float = 20.0) -> int:
    """SIGTERM to the process we started (by pid), wait, SIGKILL if it hangs; its status."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
    try:
        return proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return -9


def _ready(proc: subprocess.Popen, prefix: str) -> str:
    line = proc.stdout.readline()
    if not line.startswith(prefix):
        _stop(proc)
        raise RuntimeError(f"{prefix!r} not printed: {line!r}")
    return line.strip()


def fly_over_radio(
    out: Path,
    *,
    uavs: int = 12,
    duration_s: float = 400.0,
    budget_bytes_s: float | None = BUDGET_BYTES_S,
    rate_bytes_s: float = LINK_RATE_BYTES_S,
    delay_ms: float = 50.0,
    loss: float = 0.10,
    seed: int = 1,
    udp: bool = False,
) -> dict:
    """Fly ``uavs`` UAVs on the paper's ellipse for ``duration_s`` (simulated = wall s) with
    their group over the radio (``rate_bytes_s`` bytes/s shared, ``delay_ms`` ms, ``loss``
    probability, ``seed``) and ``--group-budget budget_bytes_s`` (None: no budget). ``udp``:
    Zenoh's UDP link through the relay's datagram mode instead of TCP (no retransmission).

    Returns the figures: the exit statuses, ``metrics.json``'s headline measures, the
    bytes offered to the link (both directions, every header, retransmissions and
    acknowledgements) per second and per :data:`WINDOW_S` window, and the bytes on the air
    per second, against the link's rate and the group's share of it, during the join (the
    first :data:`JOIN_S` s) and after, the queue's longest wait, the members' last state
    rate, the wall time."""
    out.mkdir(parents=True, exist_ok=True)
    mission = paper_mission(out, uavs, duration_s)
    radio_port, router_port, ground_port = free_tcp_port(), free_tcp_port(), free_tcp_port()
    proto = "udp" if udp else "tcp"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    popen = dict(cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    procs: dict[str, subprocess.Popen] = {}
    codes: dict[str, int] = {}
    try:
        procs["router"] = subprocess.Popen(
            _python("-m", "companion", "zenoh-router",
                    "--listen", f"{proto}/127.0.0.1:{router_port}",
                    "--listen", f"tcp/127.0.0.1:{ground_port}"), **popen,
        )  # fmt: skip
        _ready(procs["router"], "zenoh-router: ready")
        procs["radio"] = subprocess.Popen(
            _python("-m", "sitl_model.radio_relay",
                    "--listen", f"127.0.0.1:{radio_port}", "--to", f"127.0.0.1:{router_port}",
                    "--rate-bytes-s", f"{rate_bytes_s:g}", "--delay-ms", f"{delay_ms:g}",
                    "--loss", f"{loss:g}", "--seed", str(seed),
                    "--stats", str(out / "radio.json"), *([] if udp else ["--tcp"])), **popen,
        )  # fmt: skip
        _ready(procs["radio"], "radio-relay: ready")
        key = f"patrol/radio-{secrets.token_hex(4)}"
        fleet_args = [
            "fleet", str(mission), "--out", str(out / "run"), "--no-lockstep",
            "--speedup", "1", "--no-progress",
            "--group", f"zenoh-client:{proto}/127.0.0.1:{radio_port}?scout=off&key={key}",
            "--observer-group", f"zenoh-client:tcp/127.0.0.1:{ground_port}?scout=off",
        ]  # fmt: skip
        if budget_bytes_s is not None:
            fleet_args += ["--group-budget", f"{budget_bytes_s:g}"]
        with open(out / "fleet.log", "w") as log:
            fleet = subprocess.Popen(
                _python("-m", "companion", *fleet_args), cwd=REPO, env=env, stdout=log,
                stderr=subprocess.STDOUT,
            )  # fmt: skip
            procs["fleet"] = fleet
            try:
                codes["fleet"] = fleet.wait(duration_s * 3 + 300)
            except subprocess.TimeoutExpired:
                codes["fleet"] = _stop(fleet, 60)
    finally:
        for name in ("fleet", "radio", "router"):  # the fleet first: it stops its own
            if name in procs and name not in codes:
                # the fleet stops its own processes (10 s at most) and writes its report
                codes[name] = _stop(procs[name], 60.0 if name == "fleet" else 20.0)
        for p in procs.values():
            for f in (p.stdout, p.stderr):
                if f is not None:
                    f.close()
    return figures(out, codes, time.monotonic() - t0, rate_bytes_s, budget_bytes_s)


def figures(
    out: Path, codes: dict[str, int], wall_s: float, rate_bytes_s: float, budget: float | None
) -> dict:
    """The run's figures from ``out`` (``run/metrics.json``, ``radio.json``, the events)."""
    fig: dict = {"exit": codes, "wall_s": round(wall_s, 1)}
    metrics_path = out / "run" / "metrics.json"
    m = json.loads(metrics_path.read_text()) if metrics_path.is_file() else {}
    flat = _flatten(m)
    for k in ("cross_track_p95_m", "coverage_revisit_ratio", "convergence_time_s",
              "settle_time_s", "settled", "window_start_s", "window_end_s",
              "cross_track_max_m", "longest_unseen_ratio"):  # fmt: skip
        fig[k] = flat.get(k)
    radio = json.loads((out / "radio.json").read_text())
    per_s = radio["offered_bytes_per_s"]
    total = np.array(per_s["total"], dtype=float)
    backlog = np.array(radio["backlog_s_per_s"], dtype=float)
    air = np.array(radio["carried_bytes_per_s"], dtype=float)[JOIN_S:-5]
    # the flight: after the join, and without the last seconds (the fleet stopping)
    flight = total[JOIN_S:-5]
    n_win = flight.size // WINDOW_S
    windows = flight[: n_win * WINDOW_S].reshape(n_win, WINDOW_S).mean(axis=1)
    fig["link"] = {
        "rate_bytes_s": rate_bytes_s,
        "group_share_bytes_s": GROUP_SHARE * rate_bytes_s,
        "budget_bytes_s": budget,
        "seconds": int(total.size),
        "join_s": JOIN_S,
        "join_max_total_bytes_s": int(total[:JOIN_S].max()) if total.size else 0,
        "join_max_backlog_s": round(float(backlog[:JOIN_S].max()), 3) if backlog.size else 0,
        "mean_up_bytes_s": round(float(np.mean(per_s["up"][JOIN_S:-5])), 1),
        "mean_down_bytes_s": round(float(np.mean(per_s["down"][JOIN_S:-5])), 1),
        "mean_total_bytes_s": round(float(flight.mean()), 1) if flight.size else None,
        "max_window_mean_bytes_s": round(float(windows.max()), 1) if n_win else None,
        "window_s": WINDOW_S,
        "p99_total_bytes_s": round(float(np.percentile(flight, 99)), 1) if flight.size else None,
        "max_total_bytes_s": int(flight.max()) if flight.size else None,
        "seconds_over_rate": int(np.sum(flight > rate_bytes_s)),
        "max_backlog_s": round(float(backlog[JOIN_S:].max()), 3) if backlog.size else None,
        "max_carried_bytes_s": round(float(air.max()), 1) if air.size else None,
        "seconds_carried_over_share": int(np.sum(air > GROUP_SHARE * rate_bytes_s)),
        "datagrams": radio["datagrams"],
        "outcomes": radio["outcomes"],
        "uavs_seen": radio["uavs"],
    }
    fig["state_rate_hz"] = _last_schedule(out / "run")
    return fig


def _flatten(d: dict, into: dict | None = None) -> dict:
    into = {} if into is None else into
    for k, v in d.items():
        if isinstance(v, dict):
            _flatten(v, into)
        else:
            into.setdefault(k, v)
    return into


def _last_schedule(run: Path) -> dict:
    """Each companion's last ``group_schedule`` (members heard, rate Hz, time-out s)."""
    out = {}
    for path in sorted(run.glob("uav*/events.jsonl")):
        last = None
        for line in path.read_text().splitlines():
            if '"group_schedule"' in line:
                last = json.loads(line)
        if last is not None:
            out[path.parent.name] = [last.get("members"), last.get("rate_hz"),
                                     last.get("member_timeout_s")]  # fmt: skip
    return out
