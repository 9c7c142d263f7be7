"""Can the batteries and the spares keep the patrol up indefinitely? (pure; docs/energy.md)

The relief rotation, steady state. ``N`` UAVs must be on the loop at every moment; ``S``
spares stand by. Every airframe is taken as the worst of the fleet: usable flight time
``E (1 - r)`` (endurance ``E`` min from full to 0 % at cruise, reserve ``r``), one-way
transit ``tau`` (min) between a base and the loop, turnaround ``theta`` (min) on the ground
from landing to ready with a full battery. One stint: take off full, fly ``tau`` to the
loop, patrol, fly ``tau`` back and land on the reserve, so the time on station is

    T_on = E (1 - r) - 2 tau.

Each of the N stations needs a relief every ``T_on``; spread evenly, the fleet needs one
relief every ``T_on / N``. Relieving is first in, first out: the UAV relieved at relief
``j`` flies back (``tau``), turns around (``theta``), waits, and relieves again at relief
``j + S``, which comes ``S T_on / N`` later and for which it must take off ``tau`` before.
So the rotation holds if and only if

    tau + theta + tau <= S T_on / N,   i.e.   (2 tau + theta) / S <= T_on / N:

"a spare is ready every (2 tau + theta) / S min, a relief is needed every T_on / N min".
It is also necessary, whatever the schedule: each relief takes one airframe off station for
at least ``2 tau + theta``, reliefs come at least N / T_on per minute (no stint lasts more
than ``T_on``), so on average at least ``N (2 tau + theta) / T_on`` airframes are off
station (Little's law), and only ``S`` are. The fewest spares is therefore
``S_min = ceil(N (2 tau + theta) / T_on)``, and ``T_on > 0`` is needed for any at all.

In this ideal rotation the start is no harder: the N patrol UAVs start on the loop, full,
so each has ``E (1 - r) - tau = T_on + tau`` on station; relieving station k at
``tau + (k - 1) T_on / N`` (k = 1..N, at most ``T_on + tau``) with the S spares first sets up
the even spacing. The companions' rotation needs more than this bound (its stint is the
rotation's beat, and a relief's lead and landing margin lengthen the cycle): on the ellipse
4.68 spares against 3.27 (``companion.agent.relief.roster.Roster.spares_needed``, said
before a run by ``companion fleet`` and ``companion simulate``), and the start is then one
spare short with 4 (docs/energy.md, "Can the spares keep the patrol up?").

Transit: from a base to the farthest point of the loop at the slowest ground speed,
airspeed minus wind (``tau = max |loop - base| / (s0 - beta)``): the relief can then meet its
slot anywhere on the loop, whatever the wind's direction. A ground spare's base is its launch
point; a holding spare's is home (the origin), where it lands to recharge: its holding
point only shortens its first relief. Climb and descent are not counted (a few tens of
seconds at the fleet's altitudes). Relieved patrol UAVs land at a spare's base and join the
rotation, so the farthest base and the longest turnaround count for all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from companion.mission.model import Battery, Mission, Vehicles

LOOP_SAMPLES = 720  # loop points searched for the farthest from a base


@dataclass(frozen=True)
class Rotation:
    """The relief rotation's figures (min) and whether it holds.

    Attributes:
        on_station: N, UAVs on the loop at every moment.
        spares: S.
        usable_min: ``E (1 - r)`` of the weakest battery (min).
        transit_min: ``tau``, one way, the worst base (min).
        turnaround_min: ``theta``, the longest (min).
        stint_min: ``T_on = E (1 - r) - 2 tau`` (min on station per stint).
        relief_every_min: ``T_on / N`` (inf when ``T_on <= 0``: no stint at all).
        spare_ready_every_min: ``(2 tau + theta) / S`` (inf without spares).
        min_spares: ``ceil(N (2 tau + theta) / T_on)``, or None when ``T_on <= 0``.
    """

    on_station: int
    spares: int
    usable_min: float
    transit_min: float
    turnaround_min: float
    stint_min: float
    relief_every_min: float
    spare_ready_every_min: float
    min_spares: int | None

    @property
    def sustainable(self) -> bool:
        """Whether the rotation keeps N on the loop indefinitely."""
        return self.min_spares is not None and self.spares >= self.min_spares

    def why(self) -> str:
        """One sentence with the figures that decide (for an error message)."""
        n, s = self.on_station, self.spares
        head = f"{n} on station, {s} spare{'' if s == 1 else 's'}"
        if self.min_spares is None:
            return (
                f"{head}: a battery's usable {self.usable_min:.1f} min (endurance less the "
                f"reserve) does not cover the transit there and back "
                f"(2 x {self.transit_min:.1f} min), so no UAV can stay on the loop"
            )
        ready = (
            "there is no spare"
            if s == 0
            else f"a spare is ready every {self.spare_ready_every_min:.1f} min"
        )
        return (
            f"{head}: {ready}, a relief is needed every {self.relief_every_min:.1f} min "
            f"({self.stint_min:.1f} min on station per battery = {self.usable_min:.1f} min "
            f"usable - 2 x {self.transit_min:.1f} min transit; a relief ties up a UAV for "
            f"2 x {self.transit_min:.1f} min transit + {self.turnaround_min:.1f} min "
            f"turnaround): at least {self.min_spares} "
            f"spare{'' if self.min_spares == 1 else 's'} needed"
        )


def rotation(
    on_station: int, spares: int, usable_min: float, transit_min: float, turnaround_min: float
) -> Rotation:
    """The rotation of ``on_station`` UAVs and ``spares`` spares with ``usable_min`` (min of
    flight before the reserve), ``transit_min`` (one way, min) and ``turnaround_min`` (min):
    the condition of the module docstring."""
    if on_station < 1 or spares < 0:
        raise ValueError(f"need on_station >= 1 and spares >= 0, got {on_station}, {spares}")
    stint = usable_min - 2.0 * transit_min
    cycle = 2.0 * transit_min + turnaround_min
    ready = cycle / spares if spares > 0 else math.inf
    if stint <= 0:
        return Rotation(on_station, spares, usable_min, transit_min, turnaround_min, stint,
                        math.inf, ready, None)  # fmt: skip
    need = on_station * cycle / stint
    min_spares = max(math.ceil(need - 1e-9), 0)
    return Rotation(
        on_station, spares, usable_min, transit_min, turnaround_min, stint,
        stint / on_station, ready, min_spares,
    )  # fmt: skip


def transit_min(base_m: complex, loop_m: np.ndarray, groundspeed_m_s: float) -> float:
    """Minutes from ``base_m`` (complex m) to the farthest of the points ``loop_m`` at
    ``groundspeed_m_s`` (m/s)."""
    return float(np.max(np.abs(np.asarray(loop_m) - base_m))) / groundspeed_m_s / 60.0


def fleet_rotation(vehicles: Vehicles, loop_m: np.ndarray, wind_speed_m_s: float) -> Rotation:
    """The rotation of a fleet with a battery section (``vehicles.battery`` set), on the loop
    through the points ``loop_m`` (complex m) in a wind of ``wind_speed_m_s`` (m/s).

    Raises:
        ValueError: the fleet has no battery section.
    """
    if vehicles.battery is None:
        raise ValueError("the fleet has no battery: nothing to check")
    batteries: list[Battery] = [vehicles.battery]
    batteries += [sp.battery for sp in vehicles.spares if sp.battery is not None]
    usable = min(b.usable_min for b in batteries)
    slowest = vehicles.airspeed_m_s - wind_speed_m_s
    bases = [sp.base_m for sp in vehicles.spares] or [0j]  # no spare: home
    tau = max(transit_min(b, loop_m, slowest) for b in bases)
    theta = max((sp.turnaround_s for sp in vehicles.spares), default=0.0) / 60.0
    return rotation(vehicles.count, len(vehicles.spares), usable, tau, theta)


def opening_note(mission: Mission, duration_s: float, started_full: bool) -> str | None:
    """Why a run of ``mission`` for ``duration_s`` (s) should set ``vehicles.opening:
    staggered``, or None: every patrol UAV starts full (``started_full``: no battery given
    as used), the first stints end within minutes of each other (each ``T_on`` on station,
    the rotation's ``stint_min``) before the run ends, the opening is ``battery`` and there
    are fewer spares than UAVs on station, so some of those first reliefs cannot be flown at
    once (docs/energy.md, "The opening")."""
    v = mission.vehicles
    if v.battery is None or not v.spares or v.opening != "battery":
        return None
    n, s = v.count, len(v.spares)
    loop = mission.patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, LOOP_SAMPLES, False))
    stint_s = fleet_rotation(v, loop, mission.wind.speed_m_s).stint_min * 60.0
    if not started_full or s >= n or duration_s <= stint_s:
        return None
    return (
        f"every patrol UAV starts full, so all {n} first stints end together, about "
        f"{stint_s / 60.0:.0f} min in, and {s} spare{'' if s == 1 else 's'} cannot relieve "
        "them at once; "
        'set vehicles.opening: staggered to space them (docs/energy.md, "The opening")'
    )
