"""The rejoin's "back in the slot" relative to the UAV's measured tracking accuracy (pure)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.away import Away
from companion.agent.events import Rejoined
from companion.agent.modes import ModeEvent, OwnMode
from companion.agent.rejoin import (
    REJOIN_MAX_TOL_M,
    RejoinContext,
    TrackingAccuracy,
    rejoin_step,
    slot_tolerance,
)
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")


def test_slot_tolerance_keeps_the_simulator_values_and_grows_with_the_tracking_error():
    p = MISSION.patrol
    r_s = MISSION.sensor.footprint_radius_m
    base = slot_tolerance(0.0, p.length_m, r_s)
    assert base.centre_m == 3.0 and base.phase_rad == pytest.approx(math.radians(1.0))
    assert base.course_rad == pytest.approx(math.radians(1.0))
    assert base.slot_m == pytest.approx(0.2 * r_s)
    real = slot_tolerance(12.0, p.length_m, r_s)  # ArduPlane: about 12 m median off the loop
    assert real.centre_m == pytest.approx(18.0)
    assert real.phase_rad == pytest.approx(2 * math.pi * 18.0 / p.length_m)
    assert real.slot_m == pytest.approx(max(18.0, 0.2 * r_s))
    assert slot_tolerance(1e3, p.length_m, r_s).centre_m == REJOIN_MAX_TOL_M  # capped


def test_tracking_accuracy_is_a_sliding_p95():
    acc = TrackingAccuracy(window_s=100.0)
    assert acc.p95_m() == 0.0
    for k in range(200):
        acc.add(float(k), 50.0)  # early, converging: forgotten
    for k in range(200, 400):
        acc.add(float(k), float(k % 10))
    assert acc.p95_m() == pytest.approx(np.percentile([k % 10 for k in range(300, 400)], 95))


def rejoin_at(centre_error_m: float, p95_m: float):
    p = MISSION.patrol
    ctx = RejoinContext(
        p, MISSION.gains, MISSION.vehicles.max_turn_rate_rad_s,
        MISSION.sensor.footprint_radius_m, 1.0, tracking_p95_m=p95_m,
    )  # fmt: skip
    t = 500.0
    away = Away("a", 0j, VirtualParticle(1.0, t, p.period_s), rejoin_t0_s=t - 20)
    phase = away.virtual.phase(t)
    pos = complex(p.point_at_phase(phase)) + centre_error_m
    heading = float(p.course_at_phase(phase))
    stage = OwnMode.REJOIN_ALONG_LOOP
    return rejoin_step(ctx, away, stage, t, pos, heading, p.centre_m + centre_error_m, phase)


def test_a_uav_that_tracks_to_12_m_is_back_in_its_slot_at_10_m():
    u, events, changes = rejoin_at(10.0, p95_m=12.0)
    assert u is None and changes == [ModeEvent.IN_SLOT]
    assert isinstance(events[0], Rejoined) and events[0].in_slot


def test_a_uav_that_tracks_to_1_m_is_not_back_at_10_m():
    u, events, changes = rejoin_at(10.0, p95_m=1.0)
    assert u is not None and ModeEvent.IN_SLOT not in changes
    assert not [e for e in events if isinstance(e, Rejoined)]
