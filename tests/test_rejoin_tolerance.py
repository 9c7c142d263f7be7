"""The rejoin's "back in the slot" relative to the UAV's measured tracking accuracy (pure)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.away import LeftLoop, Rejoining, ToLoop
from companion.agent.events import Rejoined
from companion.agent.fix import Fix
from companion.agent.modes import ModeEvent
from companion.agent.rejoin import (
    REJOIN_MAX_TOL_M,
    RejoinContext,
    TrackingAccuracy,
    rejoin_step,
    slot_tolerance,
)
from companion.core.particle import ParticleParams, step_one
from companion.core.wind import heading_from_course
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
    # along the loop (no first stage), 20 s into the rejoin
    away = Rejoining("a", VirtualParticle(1.0, t, p.period_s), t - 20, None)
    phase = away.virtual.phase(t)
    pos = complex(p.point_at_phase(phase)) + centre_error_m
    # flying the loop's course at the slot's phase: its centre is off by the same error
    heading = float(heading_from_course(p.airspeed_m_s, float(p.course_at_phase(phase)), p.wind))
    fix = Fix(t, pos, heading, p)
    assert abs(fix.centre_m - (p.centre_m + centre_error_m)) < 1e-6
    assert abs(fix.phase_rad - phase) < 1e-9
    return rejoin_step(ctx, away, fix)


def test_a_uav_that_tracks_to_12_m_is_back_in_its_slot_at_10_m():
    u, events, changes = rejoin_at(10.0, p95_m=12.0)
    assert u is None and changes == [ModeEvent.IN_SLOT]
    assert isinstance(events[0], Rejoined) and events[0].in_slot


def test_a_uav_that_tracks_to_1_m_is_not_back_at_10_m():
    u, events, changes = rejoin_at(10.0, p95_m=1.0)
    assert u is not None and ModeEvent.IN_SLOT not in changes
    assert not [e for e in events if isinstance(e, Rejoined)]


def _rejoin_from_inside(revisit_s: float):
    """A UAV that left the ellipse at phase 1.0 rad 6 s ago, now 100 m inside the loop just
    past that point, flying the loop's course: its first rejoin decision."""
    p = MISSION.patrol
    psi0, t_s = 1.0, 106.0
    on = complex(p.point_at_phase(psi0 + 0.02))
    inward = (p.centre_m - on) / abs(p.centre_m - on)
    pos = on + 100.0 * inward
    heading = float(p.course_at_phase(psi0 + 0.02))
    left = LeftLoop(t_s=100.0, phase_rad=psi0)
    away = Rejoining("2-1", VirtualParticle(psi0, 100.0, p.period_s), t_s, ToLoop(left))
    ctx = RejoinContext(
        p,
        MISSION.gains,
        MISSION.vehicles.max_turn_rate_rad_s,
        MISSION.sensor.footprint_radius_m,
        1.0,
        revisit_s=revisit_s,
    )
    _, events, _ = rejoin_step(ctx, away, Fix(t_s, pos, heading, p))
    (path,) = [e for e in events if e.name == "rejoin_path"]
    return away, path, pos, heading, psi0


def test_a_short_excursion_on_a_long_revisit_flies_back_to_where_it_left_the_loop():
    # revisit 200 s (a long loop, few UAVs): back where it left after 6 s + the path, the
    # stretch ahead is seen again far sooner than by the UAV behind, 200 s later
    away, path, pos, heading, psi0 = _rejoin_from_inside(200.0)
    assert path.resume_after_s == 6.0
    # flown through the particle model, the path ends on the loop where it left
    p = MISSION.patrol
    params = ParticleParams(MISSION.vehicles.airspeed_m_s, MISSION.vehicles.max_turn_rate_rad_s)
    at, hd, dt = pos, heading, 0.01
    for seg in away.to_loop.plan.segments:
        for _ in range(round(seg.duration_s / dt)):
            at, hd = step_one(at, hd, seg.turn_rate_rad_s, params, p.wind.vector, dt)
    assert abs(at - complex(p.point_at_phase(psi0))) < 2.0
    # a short revisit (the UAV behind is there within 5 s), or none known: join ahead
    for revisit in (5.0, 0.0):
        _, ahead, _, _, _ = _rejoin_from_inside(revisit)
        assert ahead.resume_after_s is None
