"""When must a UAV on station leave for home? (pure; docs/energy.md, "Reliefs")

Conventions: positions complex ``north + i east`` metres, the wind the vector it blows
TOWARDS (m/s), times vehicle seconds, charge mAh, current A.

A UAV at ``pos_m`` that lands at ``base_m`` flies straight home at the airspeed ``s0``; its
ground speed along the bearing ``gamma`` to the base is ``s(gamma)`` of the agreed wind
(docs/design.md §2), so the flight home takes ``d / s(gamma)`` and costs that long at the present
current. The battery reaches the reserve ``(capacity - reserve - consumed) / rate`` from
now (``rate = I / 3.6`` mAh/s at ``I`` amperes). It must therefore leave at

    t_leave = t + (capacity - reserve - consumed) / rate - d / s(gamma) - margin

so that it lands with the reserve still in the battery. The current is smoothed
(:class:`Drain`, a first-order filter) because a bank draws more than level flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from companion.core.wind import Wind, groundspeed_from_course

MAH_PER_AS = 1.0 / 3.6  # 1 A for 1 s is 1/3.6 mAh
DRAIN_TAU_S = 30.0  # time constant of the smoothed current (s)


def home_time_s(pos_m: complex, base_m: complex, airspeed_m_s: float, wind: Wind) -> float:
    """Time (s) to fly straight from ``pos_m`` to ``base_m`` (complex m) at ``airspeed_m_s``
    (m/s) in ``wind``; 0 at the base."""
    d = base_m - pos_m
    if abs(d) < 1e-9:
        return 0.0
    course = math.atan2(d.imag, d.real)
    gs = float(groundspeed_from_course(airspeed_m_s, course, wind))
    return abs(d) / gs


def leave_time_s(
    t_s: float,
    consumed_mah: float,
    capacity_mah: float,
    reserve_mah: float,
    current_a: float,
    home_s: float,
    margin_s: float = 0.0,
) -> float:
    """The vehicle time (s) at which a UAV must leave for home to land on its reserve.

    Args:
        t_s: now (vehicle s).
        consumed_mah: charge drawn so far (mAh).
        capacity_mah: the battery's capacity (mAh).
        reserve_mah: the charge to land with (mAh).
        current_a: the current drawn (A, > 0), smoothed.
        home_s: the flight home from here (s, :func:`home_time_s`).
        margin_s: leave this much earlier still (s): the landing, the take-over.

    Raises:
        ValueError: a current that is not positive and finite.
    """
    if not (math.isfinite(current_a) and current_a > 0.0):
        raise ValueError(f"current_a must be > 0 A, got {current_a!r}")
    rate_mah_s = current_a * MAH_PER_AS
    to_reserve_s = (capacity_mah - reserve_mah - consumed_mah) / rate_mah_s
    return t_s + to_reserve_s - home_s - margin_s


@dataclass
class Drain:
    """The current drawn, smoothed over ``tau_s`` (s): ``add(t_s, current_a)`` for every
    battery report; ``current_a`` is None before the first."""

    tau_s: float = DRAIN_TAU_S
    current_a: float | None = None
    t_s: float | None = None

    def add(self, t_s: float, current_a: float) -> None:
        """One valid current report (A) at vehicle time ``t_s`` (s); a repeat of the same
        time, or an earlier one, is ignored."""
        if self.current_a is None or self.t_s is None:
            self.current_a, self.t_s = float(current_a), float(t_s)
            return
        dt = t_s - self.t_s
        if dt <= 0.0:
            return
        k = 1.0 - math.exp(-dt / self.tau_s)
        self.current_a += k * (float(current_a) - self.current_a)
        self.t_s = float(t_s)


@dataclass
class Gauge:
    """The autopilot's battery as last reported: charge left (%), drawn (mAh), each None
    until reported, and the current smoothed (:class:`Drain`)."""

    pct: float | None = None
    consumed_mah: float | None = None
    drain: Drain = field(default_factory=Drain)

    def observe(
        self,
        t_s: float,
        remaining_pct: float | None,
        consumed_mah: float | None,
        current_a: float | None,
    ) -> None:
        """A report at vehicle time ``t_s`` (s): charge left (%), drawn (mAh), current (A);
        None for a field not reported (the drain drops bad currents)."""
        self.pct = remaining_pct
        self.consumed_mah = consumed_mah
        if current_a is not None and current_a > 0.0:
            self.drain.add(t_s, current_a)
