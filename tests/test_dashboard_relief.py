"""The live page's reliefs (companion/dashboard/model.py, pure; docs/dashboard.md): each
UAV's battery and time to leave, the spares, the reliefs under way, the plan the members
fly (checked against a member's own :class:`Duty` fed the same states), a late relief
announced before it is late, and a state under a sysid the mission does not list refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.duty import Duty
from companion.dashboard.model import FleetView, Geometry
from companion.group.messages import Energy, MemberState, Mode
from companion.mission import load_mission

REPO = Path(__file__).resolve().parents[1]
RELIEF = load_mission(REPO / "missions" / "ellipse_relief.yaml")
PAPER = load_mission(REPO / "missions" / "ellipse_6uav.yaml")
PATROL = RELIEF.patrol
BASE = 300j


def _state(sysid: int, t_s: float, energy: Energy | None, phase: float = 0.0) -> MemberState:
    on_loop = energy is None or energy.role == "on_station"
    pos = complex(PATROL.point_at_phase(phase)) if on_loop else BASE
    mode = Mode.PATROL if on_loop else Mode.SPARE
    return MemberState(sysid, t_s, PATROL.centre_m, phase, mode, pos_m=pos, energy=energy)


def _fleet(t_s: float, leave: dict[int, float], spares: dict[int, str]) -> list[MemberState]:
    out = [
        _state(s, t_s, Energy("on_station", 50.0 - s, lv, 0), s * 1.0) for s, lv in leave.items()
    ]
    out += [_state(s, t_s, Energy(role, 100.0, 0.0, 0)) for s, role in spares.items()]
    return out


def test_each_uav_shows_its_battery_and_time_to_leave_and_the_plan_the_members_fly():
    view = FleetView(RELIEF)
    t = 100.0
    leave = {1: 3000.0, 2: 3400.0, 3: 700.0, 4: 3800.0, 5: 4200.0, 6: 4600.0}
    states = _fleet(t, leave, {10: "spare", 11: "spare"})
    for st in states:
        view.feed(st, rx_s=50.0)
    snap = view.snapshot(50.0)
    by = {v["sysid"]: v for v in snap["vehicles"]}
    assert by[3]["energy"]["battery_pct"] == 47.0 and by[3]["energy"]["leave_in_s"] == 600.0
    assert by[10]["energy"]["role"] == "spare" and by[10]["energy"]["ready_in_s"] == 0.0
    rel = snap["reliefs"]
    assert rel["enabled"] and [s["sysid"] for s in rel["spares"]] == [10, 11]
    first = rel["plan"][0]
    assert first["member_sysid"] == 3 and first["leave_in_s"] == 600.0 and not first["late"]
    assert first["spare_sysid"] == 10 and by[3]["energy"]["relief"] == first
    # the plan spare 10's own duty makes from the same states, reliefs in the same order
    duty, heard = Duty(10, RELIEF), Neighbours(10, 3.0)
    for st in states:
        heard.hear(st, t)
    duty.step(Fix(t, BASE, 0.0, PATROL), heard, RELIEF.gains, True)
    theirs = [(r.member, r.spare, round(r.launch_t_s - t, 1)) for r in duty.plan.reliefs]
    mine = [(r["member_sysid"], r["spare_sysid"], r["launch_in_s"]) for r in rel["plan"]]
    assert mine == theirs and len(mine) == 6
    json.dumps(snap, allow_nan=False)  # what the server sends


def test_a_relief_that_cannot_be_made_in_time_is_announced_once_before_it_is_late():
    view = FleetView(RELIEF)
    # UAV 3 must leave in 60 s; the only spare is 270 s (transit, take-over, lead) away, so
    # it goes to UAV 3 at once, late, and UAV 4 (leaving at 5000 s) gets UAV 3's return on
    # time (rule 3: no on-time relief is lost by it)
    for st in _fleet(100.0, {3: 160.0, 4: 5000.0}, {10: "spare"}):
        view.feed(st, rx_s=0.0)
    snap = view.snapshot(0.0)
    (r3,) = [r for r in snap["reliefs"]["plan"] if r["member_sysid"] == 3]
    (r4,) = [r for r in snap["reliefs"]["plan"] if r["member_sysid"] == 4]
    assert r4["spare_sysid"] == 3 and not r4["late"]
    assert r3["late"] and r3["spare_sysid"] == 10 and 0.0 < r3["late_s"] < 270.0
    late = [e for e in snap["events"] if e["kind"] == "relief_late"]
    assert len(late) == 1 and late[0]["sysid"] == 3 and late[0]["spare_sysid"] == 10
    assert late[0]["t_s"] < 160.0  # said before the leave time
    for k in range(1, 4):  # said once
        snap = view.snapshot(float(k))
    assert [e["kind"] for e in snap["events"]].count("relief_late") == 1
    # no spare at all: late by "no spare"
    alone = FleetView(RELIEF)
    alone.feed(_state(3, 100.0, Energy("on_station", 30.0, 900.0, 0)), 0.0)
    snap = alone.snapshot(0.0)
    (r,) = snap["reliefs"]["plan"]
    assert r["spare_sysid"] is None and r["late_s"] is None and r["in_slot_in_s"] is None
    assert any("no spare" in e["text"] for e in snap["events"] if e["kind"] == "relief_late")
    json.dumps(snap, allow_nan=False)


def test_reliefs_under_way_and_role_changes_are_shown_and_logged():
    view = FleetView(RELIEF)
    for st in _fleet(100.0, {3: 900.0}, {10: "spare"}):
        view.feed(st, 0.0)
    view.feed(_state(10, 101.0, Energy("relieving", 99.0, None, 3)), 1.0)
    snap = view.snapshot(1.0)
    assert snap["reliefs"]["under_way"] == [{"spare_sysid": 10, "member_sysid": 3}]
    (r,) = snap["reliefs"]["plan"]
    assert r["under_way"] and r["spare_sysid"] == 10 and r["launch_in_s"] is None
    view.feed(_state(10, 150.0, Energy("on_station", 95.0, 2900.0, 3), 3.0), 50.0)
    view.feed(_state(3, 151.0, Energy("home", 25.0, None, 0)), 51.0)
    view.feed(_state(3, 180.0, Energy("spare", 24.0, 1400.0, 0)), 80.0)
    kinds = [e["kind"] for e in view.snapshot(80.0)["events"] if e["kind"].startswith("relie")]
    assert kinds == ["relief_launched", "relief_in_slot", "relieved", "relief_landed"]


def test_a_state_under_a_sysid_the_mission_does_not_list_is_refused_and_never_planned_with():
    view = FleetView(RELIEF)
    for st in _fleet(100.0, {3: 700.0}, {}):
        view.feed(st, 0.0)
    impostor = MemberState(20, 100.0, PATROL.centre_m, 0.0, Mode.SPARE,
                           pos_m=complex(PATROL.point_at_phase(3.1)),
                           energy=Energy("spare", 100.0, 0.0, 0))  # fmt: skip
    view.feed(impostor, 0.0)
    snap = view.snapshot(0.0)
    rel = snap["reliefs"]
    assert rel["refused"] == [{"sysid": 20, "role": "spare", "reason": "not_in_mission"}]
    assert rel["spares"] == [] and rel["plan"][0]["spare_sysid"] is None
    assert rel["refused_count"] == 1
    by = {v["sysid"]: v for v in snap["vehicles"]}
    assert by[20]["energy"]["refused"] == "not_in_mission"
    assert [e["kind"] for e in snap["events"]].count("relief_refused") == 1
    view.snapshot(1.0)
    assert view.reliefs.refused_count == 1  # counted once per sysid, not per snapshot


def test_without_spares_the_page_has_no_reliefs_and_the_geometry_lists_the_spares():
    view = FleetView(PAPER)
    view.feed(_state(1, 10.0, None), 0.0)
    snap = view.snapshot(0.0)
    assert snap["reliefs"]["enabled"] is False and snap["reliefs"]["plan"] == []
    assert snap["vehicles"][0]["energy"] is None
    assert Geometry.of(PAPER).to_json()["spares"] == []
    spares = Geometry.of(RELIEF).to_json()["spares"]
    assert [s["sysid"] for s in spares] == [10, 11, 12, 13] and spares[0]["east_m"] == 300.0


def _splayed(sysid: int, t_s: float, k: int, n: int, energy: Energy, mode: Mode = Mode.PATROL):
    """Member ``sysid`` on the loop at slot ``k`` of ``n`` (phase ``2 pi k / n``)."""
    phase = 2.0 * np.pi * k / n
    pos = complex(PATROL.point_at_phase(phase))
    return MemberState(sysid, t_s, PATROL.centre_m, phase, mode, pos_m=pos, energy=energy)


def test_the_gauges_are_over_the_formation_and_spares_are_counted_apart():
    """The issue's picture: six evenly spaced on the loop and four spares on the ground read
    splay 0 and T/6 (not 36 deg and T/10), and the spares, a spare climbing out, a member
    going home and a tracker are each counted apart; the API's vehicles say where each is."""
    view = FleetView(RELIEF)
    t = 300.0
    on = [_splayed(s, t, s - 1, 6, Energy("on_station", 60.0, 3000.0 + s, 0)) for s in range(1, 7)]
    spares = [_state(s, t, Energy("spare", 100.0, 0.0, 0)) for s in (10, 11, 12, 13)]
    for st in on + spares:
        view.feed(st, rx_s=0.0)
    g = view.snapshot(0.0)["gauges"]
    T = PATROL.period_s
    assert (g["members"], g["on_station"], g["away"], g["spares"]) == (6, 6, 0, 4)
    assert (g["climbing_out"], g["going_home"], g["tracking"], g["lost"]) == (0, 0, 0, 0)
    assert g["splay_deg"] < 1e-6 and g["coverage_ideal_s"] == round(T / 6, 2)

    # spare 10 launched for UAV 3; then in its slot while UAV 3 flies home; UAV 5 tracking
    view.feed(_state(10, t + 1, Energy("relieving", 99.0, None, 3)), rx_s=1.0)
    g = view.snapshot(1.0)["gauges"]
    assert (g["members"], g["spares"], g["climbing_out"]) == (6, 3, 1)
    assert g["splay_deg"] < 1e-6 and g["coverage_ideal_s"] == round(T / 6, 2)
    view.feed(_splayed(10, t + 2, 2, 6, Energy("on_station", 97.0, 2900.0, 3)), rx_s=2.0)
    view.feed(_state(3, t + 2, Energy("home", 24.0, None, 0)), rx_s=2.0)
    view.feed(_splayed(5, t + 2, 4, 6, Energy("on_station", 55.0, 3005.0, 0), Mode.TRACKING), 2.0)
    snap = view.snapshot(2.0)
    g = snap["gauges"]
    assert (g["members"], g["on_station"], g["tracking"]) == (5, 6, 1)
    assert (g["spares"], g["climbing_out"], g["going_home"]) == (3, 0, 1)
    # the five in the formation keep their slots of six: one gap of 120 deg where 72 is due
    assert abs(g["splay_deg"] - 48.0) < 1e-6 and g["coverage_ideal_s"] == round(T / 5, 2)
    where = {v["sysid"]: v["station"] for v in snap["vehicles"]}
    assert where == {1: "formation", 2: "formation", 3: "going_home", 4: "formation",
                     5: "tracking", 6: "formation", 10: "formation", 11: "spare",
                     12: "spare", 13: "spare"}  # fmt: skip


def test_no_aircraft_in_the_formation_leaves_the_formation_gauges_empty():
    view = FleetView(RELIEF)
    for s in (10, 11):
        view.feed(_state(s, 50.0, Energy("spare", 100.0, 0.0, 0)), rx_s=0.0)
    g = view.snapshot(0.0)["gauges"]
    assert (g["members"], g["spares"]) == (0, 2)
    assert g["splay_deg"] is None and g["coverage_ideal_s"] is None


def test_a_late_relief_is_one_standing_warning_updated_in_place_and_logged_once():
    """The prediction changes (new numbers, another spare): the same one warning carries the
    new figures, the log has its one line; it goes when the member is relieved."""
    view = FleetView(RELIEF)
    for st in _fleet(100.0, {3: 160.0, 4: 5000.0}, {10: "spare"}):
        view.feed(st, rx_s=0.0)
    (w,) = view.snapshot(0.0)["warnings"]
    assert w["member_sysid"] == 3 and w["spare_sysid"] == 10 and w["late_s"] > 0.0
    first = w["late_s"]
    # UAV 3 must leave 30 s sooner: later by 30 s
    view.feed(_state(3, 101.0, Energy("on_station", 47.0, 130.0, 0), 3.0), rx_s=1.0)
    snap = view.snapshot(1.0)
    (w,) = snap["warnings"]
    assert w["member_sysid"] == 3 and abs(w["late_s"] - (first + 30.0)) < 1.5
    assert w["text"] == f"UAV 3: relief {w['late_s']:.0f} s late by UAV 10"
    # spare 10 is gone, spare 11 is there: the same warning names 11
    view.feed(_state(10, 102.0, Energy("unavailable", 100.0, None, 0)), rx_s=2.0)
    view.feed(_state(11, 102.0, Energy("spare", 100.0, 0.0, 0)), rx_s=2.0)
    snap = view.snapshot(2.0, events=500)
    (w,) = snap["warnings"]
    assert w["member_sysid"] == 3 and w["spare_sysid"] == 11 and w["since_t_s"] < 101.0
    assert [e["kind"] for e in snap["events"]].count("relief_late") == 1
    # the relief flies: no warning left, still one line
    view.feed(_state(11, 103.0, Energy("relieving", 99.0, None, 3)), rx_s=3.0)
    snap = view.snapshot(3.0, events=500)
    assert snap["warnings"] == []
    assert [e["kind"] for e in snap["events"]].count("relief_late") == 1
    json.dumps(snap, allow_nan=False)
