"""The clocks of separate firmware instances, pure: telemetry samples interpolated onto a
common vehicle time, each instance's clock carried to one wall instant, and the speed-ups
that make every clock meet the slowest one (and hold them during the hand-over).

:class:`companion.sim.firmware.world.FirmwareWorld` measures and applies them
(docs/arduplane.md, "Time base")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CLOCK_SAMPLE_S = 0.25  # wall s between clock measurements (and SIM_SPEEDUP corrections)
SLEW_MIN = 0.05  # an instance ahead is slowed to no less than this fraction of the speed-up


@dataclass
class Sample:
    """One telemetry sample of a vehicle, in vehicle time (s since the epoch)."""

    t_s: float
    pos_m: complex
    alt_m: float
    heading_deg: float
    course_deg: float
    groundspeed_m_s: float


def interpolate(samples: list[Sample], t_s: float) -> Sample | None:
    """The sample at ``t_s`` by linear interpolation (angles the short way), or None."""
    if not samples or t_s < samples[0].t_s or t_s > samples[-1].t_s:
        return None
    ts = [s.t_s for s in samples]
    k = int(np.searchsorted(ts, t_s))
    if k == 0:
        return samples[0]
    a, b = samples[k - 1], samples[k]
    span = b.t_s - a.t_s
    w = 0.0 if span <= 0 else (t_s - a.t_s) / span

    def ang(x: float, y: float) -> float:
        return (x + w * ((y - x + 180.0) % 360.0 - 180.0)) % 360.0

    return Sample(
        t_s,
        a.pos_m + w * (b.pos_m - a.pos_m),
        a.alt_m + w * (b.alt_m - a.alt_m),
        ang(a.heading_deg, b.heading_deg),
        ang(a.course_deg, b.course_deg),
        a.groundspeed_m_s + w * (b.groundspeed_m_s - a.groundspeed_m_s),
    )


def clocks_now_s(latest: list[tuple[float, float, float]], wall_s: float) -> list[float]:
    """Each instance's vehicle time at wall instant ``wall_s`` (s).

    ``latest`` holds each instance's newest (wall s received, vehicle s, speed-up) SYSTEM_TIME
    sample; each is carried to ``wall_s`` at its speed-up.
    """
    return [t + x * (wall_s - w) for w, t, x in latest]


def slewed_speedups(
    clocks_s: list[float], speedup: float, sample_s: float = CLOCK_SAMPLE_S
) -> list[float]:
    """SIM_SPEEDUP for each instance so that every clock meets the slowest one (pure).

    An instance ``lead`` vehicle seconds ahead of the slowest runs at
    ``speedup * (1 - lead / (2 speedup sample_s))`` (at least ``SLEW_MIN * speedup``) for
    the next ``sample_s`` wall seconds, which halves its lead per sample; the slowest runs
    at ``speedup``. No instance is ever asked to run faster than ``speedup``.
    """
    slowest = min(clocks_s)
    out = []
    for t in clocks_s:
        lead = t - slowest
        out.append(speedup * max(SLEW_MIN, 1.0 - lead / (2.0 * speedup * sample_s)))
    return out


def handover_cap(
    now_wall_s: float,
    until_wall_s: float,
    modes: list[str],
    speedup: float,
    held: float,
    controlled: str = "GUIDED",
) -> tuple[float, bool]:
    """SIM_SPEEDUP cap during the hand-over hold (pure).

    Args:
        now_wall_s: wall clock now (s).
        until_wall_s: wall time at which the hold ends in any case (s).
        modes: every instance's mode name, from its latest HEARTBEAT.
        speedup: the run's ``--speedup``.
        held: ``--handover-speedup``.
        controlled: the mode name the companions command in (GUIDED, OFFBOARD).

    Returns:
        (cap, still held): ``min(held, speedup)`` while some instance is not yet in
        ``controlled`` and the deadline has not passed, else ``(speedup, False)``.
    """
    if all(m == controlled for m in modes) or now_wall_s > until_wall_s:
        return speedup, False
    return min(held, speedup), True
