"""Wind kinematics: round trips and checks against direct vector arithmetic."""

import numpy as np
import pytest

from companion.core.wind import (
    Wind,
    course_from_heading,
    course_rate_from_turn_rate,
    ground_velocity,
    groundspeed_from_course,
    heading_from_course,
    turn_rate_from_course_rate,
    wrap_pi,
)

RNG = np.random.default_rng(7)
S0 = 20.0


def random_winds(n=200):
    speeds = RNG.uniform(0.0, 0.95 * S0, n)
    towards = RNG.uniform(-np.pi, np.pi, n)
    return [Wind(float(s), float(t)) for s, t in zip(speeds, towards, strict=True)]


def test_meteo_convention_south_wind_blows_north():
    w = Wind.from_meteo(5.0, 180.0)
    assert w.vector == pytest.approx(5.0 + 0j, abs=1e-12)
    assert w.from_deg == pytest.approx(180.0)
    east = Wind.from_meteo(3.0, 90.0)  # from the East: air moves West
    assert east.vector == pytest.approx(-3j, abs=1e-12)


def test_heading_course_round_trip():
    for wind in random_winds():
        heading = RNG.uniform(-np.pi, np.pi, 50)
        course = course_from_heading(S0, heading, wind)
        back = heading_from_course(S0, course, wind)
        assert np.allclose(wrap_pi(back - heading), 0.0, atol=1e-9)


def test_groundspeed_from_course_matches_vector_sum():
    for wind in random_winds():
        heading = RNG.uniform(-np.pi, np.pi, 50)
        v = S0 * np.exp(1j * heading) + wind.vector
        assert np.allclose(groundspeed_from_course(S0, np.angle(v), wind), np.abs(v), rtol=1e-12)


def test_turn_rate_course_rate_round_trip():
    for wind in random_winds():
        heading = RNG.uniform(-np.pi, np.pi, 50)
        u = RNG.uniform(-0.5, 0.5, 50)
        nu = course_rate_from_turn_rate(S0, heading, u, wind)
        assert np.allclose(turn_rate_from_course_rate(S0, heading, nu, wind), u, rtol=1e-12)


def test_course_rate_matches_finite_difference_of_the_course():
    """nu(u) against d(course)/dt of the vector sum, by central differences."""
    h = 1e-6
    for wind in random_winds(50):
        heading = RNG.uniform(-np.pi, np.pi, 20)
        u = RNG.uniform(-0.4, 0.4, 20)
        c_plus = np.angle(ground_velocity(S0, heading + u * h, wind))
        c_minus = np.angle(ground_velocity(S0, heading - u * h, wind))
        fd = wrap_pi(c_plus - c_minus) / (2 * h)
        assert np.allclose(course_rate_from_turn_rate(S0, heading, u, wind), fd, atol=1e-6)


def test_wind_must_be_slower_than_airspeed():
    with pytest.raises(ValueError, match="below the airspeed"):
        Wind(20.0, 0.0).check_against(20.0)
