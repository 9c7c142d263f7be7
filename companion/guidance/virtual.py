"""The virtual particle a prosecuting UAV broadcasts instead of its real state
(docs/design.md §5.4).

While UAV k is away, the others keep seeing a particle that flies the loop at the nominal
rate from where k was when tasked: ``psi_v(t) = psi_k(t_task) + 2 pi (t - t_task) / T`` and
``c_v = c0``. Times are simulated/vehicle seconds; phases in rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_2pi


@dataclass(frozen=True)
class VirtualParticle:
    """A particle flying the loop at the nominal rate.

    Attributes:
        phase0_rad: time-phase at ``t0_s`` (rad).
        t0_s: reference time (s).
        period_s: loop period ``T`` (s).
    """

    phase0_rad: float
    t0_s: float
    period_s: float

    def phase(self, t_s: float) -> float:
        """Time-phase at ``t_s`` (rad, [0, 2 pi))."""
        return float(wrap_2pi(self.phase0_rad + TWO_PI * (t_s - self.t0_s) / self.period_s))

    def position_m(self, patrol: Patrol, t_s: float) -> complex:
        """Where it is at ``t_s`` (world, complex m)."""
        return complex(patrol.point_at_phase(self.phase(t_s)))

    def course_rad(self, patrol: Patrol, t_s: float) -> float:
        """Its ground course at ``t_s`` (rad, world)."""
        return float(patrol.course_at_phase(self.phase(t_s)))


def phase_gap_rad(a_rad: float, b_rad: float) -> float:
    """Signed smallest difference ``a - b`` of two phases (rad, [-pi, pi))."""
    return float((a_rad - b_rad + np.pi) % TWO_PI - np.pi)
