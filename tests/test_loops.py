"""Loop geometry and time-phase tables against independent quadrature and geometry."""

import numpy as np
import pytest
from scipy.integrate import quad

from companion.core.loops import EllipseLoop, LoopError, circle, rounded_hull
from companion.core.particle import ParticleParams, ParticleState, step
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, Wind, groundspeed_from_course, heading_from_course

SOUTH5 = Wind.from_meteo(5.0, 180.0)
PAPER_ELLIPSE = EllipseLoop(0j, 400.0, 200.0, 0.0)
HEPTAGON = np.array(
    [
        -2065 - 4331j,
        867 - 2997j,
        3220 - 1541j,
        3964 + 2217j,
        2321 + 3476j,
        -2332 + 1542j,
        -2498 - 257j,
    ]
)


def parametric_ellipse(a, b, chi, c0):
    """Independent description: P(t) = c0 + e^{i chi}(a cos t - i b sin t), clockwise on the map."""

    def point(t):
        return c0 + np.exp(1j * chi) * (a * np.cos(t) - 1j * b * np.sin(t))

    def velocity(t):
        return np.exp(1j * chi) * (-a * np.sin(t) - 1j * b * np.cos(t))

    return point, velocity


def test_paper_reference_numbers():
    p = Patrol.build(PAPER_ELLIPSE, 20.0, SOUTH5)
    assert p.length_m == pytest.approx(1937.7, abs=0.05)
    assert p.period_s == pytest.approx(102.49, abs=0.005)
    assert p.period_s / 6 == pytest.approx(17.08, abs=0.005)
    still = Patrol.build(PAPER_ELLIPSE, 20.0, Wind.calm())
    assert still.period_s == pytest.approx(96.88, abs=0.005)


@pytest.mark.parametrize(
    "a,b,chi,c0,wind",
    [
        (400, 200, 0.0, 0j, SOUTH5),
        (300, 700, 0.6, 120 - 80j, Wind.from_meteo(8.0, 40.0)),
        (1500, 900, -1.1, -3000 + 500j, Wind.from_meteo(12.0, 300.0)),
    ],
)
def test_ellipse_length_and_period_against_parametric_quadrature(a, b, chi, c0, wind):
    loop = EllipseLoop(c0, a, b, chi)
    p = Patrol.build(loop, 20.0, wind)
    _, vel = parametric_ellipse(a, b, chi, c0)
    length = quad(lambda t: abs(vel(t)), 0, TWO_PI, limit=200)[0]
    period = quad(
        lambda t: abs(vel(t)) / groundspeed_from_course(20.0, np.angle(vel(t)), wind),
        0,
        TWO_PI,
        limit=200,
    )[0]
    assert p.length_m == pytest.approx(length, rel=1e-9)
    assert p.period_s == pytest.approx(period, rel=1e-7)


def test_ellipse_points_lie_on_the_ellipse_with_the_right_tangent():
    loop = EllipseLoop(50 + 20j, 300.0, 120.0, 0.4)
    g = np.linspace(0, TWO_PI, 721)
    z = (loop.offset(g)) * np.exp(-1j * 0.4)  # into the ellipse's own axes
    assert np.allclose((z.real / 300.0) ** 2 + (z.imag / 120.0) ** 2, 1.0, atol=1e-12)
    h = 1e-6
    d = (loop.offset(g + h) - loop.offset(g - h)) / (2 * h)
    assert np.allclose(np.angle(d * np.exp(-1j * g)), 0.0, atol=1e-6)  # tangent course is g
    assert np.allclose(np.abs(d), loop.radius(g), rtol=1e-6)  # |d rho / d gamma| = R


@pytest.mark.parametrize("loop", [PAPER_ELLIPSE, rounded_hull(HEPTAGON, 300.0)])
def test_closure_and_positive_curvature(loop):
    g = np.linspace(0, TWO_PI, 4001)
    assert np.all(loop.radius(g) > 0)
    assert abs(loop.offset(0.0) - loop.offset(TWO_PI)) < 1e-9
    joints = [b for b in loop.breakpoints_rad if 0 < b < TWO_PI] or None
    re = quad(lambda x: loop.radius(x) * np.cos(x), 0, TWO_PI, limit=400, points=joints)[0]
    im = quad(lambda x: loop.radius(x) * np.sin(x), 0, TWO_PI, limit=400, points=joints)[0]
    assert abs(complex(re, im)) < 1e-3 * loop.length_m()


def test_still_air_circle_period():
    p = Patrol.build(circle(10 + 10j, 250.0), 18.0, Wind.calm())
    assert p.period_s == pytest.approx(TWO_PI * 250.0 / 18.0, rel=1e-12)
    assert p.length_m == pytest.approx(TWO_PI * 250.0, rel=1e-12)


def test_rounded_hull_geometry():
    rc, r0 = 300.0, 50_000.0
    loop = rounded_hull(HEPTAGON, rc, r0)
    assert len(loop.vertices_m) == 7
    # length: each edge arc 2 R0 asin(L / 2 R0), plus the disc's perimeter 2 pi rc
    chords = np.abs(np.roll(loop.vertices_m, -1) - loop.vertices_m)
    expected = np.sum(2 * r0 * np.arcsin(chords / (2 * r0))) + TWO_PI * rc
    assert loop.length_m() == pytest.approx(expected, rel=1e-12)
    # every vertex is exactly rc from the loop, and the loop is never closer than rc to it
    pts = loop.centre_m + loop.offset(np.linspace(0, TWO_PI, 200_001))
    for v in loop.vertices_m:
        assert np.min(np.abs(pts - v)) == pytest.approx(rc, abs=0.05)
    # C1: the offset is continuous across every joint
    for g in loop.breakpoints_rad:
        assert abs(loop.offset(g - 1e-9) - loop.offset(g + 1e-9)) < 1e-3


def test_rounded_hull_drops_interior_points():
    square = np.array([0, 1000j, 1000 + 1000j, 1000, 500 + 500j, 200 + 300j])
    assert len(rounded_hull(square, 100.0).vertices_m) == 4


@pytest.mark.parametrize(
    "pts,match",
    [
        ([0, 100, 100], "at least 3 distinct"),
        ([0, 100 + 100j, 200 + 200j, 300 + 300j], "collinear"),
        ([0, 100, np.nan], "finite"),
    ],
)
def test_rounded_hull_rejects_degenerate_points(pts, match):
    with pytest.raises(LoopError, match=match):
        rounded_hull(np.array(pts, dtype=complex), 50.0)


@pytest.mark.parametrize("clockwise", [True, False])
@pytest.mark.parametrize(
    "shape,tol_m,tol_rad",
    [
        (EllipseLoop(30 - 20j, 600.0, 300.0, 0.2), 0.5, 2e-3),
        # holding u over a 10 ms step that straddles a corner/edge joint overshoots the
        # course by up to u dt; flown open loop along a 1-2 km edge that drifts a few metres
        (rounded_hull(HEPTAGON / 4, 250.0, 6000.0), 8.0, 2e-2),
    ],
)
def test_flying_the_required_turn_rate_stays_on_the_loop(clockwise, shape, tol_m, tol_rad):
    """Open loop: u = required turn rate keeps the particle on C with d psi/dt = 2 pi / T."""
    wind = Wind.from_meteo(10.0, 200.0)
    p = Patrol.build(shape, 20.0, wind, clockwise=clockwise)
    course = p.course_at_phase(0.3)
    st = ParticleState.at(
        p.point_at_phase(0.3).real,
        p.point_at_phase(0.3).imag,
        heading_from_course(20.0, course, wind),
    )
    params = ParticleParams(20.0, 1.0)
    dt = 0.01
    steps = int(p.period_s / 3 / dt)
    for _ in range(steps):
        _, psi = p.centre_and_phase(st.pos_m, st.heading_rad)
        g_c = p.course_after(psi * p.period_s / TWO_PI)
        u = p.sense * p.required_turn_rate(g_c)
        st = step(st, u, params, wind.vector, dt)
    assert p.nearest(complex(st.pos_m)).distance_m < tol_m
    _, psi = p.centre_and_phase(st.pos_m, st.heading_rad)
    assert np.angle(np.exp(1j * (psi - 0.3 - TWO_PI * steps * dt / p.period_s))) == pytest.approx(
        0, abs=tol_rad
    )


def test_time_phase_table_against_quadrature_and_inverse():
    wind = Wind.from_meteo(9.0, 75.0)
    loop = EllipseLoop(0j, 600.0, 250.0, 0.3)
    p = Patrol.build(loop, 20.0, wind)
    rng = np.random.default_rng(1)
    for g in rng.uniform(0, TWO_PI, 30):
        ref = quad(lambda x: loop.radius(x) / groundspeed_from_course(20.0, x, wind), 0, g)[0]
        assert p.time_along(g) == pytest.approx(ref, abs=1e-6)
    t = rng.uniform(0, p.period_s, 200)
    assert np.allclose(p.time_along(p.course_after(t)), t, atol=1e-6)


@pytest.mark.parametrize("clockwise", [True, False])
def test_nearest_point_against_brute_force(clockwise):
    p = Patrol.build(rounded_hull(HEPTAGON, 300.0), 20.0, SOUTH5, clockwise=clockwise)
    dense = p.point_at_phase(np.linspace(0, TWO_PI, 400_001))
    rng = np.random.default_rng(2)
    for q in rng.uniform(-6000, 6000, 20) + 1j * rng.uniform(-6000, 6000, 20):
        near = p.nearest(q)
        assert near.distance_m == pytest.approx(np.min(np.abs(dense - q)), abs=0.05)
        # the tangent there is perpendicular to the offset and points along the travel
        assert abs(np.cos(np.angle(q - near.point_m) - near.course_rad)) < 1e-4
        ahead = p.point_at_phase(near.phase_rad + 1e-4)
        assert np.cos(np.angle(ahead - near.point_m) - near.course_rad) > 0.999
        # Newton's nearest point (the control step's and the ground-station report's): the
        # same distance and phase as the scalar search, checked against the dense polyline
        phase, dist = p.phase_and_offset_of_point(q)
        assert dist == pytest.approx(np.min(np.abs(dense - q)), abs=0.05)
        assert dist == pytest.approx(near.distance_m, abs=1e-6)
        assert abs(np.remainder(phase - near.phase_rad + np.pi, TWO_PI) - np.pi) < 1e-6


def test_counter_clockwise_is_the_mirror_image():
    cw = Patrol.build(rounded_hull(HEPTAGON, 300.0), 20.0, Wind.from_meteo(10, 180))
    ccw = Patrol.build(rounded_hull(HEPTAGON, 300.0), 20.0, Wind.from_meteo(10, 180), False)
    assert ccw.length_m == pytest.approx(cw.length_m, rel=1e-12)
    # the same points are visited, in the opposite order
    a = cw.point_at_phase(np.linspace(0, TWO_PI, 50))
    b = ccw.point_at_phase(np.linspace(0, TWO_PI, 5000))
    assert max(np.min(np.abs(b - z)) for z in a) < 10.0
    assert (
        np.sin(
            np.angle(ccw.point_at_phase(0.1) - ccw.centre_m)
            - np.angle(ccw.point_at_phase(0.0) - ccw.centre_m)
        )
        < 0
    )


def test_max_required_turn_rate_of_the_paper_ellipse():
    p = Patrol.build(PAPER_ELLIPSE, 20.0, SOUTH5)
    assert np.degrees(p.max_required_turn_rate_rad_s()) == pytest.approx(11.74, abs=0.01)


def test_memoised_placement_and_re_timing_give_the_computed_values():
    p = Patrol.build(PAPER_ELLIPSE, 20.0, SOUTH5)
    rng = np.random.default_rng(5)
    points = [complex(n, e) for n, e in rng.uniform(-500.0, 500.0, (200, 2))]
    first = [p.nearest_canon(z) for z in points]  # more than the memo holds: evictions
    again = [p.nearest_canon(z) for z in points[::-1]][::-1]
    fresh = Patrol.build(PAPER_ELLIPSE, 20.0, SOUTH5)
    assert first == again == [fresh._nearest_canon(z) for z in points]
    assert p.nearest_canon(0j) == fresh._nearest_canon(0j)  # zeros are never keys
    w = Wind.from_meteo(6.0, 170.0)
    q = p.with_wind(w)
    assert p.with_wind(Wind.from_meteo(6.0, 170.0)) is q  # the same wind: shared tables
    assert np.array_equal(q._t, Patrol.build(PAPER_ELLIPSE, 20.0, w)._t)
