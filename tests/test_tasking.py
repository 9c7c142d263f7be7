"""The tasking seam (pure): who answers each alert, when, and what it logs and sends.

A four-UAV formation at hand-placed phases (this UAV, sysid 1, at 0; 2, 3, 4 a quarter loop
apart each) and sites placed on the loop at known phases, so the expected prosecutor is read
off the placement, not recomputed with the code's own formula.
"""

from __future__ import annotations

import math
from pathlib import Path

from companion.agent.alerts.book import AlertBook
from companion.agent.alerts.lifecycle import AlertStatus
from companion.agent.alerts.record import AlertRecord
from companion.agent.alerts.tasking import Tasking
from companion.agent.away import AwayRecord, Prosecuting, Rejoining, Tracking
from companion.agent.events import AgentEvent, AlertRefused, AlertRequeued, AlertTasked
from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.core.wind import heading_from_course
from companion.group.messages import Alert, MemberState
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
P = MISSION.patrol
ME = 1
T_S = 50.0
TIMEOUT_S = 3.0
PHASES = {1: 0.0, 2: math.pi / 2, 3: math.pi, 4: 3 * math.pi / 2}
SLOT = VirtualParticle(PHASES[ME], T_S, P.period_s)


def own_fix(t_s: float) -> Fix:
    """This UAV on the loop at its hand-placed phase, flying the loop's course."""
    pos = complex(P.point_at_phase(PHASES[ME]))
    course = float(P.course_at_phase(PHASES[ME]))
    return Fix(t_s, pos, float(heading_from_course(P.airspeed_m_s, course, P.wind)), P)


def away(what: str) -> AwayRecord:
    """This UAV's mode's record: "prosecuting" (flying to an alert), "tracking", or else
    rejoining from the alert ``what``."""
    if what == "prosecuting":
        return Prosecuting("8-1", 0j, SLOT, search_max_s=60.0)
    if what == "tracking":
        return Tracking("8-1", T_S)
    return Rejoining(what, SLOT, T_S, None)


class Setup:
    """A Tasking over a book and a formation table, with its log and outbox as lists."""

    def __init__(self, policy: str = "next", max_prosecutors: int = 1, fence: bool = False):
        self.events: list[AgentEvent] = []
        self.sent: list[Alert] = []
        self.book = AlertBook(MISSION.sensor.footprint_radius_m, sysid=ME)
        self.heard = Neighbours(ME, TIMEOUT_S)
        for s in (2, 3, 4):
            self.hear(s)
        self.tasking = Tasking(
            ME,
            self.book,
            self.heard,
            policy=policy,
            max_prosecutors=max_prosecutors,
            member_timeout_s=TIMEOUT_S,
            bid_window_s=1.0,
            fence=MISSION.fence if fence else None,
            max_u=MISSION.vehicles.max_turn_rate_rad_s,
        )

    def hear(self, sysid: int, mode: str = "patrol", alert_id: str = "", t_s: float = T_S):
        """A member's state at ``t_s``, received at once, at its hand-placed phase."""
        state = MemberState(sysid, t_s, P.centre_m, PHASES[sysid], mode, alert_id)  # type: ignore[arg-type]
        self.heard.hear(state, t_s)

    def report(self, alert_id: str, site_phase_rad: float, detector: int = 3) -> AlertRecord:
        site = complex(P.point_at_phase(site_phase_rad))
        return self.apply(Alert(alert_id, site, detector, T_S, "new"))

    def apply(self, alert: Alert) -> AlertRecord:
        _, events = self.book.apply(alert, T_S, own=False)
        self.events += events
        return self.book.records.get(alert.alert_id)

    def assign(self, t_s: float = T_S, own: AwayRecord | None = None) -> AlertRecord | None:
        """This UAV's tasking at ``t_s``, its mode's record ``own`` (None: on patrol)."""
        done = self.tasking.assign(own_fix(t_s), own)
        self.events += done.events
        self.sent += done.send
        return done.mine

    def requeue_alerts_of(self, sysid: int, t_s: float) -> None:
        self.events += self.tasking.requeue_alerts_of(sysid, t_s)

    def tasked(self) -> list[tuple[str, int]]:
        return [(e.alert_id, e.prosecutor_sysid) for e in self.events if type(e) is AlertTasked]


def test_next_policy_tasks_the_member_next_behind_the_site():
    # the site a little ahead of UAV 2 (pi/2): UAV 2 passes it next
    s = Setup()
    rec = s.report("3-1", math.pi / 2 + 0.3)
    assert s.assign() is None  # not this UAV
    assert s.tasked() == [("3-1", 2)]
    assert rec.status is AlertStatus.TASKED and rec.prosecutor == 2
    # a little ahead of this UAV (0): this UAV is next, and is told to go at once
    s = Setup()
    rec = s.report("3-1", 0.3)
    assert s.assign() is rec
    assert rec.status is AlertStatus.UNDER_WAY and s.tasked() == [("3-1", ME)]


def test_the_reporter_is_skipped_when_another_member_is_free():
    # UAV 3 (pi) reports a site just ahead of itself: the next behind it, UAV 2, goes
    s = Setup()
    s.report("3-1", math.pi + 0.2, detector=3)
    s.assign()
    assert s.tasked() == [("3-1", 2)]


def test_at_most_max_prosecutors_away_but_a_hand_off_goes_at_once():
    s = Setup()
    s.hear(4, mode="prosecuting", alert_id="9-1")  # already away for another alert
    s.report("3-1", math.pi / 2 + 0.3)
    assert s.assign() is None and s.tasked() == []  # waits: one UAV away already
    assert s.book.records["3-1"].status is AlertStatus.QUEUED
    two = Setup(max_prosecutors=2)
    two.hear(4, mode="prosecuting", alert_id="9-1")
    two.report("3-1", math.pi / 2 + 0.3)
    two.assign()
    assert two.tasked() == [("3-1", 2)]
    # this UAV flies back from alert 3-1, which was confirmed: the next one goes at once
    h = Setup()
    h.report("3-1", math.pi / 2 + 0.3)
    h.assign(own=away("3-1"))
    assert h.tasked() == [("3-1", 2)]


def test_a_tracker_is_not_counted_away_but_one_uav_stays_on_patrol():
    # UAV 4 stays over a persistent intruder (out of the formation): with at most one away,
    # a decoy is still answered at once, by the next UAV behind it on patrol
    s = Setup()
    s.hear(4, mode="tracking", alert_id="9-1")
    s.report("3-1", math.pi / 2 + 0.3)
    s.assign()
    assert s.tasked() == [("3-1", 2)]
    # this UAV is the tracker: the same
    own = Setup()
    own.report("3-1", math.pi / 2 + 0.3)
    own.assign(own=away("tracking"))
    assert own.tasked() == [("3-1", 2)]
    # but a prosecution that would leave nobody on patrol beside a tracker waits
    last = Setup(max_prosecutors=3)
    last.hear(4, mode="tracking", alert_id="9-1")
    last.hear(3, mode="prosecuting", alert_id="8-1")
    last.report("3-1", math.pi / 2 + 0.3)
    last.assign(own=away("prosecuting"))  # this UAV away too: only UAV 2 is on patrol
    assert last.tasked() == []
    assert last.book.records["3-1"].status is AlertStatus.QUEUED


def test_a_tasked_member_never_seen_under_way_is_replaced():
    s = Setup()
    rec = s.report("3-1", math.pi / 2 + 0.3)
    s.assign()
    assert rec.prosecutor == 2
    s.assign(t_s=T_S + TIMEOUT_S - 0.1)  # within the timeout: still waited for
    assert [type(e) for e in s.events].count(AlertRequeued) == 0
    for m in (2, 3, 4):  # everyone still on patrol (2 never left), heard just now
        s.hear(m, t_s=T_S + TIMEOUT_S + 0.1)
    s.assign(t_s=T_S + TIMEOUT_S + 0.1)
    assert AlertRequeued(t_s=T_S + TIMEOUT_S + 0.1, sysid=ME, alert_id="3-1") in s.events
    assert 2 in rec.excluded
    # the next behind the site after UAV 2 is this UAV (0)
    assert s.tasked() == [("3-1", 2), ("3-1", ME)] and rec.status is AlertStatus.UNDER_WAY


def test_seen_under_way_then_lost_goes_back_to_the_queue():
    s = Setup()
    rec = s.report("3-1", math.pi / 2 + 0.3)
    s.assign()
    s.hear(2, mode="prosecuting", alert_id="3-1")
    s.assign()
    assert rec.status is AlertStatus.UNDER_WAY
    s.requeue_alerts_of(2, T_S + 5.0)
    assert s.events[-1] == AlertRequeued(
        t_s=T_S + 5.0, sysid=ME, alert_id="3-1", reason="prosecutor_lost"
    )
    assert rec.status is AlertStatus.QUEUED and rec.excluded == {2}
    s.requeue_alerts_of(ME, T_S + 5.0)  # this UAV's own loss is not its business
    assert len([e for e in s.events if type(e) is AlertRequeued]) == 1


def test_fastest_policy_bids_then_the_smallest_bid_wins():
    s = Setup(policy="fastest")
    rec = s.report("3-1", math.pi / 2 + 0.3)
    assert s.assign() is None
    assert rec.status is AlertStatus.BIDDING and s.tasked() == []
    (bid,) = s.sent
    assert bid.state == "bid" and bid.detector_sysid == ME and bid.bid_s == rec.bids[ME] > 0
    rec.bids[2] = rec.bids[ME] + 5.0  # the others' bids, as heard over the group
    rec.bids[4] = rec.bids[ME] - 5.0
    assert s.assign(t_s=T_S + 0.5) is None and s.tasked() == []  # the window is still open
    s.assign(t_s=T_S + 1.0)
    assert s.tasked() == [("3-1", 4)]


def test_a_site_outside_the_fence_is_refused_once_and_nobody_is_tasked():
    s = Setup(fence=True)
    far = P.centre_m + 20_000.0  # 20 km north of the loop's centre
    s.apply(Alert("3-1", far, 3, T_S, "new"))
    s.assign()
    s.assign(t_s=T_S + 1.0)
    refused = [e for e in s.events if type(e) is AlertRefused]
    assert len(refused) == 1 and refused[0].reason == "fence" and refused[0].alert_id == "3-1"
    assert s.tasked() == [] and s.book.records["3-1"].status is AlertStatus.DONE
    inside = Setup(fence=True)
    inside.report("3-1", math.pi / 2 + 0.3)
    inside.assign()
    assert inside.tasked() == [("3-1", 2)]
