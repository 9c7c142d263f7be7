"""The phase hold by airspeed (companion/guidance/steering.py, formation.py, neighbours.py).

Independent checks: the splay potential's curvature against a finite difference of its
gradient; the airspeed law closed here on plain phase kinematics (each slot moves at the
airspeed it is given), its time constant read from the decay; the position-based phase
against points placed on the loop by ``point_at_phase``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from companion.agent.neighbours import Neighbours
from companion.core.wind import TWO_PI
from companion.group.messages import MemberState
from companion.guidance.formation import (
    splay_airspeed,
    splay_slot_error_m,
    steered_phase_gradient,
)
from companion.guidance.steering import (
    Gains,
    phase_gains_m2_s,
    phase_speed_offset,
    splay_curvature_m2_s,
    splay_gradient,
)
from companion.mission import load_mission

MISSION = load_mission("missions/ellipse_6uav.yaml")
PATROL = MISSION.patrol


@pytest.mark.parametrize("n", [2, 3, 4, 6, 9])
def test_curvature_is_the_gradients_slope_at_a_perfect_splay(n):
    g = Gains()
    k_m = phase_gains_m2_s(PATROL, g, n)
    psi = np.arange(n) * TWO_PI / n + 0.3
    h = 1e-5
    up, dn = psi.copy(), psi.copy()
    up[1] += h
    dn[1] -= h
    slope = (splay_gradient(up[1], up, k_m) - splay_gradient(dn[1], dn, k_m)) / (2 * h)
    assert splay_curvature_m2_s(PATROL, g, n) == pytest.approx(float(slope), rel=1e-5)
    assert splay_curvature_m2_s(PATROL, g, 1) == 0.0


def test_behind_its_slot_a_uav_speeds_up_ahead_it_slows_within_the_authority():
    g = Gains(speed_authority_m_s=1.5, speed_tau_s=15.0)
    n = 6
    psi = np.arange(n) * TWO_PI / n
    metres_per_rad = PATROL.length_m / TWO_PI
    for lag_m in (-3.0, 3.0, -60.0, 60.0):
        own = psi[0] + lag_m / metres_per_rad
        v = splay_airspeed(PATROL, g, own, list(psi[1:]))
        dv = v - PATROL.airspeed_m_s
        assert math.copysign(1.0, dv) == -math.copysign(1.0, lag_m)  # behind (<0): faster
        assert abs(dv) <= g.speed_authority_m_s
        if abs(lag_m) < 10:  # linear: the slot error over tau
            assert abs(dv) == pytest.approx(abs(lag_m) / g.speed_tau_s, rel=0.03)
        else:
            assert abs(dv) > 0.9 * g.speed_authority_m_s
    # the fixed airspeed of the paper, and a lone UAV, hold the mission's
    off = dataclasses.replace(g, speed_authority_m_s=0.0)
    assert splay_airspeed(PATROL, off, 0.5, list(psi[1:])) == PATROL.airspeed_m_s
    assert splay_airspeed(PATROL, g, 0.5, []) == PATROL.airspeed_m_s
    assert phase_speed_offset(PATROL, g, 100.0, 0.0) == 0.0


def test_the_airspeed_alone_closes_the_splay_with_its_time_constant():
    """Six slots moved only by their airspeed (ds/dt = v - s0 + drift, drift common to all):
    one displaced by 6 m decays as exp(-t N / ((N - 1) tau)), since the others answer it."""
    g = Gains(speed_authority_m_s=3.0, speed_tau_s=12.0)
    n, dt = 6, 0.05
    metres_per_rad = PATROL.length_m / TWO_PI
    s = np.arange(n) * PATROL.length_m / n
    s[2] += 6.0
    err0 = None
    errs = []
    for k in range(int(30.0 / dt)):
        psi = s / metres_per_rad
        v = np.array([splay_airspeed(PATROL, g, psi[i], list(np.delete(psi, i))) for i in range(n)])
        s = s + (v - PATROL.airspeed_m_s) * dt
        gaps = np.diff(np.r_[s, s[0] + PATROL.length_m])
        err = float(np.max(np.abs(gaps - PATROL.length_m / n)))
        err0 = err if err0 is None else err0
        errs.append((k * dt, err))
    rate = n / ((n - 1) * g.speed_tau_s)
    for t, err in errs[:: int(5.0 / dt)]:
        assert err == pytest.approx(err0 * math.exp(-rate * t), rel=0.1, abs=0.02)


def test_steering_leaves_the_slot_error_the_airspeed_takes_out():
    g = Gains(speed_authority_m_s=1.5, speed_tau_s=15.0)
    n = 6
    curv = splay_curvature_m2_s(PATROL, g, n)
    zone_m = g.speed_authority_m_s * g.speed_tau_s
    metres_per_rad = PATROL.length_m / TWO_PI
    small = curv * (zone_m / 4) / metres_per_rad  # a gradient worth a quarter of the zone
    assert abs(steered_phase_gradient(PATROL, g, small, n)) < 0.03 * small
    big = curv * (20 * zone_m) / metres_per_rad
    left = steered_phase_gradient(PATROL, g, big, n)
    assert big - left == pytest.approx(curv * zone_m / metres_per_rad, rel=1e-6)
    off = dataclasses.replace(g, speed_authority_m_s=0.0)
    assert steered_phase_gradient(PATROL, off, small, n) == small


def test_once_formed_the_steering_takes_out_at_most_its_limit():
    g = Gains()
    n = 3
    curv = splay_curvature_m2_s(PATROL, g, n)
    metres_per_rad = PATROL.length_m / TWO_PI
    limit_m = 16.0
    # a member left: a third of a slot (the loop / 3 / 3) to take out
    big = curv * (PATROL.length_m / 9) / metres_per_rad
    capped = steered_phase_gradient(PATROL, g, big, n, limit_m)
    assert 0.0 < capped * metres_per_rad / curv <= limit_m
    assert capped * metres_per_rad / curv == pytest.approx(limit_m, rel=0.01)  # saturated
    assert steered_phase_gradient(PATROL, g, -big, n, limit_m) == pytest.approx(-capped)
    # the unbounded law leaves the steering nearly all of it (the acquisition)
    assert steered_phase_gradient(PATROL, g, big, n) > 10 * capped
    # within the airspeed's reach the limit changes next to nothing
    small = curv * 8.0 / metres_per_rad
    assert steered_phase_gradient(PATROL, g, small, n, limit_m) == pytest.approx(
        steered_phase_gradient(PATROL, g, small, n), rel=0.01, abs=1e-9
    )
    assert steered_phase_gradient(PATROL, g, big, n, 0.0) == 0.0


@pytest.mark.parametrize("n", [2, 3, 6])
def test_slot_error_is_the_along_loop_distance_from_the_splay_slot(n):
    # the others a perfect splay apart; this UAV moved by a known distance from its slot
    g = Gains()
    slot = np.arange(n) * TWO_PI / n + 0.7
    got = {}
    for metres in (-40.0, -12.0, -5.0, 0.0, 5.0, 12.0, 40.0):
        own = slot[0] + metres / PATROL.length_m * TWO_PI
        got[metres] = splay_slot_error_m(PATROL, g, float(own), list(slot[1:]))
        if abs(metres) <= 12.0:  # near the splay: the distance itself
            assert got[metres] == pytest.approx(metres, rel=0.02, abs=0.05)
    # farther, the potential's harmonics bend it, but it still grows with the distance
    assert got[40.0] > got[12.0] and got[-40.0] < got[-12.0]
    assert got[40.0] == pytest.approx(40.0, rel=0.1)
    assert splay_slot_error_m(PATROL, g, 1.0, []) == 0.0


def test_phase_of_point_is_where_along_the_loop_not_the_course():
    for ph in np.linspace(0.05, TWO_PI - 0.05, 17):
        p = complex(PATROL.point_at_phase(ph))
        assert PATROL.phase_of_point(p) == pytest.approx(ph, abs=1e-6)
        normal = 1j * np.exp(1j * float(PATROL.course_at_phase(ph)))
        assert PATROL.phase_of_point(p + 30.0 * normal) == pytest.approx(ph, abs=1e-6)


def test_neighbours_read_phases_from_positions_of_members_on_patrol():
    nb = Neighbours(sysid=1, member_timeout_s=3.0)
    on_loop = complex(PATROL.point_at_phase(2.0))
    nb.hear(MemberState(2, 100.0, PATROL.centre_m, 2.5, "patrol", pos_m=on_loop), 100.0)
    nb.hear(MemberState(3, 100.0, PATROL.centre_m, 4.0, "prosecuting", "a1", pos_m=0j), 100.0)
    nb.hear(MemberState(4, 100.0, PATROL.centre_m, 5.0, "patrol"), 100.0)  # no position
    got = nb.positions_phases(101.0, PATROL)
    adv = TWO_PI / PATROL.period_s
    assert got[0] == pytest.approx(2.0 + adv, abs=1e-6)  # its position, not its 2.5
    assert got[1] == pytest.approx(4.0 + adv, abs=1e-9)  # away: its virtual particle
    assert got[2] == pytest.approx(5.0 + adv, abs=1e-9)


def test_the_steering_reads_positions_on_the_loop_and_courses_far_from_it():
    from companion.agent.neighbours import ON_LOOP_M

    nb = Neighbours(sysid=1, member_timeout_s=3.0)
    on_loop = complex(PATROL.point_at_phase(2.0))
    pt = complex(PATROL.point_at_phase(3.0))
    near = PATROL.nearest(pt)
    # a point ON_LOOP_M off the loop, on the normal at the phase-3.0 point (outside)
    normal = complex(np.exp(1j * (near.course_rad + np.pi / 2)))
    off = pt + ON_LOOP_M * normal
    far = pt + 5 * ON_LOOP_M * normal
    nb.hear(MemberState(2, 100.0, PATROL.centre_m, 2.5, "patrol", pos_m=on_loop), 100.0)
    nb.hear(MemberState(3, 100.0, PATROL.centre_m, 3.5, "patrol", pos_m=off), 100.0)
    nb.hear(MemberState(4, 100.0, PATROL.centre_m, 1.0, "patrol", pos_m=far), 100.0)
    got = [p for p, _ in nb.steering_phases(100.0, PATROL)]
    assert got[0] == pytest.approx(2.0, abs=1e-3)  # on the loop: where it is
    d = PATROL.phase_and_offset_of_point(off)
    assert d[1] == pytest.approx(ON_LOOP_M, rel=0.05)
    w = math.exp(-((d[1] / ON_LOOP_M) ** 2))  # about e^-1 of the way to its position
    assert got[1] == pytest.approx(3.5 + w * (d[0] - 3.5), abs=1e-6)
    assert got[2] == pytest.approx(1.0, abs=1e-6)  # far off: its course phase (acquiring)


@pytest.mark.parametrize(
    ("key", "value"), [("speed_authority_m_s", -1.0), ("speed_tau_s", 0.5), ("speed_tau_s", 1e9)]
)
def test_bad_speed_gains_are_refused(key, value):
    with pytest.raises(ValueError, match=key):
        Gains(**{key: value})


def _circle_patrol(radius_m: float, airspeed_m_s: float):
    from companion.core.loops import circle
    from companion.core.patrol import Patrol
    from companion.core.wind import Wind

    return Patrol.build(circle(0j, radius_m), airspeed_m_s, Wind(0.0, 0.0))


@pytest.mark.parametrize(("n", "factor"), [(2, 2.0), (3, math.sqrt(3.0)), (4, 2.0), (6, 2.0)])
def test_slot_shift_per_wind_on_a_circle_in_still_air_is_first_order_kinematics(n, factor):
    # On a circle of radius R flown at s0 in a small wind w, the ground speed at course g is
    # s0 + w cos(g - a) to first order, so the time along the loop is
    # (R / s0) (g - (w / s0) sin(g - a)) + const; between two points the time-phase changes
    # by (w / s0) (sin(g_k - a) - sin(g_0 - a)), whose largest size over the wind's
    # direction a and the members k is (w / s0) max|e^{i g_k} - e^{i g_0}|: 2 for an even
    # count (opposite points), sqrt(3) for three. As a slot shift (x R), per m/s:
    # factor R / s0.
    from companion.guidance.formation import slot_shift_per_wind_s

    radius, s0 = 500.0, 20.0
    patrol = _circle_patrol(radius, s0)
    assert slot_shift_per_wind_s(patrol, n) == pytest.approx(factor * radius / s0, rel=0.02)
    assert slot_shift_per_wind_s(patrol, 1) == 0.0


def test_the_fleets_wind_moves_no_faster_than_the_airspeed_moves_the_slots():
    from companion.guidance.formation import slot_shift_per_wind_s, wind_rate_limit_m_s2

    patrol = _circle_patrol(500.0, 20.0)
    g = Gains()
    rate = wind_rate_limit_m_s2(patrol, g, 4)
    assert rate == pytest.approx(g.speed_authority_m_s / slot_shift_per_wind_s(patrol, 4))
    assert rate == pytest.approx(2.0 / 50.0, rel=0.02)  # 2 m/s over 2 R / s0 = 50 s
    assert wind_rate_limit_m_s2(patrol, dataclasses.replace(g, speed_authority_m_s=0.0), 4) == 0
    assert wind_rate_limit_m_s2(patrol, dataclasses.replace(g, centre_form="mean"), 4) == 0
    # the paper's two cases: WPAFB's slots move 20 times more per m/s of wind than the ellipse's
    wpafb = load_mission("missions/wpafb_4uav.yaml")
    s_e = slot_shift_per_wind_s(PATROL, MISSION.vehicles.count)
    s_w = slot_shift_per_wind_s(wpafb.patrol, wpafb.vehicles.count)
    assert 15 < s_e < 30 and 300 < s_w < 600, (s_e, s_w)
