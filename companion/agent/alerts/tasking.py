"""Tasking (pure): which UAV answers each queued alert, and when (docs/design.md §5).

One :class:`Tasking` per :class:`companion.agent.agent.Agent`. Every companion runs the same rules
on the same shared state, so they all pick the same prosecutor without a round of messages:

* policy "next" (the paper's): among the members on patrol (the reporter excluded) the one
  whose time-phase is next behind the phase of the loop point nearest the site;
* policy "fastest": the free members bid their planned times over the group for
  ``bid_window_s``; the smallest bid (then the lowest sysid) takes it;
* at most ``max_prosecutors`` UAVs away at once (flying to an alert, tasked to one, or
  flying back into their slot); further alerts wait in (time, id) order, except a hand-off
  (the same intruder confirmed), which goes at once. A tracker (staying over a persistent
  intruder) is out of the formation, which has re-splayed without it, so it is not counted:
  another alert is answered while it tracks, as long as one UAV stays on patrol;
* a tasked UAV never seen under way within ``member_timeout_s``, or one that leaves the
  formation, is excluded and the alert is tasked again;
* an alert the geofence rules out is refused by every companion alike, once.

It reads the alert book (:mod:`companion.agent.alerts.book`) and the members heard
(:mod:`companion.agent.neighbours`), changes alert records only through their methods (the
tables of :mod:`companion.agent.alerts.lifecycle`), and returns its events and the bids to
send (:class:`Assigned`) for the caller to log and send in order. Times are vehicle seconds,
positions complex north + i east metres, phases and headings radians.
"""

from __future__ import annotations

from typing import Literal, NamedTuple

from companion.agent.alerts.book import AlertBook
from companion.agent.alerts.lifecycle import OPEN, AlertEvent, AlertStatus
from companion.agent.alerts.paths import fence_refusal, plan_to_site
from companion.agent.alerts.record import AlertRecord
from companion.agent.away import AwayRecord, Rejoining, Tracking
from companion.agent.events import AgentEvent, AlertRefused, AlertRequeued, AlertTasked
from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.group.messages import Alert
from companion.mission.model import FenceSpec
from companion.planner import Plan

Policy = Literal["next", "fastest"]

BID_REBROADCAST_S = 0.25  # a bid is re-sent this often while the window is open (s)
Events = list[AgentEvent]


class Assigned(NamedTuple):
    """What one :meth:`Tasking.assign` did.

    Attributes:
        mine: the alert this UAV has just tasked itself with (it starts at once), or None.
        events: the events, in order.
        send: the alert messages (bids) to send to the group, in order.
    """

    mine: AlertRecord | None
    events: tuple[AgentEvent, ...]
    send: tuple[Alert, ...]


def flying_back_from(away: AwayRecord | None) -> str | None:
    """What the tasking counts of this UAV, from its mode's record (:mod:`companion.agent.away`):
    None on patrol (free to be tasked); while away, the alert it flies back from when
    rejoining, "" when flying to one or tracking (the shape of :meth:`Neighbours.away`)."""
    if away is None:
        return None
    return away.alert_id if isinstance(away, Rejoining) else ""


def next_in_sequence(reporter_phase_rad: float, candidates: dict[int, float]) -> int | None:
    """System id of the candidate whose phase is next behind ``reporter_phase_rad``.

    Args:
        reporter_phase_rad: the reporter's time-phase (rad).
        candidates: sysid -> time-phase (rad) of the members free to take the alert.

    Returns:
        The chosen sysid, or None when there is no candidate. Ties go to the lower sysid.
    """
    if not candidates:
        return None
    behind = {s: (reporter_phase_rad - p) % TWO_PI for s, p in candidates.items()}
    return min(behind, key=lambda s: (behind[s] if behind[s] > 1e-9 else TWO_PI, s))


class Tasking:
    """The tasking rules of one companion.

    Args:
        sysid: this UAV's system id.
        book: the alert book the Agent keeps (records change only through their methods).
        heard: the members heard (:class:`companion.agent.neighbours.Neighbours`).
        policy: "next" or "fastest".
        max_prosecutors: most UAVs away at once.
        member_timeout_s: a tasked UAV not under way after this long is replaced (s).
        bid_window_s: how long bids are collected under "fastest" (s).
        fence: the mission's fence (None: no geofence check).
        max_u: the vehicles' turn-rate limit (rad/s), for plans and the fence check.
    """

    def __init__(
        self,
        sysid: int,
        book: AlertBook,
        heard: Neighbours,
        *,
        policy: Policy,
        max_prosecutors: int,
        member_timeout_s: float,
        bid_window_s: float,
        fence: FenceSpec | None,
        max_u: float,
    ) -> None:
        """Keep the rules' parameters and the Agent's book and members."""
        self.sysid = sysid
        self.book = book
        self.heard = heard
        self.policy = policy
        self.max_prosecutors = max_prosecutors
        self.member_timeout_s = member_timeout_s
        self.bid_window_s = bid_window_s
        self.fence = fence
        self.max_u = max_u

    def assign(self, fix: Fix, away: AwayRecord | None) -> Assigned:
        """Give queued alerts a prosecutor while fewer than ``max_prosecutors`` are away.

        Args:
            fix: this UAV's state (its time, position, heading, time-phase) against the loop
                in the fleet's wind.
            away: this UAV's mode's record (:mod:`companion.agent.away`), None on patrol:
                what it flies back from (:func:`flying_back_from`) and whether it tracks an
                intruder (out of the formation).

        Returns:
            The alert this UAV has just tasked itself with, the events and the bids to send.

        O(open alerts + members) per call, plus one plan or nearest-point search per tasking.
        """
        t_s = fix.t_s
        own_away = flying_back_from(away)
        own_tracking = isinstance(away, Tracking)
        open_ = self.book.open_records()
        events = self._note_heard(open_, t_s)
        bids: list[Alert] = []
        mine = self._task(fix, open_, events, bids, own_away, own_tracking)
        return Assigned(mine, tuple(events), tuple(bids))

    def _task(
        self,
        fix: Fix,
        open_: list[AlertRecord],
        events: Events,
        bids: list[Alert],
        own_away: str | None,
        own_tracking: bool,
    ) -> AlertRecord | None:
        """Task the queued alerts of ``open_`` in order (events and bids into the lists);
        the alert this UAV tasked itself with, or None."""
        t_s, patrol = fix.t_s, fix.patrol
        queue = self.book.queue(open_)
        if not queue:
            return None  # the usual step: nothing waits
        away = self._away(open_, own_away)
        trackers = {s for s, _ in self.heard.tracking()} | ({self.sysid} if own_tracking else set())
        n_away = len(away.keys() - trackers)
        busy = {r.prosecutor for r in open_ if r.status is AlertStatus.TASKED}
        for rec in queue:
            if self._fence_refuses(patrol, t_s, rec, events):
                continue
            # a hand-off (the intruder confirmed) does not wait for the confirming UAV to be
            # back in its slot: the paper's next UAV goes at once; other alerts wait
            handing_off = sum(1 for a in away.values() if a == rec.alert.alert_id)
            if n_away - handing_off >= self.max_prosecutors:
                return None
            phases = self._free_phases(patrol, t_s, fix.phase_rad, own_free=own_away is None)
            members = {s: p for s, p in phases.items() if s not in busy}
            free = {s: p for s, p in members.items() if s not in rec.excluded}
            if not free and members:  # every free member was tried: try them all again
                rec.excluded.clear()
                free = members
            if len(free) > 1:
                free.pop(rec.alert.detector_sysid, None)
            if not free or (trackers and len(members) < 2):  # one stays on patrol
                return None
            chosen = self._choose(fix, rec, free, bids)
            if chosen is None:
                return None
            rec.task(chosen, t_s, started=chosen == self.sysid)
            n_away += 1
            busy.add(chosen)
            events.append(
                AlertTasked(
                    t_s=t_s,
                    sysid=self.sysid,
                    alert_id=rec.alert.alert_id,
                    prosecutor_sysid=chosen,
                    policy=self.policy,
                )
            )
            if chosen == self.sysid:
                return rec
        return None

    def _note_heard(self, open_: list[AlertRecord], t_s: float) -> Events:
        """What the members share, on the open alerts: an alert is taken once its prosecutor
        is seen away for it, tracked once its tracker shares it; a tasked UAV never seen under
        way within ``member_timeout_s`` is excluded and the alert queued again."""
        records = self.book.records
        for s, alert_id in self.heard.prosecuting():
            rec = records.get(alert_id)
            if rec is not None and rec.status in OPEN and rec.status is not AlertStatus.TRACKED:
                rec.seen_under_way(s)
        for s, alert_id in self.heard.tracking():  # a member staying over its intruder
            rec = records.get(alert_id)
            if rec is not None and rec.status in OPEN:
                rec.tracked_by(s)
        events: Events = []
        for rec in open_:  # a tasked UAV that never left: task another
            if (
                rec.status is AlertStatus.TASKED
                and rec.prosecutor != self.sysid
                and t_s - rec.taken_t_s > self.member_timeout_s
            ):
                rec.excluded.add(rec.prosecutor)
                rec.requeue(AlertEvent.TASK_LAPSED)
                events.append(AlertRequeued(t_s=t_s, sysid=self.sysid, alert_id=rec.alert.alert_id))
        return events

    def _choose(
        self, fix: Fix, rec: AlertRecord, free: dict[int, float], bids: list[Alert]
    ) -> int | None:
        """The member of ``free`` (sysid -> time-phase, rad) that takes ``rec`` by the policy;
        None while the "fastest" policy's bids are still collected."""
        if self.policy == "fastest":
            return self._auction(fix, rec, free, bids)
        if rec.site_phase_rad is None:
            rec.site_phase_rad = float(fix.patrol.nearest(rec.alert.site_m).phase_rad)
        return next_in_sequence(rec.site_phase_rad, free)

    def requeue_alerts_of(self, sysid: int, t_s: float) -> Events:
        """A member left the formation (crashed, link lost) at ``t_s`` (s): an alert it held
        goes back to the queue, with it excluded, so the site is not left unserved. Returns
        the events."""
        events: Events = []
        for rec in self.book.open_records():
            if rec.taken and rec.prosecutor == sysid and sysid != self.sysid:
                rec.excluded.add(sysid)
                rec.requeue(AlertEvent.PROSECUTOR_LOST)
                events.append(
                    AlertRequeued(
                        t_s=t_s,
                        sysid=self.sysid,
                        alert_id=rec.alert.alert_id,
                        reason="prosecutor_lost",
                    )
                )
        return events

    def _free_phases(
        self, patrol: Patrol, t_s: float, own_phase: float, own_free: bool
    ) -> dict[int, float]:
        """Phases (rad) of the members on patrol (not away), this UAV included when free."""
        out = self.heard.phases(t_s, patrol.period_s, on_patrol=True)
        if own_free:
            out[self.sysid] = own_phase
        return out

    def _away(self, open_: list[AlertRecord], own_away: str | None) -> dict[int, str]:
        """UAVs off the perimeter: flying to an alert, tasked to one and not yet gone, or
        flying back into their slot (``open_``: the open alert records). Each maps to the
        alert it is flying back from, "" for the others."""
        away = self.heard.away()
        if own_away is not None:
            away[self.sysid] = own_away
        for r in open_:
            if r.status is AlertStatus.TASKED:
                away.setdefault(r.prosecutor, "")
        return away

    def _fence_refuses(self, patrol: Patrol, t_s: float, rec: AlertRecord, events: Events) -> bool:
        """Refuse an alert the geofence rules out
        (:func:`companion.agent.alerts.paths.fence_refusal`:
        a function of the mission and the site only, so every companion refuses it alike and
        no UAV is tasked). Checked once per alert."""
        if self.fence is None or rec.fence_checked:
            return False
        rec.fence_checked = True
        reason = fence_refusal(patrol, self.fence.fence, rec.alert.site_m, self.max_u)
        if reason is None:
            return False
        rec.finish(t_s, AlertEvent.REFUSED)
        site = rec.alert.site_m
        events.append(
            AlertRefused(
                t_s=t_s,
                sysid=self.sysid,
                alert_id=rec.alert.alert_id,
                reason="fence",
                detail=reason,
                north_m=round(site.real, 2),
                east_m=round(site.imag, 2),
            )
        )
        return True

    def _auction(
        self, fix: Fix, rec: AlertRecord, free: dict[int, float], bids: list[Alert]
    ) -> int | None:
        """The "fastest" policy: bid this UAV's planned time (s), re-send it while the window
        is open (into ``bids``), and once it has closed return the smallest bid's sysid
        (None: not yet)."""
        t_s = fix.t_s
        if rec.status is AlertStatus.QUEUED:
            rec.open_bidding(t_s + self.bid_window_s)
        if self.sysid in free and self.sysid not in rec.bids:
            plan = plan_to_site(
                fix.patrol, fix.pos_m, fix.heading_rad, rec.alert.site_m, self.max_u
            )
            rec.bids[self.sysid] = plan.time_s if isinstance(plan, Plan) else float("inf")
        if self.sysid in free and t_s - rec.rebroadcast_s >= BID_REBROADCAST_S:
            rec.rebroadcast_s = t_s
            bids.append(
                Alert(
                    rec.alert.alert_id,
                    rec.alert.site_m,
                    self.sysid,
                    rec.alert.t_s,
                    "bid",
                    bid_s=rec.bids[self.sysid],
                )
            )
        if t_s < rec.bid_deadline_s:
            return None
        offers = {s: b for s, b in rec.bids.items() if s in free}
        if not offers:
            return None
        return min(offers, key=lambda s: (offers[s], s))
