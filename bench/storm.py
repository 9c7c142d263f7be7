"""Alert storm: 1,000 operator alerts in 10 simulated seconds, against the fleet's decisions.

A storm is ``--count`` signed operator alerts (sysid 255, state "new") sent over
``--over-s`` seconds of vehicle time about ``--sites`` distinct sites spread round the
perimeter (every other one ``--outward-m`` outside the loop, so no two are within the merge
radius): the first report of each site, repeats of ids already sent (same id, same time, as
an operator re-sends against loss) and other reports of a site a few metres from it under new
ids. Every companion must merge the duplicates, give each site at most one prosecutor,
queue the rest in (time, id) order, keep its control rate, and keep N-1 UAVs on the loop.

Usage (from the repository root)::

    # inject into a running fleet (the operator's end: the fleet key, the group's address)
    PYTHONPATH=. python bench/storm.py inject --group 239.255.14.1:14600 --key-file fleet.key \\
        --mission missions/ellipse_6uav.yaml [--count 1000 --over-s 10 --sites 20]
    # the bench: in memory (the real stack, companion.sim.inmemory; Agent.update times), then
    # six real companion processes over MAVLink at 20x on a fresh fleet key (about 30 s each)
    PYTHONPATH=. python bench/storm.py run [--count 1000 --over-s 10 --sites 20]

Vehicle time: the injector paces the storm by the vehicle time it hears in the members'
states (the same clock the alerts carry), so 10 simulated seconds take 0.5 s of wall time at
20x and 10 s at 1x. Prints figures; asserts nothing (tests/test_alert_storm.py asserts).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import selectors
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # before bench/ itself: bench/companion.py is not the package

from companion.agent.agent import Agent
from companion.agent.fix import Fix
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.core.patrol import Patrol
from companion.group.codec import OPERATOR_SYSID
from companion.group.messages import (
    Alert,
    MemberState,
)
from companion.group.transport import Group
from companion.mission import load_mission
from companion.sim.inmemory.engine import TICK_EVERY as CONTROL_STEPS

FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"
Kind = Literal["first", "repeat", "near"]


# ---- the storm (pure) ----------------------------------------------------------------------
@dataclass(frozen=True)
class StormAlert:
    """One message of a storm.

    Attributes:
        send_s: when to send it, from the storm's start (vehicle s).
        report_s: the report's time from the storm's start (s); a repeat carries its
            original's.
        alert_id: the alert id (a repeat carries its original's).
        site: index of the distinct site it reports.
        site_m: where it says the intruder is (complex north + i east, m).
        kind: "first" report of the site, "repeat" of an id, or "near": another report of
            the site under a new id.
    """

    send_s: float
    report_s: float
    alert_id: str
    site: int
    site_m: complex
    kind: Kind

    def alert(self, start_t_s: float) -> Alert:
        """The operator's alert (sysid 255, state new) for a storm started at ``start_t_s``."""
        return Alert(self.alert_id, self.site_m, 255, start_t_s + self.report_s, "new")


def storm_sites(patrol: Patrol, count: int, outward_m: float = 200.0) -> list[complex]:
    """``count`` sites equally spaced in time round the loop, every other one moved
    ``outward_m`` (m) away from the loop's centre (world, complex m)."""
    if count < 1:
        raise ValueError(f"the storm needs at least one site, got {count}")
    phases = np.arange(count) * 2.0 * np.pi / count
    out = []
    for k, psi in enumerate(phases):
        p = complex(patrol.point_at_phase(psi))
        radial = p - patrol.centre_m
        shift = outward_m * radial / abs(radial) if k % 2 else 0.0
        out.append(p + shift)
    return out


def storm_plan(
    sites: Sequence[complex],
    count: int = 1000,
    over_s: float = 10.0,
    *,
    seed: int = 0,
    repeat_fraction: float = 0.5,
    jitter_m: float = 20.0,
    id_prefix: str = "st",
) -> list[StormAlert]:
    """``count`` messages evenly spread over ``over_s`` (s) about ``sites``, in send order.

    Each message reports a site drawn at random (``seed``): its first report, else a repeat
    of one of its ids (probability ``repeat_fraction``), else a new id within ``jitter_m``
    (m) of it. Every site is reported (the first ``len(sites)`` draws cover them all, in a
    random order, spread over the first third of the storm).
    """
    if count < len(sites):
        raise ValueError(f"{count} messages cannot report {len(sites)} sites")
    if len(id_prefix) > 6:
        raise ValueError("id_prefix: at most 6 characters (alert ids are 16 at most)")
    rng = np.random.default_rng(seed)
    dt = over_s / count
    order = rng.permutation(len(sites))
    later = rng.choice(np.arange(1, max(count // 3, len(sites))), len(sites) - 1, replace=False)
    first_at = [0, *sorted(later.tolist())]
    firsts = dict(zip(first_at, order.tolist(), strict=True))
    ids: dict[int, list[tuple[str, float, complex]]] = {}  # site -> (id, report s, where)
    plan: list[StormAlert] = []
    for n in range(count):
        t = n * dt
        if n in firsts:
            k = firsts[n]
        else:
            known = sorted(ids)
            k = int(known[rng.integers(len(known))])
        if k not in ids:
            aid, kind, report, where = f"{id_prefix}{k:02d}-{n:04d}", "first", t, sites[k]
            ids[k] = [(aid, t, where)]
        elif rng.random() < repeat_fraction:
            aid, report, where = ids[k][int(rng.integers(len(ids[k])))]
            kind = "repeat"
        else:
            r = jitter_m * np.sqrt(rng.random())
            where = sites[k] + r * np.exp(1j * rng.uniform(0.0, 2.0 * np.pi))
            aid, kind, report = f"{id_prefix}{k:02d}-{n:04d}", "near", t
            ids[k].append((aid, t, where))
        plan.append(StormAlert(t, report, aid, k, complex(where), kind))
    return plan


def canonical_ids(plan: Sequence[StormAlert]) -> list[str]:
    """The first report's id of every site, in queue order (report time, id)."""
    firsts = [a for a in plan if a.kind == "first"]
    return [a.alert_id for a in sorted(firsts, key=lambda a: (a.report_s, a.alert_id))]


# ---- the storm in memory (the real stack) ---------------------------------------------------
@dataclass
class InMemoryStorm:
    """A storm sent by the operator into the group of ``companion simulate``'s engine
    (:class:`companion.sim.inmemory.Engine`: six real ``Runner``s on the simulator, the alerts
    signed frames on the group), as ``inject`` sends one into a real fleet.

    Attributes:
        events: every companion event (times in vehicle s, unix).
        agents: each companion's :class:`~companion.agent.agent.Agent` after the run (sysid order).
        away: per control period (0.1 s), (simulated s, companions not in "patrol").
        update_s: per ``Agent.update`` call, (simulated s, wall seconds it took).
        receive_s: per storm message and companion, the wall seconds ``receive_alert`` took.
        sent: storm messages sent.
        start_t_s: the storm's start in vehicle time (unix s; the alerts' time base).
    """

    events: list[dict]
    agents: list[Agent]
    away: list[tuple[float, int]]
    update_s: list[tuple[float, float]]
    receive_s: list[float]
    sent: int
    start_t_s: float


def run_inmemory(
    mission_path: Path,
    plan: Sequence[StormAlert],
    start_s: float = 40.0,
    until_s: float = 200.0,
    timer: Callable[[], float] = time.perf_counter,
) -> InMemoryStorm:
    """Fly ``mission_path`` (a mission without intruders) in memory to ``until_s`` (simulated
    s); the storm starts at ``start_s`` (s). Each message is signed by the operator and
    posted to the group at the first physics step (50 Hz) at or after its send time; every
    companion reads it at its next step and decides on it at its next control step (10 Hz).
    ``Agent.update`` and ``Agent.receive_alert`` are timed with ``timer`` (s)."""
    from companion.sim.inmemory import Engine, EngineConfig

    pending = list(plan)
    away: list[tuple[float, int]] = []
    update_s: list[tuple[float, float]] = []
    receive_s: list[float] = []
    timed: set[int] = set()  # sysids whose agent is instrumented
    sent = 0
    with Engine(EngineConfig(mission_path)) as engine:
        start_t_s = SIM_EPOCH_UNIX_S + start_s  # the companions' vehicle time is unix time

        def instrument(sysid: int, agent: Agent) -> None:
            update, receive = agent.update, agent.receive_alert

            def timed_update(fix: Fix) -> Any:
                t0 = timer()
                out = update(fix)
                update_s.append((engine.t_s, timer() - t0))
                return out

            def timed_receive(alert: Alert, t_s: float) -> None:
                t0 = timer()
                receive(alert, t_s)
                if alert.detector_sysid == OPERATOR_SYSID and alert.state == "new":
                    receive_s.append(timer() - t0)

            agent.update = timed_update  # type: ignore[method-assign]
            agent.receive_alert = timed_receive  # type: ignore[method-assign]
            timed.add(sysid)

        while engine.t_s < until_s - 1e-9:
            due = [a for a in pending if start_s + a.send_s <= engine.t_s + 1e-9]
            pending = pending[len(due) :]
            for a in due:
                engine.operator_send(a.alert(start_t_s))
                sent += 1
            engine.step()
            for sysid, r in zip(engine.sysids, engine.runners, strict=True):
                if sysid not in timed and r.agent is not None:
                    instrument(sysid, r.agent)
            if engine.sim.steps % CONTROL_STEPS == 0:
                modes = [r.agent_mode for r in engine.runners]
                away.append((engine.t_s, sum(m != "patrol" for m in modes)))
        agents = [r.agent for r in engine.runners]
        events = list(engine.companion_events)
    return InMemoryStorm(events, agents, away, update_s, receive_s, sent, start_t_s)


# ---- the operator's injector (real group) --------------------------------------------------
def inject(
    group: Group,
    plan: Sequence[StormAlert],
    *,
    listen_s: float = 10.0,
    timeout_s: float = 120.0,
) -> tuple[float, int, float]:
    """Send ``plan`` into ``group`` (a :class:`~companion.group.transport.Group` of sysid 255),
    paced by the vehicle time heard in the members' states.

    Returns:
        (storm start in vehicle s, messages sent, wall seconds the sending took).

    Raises:
        TimeoutError: no member heard within ``listen_s`` (s), or the storm not sent
            within ``timeout_s`` (s) of wall time.
    """
    vt = -1.0
    deadline = time.monotonic() + listen_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)

        def hear(wait_s: float) -> None:
            nonlocal vt
            sel.select(wait_s)
            for msg in group.receive():
                if isinstance(msg, MemberState):
                    vt = max(vt, msg.t_s)

        while vt < 0:
            if time.monotonic() > deadline:
                raise TimeoutError(f"no member state heard in {listen_s} s")
            hear(0.1)
        start, sent, t0 = vt, 0, time.monotonic()
        deadline = t0 + timeout_s
        while sent < len(plan):
            due = vt - start
            while sent < len(plan) and plan[sent].send_s <= due:
                group.send_alert(plan[sent].alert(start))
                sent += 1
            if time.monotonic() > deadline:
                raise TimeoutError(f"sent {sent} of {len(plan)} in {timeout_s} s")
            hear(0.002)
    return start, sent, time.monotonic() - t0


# ---- analysis of a real run ----------------------------------------------------------------
def away_intervals(events: Sequence[dict], t_end_s: float) -> dict[int, list[tuple[float, float]]]:
    """Per sysid, the times (s) it was away: from tasking itself to an alert (its
    ``alert_tasked`` naming itself) to its ``rejoined`` (or ``t_end_s``), or to its yield
    (``prosecution_end`` "yielded": another UAV on the same alert kept it, and this one turned
    back at once; the truth's off-loop count is the check of where it really was)."""
    out: dict[int, list[tuple[float, float]]] = {}
    since: dict[int, float] = {}
    for e in sorted(events, key=lambda e: e["t_s"]):
        s = e.get("sysid")
        if e["event"] == "alert_tasked" and e.get("prosecutor_sysid") == s and s not in since:
            since[s] = e["t_s"]
        elif s in since and (
            e["event"] == "rejoined"
            or (e["event"] == "prosecution_end" and e.get("outcome") == "yielded")
        ):
            out.setdefault(s, []).append((since.pop(s), e["t_s"]))
    for s, t0 in since.items():
        out.setdefault(s, []).append((t0, t_end_s))
    return out


def max_away(intervals: dict[int, list[tuple[float, float]]], times_s: np.ndarray) -> int:
    """The most UAVs away at once over the sample times ``times_s`` (s)."""
    count = np.zeros(len(times_s), dtype=int)
    for spans in intervals.values():
        for t0, t1 in spans:
            count += (times_s >= t0) & (times_s <= t1)
    return int(count.max()) if len(count) else 0


def setpoint_rates(out: Path, t0_s: float, t1_s: float) -> dict[str, float]:
    """Per companion folder (``c1``...), SET_ATTITUDE_TARGET per simulated second in
    [``t0_s``, ``t1_s``) (s), from its ``autopilot.tlog``."""
    from pymavlink import mavutil

    rates = {}
    for path in sorted(out.glob("c*/autopilot.tlog")):
        log = mavutil.mavlink_connection(str(path))
        n = 0
        while (msg := log.recv_match(type="SET_ATTITUDE_TARGET")) is not None:
            t = msg._timestamp - SIM_EPOCH_UNIX_S
            n += t0_s <= t < t1_s
        log.close()
        rates[path.parent.name] = n / (t1_s - t0_s)
    return rates


def storm_figures(
    events: Sequence[dict],
    plan: Sequence[StormAlert],
    times_s: np.ndarray,
    start_s: float,
    over_s: float,
    t_end_s: float,
) -> dict:
    """What the companions did with the storm, from their events and the truth sample times
    (simulated s) up to ``t_end_s`` (before the companions are stopped: a companion stopped
    while away leaves the formation, and the others go on without it)."""
    events = [e for e in events if e["t_s"] <= t_end_s]
    times_s = times_s[times_s <= t_end_s]
    ids = {a.alert_id for a in plan}
    plans: dict[str, set[int]] = {}
    order: list[str] = []
    for e in sorted(events, key=lambda e: e["t_s"]):
        if e["event"] == "plan" and e.get("alert_id") in ids:
            if e["alert_id"] not in plans:
                order.append(e["alert_id"])
            plans.setdefault(e["alert_id"], set()).add(e["sysid"])
    merged = {e["alert_id"] for e in events if e["event"] == "alert_merged"}
    counts: dict[int, dict] = {}
    for e in events:
        if e["event"] == "alert_counts":
            counts[e["sysid"]] = e  # the last of each companion
    site_of = {a.alert_id: a.site for a in plan}
    distinct = Counter(
        e["sysid"]
        for e in events
        if e["event"] in ("alert_new", "alert_received") and e["alert_id"] in ids
    )
    intervals = away_intervals(events, t_end_s)
    planned = {(e["alert_id"], e["sysid"]): e["t_s"] for e in events if e["event"] == "plan"}
    yields = {
        (e["alert_id"], e["sysid"]): round(e["t_s"] - planned.get((e["alert_id"], e["sysid"]),
                                                              e["t_s"]), 3)
        for e in events
        if e["event"] == "prosecution_end" and e.get("outcome") == "yielded"
    }  # fmt: skip
    return {
        "sent": len(plan),
        "distinct_ids": len(ids),
        "sites": len({a.site for a in plan}),
        "repeats_sent": sum(a.kind == "repeat" for a in plan),
        "near_duplicates_sent": sum(a.kind == "near" for a in plan),
        "distinct_per_companion": sorted(distinct.values()),
        "merged_per_companion": sorted(c["merged"] for c in counts.values()),
        "merged_logged_ids": len(merged & ids),
        "prosecuted": order,
        "prosecutors": {a: sorted(s) for a, s in plans.items()},
        # who kept each alert (the others yielded it: two tasked on split views, the lower
        # sysid keeps it), and each yield's time after its own plan (s)
        "kept_by": {a: sorted(x for x in s if (a, x) not in yields) for a, s in plans.items()},
        "yields": {f"{a}:{x}": dt for (a, x), dt in yields.items()},
        "sites_prosecuted": [site_of[a] for a in order],
        "max_away": max_away(intervals, times_s[times_s >= start_s]),
        "canonical_order": canonical_ids(plan),
        "storm_window_s": (start_s, start_s + over_s),
    }


# ---- the bench -----------------------------------------------------------------------------
def quiet_mission_file(folder: Path) -> Path:
    """The fast test mission without intruders, written into ``folder``."""
    text = FAST.read_text().split("scenario:")[0] + "scenario:\n  duration_s: 500.0\n"
    path = folder / "storm_quiet.yaml"
    path.write_text(text)
    return path


def percentiles_us(samples: Sequence[float]) -> str:
    """``p50/p99/max`` of durations (s) in microseconds."""
    a = np.asarray(samples) * 1e6
    return f"{np.median(a):.0f}/{np.percentile(a, 99):.0f}/{a.max():.0f} us"


def bench_inmemory(args: argparse.Namespace) -> None:
    """The storm in memory (the real stack): decisions and Agent.update times, storm vs
    before."""
    with tempfile.TemporaryDirectory(prefix="storm-") as tmp:
        mission_path = quiet_mission_file(Path(tmp))
        mission = load_mission(mission_path)
        sites = storm_sites(mission.patrol, args.sites, args.outward_m)
        plan = storm_plan(sites, args.count, args.over_s, seed=args.seed)
        t0 = time.perf_counter()
        run = run_inmemory(mission_path, plan, args.start_s, args.start_s + args.after_s)
        wall = time.perf_counter() - t0
        one = run_inmemory(mission_path, plan[:1], args.start_s, args.start_s + args.over_s)
    ev = run.events
    upd = np.array(run.update_s)
    storm = upd[(upd[:, 0] >= args.start_s) & (upd[:, 0] < args.start_s + args.over_s), 1]
    before = upd[(upd[:, 0] >= args.start_s - args.over_s) & (upd[:, 0] < args.start_s), 1]
    after = upd[upd[:, 0] >= args.start_s + args.over_s, 1]
    plans = [e["alert_id"] for e in ev if e["event"] == "plan"]
    counts = [a.alerts.counts for a in run.agents]
    print(
        f"in memory, the real stack ({args.start_s + args.after_s:g} simulated s in "
        f"{wall:.1f} s of wall time)"
    )
    print(
        f"  sent {run.sent}: {args.sites} sites, {sum(a.kind == 'repeat' for a in plan)} repeats, "
        f"{sum(a.kind == 'near' for a in plan)} near duplicates under new ids"
    )
    print(
        f"  per companion: distinct {sorted({c['distinct'] for c in counts})}, merged "
        f"{sorted({c['merged'] for c in counts})}, repeats {sorted({c['repeats'] for c in counts})}"
        f", overflow {sorted({c['overflow'] for c in counts})}, merge events logged "
        f"{sum(e['event'] == 'alert_merged' for e in ev) // len(counts)} (suppressed "
        f"{sorted({c['suppressed'] for c in counts})})"
    )
    print(
        f"  prosecuted {len(plans)} in {args.after_s:g} s, {len(set(plans))} distinct ids, "
        f"in queue order: {plans == canonical_ids(plan)[: len(plans)]}; "
        f"max away at once {max(n for _, n in run.away)}"
    )
    print(
        f"  Agent.update p50/p99/max: before {percentiles_us(before)}, storm "
        f"{percentiles_us(storm)}, after {percentiles_us(after)}"
    )
    u1 = np.array(one.update_s)
    u1 = u1[(u1[:, 0] >= args.start_s) & (u1[:, 0] < args.start_s + args.over_s), 1]
    print(f"  Agent.update p50/p99/max with one alert instead, same window: {percentiles_us(u1)}")
    print(f"  Agent.receive_alert p50/p99/max during the storm: {percentiles_us(run.receive_s)}")
    print(f"  records kept per companion at the end: {[len(a.alerts.records) for a in run.agents]}")


def bench_fleet(args: argparse.Namespace) -> None:
    """The storm against six real companions over MAVLink on a fresh fleet key."""
    from companion.group.codec import COMPID_OPERATOR, OPERATOR_SYSID
    from companion.group.keys import signing_from_key_file
    from tests.fleet_harness import companion_cli, final_status, measures, start_fleet

    with tempfile.TemporaryDirectory(prefix="storm-") as tmp_name:
        tmp = Path(args.out) if args.out else Path(tmp_name)
        tmp.mkdir(parents=True, exist_ok=True)
        key = tmp / "fleet.key"
        if companion_cli("keygen", str(key)).returncode != 0:
            raise SystemExit("keygen failed")
        mission_path = quiet_mission_file(tmp)
        mission = load_mission(mission_path)
        plan = storm_plan(
            storm_sites(mission.patrol, args.sites, args.outward_m),
            args.count,
            args.over_s,
            seed=args.seed,
        )
        t_wall = time.perf_counter()
        f = start_fleet(tmp / "run", mission_path, key_file=key, speedup=args.speedup)
        try:
            group_arg = next(a for a in f.companions[0].proc.args if a.startswith("239.255."))
            addr, port = group_arg.rsplit(":", 1)
            f.wait_sim_time(args.start_s)
            signing = signing_from_key_file(key, OPERATOR_SYSID)
            with Group(
                OPERATOR_SYSID, signing, address=addr, port=int(port), compid=COMPID_OPERATOR
            ) as g:
                start_vt, sent, send_wall = inject(g, plan)
            start = start_vt - SIM_EPOCH_UNIX_S  # the simulator's vehicle time is unix time
            f.wait_sim_time(start + args.after_s, timeout_s=300)
        finally:
            codes = f.stop()
        wall = time.perf_counter() - t_wall
        m, events = measures(f.out, mission_path)
        fig = storm_figures(events, plan, m.t_s, start, args.over_s, start + args.after_s)
        rates = setpoint_rates(f.out, start, start + args.over_s)
        quiet = setpoint_rates(f.out, start - 20.0, start)
        later = setpoint_rates(f.out, start + args.over_s, start + args.over_s + 20.0)
        finals = [final_status(c) for c in f.companions]
        print(f"real processes at {args.speedup:g}x ({wall:.0f} s of wall time), exit {codes}")
        print(
            f"  sent {sent} signed alerts in {send_wall:.2f} s of wall time from vehicle time "
            f"{start:.1f} s; {fig['sites']} sites, {fig['repeats_sent']} repeats, "
            f"{fig['near_duplicates_sent']} near duplicates"
        )
        print(
            f"  distinct per companion {fig['distinct_per_companion']}, merged per companion "
            f"{fig['merged_per_companion']}"
        )
        pros = fig["prosecuted"]
        in_order = pros == fig["canonical_order"][: len(pros)]
        print(
            f"  prosecuted {len(pros)} in {args.after_s:g} s: {fig['prosecutors']} "
            f"(in queue order: {in_order}); max away at once {fig['max_away']}"
        )
        print(
            "  setpoints per simulated s during the storm: "
            + ", ".join(f"{v:.2f}" for v in rates.values())
            + " (20 s before: "
            + ", ".join(f"{v:.2f}" for v in quiet.values())
            + "; 20 s after: "
            + ", ".join(f"{v:.2f}" for v in later.values())
            + ")"
        )
        for line in finals:
            print("  " + " ".join(p for p in line.split() if p.split("=")[0] in FINAL_FIELDS))


FINAL_FIELDS = ("sysid", "sp/s", "group_rx", "drops", "lat_ms", "cpu_pct")


def cmd_inject(args: argparse.Namespace) -> int:
    """``inject``: send a storm into a running fleet's group."""
    from companion.group.address import parse_group
    from companion.group.codec import COMPID_OPERATOR, OPERATOR_SYSID
    from companion.group.keys import signing_from_key_file
    from companion.group.transport import open_group

    mission = load_mission(args.mission)
    plan = storm_plan(
        storm_sites(mission.patrol, args.sites, args.outward_m),
        args.count,
        args.over_s,
        seed=args.seed,
        id_prefix=args.id_prefix,
    )
    where = parse_group(args.group)
    signing = None if args.insecure else signing_from_key_file(args.key_file, OPERATOR_SYSID)
    with open_group(where, OPERATOR_SYSID, signing, compid=COMPID_OPERATOR) as g:
        start, sent, wall = inject(g, plan, listen_s=args.listen_s)
    if args.plan_out:
        with open(args.plan_out, "w") as fh:
            for a in plan:
                row = dataclasses.asdict(a)
                row["site_m"] = [round(a.site_m.real, 3), round(a.site_m.imag, 3)]
                fh.write(json.dumps({**row, "start_t_s": start}) + "\n")
    print(json.dumps({"start_t_s": start, "sent": sent, "wall_s": round(wall, 3)}))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line and run ``inject`` or ``run``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name in ("inject", "run"):
        p = sub.add_parser(name)
        p.add_argument("--count", type=int, default=1000, help="messages (default 1000)")
        p.add_argument("--over-s", type=float, default=10.0, help="vehicle s (default 10)")
        p.add_argument("--sites", type=int, default=20, help="distinct sites (default 20)")
        p.add_argument("--outward-m", type=float, default=200.0, help="every other site out")
        p.add_argument("--seed", type=int, default=0)
    inj = sub.choices["inject"]
    inj.add_argument("--group", required=True, metavar="ADDR:PORT")
    inj.add_argument("--mission", required=True, help="mission YAML (the perimeter)")
    auth = inj.add_mutually_exclusive_group(required=True)
    auth.add_argument("--key-file", help="fleet key: the storm is signed as the operator")
    auth.add_argument("--insecure", action="store_true")
    inj.add_argument("--listen-s", type=float, default=10.0, help="wait for a member's time")
    inj.add_argument("--id-prefix", default="st", help="alert id prefix (<= 6 characters)")
    inj.add_argument("--plan-out", help="write the messages sent as JSON lines")
    run = sub.choices["run"]
    run.add_argument("--start-s", type=float, default=40.0, help="storm start (simulated s)")
    run.add_argument("--after-s", type=float, default=150.0, help="simulated s from the start")
    run.add_argument("--speedup", type=float, default=20.0)
    run.add_argument("--out", help="keep the fleet run here")
    run.add_argument("--no-fleet", action="store_true", help="in memory only")
    args = ap.parse_args(argv)
    if args.count < 1 or args.sites < 1 or not args.over_s > 0 or args.count < args.sites:
        print("storm: need --count >= --sites >= 1 and --over-s > 0", file=sys.stderr)
        return 2
    if args.cmd == "inject":
        try:
            return cmd_inject(args)
        except (ValueError, TimeoutError) as exc:  # UserError is a ValueError
            print(f"storm: {exc}", file=sys.stderr)
            return 2
    bench_inmemory(args)
    if not args.no_fleet:
        bench_fleet(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
