"""One control step's kinematic fix (pure): where the UAV is, when, and what follows from it.

A :class:`Fix` is made once per control step and passed down to every decision of that step
(the formation, the alert duty, the reliefs, the rejoin): no function takes the time, the
position and the heading apart, and what is derived from them against the loop (its centre
and time-phase, docs/design.md §3-4; the nearest loop point's phase and the distance from
the loop) is computed at most once a step, on first use.

Conventions (docs/design.md §1): vehicle time in s, positions complex ``north + i east`` m in
the mission's local frame, the air heading a compass angle in rad.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field
from functools import cached_property

from companion.core.patrol import LoopPoint, Patrol


@dataclass(frozen=True)
class Fix:
    """A UAV's state at one instant, read against one patrol (frozen).

    Attributes:
        t_s: vehicle time (s).
        pos_m: position (complex m).
        heading_rad: air heading (rad, compass).
        patrol: the loop and wind the derived values are read against.
    """

    t_s: float
    pos_m: complex
    heading_rad: float
    patrol: Patrol = field(repr=False, compare=False)

    @cached_property
    def course_rad(self) -> float:
        """Its ground course (rad, compass) from the air heading in the patrol's wind."""
        v = self.patrol.airspeed_m_s * cmath.exp(1j * self.heading_rad) + self.patrol.wind.vector
        return math.atan2(v.imag, v.real)

    @cached_property
    def _centre_phase(self) -> tuple[complex, float]:
        return self.patrol.centre_and_phase_of_course(self.pos_m, self.course_rad)

    @property
    def centre_m(self) -> complex:
        """The loop centre ``c = r - rho(gamma)`` this fix implies (complex m)."""
        return self._centre_phase[0]

    @property
    def phase_rad(self) -> float:
        """The time-phase ``psi(gamma)`` of its ground course (rad, [0, 2 pi); eq. 14)."""
        return self._centre_phase[1]

    @cached_property
    def loop_point(self) -> LoopPoint:
        """The loop point nearest the position (:meth:`Patrol.loop_point`, searched from the
        tangent parallel to its course)."""
        return self.patrol.loop_point_on_course(self.pos_m, self.course_rad)

    @property
    def loop_phase_rad(self) -> float:
        """The time-phase of the loop point nearest the position (rad, [0, 2 pi)): where
        along the loop it is, whatever its course."""
        return self.loop_point.phase_rad

    @property
    def loop_offset_m(self) -> float:
        """Its distance from the loop (m, >= 0)."""
        return abs(self.loop_point.offset_m)

    def against(self, patrol: Patrol) -> Fix:
        """The same fix read against ``patrol`` (another wind: the derived values follow)."""
        if patrol is self.patrol:
            return self
        return Fix(self.t_s, self.pos_m, self.heading_rad, patrol)
