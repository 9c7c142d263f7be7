"""The multiple-model track against truths generated here by plain kinematics (issue 47):
a straight drive, a truck turning 90 deg at 10 m/s, a walker that stops; a short sighting's
velocity honest for a vehicle; a prediction that grows for a manoeuvre; fusion that does not
count one track twice; bad tracks refused."""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

from companion.agent.alerts.fusion import fuse
from companion.agent.alerts.motion import MotionFilter
from companion.agent.alerts.record import AlertRecord
from companion.agent.alerts.track import CvFit, TrackFit, track_refusal
from companion.group.messages import Alert, Track

RATE_HZ = 5.0
SIGMA_M = 3.0


def truck_turning(t: float, t_turn: float = 4.0, speed: float = 10.0, rate: float = 0.2):
    """A truck north at ``speed`` m/s, turning right (towards east) at ``rate`` rad/s from
    ``t_turn`` s for 90 deg, then east: its position (complex m), by kinematics."""
    dur = (math.pi / 2) / rate
    if t <= t_turn:
        return complex(speed * t, 0.0)
    p_turn = complex(speed * t_turn, 0.0)
    r = speed / rate
    tau = min(t - t_turn, dur)
    # centre of the turn is r to the east of the turn's start; the truck goes round it
    ang = rate * tau
    p = p_turn + complex(r * math.sin(ang), r * (1 - math.cos(ang)))
    return p + complex(0.0, speed) * max(0.0, t - t_turn - dur)


def noisy(rng, truth, t0: float, t1: float):
    """5 Hz sightings of ``truth(t)`` with SIGMA_M noise per axis."""
    n = round((t1 - t0) * RATE_HZ) + 1
    for k in range(n):
        t = t0 + k / RATE_HZ
        yield t, truth(t) + complex(*rng.normal(0.0, SIGMA_M, 2))


def test_the_truck_geometry_turns_ninety_degrees_at_ten_metres_a_second():
    v_before = (truck_turning(3.9) - truck_turning(3.8)) / 0.1
    v_after = (truck_turning(20.1) - truck_turning(20.0)) / 0.1
    assert abs(abs(v_before) - 10.0) < 1e-6 and abs(abs(v_after) - 10.0) < 1e-6
    assert abs(cmath.phase(v_after) - math.pi / 2) < 1e-6


def test_a_straight_drive_is_the_constant_velocity_model_and_within_its_sigmas():
    rng = np.random.default_rng(1)
    z, probs = [], []
    for _ in range(60):
        f = MotionFilter(SIGMA_M)
        v = 8.0 * cmath.exp(1j * rng.uniform(0, 2 * math.pi))
        for t, p in noisy(rng, lambda t, v=v: v * t, 0.0, 6.0):
            f.add(t, p)
        tr = f.track()
        assert tr is not None
        z.append(abs(tr.pos_m - v * tr.t_s) / tr.pos_sigma_m)
        probs.append(f.probabilities()["cv"])
    assert np.mean(np.array(z) < 3.0 * math.sqrt(2)) > 0.95
    assert np.median(probs) > 0.5


def test_a_truck_turning_ninety_degrees_is_followed_by_the_turn_model():
    rng = np.random.default_rng(2)
    err_imm, err_cv, turn_won, rates = [], [], 0, []
    for _ in range(40):
        imm, cv = MotionFilter(SIGMA_M), CvFit(SIGMA_M)
        for t, p in noisy(rng, truck_turning, 0.0, 9.0):  # 4 s straight, 5 s into the turn
            imm.add(t, p)
            cv.add(t, p)
        a, b = imm.track(), cv.track()
        assert a is not None and b is not None
        truth = truck_turning(a.t_s)
        err_imm.append(abs(a.pos_m - truth))
        err_cv.append(abs(b.pos_m - truth))
        turn_won += a.model == "turn"
        rates.append(a.turn_rad_s)
        # one second on: the turn model's prediction against the truth
        assert (
            abs(a.predict(a.t_s + 1.0) - truck_turning(a.t_s + 1.0))
            < 3.0 * a.sigma_m(a.t_s + 1.0) + 3.0
        )
    assert turn_won >= 30  # the turn model in use in most trials
    assert abs(np.median(rates) - 0.2) < 0.05  # its rate near the truth's 0.2 rad/s
    assert np.median(err_imm) < 0.5 * np.median(err_cv)  # the straight fit lags the turn


def test_a_walker_that_stops_is_the_stop_model_with_no_speed():
    rng = np.random.default_rng(3)
    stopped, speeds = 0, []
    for _ in range(40):
        f = MotionFilter(SIGMA_M)

        def walker(t: float) -> complex:
            return complex(1.5 * min(t, 10.0), 0.0)  # walks 10 s, then stands still

        for t, p in noisy(rng, walker, 0.0, 30.0):
            f.add(t, p)
        tr = f.track()
        assert tr is not None
        stopped += tr.model == "stop"
        speeds.append(abs(tr.vel_m_s))
    assert stopped >= 30
    assert np.median(speeds) < 0.3


def test_two_sightings_of_a_vehicle_do_not_exclude_its_speed():
    rng = np.random.default_rng(4)
    inside = []
    for _ in range(200):
        v = 12.0 * cmath.exp(1j * rng.uniform(0, 2 * math.pi))
        f = TrackFit(SIGMA_M)
        for t, p in noisy(rng, lambda t, v=v: v * t, 0.0, 0.2):  # two sightings
            f.add(t, p)
        tr = f.track()
        assert tr is not None
        inside.append(abs(tr.vel_m_s - v) <= 3.0 * math.sqrt(2) * tr.vel_sigma_m_s)
    assert np.mean(inside) > 0.97


def test_a_prediction_grows_enough_to_hold_a_vehicle_that_turned_at_a_junction():
    # seen driving north at 10 m/s for 3 s; it turns 90 deg at a junction 10 s later; the
    # prediction 25 s after the sighting must hold it within three sigma
    rng = np.random.default_rng(5)
    held, held_old = [], []
    for _ in range(100):
        f = TrackFit(SIGMA_M)
        for t, p in noisy(rng, lambda t: complex(10.0 * t, 0.0), 0.0, 3.0):
            f.add(t, p)
        tr = f.track()
        assert tr is not None and tr.manoeuvre_m_s2 > 0.0
        side = rng.choice([-1.0, 1.0])
        truth = complex(130.0, 0.0) + side * 1j * 10.0 * 12.0  # 13 s north, 12 s east/west
        t_pred = 25.0
        held.append(abs(tr.predict(t_pred) - truth) <= 3.0 * tr.sigma_m(t_pred))
        old = Track(tr.t_s, tr.pos_m, tr.vel_m_s, tr.pos_sigma_m, tr.vel_sigma_m_s, 10)
        held_old.append(abs(old.predict(t_pred) - truth) <= 3.0 * old.sigma_m(t_pred))
    assert np.mean(held) == 1.0
    assert np.mean(held_old) < 0.5  # without the manoeuvre's growth it would be cleared


def _pass_track(rng, truth_pos: complex, truth_vel: complex, prior: Track | None) -> Track:
    f = TrackFit(SIGMA_M, prior=prior)
    t0 = prior.t_s + 20.0 if prior is not None else 0.0
    for t, p in noisy(rng, lambda t: truth_pos + truth_vel * t, t0, t0 + 4.0):
        f.add(t, p)
    tr = f.track()
    assert tr is not None
    return tr


def test_one_track_heard_twice_does_not_shrink_as_if_it_were_two():
    tr = Track(100.0, 50 + 20j, 1.0 + 0.5j, 2.0, 0.4, 21, manoeuvre_m_s2=0.3)
    twice = fuse(tr, tr)
    assert twice.pos_sigma_m == pytest.approx(tr.pos_sigma_m)
    assert twice.vel_sigma_m_s == pytest.approx(tr.vel_sigma_m_s)
    assert twice.pos_m == pytest.approx(tr.pos_m) and twice.sightings == tr.sightings
    # the information sum would claim sigma / sqrt(2): the fused track claims no such thing
    assert twice.pos_sigma_m > 1.3 * tr.pos_sigma_m / math.sqrt(2)
    # and relayed by a second member, stamped later by a fraction, the record does not shrink
    rec = AlertRecord(Alert("3-1", tr.pos_m, 3, tr.t_s, "new", track=tr))
    relayed = tr.at(tr.t_s + 0.01)
    assert rec.update_track(relayed)
    assert rec.track is not None and rec.track.pos_sigma_m >= 0.99 * tr.pos_sigma_m


def test_two_tracks_sharing_a_pass_fused_stay_as_honest_as_they_say():
    # members A and B each fit their own pass on top of the same first track (its sightings
    # shared): the naive information sum counts the first pass twice; the intersection must
    # keep the normalised errors within what it claims
    rng = np.random.default_rng(6)
    z_ci, z_naive = [], []
    for _ in range(300):
        p0, v = complex(*rng.uniform(-100, 100, 2)), complex(*rng.uniform(-1.5, 1.5, 2))
        first = _pass_track(rng, p0, v, None)
        a = _pass_track(rng, p0, v, first)
        b = _pass_track(rng, p0, v, first)
        f = fuse(a, b)
        truth = p0 + v * f.t_s
        z_ci.append(abs(f.pos_m - truth) / f.pos_sigma_m)
        pa, pb = a.pos_sigma_m**2, b.pos_sigma_m**2
        naive_p = 1.0 / (1.0 / pa + 1.0 / pb)
        naive = naive_p * (a.pos_m / pa + b.pos_m / pb)
        z_naive.append(abs(naive - truth) / math.sqrt(naive_p))
    # 2-D errors: |z|^2 averages 2 for an honest estimate
    assert np.mean(np.square(z_ci)) < 2.4
    assert np.mean(np.square(z_ci)) < np.mean(np.square(z_naive))


@pytest.mark.parametrize(
    ("field", "value", "why"),
    [
        ("model_p", 1.5, "model probability"),
        ("turn_rad_s", 5.0, "turn rate"),
        ("manoeuvre_m_s2", float("nan"), "non-finite"),
        ("manoeuvre_m_s2", -1.0, "manoeuvre"),
    ],
)
def test_a_track_with_a_bad_model_field_is_refused(field: str, value: float, why: str):
    from dataclasses import replace

    good = Track(100.0, 0j, 1.0 + 0j, 2.0, 0.5, 5, "turn", 0.7, 0.1, 1.0)
    assert track_refusal(good, 100.0, 120.0) is None
    assert why in (track_refusal(replace(good, **{field: value}), 100.0, 120.0) or "")


@pytest.mark.parametrize(
    "bad",
    [
        {"model_p": 2.0},
        {"turn_rad_s": float("inf")},
        {"manoeuvre_m_s2": 50.0},
    ],
    ids=["probability 2", "infinite turn", "manoeuvre 50"],
)
def test_an_agent_refuses_counts_and_never_flies_a_track_with_a_bad_model(bad: dict):
    from dataclasses import replace
    from pathlib import Path

    from companion.agent.agent import Agent
    from companion.agent.fix import Fix
    from companion.mission import load_mission

    mission = load_mission(Path(__file__).parent / "data" / "companion_ellipse_fast.yaml")
    agent = Agent(1, mission)
    site = complex(mission.patrol.point_at_phase(1.0))
    track = replace(Track(10.0, site, 1.0 + 0j, 2.0, 0.5, 5, "turn", 0.7, 0.1, 1.0), **bad)
    agent.receive_alert(Alert("2-1", site, 2, 10.0, "new", track=track), 10.0)
    assert "2-1" not in agent.alerts.records and agent.alerts.counts["bad_track"] == 1
    out = agent.update(Fix(10.1, site + 300, 0.0, agent.patrol))
    refused = [e for e in out.typed_events if e.name == "alert_refused"]
    assert refused and refused[0].reason == "track" and out.mode == "patrol"
