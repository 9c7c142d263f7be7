"""Formation measures (docs/design.md §8) on hand-made cases."""

import numpy as np
import pytest

from companion.core.measures import centre_error_m, convergence_time_s, splay_error_deg


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


def test_centre_error_is_the_largest_distance():
    assert centre_error_m([3 + 4j, 1j, -2], 0j) == pytest.approx(5.0)


def test_convergence_time_is_the_start_of_the_final_good_stretch():
    t = [0, 1, 2, 3, 4, 5]
    splay = [10, 1, 1, 3, 1, 1]
    centre = [1, 1, 1, 1, 1, 1]
    assert convergence_time_s(t, splay, centre) == 4
    assert convergence_time_s(t, splay, [1, 1, 1, 1, 1, 6]) is None
    assert convergence_time_s([0, 1], [0.5, 0.5], [0, 0]) == 0
