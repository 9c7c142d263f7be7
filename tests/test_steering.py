"""Steering law: gradient against finite differences, Lyapunov decrease, the paper's case.

The paper's cases are flown by the guidance-level particle fleet (``tests/particle_fleet.py``:
exact particles, a perfect group), which isolates the law; the real stack's convergence is
checked in memory by ``tests/test_inmemory.py`` and ``tests/test_simulate_cli.py``.
"""

import dataclasses

import numpy as np
import pytest

from companion.core.loops import EllipseLoop
from companion.core.measures import centre_error_m, convergence_time_s, splay_error_deg
from companion.core.particle import ParticleParams, ParticleState, step
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, Wind, heading_from_course
from companion.guidance.steering import (
    Gains,
    lyapunov,
    phase_gains_m2_s,
    reference_centre,
    splay_gradient,
    splay_potential,
    steering_turn_rate,
)
from companion.guidance.virtual import VirtualParticle
from companion.mission import load_mission
from tests.particle_fleet import FleetSimulation

PATROL = Patrol.build(EllipseLoop(0j, 400.0, 200.0, 0.0), 20.0, Wind.from_meteo(5.0, 180.0))


@pytest.mark.parametrize("n", [1, 2, 3, 6, 9, 32, 100])  # from 32: the pair table
def test_splay_gradient_is_the_derivative_of_the_potential(n):
    rng = np.random.default_rng(n)
    k_m = phase_gains_m2_s(PATROL, Gains(), n)
    psi = rng.uniform(0, TWO_PI, n)
    h = 1e-6
    for k in range(n):
        up, down = psi.copy(), psi.copy()
        up[k] += h
        down[k] -= h
        fd = (splay_potential(up, k_m) - splay_potential(down, k_m)) / (2 * h)
        assert splay_gradient(psi[k], psi, k_m) == pytest.approx(fd, rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("n", [32, 64, 257, 1000])
@pytest.mark.parametrize("gains", ["splay", "random"])
def test_the_pair_table_is_the_sum_over_harmonics(n, gains):
    """From 32 members the gradient is read from a table of one pair function (O(N) a
    member); against the definition summed here harmonic by harmonic (sines of the phase
    differences, no exponentials), for any gains, not only the splay's."""
    rng = np.random.default_rng(n)
    if gains == "splay":
        k_m = phase_gains_m2_s(PATROL, Gains(), n)
    else:
        k_m = rng.normal(0.0, 50.0, n)
    psi = rng.uniform(-10.0, 10.0, n)  # any phases, not only [0, 2 pi)
    steered = psi[rng.choice(n, 5, replace=False)]
    m = np.arange(1, n + 1)
    want = np.array([
        -sum(k_m[i] / m[i] * np.sin(m[i] * (pk - psi)).sum() for i in range(n)) / n
        for pk in steered
    ])  # fmt: skip
    got = splay_gradient(steered, psi, k_m)
    assert got.shape == (5,)
    scale = np.abs(k_m).max()
    assert np.allclose(got, want, rtol=0.0, atol=1e-8 * scale), np.abs(got - want).max() / scale
    one = splay_gradient(steered[0], psi, k_m)
    assert np.shape(one) == () and float(one) == pytest.approx(want[0], abs=1e-8 * scale)


def test_splay_is_a_critical_point_and_the_minimum():
    for big in (48, 100):  # the pair table, every member's gradient at once
        k_big = phase_gains_m2_s(PATROL, Gains(), big)
        even = np.arange(big) * TWO_PI / big + 0.4
        assert np.allclose(splay_gradient(even, even, k_big), 0.0, atol=1e-9)
    n = 6
    k_m = phase_gains_m2_s(PATROL, Gains(), n)
    splay = np.arange(n) * TWO_PI / n + 0.4
    assert np.allclose(splay_gradient(splay, splay, k_m), 0.0, atol=1e-9)
    rng = np.random.default_rng(0)
    u_splay = splay_potential(splay, k_m)
    for _ in range(200):
        assert splay_potential(rng.uniform(0, TWO_PI, n), k_m) > u_splay - 1e-9


def unsaturated_start(n, rng, spread_m=15.0):
    """UAVs near the loop, on its tangent, with random phases (so u stays far from the limit)."""
    psi = rng.uniform(0, TWO_PI, n)
    pts = PATROL.point_at_phase(psi) + spread_m * (rng.normal(size=n) + 1j * rng.normal(size=n))
    heading = heading_from_course(20.0, PATROL.course_at_phase(psi), PATROL.wind)
    return ParticleState.at(pts.real, pts.imag, heading + rng.normal(0, 0.05, n))


@pytest.mark.parametrize("form", ["fixed", "mean"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_lyapunov_function_does_not_increase(form, seed):
    """The paper's law (without the cross-track hold the product adds): V never increases."""
    rng = np.random.default_rng(seed)
    gains = Gains(centre_form=form, xtrack_bw_rad_s=0.0)
    n = 5
    st = unsaturated_start(n, rng)
    params = ParticleParams(20.0, 10.0)  # a limit that never binds: the unsaturated law
    k_m = phase_gains_m2_s(PATROL, gains, n)
    dt = 0.01
    values = [lyapunov(PATROL, gains, st.pos_m, st.heading_rad)]
    for _ in range(3000):
        c, psi = PATROL.centre_and_phase(st.pos_m, st.heading_rad)
        grad = splay_gradient(psi, psi, k_m)
        c_ref = reference_centre(PATROL, gains, c)
        u = np.array(
            [
                steering_turn_rate(PATROL, gains, complex(p), float(h), float(g), c_ref, 10.0)
                for p, h, g in zip(st.pos_m, st.heading_rad, grad, strict=True)
            ]
        )
        assert np.all(np.abs(u) < 10.0)
        st = step(st, u, params, PATROL.wind.vector, dt)
        values.append(lyapunov(PATROL, gains, st.pos_m, st.heading_rad))
    v = np.array(values)
    # sampled-data control: allow only round-off-sized increases per step
    assert np.all(np.diff(v) <= 1e-6 * v[0])
    assert v[-1] < 0.9 * v[0]


def test_saturation_is_respected():
    u = steering_turn_rate(PATROL, Gains(), 5000 + 0j, 0.0, 0.0, PATROL.centre_m, 0.2)
    assert abs(float(u)) == pytest.approx(0.2)


def test_virtual_particle_flies_the_loop_at_the_nominal_rate():
    vp = VirtualParticle(phase0_rad=1.0, t0_s=50.0, period_s=PATROL.period_s)
    assert vp.phase(50.0 + PATROL.period_s / 4) == pytest.approx(1.0 + TWO_PI / 4)
    assert PATROL.nearest(vp.position_m(PATROL, 80.0)).distance_m < 1e-4


def paper_mission():
    return load_mission("missions/ellipse_6uav.yaml")


def test_paper_ellipse_case_converges_within_eight_loop_periods():
    mission = dataclasses.replace(paper_mission(), intruders=())  # the patrol alone
    # the companions' 10 Hz: tight convergence at 129.1 s, against 129.0 s at 0.05 s steps
    # (2026-12-02), in half the time
    sim = FleetSimulation(mission, dt_s=0.1)
    series = sim.run(8 * mission.patrol.period_s)
    t = np.array(series.t_s)
    # splay error < 1 deg and centre error < 1 m reached, and held, within 8 loop periods
    tight = convergence_time_s(t, series.splay_deg, series.centre_m, 1.0, 1.0)
    assert tight is not None and tight < 8 * mission.patrol.period_s
    assert series.convergence_time_s() < 6 * mission.patrol.period_s


def test_mean_centre_form_agrees_on_centres_but_not_on_the_base():
    mission = paper_mission()
    mean = dataclasses.replace(mission, gains=Gains(centre_form="mean"))
    sim = FleetSimulation(mean, dt_s=0.1)
    sim.run(6 * mission.patrol.period_s)
    c, psi = mission.patrol.centre_and_phase(sim.state.pos_m, sim.state.heading_rad)
    assert centre_error_m(c, complex(np.mean(c))) < 2.0  # the centres agree with each other
    assert splay_error_deg(psi) < 2.0


@pytest.mark.extended
def test_wpafb_case_converges():
    """Case V.B: seven landmarks, 50 km edges, 10 m/s wind; the formation settles too.

    Judged from the true positions (where each aircraft is, and where along the loop): the
    course-based centre is ill-conditioned on 50 km edges (1 deg of course is 35 m of
    centre at R = 2000 m), and with the cross-track hold and the airspeed holding the phase
    it read 50-170 m while the aircraft flew within 1 m of the loop (measured)."""
    mission = dataclasses.replace(load_mission("missions/wpafb_4uav.yaml"), intruders=())
    patrol, n = mission.patrol, mission.vehicles.count
    sim = FleetSimulation(mission, dt_s=0.1)
    samples: list[tuple[float, float, float]] = []

    def on_truth(rows) -> None:
        t = rows[0][0]
        if t < 1.6 * patrol.period_s or round(t * 10) % 100:
            return  # from 1.6 periods on, every 10 s
        pos = [r[2] + 1j * r[3] for r in rows]
        off = max(patrol.nearest(p).distance_m for p in pos)
        phases = np.sort([patrol.phase_of_point(p) for p in pos])
        gaps = np.diff(np.r_[phases, phases[0] + TWO_PI]) / (TWO_PI / n)
        samples.append((t, off, float(np.max(np.abs(gaps - 1.0)))))

    sim.run(2.4 * patrol.period_s, on_truth=on_truth)  # converged by about 1000 s (0.8 T)
    _, off, gap = np.array(samples).T
    assert np.percentile(off, 95) < 5.0 and off.max() < 15.0  # m from the 24.7 km loop
    assert gap.max() < 0.01  # slots within 1 % of T/N (3.8 s of 383 s)
