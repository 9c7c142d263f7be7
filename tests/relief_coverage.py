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
import json
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


def judge_firmware_relief(
    out: Path, mission_path: Path, tired: int, spare: int, duration_s: float, autopilot: str
) -> dict:
    """A firmware fleet's relief of ``tired`` by ``spare`` judged from run folder ``out`` (the
    relief's events printed first, as they went): each relief event once, the hand-over
    before the tired UAV must leave, one take-off and one landing asked, the spare climbed
    out, the tired UAV at rest on the ground at the end, and the coverage over the relief
    (a period before the launch, once the formation has settled, to two after the spare
    took the slot) within the issue's bounds with the loop's count on it throughout.

    Returns the run's events, the four relief events by name, the base (complex m) and the
    tired UAV's last positions (complex m) for the autopilot's own checks of its landing.
    """
    from companion.mission import load_mission
    from companion.sim.firmware.world import GROUND_ALT_M

    events = [json.loads(x) for x in (out / "events.jsonl").read_text().splitlines()]
    for e in events:  # the relief as it went, shown before anything is judged
        if e["event"].startswith("relie") and e["sysid"] in (tired, spare):
            print({k: v for k, v in e.items() if k != "event"}, e["event"])

    def only(name: str, sysid: int) -> dict:
        got = [e for e in events if e["event"] == name and e["sysid"] == sysid]
        assert len(got) == 1, (name, sysid, got)
        return got[0]

    launch, in_slot = only("relief_launched", spare), only("relief_in_slot", spare)
    relieved, landed = only("relieved", tired), only("relief_landed", tired)
    assert launch["member_sysid"] == tired and in_slot["reason"] == "in_slot"
    assert relieved["spare_sysid"] == spare and relieved["margin_s"] > 0.0  # before it must leave
    commands = [e["command"] for e in events if e["event"] == "vehicle_command"]
    assert commands.count("takeoff") == 1 and commands.count("land") == 1
    m = load_mission(mission_path)
    p = m.patrol
    tn = p.period_s / m.vehicles.count
    # an aircraft below GROUND_ALT_M is on the ground (the firmware's altitude there wanders
    # by tenths of a metre either side of 0)
    tr = read_truth(out, ("t_s", "sysid", "north_m", "east_m", "alt_m", "groundspeed_m_s"))
    tr["alt_m"] = np.where(tr["alt_m"] < GROUND_ALT_M, 0.0, tr["alt_m"])
    assert tr["alt_m"][tr["sysid"] == spare].max() > m.vehicles.altitude_m(spare) - 10.0
    end = (tr["sysid"] == tired) & (tr["t_s"] >= tr["t_s"].max() - 5.0)
    base = complex(m.vehicles.spares[0].north_m, m.vehicles.spares[0].east_m)
    where = tr["north_m"][end] + 1j * tr["east_m"][end]
    assert (tr["alt_m"][end] == 0.0).all() and (tr["groundspeed_m_s"][end] < 1.0).all()
    settled = json.loads((out / "metrics.json").read_text())["settle_time_s"]
    t0 = max(launch["t_s"] - p.period_s, settled)
    t1 = min(in_slot["t_s"] + 2.0 * p.period_s, duration_s)
    gap, unseen = brute_coverage(tr, p, m.sensor.footprint_radius_m, t0, t1, tn)
    fewest = min(n for t, n in on_loop_counts(tr, p, 200.0, duration_s) if t0 <= t <= t1)
    print(
        f"\n{autopilot} relief: launch {launch['t_s']:.1f} s, in slot after "
        f"{in_slot['took_s']} s, margin {relieved['margin_s']} s, landing asked at "
        f"{landed['t_s']:.1f} s, the tired UAV {np.abs(where - base).max():.1f} m from the "
        f"base; window {t0:.0f}-{t1:.0f} s: revisit {gap / tn:.3f}, longest unseen "
        f"{unseen / tn:.2f} T/N, fewest on the loop {fewest}"
    )
    assert fewest >= m.vehicles.count
    assert gap / tn <= 1.15 and unseen / tn <= 1.5
    return {
        "events": events,
        "relief": {"launched": launch, "in_slot": in_slot, "relieved": relieved, "landed": landed},
        "base": base,
        "where": where,
    }
