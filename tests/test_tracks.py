"""Tracks, not points (issue 21): the estimate from noisy sightings against the truth, its
fusion over passes, and the bad tracks an Agent refuses and counts but never flies.

The estimate is checked against the truth it was made from, over many seeded trials: its
errors must be as large as its own sigmas say (normalised errors of unit spread), and two
passes twenty seconds apart must beat one pass. No formula of the fit is repeated here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.agent.agent import Agent
from companion.agent.alerts.track import MAX_INTRUDER_SPEED_M_S, TrackFit, track_refusal
from companion.agent.fix import Fix
from companion.group.messages import Alert, Track
from companion.mission import load_mission

MISSION = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
RATE_HZ = 5.0  # the camera's reports
SIGMA_M = 3.0  # the sightings' error per axis


def sightings(rng, p0: complex, v: complex, t0: float, span_s: float, sigma_m: float = SIGMA_M):
    """Noisy sightings at 5 Hz of an intruder at ``p0`` at ``t0`` moving at ``v``."""
    n = int(span_s * RATE_HZ) + 1
    for k in range(n):
        t = t0 + k / RATE_HZ
        noise = complex(*rng.normal(0.0, sigma_m, 2))
        yield t, p0 + v * (t - t0) + noise


def truth_errors(trials: int, span_s: float, speed_m_s: float, seed: int = 1):
    """Normalised errors (error / own sigma) of position and velocity over ``trials``."""
    rng = np.random.default_rng(seed)
    zp, zv, ev = [], [], []
    for _ in range(trials):
        p0 = complex(*rng.uniform(-500, 500, 2))
        v = speed_m_s * complex(math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a))
        fit = TrackFit(SIGMA_M)
        for t, p in sightings(rng, p0, v, 100.0, span_s):
            fit.add(t, p)
        tr = fit.track()
        truth_now = p0 + v * (tr.t_s - 100.0)
        zp += [
            (tr.pos_m - truth_now).real / tr.pos_sigma_m,
            (tr.pos_m - truth_now).imag / tr.pos_sigma_m,
        ]
        zv += [(tr.vel_m_s - v).real / tr.vel_sigma_m_s, (tr.vel_m_s - v).imag / tr.vel_sigma_m_s]
        ev.append(abs(tr.vel_m_s - v))
    return np.array(zp), np.array(zv), np.array(ev)


def test_a_pass_of_noisy_sightings_of_a_still_intruder_gives_errors_its_sigmas_promise():
    zp, zv, _ = truth_errors(400, span_s=4.0, speed_m_s=0.0)
    assert 0.85 < np.std(zp) < 1.15
    assert np.std(zv) < 1.15  # the prior pulls towards still: errors no larger than promised


def test_a_walker_seen_for_one_pass_is_within_its_promised_error():
    zp, zv, ev = truth_errors(400, span_s=4.0, speed_m_s=1.56)
    assert np.mean(np.abs(zp) < 3.0) > 0.97 and np.mean(np.abs(zv) < 3.0) > 0.97
    assert np.median(ev) < 2.0  # a 4 s pass gives the walker's velocity to about a m/s


def test_two_passes_twenty_seconds_apart_know_the_velocity_far_better_than_one():
    rng = np.random.default_rng(7)
    one, two = [], []
    for _ in range(200):
        p0, v = complex(*rng.uniform(-500, 500, 2)), complex(*rng.uniform(-2, 2, 2))
        first = TrackFit(SIGMA_M)
        for t, p in sightings(rng, p0, v, 100.0, 4.0):
            first.add(t, p)
        tr1 = first.track()
        second = TrackFit(SIGMA_M, prior=tr1)
        for t, p in sightings(rng, p0 + v * 20.0, v, 120.0, 4.0):
            second.add(t, p)
        tr2 = second.track()
        one.append(abs(tr1.vel_m_s - v))
        two.append(abs(tr2.vel_m_s - v))
        assert tr2.sightings == 2 * 21 and tr2.vel_sigma_m_s < tr1.vel_sigma_m_s
    assert np.median(two) < 0.3 * np.median(one)


def test_the_prediction_moves_with_the_velocity_and_its_sigma_grows():
    tr = Track(10.0, 100 + 0j, 1.0 + 2.0j, 3.0, 0.5, 10)
    assert tr.predict(20.0) == 110 + 20j
    assert tr.sigma_m(10.0) == pytest.approx(3.0)
    assert tr.sigma_m(18.0) == pytest.approx(5.0)  # hypot(3, 0.5 * 8)


NAN = float("nan")


@pytest.mark.parametrize(
    ("track", "why"),
    [
        (Track(100.0, 0j, complex(NAN, 0.0), 2.0, 0.5, 5), "non-finite"),
        (Track(100.0, 0j, complex(float("inf"), 0.0), 2.0, 0.5, 5), "non-finite"),
        (Track(100.0, 0j, 61.0 + 0j, 2.0, 0.5, 5), f"{MAX_INTRUDER_SPEED_M_S:.0f} m/s"),
        (Track(100.0, 0j, 1.0 + 0j, -2.0, 0.5, 5), "negative"),
        (Track(-100.0, 0j, 1.0 + 0j, 2.0, 0.5, 5), "old"),
    ],
)
def test_a_bad_track_is_refused_with_its_reason(track: Track, why: str):
    assert why in (track_refusal(track, 100.0, max_age_s=120.0) or "")
    assert track_refusal(Track(100.0, 0j, 1.0 + 0j, 2.0, 0.5, 5), 100.0, 120.0) is None


@pytest.mark.parametrize(
    "velocity",
    [complex(NAN, 0.0), complex(0.0, float("inf")), 75.0 + 0j],
    ids=["nan", "inf", "75 m/s"],
)
def test_an_agent_refuses_counts_and_never_flies_a_bad_track(velocity: complex):
    agent = Agent(1, MISSION)
    site = complex(MISSION.patrol.point_at_phase(1.0))
    bad = Alert("2-1", site, 2, 10.0, "new", track=Track(10.0, site, velocity, 2.0, 0.5, 5))
    agent.receive_alert(bad, 10.0)
    assert "2-1" not in agent.alerts.records and agent.alerts.counts["bad_track"] == 1
    out = agent.update(Fix(10.1, site + 300, 0.0, agent.patrol))
    refused = [e for e in out.typed_events if e.name == "alert_refused"]
    assert refused and refused[0].reason == "track"
    assert out.mode == "patrol"


def test_an_agent_refuses_a_track_older_than_its_time_out():
    agent = Agent(1, MISSION)
    site = complex(MISSION.patrol.point_at_phase(1.0))
    old = Alert("2-1", site, 2, 10.0, "new", track=Track(10.0, site, 1.0 + 0j, 2.0, 0.5, 5))
    agent.receive_alert(old, 10.0 + 121.0)
    assert "2-1" not in agent.alerts.records and agent.alerts.counts["bad_track"] == 1


def test_a_short_pass_of_a_vehicle_is_not_pulled_towards_still():
    # a 10 m/s vehicle seen for 1.2 s at the footprint's edge (6 sightings, generated
    # mission 72): the estimate must keep most of the speed and stay within its own sigmas
    _, zv, ev = truth_errors(400, span_s=1.0, speed_m_s=10.0, seed=3)
    assert np.mean(np.abs(zv) < 3.0) > 0.97  # honest: errors as large as promised
    assert np.median(ev) < 4.0  # a walker's 3 m/s prior read such a pass as about 4 m/s
    rng = np.random.default_rng(4)
    speeds = []
    for _ in range(200):
        fit = TrackFit(SIGMA_M)
        for t, p in sightings(rng, 0j, 10.0 + 0j, 0.0, 1.0):
            fit.add(t, p)
        speeds.append(fit.track().vel_m_s.real)
    assert np.median(speeds) > 8.0  # about 0.9 of the truth; 0.4 under the narrow prior


def test_a_vehicle_passing_a_walker_under_one_sensor_gives_two_contacts_and_two_tracks():
    # generated mission 71: a 8.4 m/s vehicle drove past a walker 40-50 m away while both
    # were under one UAV's sensor; one contact held both and averaged them to 4.8 m/s
    from companion.agent.alerts.contacts import Contacts

    rng = np.random.default_rng(5)
    contacts = Contacts(gate_m=50.0)  # 2 r_s of a 25 m footprint
    vehicle = (complex(614.0, 190.0), complex(0.0, 8.4))
    walker = (complex(598.0, 156.0), complex(1.4, 0.0))
    for k in range(16):
        t = 100.0 + k / RATE_HZ
        for p0, v in (vehicle, walker) if k >= 4 else (vehicle,):
            site = p0 + v * (t - 100.0) + complex(*rng.normal(0.0, 1.0, 2))
            c = contacts.find(t, site)
            if c is None:
                c = contacts.open(t, site, None)
                c.alert_id = f"a{len(contacts.items)}"
            else:
                contacts.see(c, t, site)
    assert len(contacts.items) == 2
    fast, slow = sorted(contacts.items, key=lambda c: -abs(c.track().vel_m_s))
    assert abs(fast.track().vel_m_s - vehicle[1]) < 3.0 * fast.track().vel_sigma_m_s + 0.5
    assert abs(slow.track().vel_m_s - walker[1]) < 3.0 * slow.track().vel_sigma_m_s + 0.5
    assert contacts.live_alerts(103.0) == {"a1", "a2"}
    assert contacts.live_alerts(110.0) == set()  # both out of the footprint
