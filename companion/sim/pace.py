"""How fast a firmware fleet runs on the machine it is given, and whether the patrol held.

A firmware fleet (``companion fleet --autopilot px4|arduplane``) runs free against the wall
clock: PX4 and ArduPlane SITL keep their own clocks at the speed factor, and the companions
must answer each position within the autopilot's own time-outs (PX4 leaves OFFBOARD after
COM_OF_LOSS_T, which its speed factor sets to ``X`` vehicle s, i.e. one wall second; the
companion's own OFFBOARD entry wants setpoints at least every 0.5 vehicle s, PX4's 2 Hz floor;
ArduPlane drops an attitude setpoint after 3 vehicle s). A machine that cannot hold the pace
starves the companions: in issue 48's runs PX4 then switched aircraft to AUTO.LOITER and the
fleet exited 0 with cross-track p95 46-180 m.

* :func:`choose_speedup`, before anything starts: the speed factor the machine can hold from
  its free cores (:func:`free_cores`, measured over a second of ``/proc/stat``) and the cost of
  one aircraft per unit of speed factor (:data:`CORES_PER_AIRCRAFT_X`, measured: its instance
  and its companion), at most the default, at least ``MIN_SPEEDUP``;
* :class:`PaceMonitor`, while it runs: the companions' state streams as the fleet hears them on
  the group (a member's states come from its control steps: a hole of more than ``MAX_GAP_S``
  of vehicle time is a step it could not take in time; a state heard more than ``MAX_LAG_S``
  behind the truth log is the group's delay) and the autopilots' achieved rate (the
  truth log's simulated time against the wall); starving, it asks for a slower pace (the world
  process lowers its clocks' cap: ArduPlane's SIM_SPEEDUP, PX4's pauses), at most every
  ``SLOW_COOLDOWN_WALL_S``;
* :func:`verdict`, after: one line, and whether the patrol held: no aircraft left to a failsafe,
  cross-track p95 within ``XT_P95_BOUND_M`` and coverage revisit within
  ``REVISIT_BOUND`` T/N over the last ``VERDICT_WINDOW_S`` (the bounds of issue 48's goals).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# cores one aircraft (its SITL instance and its companion) takes per unit of speed factor,
# flying, measured on the shared 2-core machine (bench/firmware_fleets.py --calibrate prints it)
CORES_PER_AIRCRAFT_X = {"px4": 0.19, "arduplane": 0.09}
HEADROOM = 0.7  # of the free cores a fleet may plan to use
MIN_SPEEDUP = 1.0
MAX_GAP_S = 0.5  # vehicle s between a member's states: PX4's 2 Hz floor
MAX_LAG_S = 1.5  # vehicle s a member's newest state may trail the truth log when heard
STARVED_GAPS = 3  # holes within the window before slowing down
WINDOW_WALL_S = 20.0
SLOW_FACTOR = 0.7  # each slow-down multiplies the pace by this
SLOW_COOLDOWN_WALL_S = 30.0
XT_P95_BOUND_M = 10.0
REVISIT_BOUND = 1.15
VERDICT_WINDOW_S = 300.0


def free_cores(sample_s: float = 1.0, stat: Path = Path("/proc/stat")) -> float | None:
    """Cores idle over ``sample_s`` wall seconds now (None where /proc/stat is missing)."""

    def read() -> tuple[int, int] | None:
        try:
            fields = stat.read_text().splitlines()[0].split()[1:]
        except (OSError, IndexError):
            return None
        ticks = [int(x) for x in fields]
        idle = ticks[3] + (ticks[4] if len(ticks) > 4 else 0)  # idle + iowait
        return idle, sum(ticks)

    a = read()
    time.sleep(sample_s)
    b = read()
    if a is None or b is None or b[1] <= a[1]:
        return None
    cores = os.cpu_count() or 1
    return cores * (b[0] - a[0]) / (b[1] - a[1])


def choose_speedup(
    aircraft: int, autopilot: str, free: float | None, default: float
) -> tuple[float, str]:
    """(speed factor, why) for ``aircraft`` aircraft of ``autopilot`` with ``free`` cores:
    ``HEADROOM`` of them over the aircraft's cost per unit of speed factor, rounded down to a
    half, between ``MIN_SPEEDUP`` and ``default``."""
    cost = CORES_PER_AIRCRAFT_X[autopilot] * aircraft
    if free is None:
        return default, "the machine's load unknown"
    x = math.floor(2.0 * HEADROOM * free / cost) / 2.0
    x = min(default, max(MIN_SPEEDUP, x))
    why = f"{free:.1f} of {os.cpu_count()} cores free, {cost:.2f} cores per 1x for {aircraft}"
    return x, why


class PaceMonitor:
    """Whether the companions keep up, from what the fleet hears (wall and vehicle s).

    Args:
        speedup: the speed factor asked for.
        max_gap_s: a longer hole (vehicle s) between a member's states is a missed step
            (``MAX_GAP_S``; longer under a group budget, whose state period is longer).
    """

    def __init__(self, speedup: float, max_gap_s: float = MAX_GAP_S) -> None:
        """Nothing heard yet."""
        self.speedup = speedup
        self.max_gap_s = max_gap_s
        self.pace = speedup  # the speed factor in force after the slow-downs
        self.last_t_s: dict[int, float] = {}  # sysid -> vehicle time of its last state
        self.holes: deque[tuple[float, int, float]] = deque()  # (wall s, sysid, hole s)
        self.worst_hole: tuple[int, float] | None = None  # (sysid, vehicle s) of the run
        self.worst_lag_s = 0.0  # a state's largest lag behind the truth log (vehicle s)
        self.slowed: list[tuple[float, float, str]] = []  # (wall s, new pace, why)
        self._truth: deque[tuple[float, float]] = deque()  # (wall s, simulated s)
        self._last_slow = -1e18

    def state(self, wall_s: float, sysid: int, t_s: float) -> None:
        """A member's state with vehicle time ``t_s`` heard at ``wall_s``: a hole since its
        last, or a lag behind the truth log, counts against the pace."""
        last = self.last_t_s.get(sysid)
        self.last_t_s[sysid] = t_s if last is None else max(last, t_s)
        lag = self._truth[-1][1] - t_s if self._truth else 0.0
        self.worst_lag_s = max(self.worst_lag_s, lag)
        hole = t_s - last if last is not None else 0.0
        if hole > self.max_gap_s or lag > MAX_LAG_S:
            hole = max(hole, lag)
            self.holes.append((wall_s, sysid, hole))
            if self.worst_hole is None or hole > self.worst_hole[1]:
                self.worst_hole = (sysid, hole)

    def truth(self, wall_s: float, sim_s: float) -> None:
        """The truth log reached simulated time ``sim_s`` at ``wall_s``."""
        self._truth.append((wall_s, sim_s))
        while self._truth and self._truth[0][0] < wall_s - WINDOW_WALL_S:
            self._truth.popleft()

    def achieved(self) -> float | None:
        """Simulated seconds per wall second over the window (None before enough)."""
        if len(self._truth) < 2 or self._truth[-1][0] - self._truth[0][0] < 5.0:
            return None
        (w0, s0), (w1, s1) = self._truth[0], self._truth[-1]
        return (s1 - s0) / (w1 - w0)

    def slow_down(self, wall_s: float) -> float | None:
        """The new pace when the companions starve now (``STARVED_GAPS`` holes in the
        window), at most every ``SLOW_COOLDOWN_WALL_S``, never below ``MIN_SPEEDUP``;
        None to keep it."""
        while self.holes and self.holes[0][0] < wall_s - WINDOW_WALL_S:
            self.holes.popleft()
        if len(self.holes) < STARVED_GAPS or wall_s - self._last_slow < SLOW_COOLDOWN_WALL_S:
            return None
        if self.pace <= MIN_SPEEDUP:
            return None
        worst = max(self.holes, key=lambda h: h[2])
        self.pace = max(MIN_SPEEDUP, round(self.pace * SLOW_FACTOR, 2))
        n, uav, hole = len(self.holes), worst[1], worst[2]
        why = f"{n} steps missed in {WINDOW_WALL_S:g} s (UAV {uav}: {hole:.1f} s)"
        self.slowed.append((wall_s, self.pace, why))
        self._last_slow = wall_s
        self.holes.clear()
        return self.pace


@dataclass(frozen=True)
class Verdict:
    """Whether a run held the patrol, and the one line that says so."""

    held: bool
    line: str


def verdict(
    folder: Path, window_s: float = VERDICT_WINDOW_S, not_before_s: float | None = None
) -> Verdict:
    """The run in ``folder`` (``truth.csv``, ``events.jsonl``, ``mission.yaml``): held when
    no aircraft was left to a failsafe (the autopilot took it after its companion's silence
    and it was not back in command at the end), and over the last ``window_s`` simulated s
    (from ``not_before_s`` at the earliest: the report's window, after the formation
    settled) the cross-track p95 (aircraft away on an alert left out) and the coverage
    revisit (worst pass interval / (T/N), intervals across an alert excused) were within
    bounds."""
    from companion.report.coverage import pass_intervals, sensor_passes
    from companion.report.metrics import loop_geometry, truth_arrays
    from companion.report.rundata import load_run

    run = load_run(folder)
    lost, failsafes, took = _lost_to_failsafes(folder / "events.jsonl")
    out_s, left = _out_of_mode(run, took)
    lost = sorted(set(lost) | set(left))
    t, _, pos, away = truth_arrays(run)
    end = float(t[-1]) if t.size else 0.0
    start = max(float(t[0]) if t.size else 0.0, end - window_s, not_before_s or -math.inf)
    win = t >= start
    patrol = run.mission.patrol
    points, polyline = loop_geometry(patrol)
    xt = polyline.distance_m(pos[:, win])[~away[:, win]]
    p95 = float(np.percentile(xt, 95)) if xt.size else math.inf
    passes = sensor_passes(points, pos[:, win], run.mission.sensor.footprint_radius_m)
    _, ia, ib = pass_intervals(t[win], passes)
    for a in run.away_windows():  # an alert's episode is excused, as in the report
        keep = (ib <= a.t0_s) | (ia >= a.t1_s)
        ia, ib = ia[keep], ib[keep]
    ideal = patrol.period_s / run.mission.vehicles.count
    revisit = float(np.max(ib - ia)) / ideal if ia.size else math.inf
    fails = []
    if lost:
        fails.append(f"aircraft {', '.join(map(str, lost))} lost to a failsafe")
    if p95 > XT_P95_BOUND_M:
        fails.append(f"cross-track p95 {p95:.1f} m > {XT_P95_BOUND_M:g} m")
    if revisit > REVISIT_BOUND:
        fails.append(f"coverage revisit {revisit:.2f} T/N > {REVISIT_BOUND:g}")
    away = ", ".join(f"UAV {k} {v:.1f} s" for k, v in sorted(out_s.items()) if v > 0)
    figures = (
        f"cross-track p95 {p95:.1f} m, revisit {revisit:.2f} T/N over the last "
        f"{end - start:.0f} s, {failsafes} failsafe{'s' if failsafes != 1 else ''} said"
        + (f"; out of the companions' mode: {away}" if away else "")
    )
    if fails:
        return Verdict(False, f"patrol NOT held: {'; '.join(fails)} ({figures})")
    return Verdict(True, f"patrol held: {figures}")


CONTROLLED_MODES = ("GUIDED", "OFFBOARD")  # the companions' modes, as the truth log names them


def _out_of_mode(run, took: dict[int, float]) -> tuple[dict[int, float], list[int]]:
    """From the truth log, each aircraft of the patrol (spares, which land and take off in
    other modes, left out) from when its companion first commanded (``took``: sysid ->
    simulated s): the simulated seconds it spent out of the companions' mode, and those not
    in it at the end (sysids)."""
    spares = {sp.sysid for sp in run.mission.vehicles.spares}
    out, left = {}, []
    for sysid, tr in run.tracks.items():
        if sysid in spares or not tr.t_s.size:
            continue
        ours = np.isin(tr.mode.astype(str), CONTROLLED_MODES)
        if sysid in took:
            first = int(np.searchsorted(tr.t_s, took[sysid]))
        else:  # its first command logged before any vehicle time: 30 s in the mode at once
            held = np.convolve(ours, np.ones(300), "valid") >= 300
            first = int(np.argmax(held)) if held.any() else tr.t_s.size
        if first >= tr.t_s.size:
            continue
        dt = np.diff(tr.t_s[first:], append=tr.t_s[-1])
        out[sysid] = float(np.sum(dt[~ours[first:]]))
        if not ours[-1]:
            left.append(sysid)
    return out, left


def _lost_to_failsafes(events: Path) -> tuple[list[int], int, dict[int, float]]:
    """(sysids taken by a failsafe after their companion's silence and not back in command
    at the end, how many such failsafes in all, each sysid's first command: simulated s)
    from a merged ``events.jsonl``."""
    taken: dict[int, bool] = {}
    took: dict[int, float] = {}
    count = 0
    if not events.is_file():
        return [], 0, took
    with open(events) as fh:
        for line in fh:
            try:
                ev = json.loads(line)
            except json.JSONDecodeError:
                continue
            sysid = ev.get("sysid")
            if ev.get("event") == "override" and ev.get("cause") == "own_silence":
                taken[sysid], count = True, count + 1
            elif ev.get("event") == "authority" and ev.get("after") == "commanding":
                taken[sysid] = False
                if ev.get("t_s") is not None:
                    took.setdefault(sysid, float(ev["t_s"]))
    return sorted(s for s, away in taken.items() if away), count, took
