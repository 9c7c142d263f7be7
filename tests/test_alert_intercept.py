"""A turning track's intercept is aimed at its predicted arc (issue 47;
:func:`companion.agent.alerts.paths.intercept`).

The planner meets a goal moving in a straight line. A track on the turn model predicts an
arc (:meth:`~companion.group.messages.Track.predict`); an intercept aimed from the arc's
point now along the velocity of the track's time (the heading before the turn) ends where
the vehicle will not be. The plan's end must lie on the predicted arc at the plan's end time;
a straight track's intercept is unchanged.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from companion.agent.alerts.paths import intercept
from companion.group.messages import Track
from companion.mission import load_mission
from companion.planner import Plan

MAX_U = math.radians(20.0)


@pytest.fixture(scope="module")
def patrol():
    return load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml").patrol


def end_of(plan: Plan) -> complex:
    return complex(plan.ground_track(0.05)[-1])


@pytest.mark.parametrize("turn_deg_s", [6.0, -6.0, 12.0])
@pytest.mark.parametrize("start", [-600.0 + 300j, 500.0 - 200j, 300j])
def test_a_turning_track_is_met_on_its_arc(patrol, turn_deg_s: float, start: complex):
    track = Track(
        0.0, 0j, 10.0 + 0j, 2.0, 0.5, 30,
        model="turn", model_p=0.9, turn_rad_s=math.radians(turn_deg_s), manoeuvre_m_s2=1.5,
    )  # fmt: skip
    t = 2.0
    plan = intercept(patrol, start, 0.0, track, t, MAX_U, along_loop=False)
    assert isinstance(plan, Plan)
    where = track.predict(t + plan.time_s)
    straight = track.predict(t) + track.vel_m_s * plan.time_s  # the old aim
    assert abs(straight - where) > 50.0  # the premise: the old aim is far off the arc
    assert abs(end_of(plan) - where) < 10.0, (end_of(plan), where, plan.time_s)


def test_a_straight_track_is_met_where_it_drives(patrol):
    track = Track(0.0, 0j, 10.0 + 0j, 2.0, 0.5, 30, manoeuvre_m_s2=0.3)
    plan = intercept(patrol, -600.0 + 300j, 0.0, track, 2.0, MAX_U, along_loop=False)
    assert isinstance(plan, Plan)
    assert abs(end_of(plan) - track.predict(2.0 + plan.time_s)) < 2.0
