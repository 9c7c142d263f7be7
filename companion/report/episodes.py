"""Alert episodes measured from the truth: one record per intruder of the mission's scenario.

From a run folder (:class:`~companion.report.rundata.RunData`: the mission, the true tracks,
the events), for each intruder: when it was first covered and first reported, every
prosecution of it, how long it was watched while inside the fence, whether a UAV cleared an
alert while it sat under that UAV, and what its episode cost the patrol. Times are
simulated seconds, positions complex ``north + i east`` metres, as everywhere.

Definitions (the constants are this module's):

* **trajectory**: ``Intruder.positions_m(t)`` from its ``appear_t_s`` until it vanishes: the
  simulator's ``intruder_vanished`` event (source "sim"; how a decoy's end is known), else
  its ``vanish_t_s``, else the end of the log. After it vanished, "where it is" means where
  it vanished (a prosecutor flying to a decoy is timed to that place).
* **covered**: some UAV's true position within the mission's footprint radius ``r_s`` of it.
  **First detection**: the first covered sample; **first alert**: the first alert event
  (``alert_new``, ``alert_received``) whose site is within :data:`SITE_RADII` ``r_s`` of it
  at that time (an alert is the nearest such intruder's; its prosecutions are its own).
* **prosecution**: a UAV's own ``alert_tasked`` to its ``rejoined`` (or the end of the log;
  :meth:`RunData.away_windows`); the plan made at tasking is its first ``plan`` event; the
  cover time is the first sample with its sensor over the intruder from the tasking until
  its ``prosecution_end`` (plus :data:`COVER_GRACE_S`; a pass on the way back after it
  cleared the alert does not count).
* **watched**: covered within the last :data:`WATCH_S` s. The share under track is the
  watched share of its time inside the fence (the mission's fence polygon; the loop if it has
  none); the longest unwatched interval is the longest run of samples inside and unwatched.
  The share under track after detection counts only its time inside the fence from its first
  detection on: what the response kept watched, apart from how long the patrol took to see
  it (a perimeter patrol sees only a band along the loop; an intruder inside the fence and
  away from the loop is not seen until it reaches it).
* **band**: within ``r_s`` of the loop, where the patrol's sensors pass every T/N. **Band to
  detection**: from the intruder's first sample in the band to its first detection (0 if it
  was seen before it reached the band; None if it never entered it): the part of the time
  before detection that is the patrol's, against the part that is the fence's (the time
  inside the fence but outside the band, which no perimeter patrol sees).
* **false clear**: a clear of one of the intruder's own alerts (or of an alert no intruder
  owns) made on a UAV's own observation (a record with ``outcome`` "cleared", or
  ``alert_cleared`` naming the UAV that checked; any future kind that says so the same way)
  while the intruder was present within :data:`FALSE_CLEAR_RADII` ``r_s`` of that UAV's true
  position. A clear of another intruder's alert (a decoy gone, with a walker 40 m away under
  its own open alert) is not this intruder's: its alert still stands. **Lost near**: the
  same test for a prosecution that ended "lost" (a mover not found, its region not covered
  by the sensor): not a claim that nothing is there, so not a false clear, but the same
  miss of an intruder within reach, counted beside it.
* **episode**: the first alert until every UAV that left for it is back (``rejoined``), or
  the end of the log. Over it: the worst pass interval that overlaps it and the longest unseen
  age reached in it, in units of T/N (:mod:`companion.report.coverage`, timed in the true
  wind as :func:`~companion.report.metrics.reference_patrol`), and per prosecutor its largest
  distance from the loop, its time from the end of its prosecution (``prosecution_end``, or a
  later ``tracker_ended``) until it is within :data:`ON_LOOP_FRACTION` ``r_s`` of the loop for
  :data:`ON_LOOP_HOLD_S` s (or until it is tasked again, if that comes sooner; tasked
  again before it was back: None, and ``retasked_before_back``, since the next
  prosecution's measures then hold its time), the quickest path back that its rejoin planned
  (``rejoin_path``: no UAV is back sooner), its ``rejoin_s``, and how long it was off the
  loop (farther than ``r_s`` from it, so that its sensor saw none of it). A loop point just
  ahead of where it left was last seen by the UAV ahead, about T/N before; it is seen next
  by the prosecutor once back or by the UAV behind, T/N later: so the episode's longest
  unseen point is at least about T/N plus the lesser of the time off the loop and T/N,
  whatever the rejoin.
* **others away**: the most UAVs away at once during the episode for other intruders'
  alerts (a tracker, another intruder's prosecution; :meth:`RunData.away_windows`). With
  ``k`` of N away only N - k patrol the loop, so the episode's goal is
  :data:`UNSEEN_GOAL_REVISITS` x the revisit of N - k UAVs, ``N / (N - k)`` T/N (the issue's
  1.5 N/(N-1) T/N with a tracker away), and it can be met only for a time off the loop of
  at most half that revisit (``revisit_left_ratio``, T/N).

Everything returned is plain JSON-ready data; :func:`format_episode` prints one line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from companion.agent.events import AlertNew, AlertReceived, PlanMade
from companion.core.fence import point_in_polygon
from companion.mission.model import Intruder
from companion.report.coverage import (
    Passes,
    Polyline,
    longest_unseen_s,
    pass_intervals,
    sensor_passes,
    unseen_stretches,
)
from companion.report.metrics import loop_geometry, reference_patrol, truth_arrays
from companion.report.rundata import Away, RunData

WATCH_S = 30.0
"""An intruder is watched while some sensor covered it in the last 30 s: a tracker that
passes over it every turn (a turn of radius 60-90 m at 20 m/s takes 20-30 s) keeps it
watched; a formation that only passes by every T/N keeps it watched when T/N <= 30 s."""
UNSEEN_GOAL_REVISITS = 1.5  # a decoy's episode: no loop point unseen longer than this
# many revisits of the UAVs left on the loop (T/N when no other UAV is away)
SITE_RADII = 2.0  # an alert is an intruder's if its site is this many r_s from it
FALSE_CLEAR_RADII = 3.0  # a clear with the intruder this many r_s from the UAV is false
ON_LOOP_FRACTION = 0.25  # back on the loop: within this fraction of r_s of it ...
ON_LOOP_HOLD_S = 5.0  # ... for this long (s)
END_EVENTS = ("prosecution_end", "tracker_ended")  # a prosecutor's own end of the flight
COVER_GRACE_S = 0.5  # the sensor over it counts until this long after the prosecution ends
_CHUNK = 2000  # samples per block of the point-in-polygon test


@dataclass(frozen=True)
class _Truth:
    """What every intruder's measures share: samples, positions, the loop, coverage."""

    t_s: np.ndarray  # (S,) common sample times (s)
    weight_s: np.ndarray  # (S,) how long each sample stands for (s)
    sysids: list[int]
    pos_m: np.ndarray  # (A, S) true positions (complex m)
    loop_points_m: np.ndarray  # coverage points along the loop (complex m)
    polyline: Polyline
    r_s_m: float
    ideal_s: float  # T/N in the true wind (s)
    stretches: tuple[np.ndarray, np.ndarray, np.ndarray]  # unseen (point, from_s, to_s)
    intervals: tuple[np.ndarray, np.ndarray, np.ndarray]  # pass (point, from_s, to_s)

    @classmethod
    def of(cls, run: RunData) -> _Truth:
        """Read the truth of ``run`` once."""
        t, sysids, pos, _ = truth_arrays(run)
        patrol = run.mission.patrol
        points, polyline = loop_geometry(patrol)
        r_s = run.mission.sensor.footprint_radius_m
        ref, _ = reference_patrol(run)
        passes: Passes = sensor_passes(points, pos, r_s)
        step = np.diff(t)
        last = float(np.median(step)) if step.size else 0.0
        return cls(
            t_s=t,
            weight_s=np.append(step, last),
            sysids=sysids,
            pos_m=pos,
            loop_points_m=points,
            polyline=polyline,
            r_s_m=r_s,
            ideal_s=ref.period_s / run.mission.vehicles.count,
            stretches=unseen_stretches(t, passes),
            intervals=pass_intervals(t, passes),
        )

    def row(self, sysid: int) -> np.ndarray:
        """One UAV's true positions (complex m) at the samples."""
        return self.pos_m[self.sysids.index(sysid)]

    def at(self, sysid: int, t_s: float) -> complex | None:
        """A UAV's true position at the last sample at or before ``t_s`` (s), or None."""
        if sysid not in self.sysids or not self.t_s.size:
            return None
        j = max(int(np.searchsorted(self.t_s, t_s, side="right")) - 1, 0)
        return complex(self.row(sysid)[j])


def vanish_time_s(run: RunData, intruder: Intruder) -> tuple[float, str]:
    """When ``intruder`` vanished (s) and how that is known: "sim" (the simulator's
    ``intruder_vanished``), "mission" (its ``vanish_t_s``) or "end" (present to the end)."""
    for ev in run.events:
        if (
            ev.get("event") == "intruder_vanished"
            and ev.get("intruder") == intruder.id
            and ev.get("source", "sim") == "sim"
            and float(ev["t_s"]) >= intruder.appear_t_s
        ):
            return float(ev["t_s"]), "sim"
    if intruder.vanish_t_s is not None:
        return float(intruder.vanish_t_s), "mission"
    end = float(run.times_s[-1]) if run.times_s.size else intruder.appear_t_s
    return end + 1e-3, "end"


def trajectory_m(intruder: Intruder, t_s: np.ndarray, vanish_s: float) -> np.ndarray:
    """Where ``intruder`` is at each time (complex m): held where it vanished after
    ``vanish_s`` (s) and where it appears before it does."""
    return intruder.positions_m(np.minimum(np.asarray(t_s, dtype=float), vanish_s))


def _inside(points_m: np.ndarray, polygon_m: np.ndarray) -> np.ndarray:
    """:func:`point_in_polygon` in blocks of samples (bounded memory)."""
    out = np.zeros(points_m.size, dtype=bool)
    for j in range(0, points_m.size, _CHUNK):
        out[j : j + _CHUNK] = point_in_polygon(points_m[j : j + _CHUNK], polygon_m)
    return out


def _longest_run_s(mask: np.ndarray, weight_s: np.ndarray) -> float:
    """The largest total weight (s) of a run of consecutive True samples."""
    best = cur = 0.0
    for on, w in zip(mask.tolist(), weight_s.tolist(), strict=True):
        cur = cur + w if on else 0.0
        best = max(best, cur)
    return best


def _first_s(t_s: np.ndarray, mask: np.ndarray) -> float | None:
    hit = np.flatnonzero(mask)
    return float(t_s[hit[0]]) if hit.size else None


def _r(x: float | None, nd: int = 3) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def alert_owners(run: RunData, truth: _Truth) -> dict[str, str]:
    """Alert id -> the id of the intruder it reports (the nearest present one within
    :data:`SITE_RADII` r_s of its site when it was first logged)."""
    intruders = run.mission.intruders
    vanish = {it.id: vanish_time_s(run, it)[0] for it in intruders}
    out: dict[str, str] = {}
    for ev in run.agent_events:
        if not isinstance(ev, (AlertNew, AlertReceived)) or ev.alert_id in out:
            continue
        site = complex(ev.north_m, ev.east_m)
        best, best_d = None, SITE_RADII * truth.r_s_m
        for it in intruders:
            if not it.appear_t_s <= ev.t_s <= vanish[it.id] + 1.0:
                continue
            d = abs(it.position_m(min(ev.t_s, vanish[it.id])) - site)
            if d <= best_d:
                best, best_d = it.id, d
        if best is not None:
            out[ev.alert_id] = best
    return out


def clears(run: RunData) -> list[tuple[float, int, str]]:
    """Clears made on a UAV's own observation: (time s, that UAV's sysid, alert id), one per
    alert and UAV (its own record's time when it logged one, else the earliest)."""
    found: dict[tuple[str, int], tuple[float, bool]] = {}
    for ev in run.events:
        name = ev.get("event")
        if ev.get("outcome") == "cleared" and "sysid" in ev:
            who = int(ev["sysid"])
        elif name == "alert_cleared" and "detector_sysid" in ev:
            who = int(ev["detector_sysid"])
        else:
            continue
        key = (str(ev.get("alert_id")), who)
        own = int(ev.get("sysid", -1)) == who
        t = float(ev["t_s"])
        had = found.get(key)
        if had is None or (own and not had[1]) or (own == had[1] and t < had[0]):
            found[key] = (t, own)
    return sorted((t, who, alert) for (alert, who), (t, _) in found.items())


def _near(
    truth: _Truth,
    it: Intruder,
    t_v: float,
    owners: dict[str, str],
    ends: list[tuple[float, int, str]],
    r_s: float,
) -> list[dict]:
    """Of ``ends`` (time s, sysid, alert id: clears or losses), those of ``it``'s own alerts
    (or of alerts no intruder owns) made while ``it`` was present (before ``t_v``, s) within
    ``FALSE_CLEAR_RADII`` ``r_s`` (m) of that UAV's true position."""
    near = []
    for t_c, who, alert in ends:
        if not it.appear_t_s <= t_c < t_v or owners.get(alert, it.id) != it.id:
            continue
        at = truth.at(who, t_c)
        if at is not None and abs(it.position_m(t_c) - at) <= FALSE_CLEAR_RADII * r_s:
            near.append({"t_s": t_c, "sysid": who, "alert_id": alert})
    return near


def losses(run: RunData) -> list[tuple[float, int, str]]:
    """Prosecutions that ended "lost" (a mover not found, its region not covered): (time s,
    the prosecutor's sysid, alert id)."""
    return sorted(
        (float(ev["t_s"]), int(ev["sysid"]), str(ev.get("alert_id")))
        for ev in run.events
        if ev.get("event") == "prosecution_end" and ev.get("outcome") == "lost" and "sysid" in ev
    )


def _next_tasking_s(windows: list[Away], away: Away) -> float | None:
    """When (s) the prosecutor of ``away`` was next tasked, to any alert, or None."""
    return min(
        (w.t0_s for w in windows if w.sysid == away.sysid and w.t0_s > away.t0_s), default=None
    )


def _prosecution(
    run: RunData,
    truth: _Truth,
    away: Away,
    target_m: np.ndarray,
    present: np.ndarray,
    next_tasked_s: float | None = None,
) -> dict:
    """One prosecution's measures (see the module doc); ``next_tasked_s`` (s): when its
    prosecutor was next tasked, which ends the wait for it to be back on the loop."""
    t = truth.t_s
    mine = [
        ev
        for ev in run.events
        if ev.get("sysid") == away.sysid
        and ev.get("alert_id") == away.alert_id
        and away.t0_s <= float(ev["t_s"]) <= away.t1_s
    ]
    plan = next(
        (
            e
            for e in run.agent_events
            if isinstance(e, PlanMade)
            and e.sysid == away.sysid
            and e.alert_id == away.alert_id
            and away.t0_s <= e.t_s <= away.t1_s
        ),
        None,
    )
    ends = [ev for ev in mine if ev.get("event") in END_EVENTS]
    outcome = next((ev.get("outcome") for ev in ends if "outcome" in ev), None)
    rejoined = next((ev for ev in mine if ev.get("event") == "rejoined"), None)
    t_end = float(ends[-1]["t_s"]) if ends else None
    pos = truth.row(away.sysid)
    inwin = (t >= away.t0_s) & (t <= away.t1_s)
    # over it while prosecuting: a pass on the way back after a clear does not count
    t_first_end = float(ends[0]["t_s"]) + COVER_GRACE_S if ends else away.t1_s
    over = inwin & (t <= t_first_end) & (np.abs(pos - target_m) <= truth.r_s_m)
    t_cover = _first_s(t, over)
    cover_s = None if t_cover is None else t_cover - away.t0_s
    planned = plan.planned_time_s if plan is not None else None
    dist = truth.polyline.distance_m(pos)
    excursion = float(np.max(dist[inwin])) if inwin.any() else None
    off_s = float(np.sum(truth.weight_s[inwin & (dist > truth.r_s_m)]))
    back = None if t_end is None else _back_on_loop_s(t, dist, t_end, truth.r_s_m, next_tasked_s)
    retasked = back is None and next_tasked_s is not None and t_end is not None
    path_back = next(
        (
            float(ev["planned_time_s"])
            for ev in mine
            if ev.get("event") == "rejoin_path" and t_end is not None and ev["t_s"] >= t_end
        ),
        None,
    )  # the quickest path back onto the loop, planned as the rejoin began
    j_cover = None if t_cover is None else int(np.searchsorted(t, t_cover))
    return {
        "sysid": away.sysid,
        "alert_id": away.alert_id,
        "tasked_t_s": _r(away.t0_s),
        "planned_time_s": planned,
        "cover_s": _r(cover_s),
        "cover_over_plan": _r(cover_s / planned, 4) if cover_s is not None and planned else None,
        "present_at_cover": None if j_cover is None else bool(present[j_cover]),
        "outcome": outcome,
        "ended_t_s": _r(t_end),
        "max_excursion_m": _r(excursion, 1),
        "off_loop_s": _r(off_s),
        "off_loop_ratio": _r(off_s / truth.ideal_s, 4),
        "back_on_loop_s": _r(back),
        "back_on_loop_ratio": _r(None if back is None else back / truth.ideal_s, 4),
        "retasked_before_back": retasked,
        "path_back_s": path_back,
        "rejoin_s": None if rejoined is None else rejoined.get("rejoin_s"),
        "rejoined_t_s": None if rejoined is None else float(rejoined["t_s"]),
    }


def _back_on_loop_s(
    t_s: np.ndarray,
    dist_m: np.ndarray,
    t_end_s: float,
    r_s_m: float,
    next_tasked_s: float | None = None,
) -> float | None:
    """From ``t_end_s`` (s) to the first sample that starts :data:`ON_LOOP_HOLD_S` s within
    :data:`ON_LOOP_FRACTION` r_s of the loop (s), or None. A new tasking at
    ``next_tasked_s`` (s) ends the wait: a UAV still on the loop then is back (its hold cut
    short by the tasking, not by leaving), one not yet back is None."""
    near = dist_m <= ON_LOOP_FRACTION * r_s_m
    far_t = t_s[~near]
    stop_s = math.inf if next_tasked_s is None else next_tasked_s
    for j in np.flatnonzero(near & (t_s >= t_end_s)):
        t0 = float(t_s[j])
        if t0 >= stop_s:
            return None  # tasked again before it was back
        hold_end_s = min(t0 + ON_LOOP_HOLD_S, stop_s)
        if hold_end_s > float(t_s[-1]):
            return None  # the log ends before it has held
        nxt = np.searchsorted(far_t, t0)
        if nxt >= far_t.size or far_t[nxt] > hold_end_s:
            return t0 - t_end_s
    return None


def _band_to_detect(t_band_s: float | None, t_seen_s: float | None, t_end_s: float) -> float | None:
    """From first in the band (s) to first detection (s): 0 if seen before the band, None if
    never in the band; never detected counts until the intruder's end ``t_end_s`` (s)."""
    if t_band_s is None:
        return None
    if t_seen_s is None:
        return _r(t_end_s - t_band_s)
    return _r(max(0.0, t_seen_s - t_band_s))


def most_away_at_once(windows: list[Away], t0_s: float, t1_s: float) -> int:
    """The most UAVs of ``windows`` away at once within ``[t0_s, t1_s]`` (s)."""
    edges = sorted(
        [(max(w.t0_s, t0_s), 1) for w in windows if w.t0_s <= t1_s and w.t1_s >= t0_s]
        + [(min(w.t1_s, t1_s), -1) for w in windows if w.t0_s <= t1_s and w.t1_s >= t0_s],
        key=lambda e: (e[0], -e[1]),
    )  # a window that ends as another begins overlaps it
    best = cur = 0
    for _, step in edges:
        cur += step
        best = max(best, cur)
    return best


def _episode(truth: _Truth, t0_s: float, t1_s: float, ended: bool) -> dict:
    """The patrol's coverage over an episode [t0_s, t1_s] (s), in units of T/N."""
    _, ia, ib = truth.intervals
    hit = (ia <= t1_s) & (ib >= t0_s)
    worst = float(np.max(ib[hit] - ia[hit])) if hit.any() else None
    _, sa, sb = truth.stretches
    unseen = longest_unseen_s(sa, sb, t0_s, t1_s)
    return {
        "t0_s": _r(t0_s),
        "t1_s": _r(t1_s),
        "ended": ended,
        "max_pass_interval_s": _r(worst),
        "coverage_revisit_ratio": _r(None if worst is None else worst / truth.ideal_s, 4),
        "longest_unseen_s": _r(unseen),
        "longest_unseen_ratio": _r(unseen / truth.ideal_s, 4),
    }


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True in ``mask``: (first index, last index), in order."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))


def band_crossings(
    run: RunData,
    truth: _Truth,
    it: Intruder,
    target_m: np.ndarray,
    present: np.ndarray,
    in_band: np.ndarray,
    covered: np.ndarray,
    windows: list[Away],
) -> list[dict]:
    """``it``'s crossings of the band, each with its speed, the UAVs away, the promise and
    whether it was seen (the module doc's **crossing**); ``target_m``: where it is at each
    sample (complex m)."""
    t = truth.t_s
    n = run.mission.vehicles.count
    out = []
    for j0, j1 in _runs(in_band):
        a, b = j0 - 1, j1 + 1
        if a < 0 or b >= t.size or not (present[a] and present[b]):
            continue  # appeared or vanished in the band, or the log's ends
        came_in, went_in = _inside(target_m[[a, b]], truth.loop_points_m)
        if came_in == went_in:
            continue  # left on the side it came from
        t0, t1 = float(t[a]), float(t[b])
        hit = np.flatnonzero(covered[j0 : j1 + 1])
        t_seen = float(t[j0 + hit[0]]) if hit.size else t1  # away after that is moot
        k = min(most_away_at_once(windows, t0, t_seen), n - 1)
        g = run.mission.crossing_guarantee(away=k)
        speed = it.max_speed_between_m_s(t0, t1)
        out.append(
            {
                "t0_s": _r(float(t[j0])),
                "t1_s": _r(float(t[j1])),
                "inward": bool(went_in),
                "speed_m_s": _r(speed),
                "away": k,
                "promised_m_s": _r(g.sure_m_s),  # None: every crossing (the discs overlap)
                "promised": bool(speed <= g.sure_m_s),
                "seen": bool(hit.size),
            }
        )
    return out


def episode_measures(run: RunData) -> list[dict]:
    """One record per intruder of the mission's scenario (see the module doc)."""
    truth = _Truth.of(run)
    t, r_s = truth.t_s, truth.r_s_m
    fence = run.mission.fence
    fence_m = np.asarray(fence.fence.polygon_m) if fence is not None else truth.loop_points_m
    owners = alert_owners(run, truth)
    windows = run.away_windows()
    all_clears = clears(run)
    all_losses = losses(run)
    out = []
    for it in run.mission.intruders:
        t_v, source = vanish_time_s(run, it)
        present = (t >= it.appear_t_s) & (t < t_v)
        target = trajectory_m(it, t, t_v)
        covered = present & (np.abs(truth.pos_m - target).min(axis=0, initial=np.inf) <= r_s)
        last = np.maximum.accumulate(np.where(covered, t, -np.inf)) if t.size else t
        watched = t - last <= WATCH_S
        in_fence = present & _inside(target, fence_m)
        in_loop = _inside(target[present], truth.loop_points_m)
        t_seen = _first_s(t, covered)
        in_band = present & (truth.polyline.distance_m(target) <= r_s)
        t_band = _first_s(t, in_band)
        alert_ids = sorted(a for a, owner in owners.items() if owner == it.id)
        first_alert = min(
            (e.t_s for e in run.agent_events
             if isinstance(e, (AlertNew, AlertReceived)) and e.alert_id in alert_ids),
            default=None,
        )  # fmt: skip
        mine = [w for w in windows if w.alert_id in alert_ids]
        pros = [_prosecution(run, truth, w, target, present, _next_tasking_s(windows, w))
                for w in mine]  # fmt: skip
        crossings = band_crossings(run, truth, it, target, present, in_band, covered, windows)
        false = _near(truth, it, t_v, owners, all_clears, r_s)
        lost_near = _near(truth, it, t_v, owners, all_losses, r_s)
        inside_s = float(np.sum(truth.weight_s[in_fence]))
        watched_s = float(np.sum(truth.weight_s[in_fence & watched]))
        after = in_fence & (t >= t_seen) if t_seen is not None else np.zeros_like(in_fence)
        after_s = float(np.sum(truth.weight_s[after]))
        after_watched_s = float(np.sum(truth.weight_s[after & watched]))
        episode = None
        if first_alert is not None and mine:
            ended = all(p["rejoined_t_s"] is not None for p in pros)
            episode = _episode(truth, first_alert, max(w.t1_s for w in mine), ended)
            others = [w for w in windows if w.alert_id not in alert_ids]
            k = most_away_at_once(others, episode["t0_s"], episode["t1_s"])
            n = run.mission.vehicles.count
            left = n / (n - k) if k < n else None  # the revisit of those left, T/N
            episode["others_away"] = k
            episode["revisit_left_ratio"] = _r(left, 4)
            episode["unseen_goal_ratio"] = _r(
                None if left is None else UNSEEN_GOAL_REVISITS * left, 4
            )
        out.append(
            {
                "intruder_id": it.id,
                "kind": it.kind,
                "speed_m_s": round(it.max_speed_m_s, 3),
                "appear_t_s": it.appear_t_s,
                "vanish_t_s": _r(t_v),
                "vanish_source": source,
                "crosses_loop": bool(in_loop.any() and not in_loop.all()),
                "detect_s": _r(None if t_seen is None else t_seen - it.appear_t_s),
                "alert_s": _r(None if first_alert is None else first_alert - it.appear_t_s),
                "band_to_detect_s": _band_to_detect(t_band, t_seen, t_v),
                "crossings": crossings,
                "promised_crossings": sum(c["promised"] for c in crossings),
                "promised_crossings_missed": sum(
                    c["promised"] and not c["seen"] for c in crossings
                ),
                "alert_ids": alert_ids,
                "prosecutions": pros,
                "inside_fence_s": _r(inside_s),
                "under_track_fraction": _r(watched_s / inside_s, 4) if inside_s > 0 else None,
                "under_track_after_detection_fraction": (
                    _r(after_watched_s / after_s, 4) if after_s > 0 else None
                ),
                "longest_unwatched_s": _r(_longest_run_s(in_fence & ~watched, truth.weight_s)),
                "longest_uncovered_s": _r(_longest_run_s(in_fence & ~covered, truth.weight_s)),
                "false_clears": len(false),
                "false_clear_events": false,
                "lost_near": len(lost_near),
                "lost_near_events": lost_near,
                "episode": episode,
                "ideal_revisit_s": _r(truth.ideal_s),
                "watch_s": WATCH_S,
            }
        )
    return out


def format_episode(rec: dict) -> str:
    """One line for an intruder's record of :func:`episode_measures`."""

    def f(v: float | None, fmt: str = ".1f", unit: str = " s") -> str:
        return "n/a" if v is None else f"{v:{fmt}}{unit}"

    pros = rec["prosecutions"]
    ratios = [p["cover_over_plan"] for p in pros if p["cover_over_plan"] is not None]
    backs = [p["back_on_loop_ratio"] for p in pros if p["back_on_loop_ratio"] is not None]
    excursions = [p["max_excursion_m"] for p in pros if p["max_excursion_m"] is not None]
    rejoins = [p["rejoin_s"] for p in pros if p["rejoin_s"] is not None]
    moving = f" {rec['speed_m_s']:.1f} m/s" if rec["speed_m_s"] else ""
    cross = ", crosses the loop" if rec["crosses_loop"] else ""
    parts = [
        f"{rec['intruder_id']} ({rec['kind']}{moving}{cross}): covered after "
        f"{f(rec['detect_s'])}, alert after {f(rec['alert_s'])}",
        f"{len(pros)} prosecution(s), cover / plan worst {f(max(ratios, default=None), '.2f', '')}",
        f"under track {f(_pct(rec['under_track_fraction']), '.0f', ' %')} of "
        f"{f(rec['inside_fence_s'], '.0f')} in the fence "
        f"({f(_pct(rec['under_track_after_detection_fraction']), '.0f', ' %')} after its "
        f"detection), longest unwatched {f(rec['longest_unwatched_s'])}",
        f"false clears {rec['false_clears']}, lost near {rec.get('lost_near', 0)}",
    ]
    crossings = rec.get("crossings") or []
    if crossings:
        promised = [c for c in crossings if c["promised"]]
        parts.append(
            f"crossed the band {len(crossings)}x, seen {sum(c['seen'] for c in crossings)}; "
            f"{len(promised)} no faster than the promise, seen {sum(c['seen'] for c in promised)}"
        )
    ep = rec["episode"]
    if ep is not None:
        parts.append(
            f"episode {ep['t0_s']:.0f}-{ep['t1_s']:.0f} s{'' if ep['ended'] else ' (open)'}: "
            f"revisit {f(ep['coverage_revisit_ratio'], '.2f', '')}, longest unseen "
            f"{f(ep['longest_unseen_ratio'], '.2f', ' T/N')}, excursion "
            f"{f(max(excursions, default=None), '.0f', ' m')}, back on the loop "
            f"{f(max(backs, default=None), '.2f', ' T/N')}, rejoin {f(max(rejoins, default=None))}"
        )
    return "; ".join(parts)


def _pct(x: float | None) -> float | None:
    return None if x is None else 100.0 * x
