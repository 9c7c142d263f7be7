"""The prosecution seam (pure): the path to the site, its re-planning and how it ends."""

from __future__ import annotations

import math
from pathlib import Path

from companion.agent.alerts.paths import turn_rate_at
from companion.agent.alerts.prosecution import Prosecution
from companion.agent.away import Away
from companion.agent.events import PlanFailed, PlanMade, ProsecutionEnd, Replan, SiteCovered
from companion.core.wind import heading_from_course
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
P = MISSION.patrol
T0_S = 100.0
HOLD_S = 0.1
SYSID = 3


def on_loop(phase_rad: float) -> tuple[complex, float]:
    """A position (m) on the loop and the air heading (rad) that flies its tangent."""
    course = float(P.course_at_phase(phase_rad))
    heading = float(heading_from_course(P.airspeed_m_s, course, P.wind))
    return complex(P.point_at_phase(phase_rad)), heading


def outside_site(phase_rad: float, out_m: float = 50.0) -> complex:
    loop = complex(P.point_at_phase(phase_rad))
    return loop + out_m * (loop - P.centre_m) / abs(loop - P.centre_m)


def prosecution(site_m: complex) -> Prosecution:
    away = Away("1-1", site_m, VirtualParticle(0.0, T0_S, P.period_s))
    return Prosecution(
        away,
        sysid=SYSID,
        max_u=MISSION.vehicles.max_turn_rate_rad_s,
        sensor_m=MISSION.sensor.footprint_radius_m,
        replan_s=1.0,
        hold_s=HOLD_S,
    )


def started() -> tuple[Prosecution, complex, float]:
    pos, heading = on_loop(0.0)
    pros = prosecution(outside_site(math.pi / 2))
    assert [type(e) for e in pros.start(P, T0_S, pos, heading)] == [PlanMade]
    return pros, pos, heading


def test_start_plans_and_flies_the_path_between_replans():
    pos, heading = on_loop(0.0)
    pros = prosecution(outside_site(math.pi / 2))
    away = pros.away
    (ev,) = pros.start(P, T0_S, pos, heading)
    assert ev == PlanMade(
        t_s=T0_S,
        sysid=SYSID,
        alert_id="1-1",
        planned_time_s=round(away.plan.time_s, 3),
        path_type=away.plan.family,
    )
    assert away.planned_time_s == away.plan.time_s > 0 and away.plan_t0_s == T0_S
    u, events = pros.step(P, T0_S + 0.5, pos, heading, alert_t_s=T0_S)
    assert events == [] and u == turn_rate_at(away.plan, 0.5, HOLD_S)


def test_a_much_longer_replan_keeps_the_path_in_force():
    pros, pos, heading = started()
    plan = pros.away.plan
    assert pros.replan(P, T0_S + 1.0, pos, heading + math.pi) == []  # a whole turn longer
    assert pros.away.plan is plan and pros.away.last_plan_s == T0_S + 1.0
    (ev,) = pros.replan(P, T0_S + 2.0, pos, heading)
    assert isinstance(ev, Replan) and pros.away.plan_t0_s == T0_S + 2.0


def test_no_path_is_reported_on_the_first_plan_only():
    site = outside_site(0.0)
    pros = prosecution(site)
    (ev,) = pros.start(P, T0_S, site, 0.0)  # already on the site
    assert isinstance(ev, PlanFailed) and ev.reason
    assert pros.away.plan is None
    assert pros.replan(P, T0_S + 1.0, site, 0.0) == []
    u, _ = pros.step(P, T0_S + 1.5, site, 0.0, alert_t_s=None)
    assert u is None  # no path: the site is cleared


def test_the_site_is_covered_once_within_the_sensor():
    pros, _, heading = started()
    near = pros.site_m + 0.9 * MISSION.sensor.footprint_radius_m
    _, events = pros.step(P, T0_S + 0.5, near, heading, alert_t_s=T0_S - 2.0)
    assert events == [
        SiteCovered(
            t_s=T0_S + 0.5,
            sysid=SYSID,
            alert_id="1-1",
            response_time_s=2.5,
            planned_time_s=round(pros.away.plan.time_s, 3),
        )
    ]
    _, again = pros.step(P, T0_S + 0.6, near, heading, alert_t_s=T0_S - 2.0)
    assert again == []


def test_the_path_flown_ends_in_clear():
    pros, pos, heading = started()
    t_end = T0_S + pros.away.plan.time_s
    u, _ = pros.step(P, t_end, pos, heading, alert_t_s=None)
    assert u is None
    outcome, events = pros.end(t_end, None, alert_t_s=None)  # no record: the start stands in
    assert outcome == "cleared"
    assert events == [
        ProsecutionEnd(
            t_s=t_end,
            sysid=SYSID,
            alert_id="1-1",
            outcome="cleared",
            planned_time_s=round(pros.away.planned_time_s, 3),
            response_time_s=round(t_end - T0_S, 3),
        )
    ]


def test_a_redetection_confirms_and_covers_the_site():
    pros, _, _ = started()
    outcome, events = pros.end(T0_S + 5.0, pros.site_m + 10.0, alert_t_s=T0_S - 1.0)
    assert outcome == "confirmed" and pros.away.covered
    assert [(e.name, e.response_time_s) for e in events] == [
        ("site_covered", 6.0),
        ("prosecution_end", 6.0),
    ]


def test_a_cancel_names_who_cleared_it():
    pros, _, _ = started()
    (ev,) = pros.cancel(T0_S + 3.0, 255)
    assert ev.to_record() == {
        "t_s": T0_S + 3.0,
        "event": "prosecution_end",
        "sysid": SYSID,
        "alert_id": "1-1",
        "outcome": "cancelled",
        "by_sysid": 255,
        "planned_time_s": round(pros.away.planned_time_s, 3),
    }
