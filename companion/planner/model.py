"""The minimum-time planner's question and answer: :class:`Pose`, :class:`Goal`, :class:`Aircraft`
in; :class:`Plan` (of :class:`Segment`) or :class:`NoPath` out.

Conventions: complex positions ``north + i east`` (m), compass angles (rad, 0 = North,
pi/2 = East), positive turn rate = right turn. Segments are air-relative: a segment of turn
rate ``u`` held for ``duration_s`` turns the air heading by ``u * duration_s`` while the air
mass drifts with the wind.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from companion.core.particle import arc_factor
from companion.core.wind import wrap_pi


@dataclass(frozen=True)
class Pose:
    """Where a path starts.

    Attributes:
        position_m: position (m, complex north + i east).
        heading_rad: air heading (rad, compass).
    """

    position_m: complex
    heading_rad: float


@dataclass(frozen=True)
class Goal:
    """Where a path ends.

    Attributes:
        position_m: the goal's position at t = 0 (m, complex).
        course_rad: ground course at arrival (rad), or None.
        heading_rad: air heading at arrival (rad), or None. At most one of the two; neither
            means a free final heading.
        velocity_m_s: the goal's constant ground velocity (m/s, complex); nonzero asks for
            the minimum-time intercept of the moving goal.
    """

    position_m: complex
    course_rad: float | None = None
    heading_rad: float | None = None
    velocity_m_s: complex = 0j


@dataclass(frozen=True)
class Aircraft:
    """What the planner needs of the aircraft.

    Attributes:
        airspeed_m_s: constant airspeed ``s0`` (m/s), above the wind speed.
        max_turn_rate_rad_s: turn-rate limit ``omega`` (rad/s), > 0.
    """

    airspeed_m_s: float
    max_turn_rate_rad_s: float


@dataclass(frozen=True)
class Segment:
    """One piece of a plan: a constant air-relative turn rate held for a duration.

    Attributes:
        turn_rate_rad_s: turn rate (rad/s), positive = right, 0 = straight.
        duration_s: how long it is held (s), >= 0.
    """

    turn_rate_rad_s: float
    duration_s: float


@dataclass(frozen=True)
class NoPath:
    """The geometry has no solution (a result, not an exception).

    Attributes:
        reason: one sentence saying why.
    """

    reason: str


def propagate(
    pos_m: complex,
    heading_rad: float,
    airspeed_m_s: float,
    wind_m_s: complex,
    turn_rate_rad_s: float,
    duration_s: float,
) -> tuple[complex, float]:
    """Exact end pose after holding ``turn_rate_rad_s`` (rad/s) for ``duration_s`` (s).

    Returns the new position (m, complex) and air heading (rad, not wrapped).
    """
    dtheta = turn_rate_rad_s * duration_s
    air = airspeed_m_s * duration_s * np.exp(1j * heading_rad) * arc_factor(dtheta)
    return complex(pos_m + air + wind_m_s * duration_s), heading_rad + dtheta


@dataclass(frozen=True)
class Plan:
    """A minimum-time path: turn-rate segments in flight order and the context to fly them.

    Attributes:
        time_s: total flight time (s), the sum of the segment durations.
        family: the path word in flight order, R = right turn, L = left turn, S = straight
            (e.g. ``"RSL"``; zero-length pieces are dropped, so a straight flight is ``"S"``).
        segments: the air-relative segments in flight order.
        start_m: start position (m, complex north + i east).
        start_heading_rad: start air heading (rad, compass).
        airspeed_m_s: airspeed (m/s).
        wind_m_s: wind vector (m/s, complex, direction blown towards).
    """

    time_s: float
    family: str
    segments: tuple[Segment, ...]
    start_m: complex
    start_heading_rad: float
    airspeed_m_s: float
    wind_m_s: complex

    @property
    def end_heading_rad(self) -> float:
        """Air heading at arrival (rad, wrapped to [-pi, pi))."""
        total = self.start_heading_rad + sum(
            s.turn_rate_rad_s * s.duration_s for s in self.segments
        )
        return float(wrap_pi(total))

    @property
    def end_course_rad(self) -> float:
        """Ground course at arrival (rad, [-pi, pi))."""
        v = self.airspeed_m_s * np.exp(1j * self.end_heading_rad) + self.wind_m_s
        return float(np.angle(v))

    @property
    def end_m(self) -> complex:
        """Arrival position (m, complex), by exact propagation of the segments."""
        pos, heading = self.start_m, self.start_heading_rad
        for seg in self.segments:
            pos, heading = self._step(pos, heading, seg, seg.duration_s)
        return pos

    def ground_track(self, step_s: float = 0.5) -> np.ndarray:
        """Ground positions (m, complex) every ``step_s`` seconds, both ends included."""
        if not step_s > 0:
            raise ValueError(f"step_s must be > 0, got {step_s!r}")
        times = np.append(np.arange(0.0, self.time_s, step_s), self.time_s)
        out = np.empty(times.shape, dtype=complex)
        pos, heading, t0 = self.start_m, self.start_heading_rad, 0.0
        for seg in self.segments:
            t1 = t0 + seg.duration_s
            inside = (times >= t0) & (times <= t1)
            for j in np.nonzero(inside)[0]:
                out[j] = self._step(pos, heading, seg, times[j] - t0)[0]
            pos, heading = self._step(pos, heading, seg, seg.duration_s)
            t0 = t1
        return out

    def _step(
        self, pos: complex, heading: float, seg: Segment, dt_s: float
    ) -> tuple[complex, float]:
        return propagate(pos, heading, self.airspeed_m_s, self.wind_m_s, seg.turn_rate_rad_s, dt_s)
