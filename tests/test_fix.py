"""The per-step Fix: derived values against the loop, computed once, read against another wind."""

from __future__ import annotations

import math

from companion.agent.fix import Fix
from companion.core.loops import EllipseLoop
from companion.core.patrol import Patrol
from companion.core.wind import Wind


def _patrol(wind: Wind) -> Patrol:
    return Patrol.build(EllipseLoop(0j, 400.0, 200.0, 0.0), 20.0, wind)


def test_a_fix_on_the_loop_has_the_loops_centre_and_no_offset() -> None:
    """On the ellipse at the end of its major axis heading East (the tangent there), the
    centre a fix implies is the loop's centre and the point is on the loop; independent
    reference: the ellipse's own geometry, not the patrol's tables."""
    patrol = _patrol(Wind.from_meteo(0.0, 0.0))
    fix = Fix(10.0, complex(400.0, 0.0), math.pi / 2, patrol)
    assert abs(fix.centre_m - 0j) < 1e-6
    assert fix.loop_offset_m < 1e-6
    assert abs(fix.loop_phase_rad - fix.phase_rad) < 1e-6


def test_derived_values_are_computed_once() -> None:
    """A second read returns the very same objects (no new computation)."""
    fix = Fix(0.0, complex(300.0, 50.0), 1.0, _patrol(Wind.from_meteo(5.0, 180.0)))
    assert fix._centre_phase is fix._centre_phase
    assert fix.loop_point is fix.loop_point


def test_against_another_wind_moves_the_phase_not_the_point() -> None:
    """Read against another wind the course, hence centre and phase, change; the position's
    offset from the loop does not (the loop is the same)."""
    still = _patrol(Wind.from_meteo(0.0, 0.0))
    windy = still.with_wind(Wind.from_meteo(6.0, 90.0))
    fix = Fix(0.0, complex(200.0, 150.0), 0.3, still)
    other = fix.against(windy)
    assert fix.against(still) is fix
    assert other.pos_m == fix.pos_m and other.t_s == fix.t_s
    assert abs(other.loop_offset_m - fix.loop_offset_m) < 1e-9
    assert abs(other.centre_m - fix.centre_m) > 1e-3
