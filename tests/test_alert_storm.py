"""Alert storm (issue 7): duplicates merged, one prosecutor per site, the rest queued in
order, N-1 UAVs on the perimeter, bounded memory and logs, the control rate kept.

Three tiers: the alert book and the tasking rules on single agents (milliseconds), the
whole fleet in memory (``companion.sim.inmemory``: six real ``Runner``s on the simulator, the
storm signed frames on the group) under 1,000 alerts in 10 simulated seconds, and six real
companion processes over MAVLink with a signed storm from the operator.
Timings are measured by ``bench/storm.py``, not asserted here.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from bench.storm import (
    canonical_ids,
    inject,
    quiet_mission_file,
    run_inmemory,
    setpoint_rates,
    storm_figures,
    storm_plan,
    storm_sites,
)
from companion.agent.agent import Agent
from companion.agent.alerts.book import CLOSED_IDS_MAX, STORM_EVENTS_PER_S
from companion.agent.config import AgentConfig
from companion.agent.fix import Fix
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.group.messages import Alert, MemberState, Track
from companion.mission import load_mission
from tests.fleet_harness import FAST, companion_cli, measures, report

MISSION = dataclasses.replace(load_mission(FAST), intruders=())
PATROL = MISSION.patrol
R_S = MISSION.sensor.footprint_radius_m


def op(alert_id: str, site: complex, t_s: float, state: str = "new") -> Alert:
    """An operator's alert (sysid 255)."""
    return Alert(alert_id, site, 255, t_s, state)


def member(sysid: int, t_s: float, phase: float, mode: str = "patrol", alert_id: str = ""):
    """A member's state on the loop at ``phase`` (rad)."""
    return MemberState(sysid, t_s, PATROL.centre_m, phase, mode, alert_id)


def on_loop(phase: float) -> tuple[complex, float]:
    """Position and air heading of a UAV on the loop at ``phase`` (rad)."""
    pos = complex(PATROL.point_at_phase(phase))
    course = float(PATROL.course_at_phase(phase))
    wind = PATROL.wind.vector
    v = PATROL.airspeed_m_s
    # air heading whose ground velocity lies along the course (wind triangle)
    cross = (wind * np.exp(-1j * course)).imag
    heading = course - np.arcsin(np.clip(cross / v, -1.0, 1.0))
    return pos, float(heading)


def held_agent(sysid: int = 1, **options) -> Agent:
    """An agent whose one neighbour is away, so it tasks nobody: the book alone is tested."""
    agent = Agent(sysid, MISSION, AgentConfig(member_timeout_s=1e3, **options))
    agent.receive_state(member(sysid % 6 + 1, 0.0, 1.0, "rejoining", "x"), 0.0)
    return agent


def events(out_or_list, name: str) -> list[dict]:
    evs = out_or_list.events if hasattr(out_or_list, "events") else out_or_list
    return [e for e in evs if e["event"] == name]


SITES = storm_sites(PATROL, 20)


# ---- the alert book on one agent -----------------------------------------------------------
def test_repeats_and_reports_of_the_same_site_are_merged_counted_and_logged():
    agent = held_agent()
    a = op("a", SITES[0], 10.0)
    agent.receive_alert(a, 10.0)
    for _ in range(5):
        agent.receive_alert(a, 10.1)  # re-sent against loss: same id, same time
    near = op("b", SITES[0] + 0.9 * 2 * R_S, 11.0)  # within 2 r_s: the same site
    for _ in range(3):
        agent.receive_alert(near, 11.0)
    agent.receive_alert(op("c", SITES[5], 12.0), 12.0)  # another site
    out = agent.update(Fix(12.1, *on_loop(0.0), agent.patrol))
    assert sorted(agent.alerts.records) == ["a", "c"]
    assert agent.alerts.counts["received"] == 10
    assert agent.alerts.counts["distinct"] == 2
    assert agent.alerts.counts["merged"] == 1
    assert agent.alerts.counts["repeats"] == 7  # 5 of a, 2 more of b
    (merged,) = events(out, "alert_merged")
    assert (merged["alert_id"], merged["into"]) == ("b", "a")
    assert [e["alert_id"] for e in events(out, "alert_new")] == ["a", "c"]
    (counts,) = events(out, "alert_counts")
    assert counts["merged"] == 1 and counts["repeats"] == 7


def test_the_earlier_report_of_a_site_wins_whatever_the_arrival_order():
    early, late = op("z-early", SITES[3], 20.0), op("a-late", SITES[3] + 30, 21.0)
    kept = []
    for order in ((early, late), (late, early)):
        agent = Agent(1, MISSION)
        for a in order:
            agent.receive_alert(a, 22.0)
        kept.append(sorted(agent.alerts.records))
        agent.receive_alert(late, 23.0)  # a repeat of the loser stays merged
        assert sorted(agent.alerts.records) == ["z-early"]
    assert kept == [["z-early"], ["z-early"]]


def test_a_site_just_cleared_absorbs_the_reports_made_before_the_check_only():
    """A report made before the site was checked (a late relay) is the cleared alert; one
    made after it is news: the intruder is there after all (issue 21: a walker seen again
    1.2 s after its alert was cleared raised nothing)."""
    agent = Agent(1, MISSION, AgentConfig(merge_hold_s=10.0))
    agent.receive_alert(op("a", SITES[0], 10.0), 10.0)
    agent.receive_alert(Alert("a", SITES[0], 3, 20.0, "cleared"), 20.0)
    agent.receive_alert(op("stale", SITES[0] + 10, 8.0), 21.0)  # made before the check
    agent.receive_alert(op("soon", SITES[0] + 10, 21.2), 21.3)  # seen again after it
    agent.receive_alert(op("later", SITES[0] + 10, 31.0), 31.0)  # the same, later
    assert agent.alerts.counts["merged"] == 2
    assert agent.alerts.records["soon"].status == "queued" and "later" not in agent.alerts.records
    assert "stale" not in agent.alerts.records


def test_a_cleared_site_finishes_the_other_ids_reported_there_before():
    """A companion that missed a site's first report holds a later one under another id:
    the prosecutor's "cleared" for the first id answers it too (no second UAV)."""
    agent = Agent(1, MISSION)
    agent.receive_alert(op("second", SITES[0] + 15, 11.0), 11.0)  # "first" was lost
    agent.receive_alert(Alert("first", SITES[0], 4, 30.0, "cleared"), 30.0)
    assert agent.alerts.records["second"].status == "done"
    assert not agent.alerts.book.open_records()


def test_a_clear_finishes_only_the_alerts_expected_under_the_sensor_that_checked():
    """Generated mission 124: a decoy's alert checked and cleared (the clear carrying no
    track) finished the alert of a still intruder tracked 83 m from it (footprint 52 m
    there), which the checking UAV had itself just seen: the 2 r_s gate of a point reached
    past the footprint. Now a clear answers another open alert only where the check's
    footprint covered its prediction; beyond it, that alert stays open."""
    for off_r_s, answered in ((1.6, False), (0.9, True)):
        agent = Agent(1, MISSION)
        there = SITES[0] + off_r_s * R_S  # within 2 r_s of the decoy's point
        tracked = Track(10.5, there, 0j, 0.7, 0.05, 37)
        agent.receive_alert(Alert("static", there, 9, 10.5, "new", track=tracked), 10.6)
        seen = Track(11.0, SITES[0], 0j, 1.0, 0.3, 5)
        agent.receive_alert(Alert("decoy", SITES[0], 10, 11.0, "new", track=seen), 11.1)
        assert sorted(agent.alerts.records) == ["decoy", "static"]  # two sensor tracks: two alerts
        agent.receive_alert(Alert("decoy", SITES[0], 7, 30.0, "cleared"), 30.0)
        assert agent.alerts.records["decoy"].status == "done"
        assert (agent.alerts.records["static"].status == "done") == answered, off_r_s


def test_a_lost_mover_answers_its_twins_as_lost_not_cleared():
    """A prosecutor that could not cover a mover's region says "lost"; the other open
    reports expected where it looked are lost with it (logged ``alert_lost`` via its id),
    not cleared: nobody claims the intruder is not there."""
    agent = Agent(1, MISSION)
    agent.receive_alert(op("second", SITES[0] + 15, 11.0), 11.0)  # "first" was lost
    agent.receive_alert(Alert("first", SITES[0], 4, 30.0, "lost"), 30.0)
    assert agent.alerts.records["second"].status == "done"
    logged = agent.update(Fix(30.0, *on_loop(0.0), agent.patrol)).events
    assert events(logged, "alert_lost") == [
        {
            "t_s": 30.0,
            "event": "alert_lost",
            "sysid": 1,
            "alert_id": "second",
            "detector_sysid": 4,
            "via": "first",
        }
    ]
    assert not events(logged, "alert_cleared")


def test_overflow_drops_the_last_in_queue_order_and_stays_dropped():
    sites = storm_sites(PATROL, 8)
    shuffled = [3, 0, 4, 1, 2]  # arrival order of alerts reported at t = 1..5 s
    agent = held_agent(max_open_alerts=3)
    for k in shuffled:
        agent.receive_alert(op(f"a{k}", sites[k], 1.0 + k), 10.0)
    assert sorted(agent.alerts.records) == ["a0", "a1", "a2"]  # the three earliest, in any order
    assert agent.alerts.counts["overflow"] == 2
    agent.receive_alert(op("a4", sites[4], 5.0), 11.0)  # a repeat of a dropped one
    assert sorted(agent.alerts.records) == ["a0", "a1", "a2"]
    out = agent.update(Fix(11.0, *on_loop(0.0), agent.patrol))
    assert {e["alert_id"] for e in events(out, "alert_overflow")} == {"a3", "a4"}


def test_memory_and_logs_stay_bounded_under_a_flood_of_distinct_alerts():
    agent = held_agent()
    rng = np.random.default_rng(1)
    n = CLOSED_IDS_MAX + 6000
    logged = []
    for i in range(n):  # 10,000 distinct ids at random places over 10 s
        t = 10.0 + 10.0 * i / n
        site = complex(*rng.uniform(-3000.0, 3000.0, 2))
        agent.receive_alert(op(f"f{i}", site, t), t)
        if i % 100 == 0:
            logged += agent.update(Fix(t, *on_loop(0.0), agent.patrol)).events
    assert len(agent.alerts.book.open_records()) <= agent.alerts.book.max_open
    assert len(agent.alerts.records) <= 2 * agent.alerts.book.max_open
    assert len(agent.alerts.book._closed) <= CLOSED_IDS_MAX
    assert (
        agent.alerts.counts["distinct"]
        + agent.alerts.counts["merged"]
        + agent.alerts.counts["overflow"]
        == n - agent.alerts.counts["repeats"]
    )
    storm_events = events(logged, "alert_merged") + events(logged, "alert_overflow")
    assert len(storm_events) <= STORM_EVENTS_PER_S * 11  # 10 s of flood, one window spare
    per_s = np.bincount(np.floor([e["t_s"] for e in storm_events]).astype(int))
    assert per_s.max() <= 2 * STORM_EVENTS_PER_S
    assert agent.alerts.counts["suppressed"] > 0
    # once nothing is open any more, finished records are forgotten: only ids remain
    for rec in list(agent.alerts.book.open_records()):
        agent.receive_alert(Alert(rec.alert.alert_id, rec.alert.site_m, 2, 30.0, "cleared"), 30)
    agent.update(Fix(60.0, *on_loop(0.0), agent.patrol))
    assert not agent.alerts.records


def test_a_uav_flying_back_into_its_slot_counts_as_away():
    """N - 1 on the perimeter: the next alert waits until the last prosecutor is back."""
    agent = Agent(2, MISSION, AgentConfig(member_timeout_s=100.0))
    phases = {s: -(s - 1) * np.pi / 3 for s in range(1, 7)}
    for s in (1, 3, 4, 5, 6):
        mode = "rejoining" if s == 4 else "patrol"
        agent.receive_state(member(s, 50.0, phases[s], mode, "old" if s == 4 else ""), 50.0)
    agent.receive_alert(op("a", SITES[0], 50.0), 50.0)
    out = agent.update(Fix(50.1, *on_loop(phases[2]), agent.patrol))
    assert not events(out, "alert_tasked") and agent.alerts.records["a"].status == "queued"
    agent.receive_state(member(4, 51.0, phases[4]), 51.0)  # handed back its real state
    out = agent.update(Fix(51.1, *on_loop(phases[2]), agent.patrol))
    assert len(events(out, "alert_tasked")) == 1


def test_two_prosecutors_allowed_means_two_different_uavs():
    """Two sites just ahead of UAV 3: it takes the first, the next UAV behind the second."""
    agent = Agent(5, MISSION, AgentConfig(max_prosecutors=2, member_timeout_s=100.0))
    phases = {s: -(s - 1) * np.pi / 3 % (2 * np.pi) for s in range(1, 7)}
    for s in (1, 2, 3, 4, 6):
        agent.receive_state(member(s, 50.0, phases[s]), 50.0)
    for k, dphase in enumerate((0.1, 0.6)):
        site = complex(PATROL.point_at_phase(phases[3] + dphase))
        agent.receive_alert(op(f"a{k}", site, 50.0 + k), 50.0)
    out = agent.update(Fix(50.1, *on_loop(phases[5]), agent.patrol))
    assert {e["prosecutor_sysid"] for e in events(out, "alert_tasked")} == {3, 4}


# ---- the fleet in memory (the real stack) --------------------------------------------------
START_S, OVER_S = 40.0, 10.0


@pytest.fixture(scope="module")
def quiet(tmp_path_factory):
    """The fast test mission without intruders, as a file (what the engine flies)."""
    return quiet_mission_file(tmp_path_factory.mktemp("storm"))


@pytest.fixture(scope="module")
def storm(quiet):
    """1,000 alerts in 10 simulated s about 20 sites, 150 s of flight from the storm."""
    plan = storm_plan(SITES, 1000, OVER_S, seed=3)
    return plan, run_inmemory(quiet, plan, START_S, START_S + 150.0)


def test_storm_sites_are_distinct_beyond_the_merge_radius():
    jitter = max(abs(a.site_m - SITES[a.site]) for a in storm_plan(SITES, 1000, seed=3))
    gap = min(abs(a - b) for a, b in itertools.combinations(SITES, 2))
    assert gap - 2 * jitter > 2 * R_S  # no report can merge into another site's
    assert jitter <= R_S  # every report of a site merges into its first


@pytest.mark.contract
def test_storm_in_memory_one_prosecutor_per_site_served_in_queue_order(storm):
    plan, run = storm
    ev = run.events
    assert run.sent == 1000 and len({a.site for a in plan}) == 20
    plans = [e for e in ev if e["event"] == "plan"]
    order = list(dict.fromkeys(e["alert_id"] for e in plans))
    prosecutors = {a: {e["sysid"] for e in plans if e["alert_id"] == a} for a in order}
    report("storm in memory", {"prosecuted": prosecutors, "max_away": max(run.away)[1]})
    assert len(order) >= 2  # the window lets the queue move on
    assert all(len(s) == 1 for s in prosecutors.values()), prosecutors
    assert order == canonical_ids(plan)[: len(order)]  # only first reports, in queue order
    # every companion that tasked an alert named the same UAV, that UAV among them (a
    # companion that saw it under way before its own turn to task it logs no tasking: a
    # prosecutor handed back on the loop is free at once in its own view, still away in
    # the others' until its next state)
    tasked = events(ev, "alert_tasked")
    for a in order:
        named = {e["prosecutor_sysid"] for e in tasked if e["alert_id"] == a}
        deciders = [e["sysid"] for e in tasked if e["alert_id"] == a]
        assert len(named) == 1 and named <= set(deciders) and len(deciders) == len(set(deciders))


@pytest.mark.contract
def test_storm_in_memory_at_most_one_uav_away(storm):
    _, run = storm
    away = np.array([n for t, n in run.away if t > START_S + 1.0])
    assert away.max() == 1  # someone was away, never two
    assert np.mean(away) > 0.9  # and the queue kept one away nearly all the time


@pytest.mark.contract
def test_storm_in_memory_every_companion_keeps_the_same_bounded_books(storm):
    plan, run = storm
    near = sum(a.kind == "near" for a in plan)
    queues, books = set(), set()
    for agent in run.agents:
        c = agent.alerts.counts
        # every report near a site merges into it, but one made after its site was checked:
        # that one is news (an alert of its own)
        assert c["distinct"] >= 20 and c["overflow"] == 0
        assert c["merged"] + (c["distinct"] - 20) == near
        books.add((c["distinct"], c["merged"]))
        assert len(agent.alerts.records) <= c["distinct"]
        queues.add(
            tuple(
                r.alert.alert_id for r in agent.alerts.book.queue(agent.alerts.book.open_records())
            )
        )
    (queue,) = queues  # every companion holds the same queue, in the same order
    assert len(books) == 1  # and the same counts
    news = {r.alert.alert_id for r in run.agents[0].alerts.records.values()} - set(
        canonical_ids(plan)
    )
    assert queue and set(queue) <= set(canonical_ids(plan)) | news
    merged_logged = events(run.events, "alert_merged")
    assert near > len(merged_logged) / 6 >= STORM_EVENTS_PER_S * 5  # logged, but capped
    assert len(merged_logged) / 6 <= STORM_EVENTS_PER_S * (OVER_S + 1)


@pytest.mark.contract
def test_storm_in_memory_queue_drains_one_site_at_a_time(quiet):
    """A small storm flown until served: every site exactly once, in order, one at a time."""
    sites = storm_sites(PATROL, 6)[::2]  # three sites on the loop
    plan = storm_plan(sites, 150, OVER_S, seed=5)
    run = run_inmemory(quiet, plan, START_S, START_S + 230.0)
    plans = [e for e in run.events if e["event"] == "plan"]
    assert [e["alert_id"] for e in plans] == canonical_ids(plan)
    assert max(n for _, n in run.away) == 1
    for agent in run.agents:
        assert not agent.alerts.book.open_records()


# ---- real companions over MAVLink ----------------------------------------------------------
@pytest.mark.slow
@pytest.mark.integration
def test_storm_against_real_companions(fleet_factory, tmp_path):
    """1,000 signed operator alerts in 10 simulated s into a keyed fleet of six companions:
    one prosecutor per distinct alert, merged reports never prosecuted, the queue in order,
    at most one UAV away at any truth sample, the control rate kept, every process exits 0."""
    from bench.storm import quiet_mission_file
    from companion.group.codec import COMPID_OPERATOR, OPERATOR_SYSID
    from companion.group.keys import signing_from_key_file
    from companion.group.transport import Group

    key = tmp_path / "fleet.key"
    assert companion_cli("keygen", str(key)).returncode == 0
    mission = quiet_mission_file(tmp_path)
    plan = storm_plan(storm_sites(load_mission(mission).patrol, 20), 1000, OVER_S, seed=7)
    f = fleet_factory(mission=mission, key_file=key)
    addr, port = next(a for a in f.companions[0].proc.args if a.startswith("239.255.")).split(":")
    f.wait_sim_time(START_S)
    signing = signing_from_key_file(key, OPERATOR_SYSID)
    with Group(OPERATOR_SYSID, signing, address=addr, port=int(port), compid=COMPID_OPERATOR) as g:
        start_vt, sent, wall_s = inject(g, plan)
    start = start_vt - SIM_EPOCH_UNIX_S
    t_end = start + 150.0
    f.wait_sim_time(t_end, timeout_s=150)
    codes = f.stop()
    m, ev = measures(f.out, mission)
    fig = storm_figures(ev, plan, m.t_s, start, OVER_S, t_end)
    storm_rate = setpoint_rates(f.out, start, start + OVER_S)
    quiet_rate = setpoint_rates(f.out, start - 20.0, start)
    after_rate = setpoint_rates(f.out, start + OVER_S, start + OVER_S + 20.0)
    counts = {e["sysid"]: e for e in ev if e["event"] == "alert_counts"}
    # UAVs off the perimeter at each truth sample, from the truth alone (a cross-check of the
    # events): loop centre more than a sensor footprint from the base's
    off_loop = np.abs(m.centres_m - PATROL.centre_m) > R_S
    window = (m.t_s >= start) & (m.t_s <= t_end)
    report(
        "storm fleet",
        {
            "sent": sent,
            "send_wall_s": wall_s,
            "start_s": start,
            **{k: fig[k] for k in ("prosecutors", "yields", "max_away", "distinct_per_companion")},
            "merged_per_companion": fig["merged_per_companion"],
            "max_off_loop": int(off_loop[window].sum(axis=1).max()),
            "setpoints_per_s_storm": storm_rate,
            "setpoints_per_s_before": quiet_rate,
            "setpoints_per_s_after": after_rate,
        },
    )
    assert codes == [0] * 7
    assert sent == 1000
    pros = fig["prosecuted"]
    assert pros, "nothing was prosecuted"
    # one prosecutor per alert: where two were tasked on split views (a loaded machine), the
    # higher sysid yielded within one state period of its plan
    assert all(len(s) == 1 for s in fig["kept_by"].values()), fig["prosecutors"]
    assert all(dt <= 0.5 for dt in fig["yields"].values()), fig["yields"]
    assert pros == fig["canonical_order"][: len(pros)]  # first reports only, in queue order
    assert len(set(fig["sites_prosecuted"])) == len(pros)
    assert fig["max_away"] <= 1
    assert int(off_loop[window].sum(axis=1).max()) <= 1
    assert len(counts) == 6 and all(c["received"] >= 950 for c in counts.values()), counts
    # the control loop kept its rate through the storm: within 10 % of the nominal 10/s, or,
    # on a machine too busy for 10/s at 20x, of the rate the same companion held in the 20 s
    # before or after it (a dip of the storm's own, not of the machine's)
    for name, rate in storm_rate.items():
        reference = min(10.0, quiet_rate[name], after_rate[name])
        assert rate >= 0.9 * reference, (storm_rate, quiet_rate, after_rate)


def test_an_alert_whose_prosecutor_leaves_the_formation_is_tasked_again():
    """The prosecutor's companion dies mid-prosecution: once the member timeout drops it,
    its alert is re-queued (it excluded) and the next UAV in line is tasked."""
    agent = Agent(2, MISSION, AgentConfig(member_timeout_s=3.0))
    phases = {s: (s - 1) * 2 * np.pi / 6 for s in range(1, 7)}
    site = SITES[7]

    def hear(t_s: float, lost: set[int]) -> None:
        for s, ph in phases.items():
            if s == 2 or s in lost:
                continue
            mode, alert_id = ("prosecuting", "a") if s == 3 else ("patrol", "")
            agent.receive_state(member(s, t_s, ph, mode, alert_id), t_s)

    agent.receive_alert(op("a", site, 10.0), 10.0)
    hear(10.0, set())
    agent.update(Fix(10.1, *on_loop(phases[2]), agent.patrol))
    assert agent.alerts.records["a"].prosecutor == 3  # seen away for it
    out_events: list[dict] = []
    for k in range(1, 60):  # UAV 3 falls silent at 10 s; the others go on
        t = 10.0 + 0.1 * k
        hear(t, {3})
        out_events += agent.update(Fix(t + 0.05, *on_loop(phases[2]), agent.patrol)).events
    lost = events(out_events, "member_lost")
    requeued = events(out_events, "alert_requeued")
    tasked = events(out_events, "alert_tasked")
    assert [e["member_sysid"] for e in lost] == [3]
    assert [(e["alert_id"], e["reason"]) for e in requeued] == [("a", "prosecutor_lost")]
    assert len(tasked) == 1 and tasked[0]["alert_id"] == "a"
    assert tasked[0]["prosecutor_sysid"] not in (3, None)
    assert requeued[0]["t_s"] <= tasked[0]["t_s"] <= requeued[0]["t_s"] + 0.2


def test_a_hand_off_goes_at_once_other_alerts_wait_for_the_rejoin():
    """UAV 3 confirmed intruder "a" and flies back into its slot: the hand-off of "a" is
    tasked at once (the paper's next UAV), a new alert "b" waits until 3 is back."""
    phases = {s: (s - 1) * 2 * np.pi / 6 for s in range(1, 7)}
    tasked = {}
    for alert in (Alert("a", SITES[7], 3, 20.0, "confirmed"), op("b", SITES[12], 20.0)):
        agent = Agent(2, MISSION, AgentConfig(member_timeout_s=30.0))
        if alert.alert_id == "b":
            agent.receive_alert(op("a", SITES[7], 10.0), 10.0)
        for s, ph in phases.items():
            if s != 2:
                mode, aid = ("rejoining", "a") if s == 3 else ("patrol", "")
                agent.receive_state(member(s, 19.0, ph, mode, aid), 19.0)
        agent.receive_alert(alert, 20.0)
        evs: list[dict] = []
        for k in range(10):
            evs += agent.update(Fix(20.0 + 0.1 * k, *on_loop(phases[2]), agent.patrol)).events
        tasked[alert.alert_id] = [
            e["prosecutor_sysid"]
            for e in events(evs, "alert_tasked")
            if e["alert_id"] == alert.alert_id
        ]
    assert len(tasked["a"]) == 1 and tasked["a"][0] != 3
    assert tasked["b"] == []
