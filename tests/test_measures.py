"""Formation measures (docs/design.md §8) on hand-made cases."""

import numpy as np
import pytest

from companion.core.measures import (
    centre_error_m,
    convergence_time_s,
    splay_error_deg,
    splay_errors_deg,
)


def test_perfect_splay_is_zero_in_any_order():
    psi = np.radians([300.0, 60.0, 180.0, 0.0, 240.0, 120.0])
    assert splay_error_deg(psi) == pytest.approx(0.0, abs=1e-9)
    assert splay_error_deg([1.0]) == 0.0


def test_one_member_late_by_three_degrees():
    psi = np.radians([0.0, 90.0, 183.0, 270.0])
    # gaps 90, 93, 87, 90 -> worst deviation 3 deg
    assert splay_error_deg(psi) == pytest.approx(3.0)


def test_all_together_is_the_worst_case():
    assert splay_error_deg(np.zeros(4)) == pytest.approx(270.0)


def test_splay_of_every_time_at_once_is_each_time_alone():
    """The array form (every column of members x times at once) gives, bit for bit, what the
    one-time form gives column by column, and a hand-made column its known value."""
    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 6, 11):
        phases = rng.uniform(-10.0, 10.0, (n, 40))
        phases[:, 0] = np.radians(np.arange(n) * 360.0 / max(n, 1))  # evenly spread
        got = splay_errors_deg(phases)
        assert got.shape == (40,)
        assert list(got) == [splay_error_deg(phases[:, j]) for j in range(40)]
        assert got[0] == pytest.approx(0.0, abs=1e-9)
    late = np.radians([[0.0], [90.0], [183.0], [270.0]])  # one member 3 deg late
    assert splay_errors_deg(late)[0] == pytest.approx(3.0)


def test_centre_error_is_the_largest_distance():
    assert centre_error_m([3 + 4j, 1j, -2], 0j) == pytest.approx(5.0)


def test_convergence_time_is_the_start_of_the_final_good_stretch():
    t = [0, 1, 2, 3, 4, 5]
    splay = [10, 1, 1, 3, 1, 1]
    centre = [1, 1, 1, 1, 1, 1]
    assert convergence_time_s(t, splay, centre) == 4
    assert convergence_time_s(t, splay, [1, 1, 1, 1, 1, 6]) is None
    assert convergence_time_s([0, 1], [0.5, 0.5], [0, 0]) == 0
