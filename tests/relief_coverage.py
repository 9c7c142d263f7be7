"""The reliefs' coverage judged from a truth log by brute force (a test helper, not the
report's code): the contract tests of a relief in memory and over UDP, and of a lost UAV
replaced, all measure it the same way.

Points every 10 m along the loop; a point is seen at a truth time when an aircraft in the
air (altitude > 0: a sensor on the ground sees nothing) is within the sensor's footprint.
Over a window ``[w0, w1]`` (simulated s): the *revisit* is the longest interval between the
starts of two successive passes of one point, the *longest unseen* the longest time a point
went unseen; both are divided by ``T/N`` by the callers.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.core.patrol import Patrol

TRUTH_KEYS = ("t_s", "sysid", "north_m", "east_m", "alt_m", "battery_remaining_pct")


def read_truth(out: Path, keys: Iterable[str] = TRUTH_KEYS) -> dict[str, np.ndarray]:
    """``out/truth.csv``'s columns ``keys`` (those the relief tests use), as float arrays."""
    with open(out / "truth.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([float(r[k]) for r in rows]) for k in keys}


def brute_coverage(
    tr: dict[str, np.ndarray],
    patrol: Patrol,
    radius_m: float,
    w0_s: float,
    w1_s: float,
    revisit_s: float,
    exclude: Iterable[int] = (),
) -> tuple[float, float]:
    """(longest revisit interval, longest unseen) in s over ``[w0_s, w1_s]`` (s) of the
    loop of ``patrol``, seen within ``radius_m`` (m) by the aircraft of ``tr`` (but the
    sysids in ``exclude``); ``revisit_s`` (T/N, s) sets how far before ``w0_s`` a pass that
    is still under way counts from."""
    n_pts = round(patrol.length_m / 10.0)
    pts = patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, n_pts, endpoint=False))
    times = np.unique(tr["t_s"])
    times = times[(times >= w0_s - 3 * revisit_s) & (times <= w1_s)]
    covered = np.zeros((pts.size, times.size), dtype=bool)
    skip = set(exclude)
    for sysid in np.unique(tr["sysid"]):
        if int(sysid) in skip:
            continue
        k = (tr["sysid"] == sysid) & np.isin(tr["t_s"], times)
        pos = tr["north_m"][k] + 1j * tr["east_m"][k]
        pos = np.where(tr["alt_m"][k] > 0.0, pos, np.nan)  # a sensor on the ground sees nothing
        idx = np.searchsorted(times, tr["t_s"][k])
        covered[:, idx] |= np.abs(pts[:, None] - pos[None, :]) <= radius_m
    worst_interval, worst_unseen = 0.0, 0.0
    for row in covered:
        starts = times[1:][row[1:] & ~row[:-1]]
        ends = times[:-1][row[:-1] & ~row[1:]]
        starts_in = starts[starts >= w0_s]
        if starts_in.size >= 2:
            worst_interval = max(worst_interval, float(np.max(np.diff(starts_in))))
        for e in ends[ends >= w0_s - 2 * revisit_s]:
            nxt = starts[starts > e]
            gap = (nxt[0] if nxt.size else w1_s) - max(e, w0_s)
            worst_unseen = max(worst_unseen, float(gap))
    return worst_interval, worst_unseen


def on_loop_counts(
    tr: dict[str, np.ndarray],
    patrol: Patrol,
    t0_s: float,
    t1_s: float,
    within_m: float = 30.0,
    exclude: Iterable[int] = (),
    every: int = 10,
) -> list[tuple[float, int]]:
    """(t, how many aircraft in the air are within ``within_m`` (m) of the loop) at every
    ``every``-th truth time in ``[t0_s, t1_s]`` (s), the sysids in ``exclude`` left out."""
    loop = patrol.sample_by_time(720)
    skip = np.isin(tr["sysid"], list(exclude))
    air = (tr["alt_m"] > 0.0) & ~skip
    out = []
    ts = np.unique(tr["t_s"][(tr["t_s"] >= t0_s) & (tr["t_s"] <= t1_s)])
    for t in ts[::every]:
        k = (tr["t_s"] == t) & air
        pos = tr["north_m"][k] + 1j * tr["east_m"][k]
        off = np.min(np.abs(pos[:, None] - loop[None, :]), axis=1) if pos.size else pos.real
        out.append((float(t), int(np.sum(off < within_m))))
    return out


def companion_events(eng, name: str) -> list[dict]:
    """The in-memory engine's companion events named ``name``, their ``t_s`` in simulated s
    (``eng``: a :class:`companion.sim.inmemory.Engine`)."""
    return [
        {**e, "t_s": e["t_s"] - SIM_EPOCH_UNIX_S}
        for e in eng.companion_events
        if e.get("event") == name
    ]
