"""Convex-outline check of waypoint lists (companion.core.outline): a table of known cases."""

import numpy as np
import pytest

from companion.core.outline import outline_fault

# a 4 km square, corners listed clockwise on the map (north, east in m)
SQUARE = [(-2000, -2000), (2000, -2000), (2000, 2000), (-2000, 2000)]


def pts(rows):
    return [complex(n, e) for n, e in rows]


@pytest.mark.parametrize(
    "rows",
    [
        SQUARE,
        SQUARE[::-1],  # either sense of listing
        SQUARE[2:] + SQUARE[:2],  # any starting corner
        [(0, 0), (1000, 0), (0, 1000)],  # a triangle in either order
        [(0, 0), (0, 1000), (1000, 0)],
        [(-2000, -2000), (0, -2000), (2000, -2000), (2000, 2000), (-2000, 2000)],  # on an edge
        [(-2000, -2000), (0, -1999.5), (2000, -2000), (2000, 2000), (-2000, 2000)],  # 0.5 m in
        [(0.0, 0.0), (0.0, 0.0)],  # too few: left to the loop builder
        [(0, 0), (1000, 1000), (2000, 2000)],  # collinear: left to the loop builder
    ],
)
def test_convex_outlines_pass(rows):
    assert outline_fault(pts(rows)) is None


def test_ellipse_samples_rounded_to_a_centimetre_pass():
    a = np.linspace(0, 2 * np.pi, 500, endpoint=False)
    ring = np.round(12_000 * np.cos(a), 2) + 1j * np.round(3000 * np.sin(a), 2)
    assert outline_fault(ring) is None


@pytest.mark.parametrize(
    ("rows", "index", "kind", "other"),
    [
        ([*SQUARE, SQUARE[0]], 4, "repeat", 0),  # closing the outline by repeating a corner
        ([(-2000, -2000), (2000, -2000), (2000, 2000), (1999.5, 2000.5)], 3, "repeat", 2),
        ([(-2000, -2000), (2000, -2000), (0, -500), (2000, 2000), (-2000, 2000)], 2, "dent", None),
        ([(0, 0), *SQUARE], 0, "dent", None),  # the first waypoint is the dent
        ([SQUARE[0], SQUARE[2], SQUARE[1], SQUARE[3]], 1, "order", None),  # bow-tie
        (
            [(np.cos(t) * 1e3, np.sin(t) * 1e3) for t in np.radians([0, 144, 288, 72, 216])],
            1,
            "order",
            None,
        ),  # a pentagram: right turns all the way, but twice round
        (
            [(np.cos(t) * 1e3, np.sin(t) * 1e3) for t in np.radians([0, 60, 180, 120, 240, 300])],
            2,
            "order",
            None,
        ),  # one swapped pair
    ],
)
def test_faulty_outlines_name_the_waypoint(rows, index, kind, other):
    fault = outline_fault(pts(rows))
    assert fault is not None
    assert (fault.index, fault.kind, fault.other) == (index, kind, other)


def test_dent_depth_is_the_distance_inside_the_hull():
    rows = [(-2000, -2000), (2000, -2000), (0, -500), (2000, 2000), (-2000, 2000)]
    assert outline_fault(pts(rows)).depth_m == pytest.approx(1500.0)
