"""Fusing two tracks of one intruder without counting a sighting twice (pure).

Tracks travel round the group: a member fits its pass on top of the track it heard, another
relays it, a third fits on top of that one. Two tracks of one intruder therefore share an
unknown part of their sightings, and the Kalman (information) sum of the two would count
that part twice: the same track heard twice would look twice as sure. Covariance
intersection (Julier and Uhlmann, 1997) fuses two estimates whose correlation is unknown
and stays consistent whatever it is:

    P^-1 = w Pa^-1 + (1 - w) Pb^-1,   x = P (w Pa^-1 xa + (1 - w) Pb^-1 xb),   w in [0, 1]

with ``w`` chosen to make ``P`` smallest (here the product of the position and velocity
variances, over a grid of ``CI_STEPS`` + 1 weights that includes 0 and 1, so the result is
never less sure than the surer of the two). The same track fused with itself is itself.

A :class:`~companion.group.messages.Track` holds per-axis sigmas (isotropic position and
velocity blocks), so the intersection is taken on the two blocks with one weight. The
older track is first predicted to the newer one's time (:meth:`Track.at`, with its
manoeuvre growth). Two tracks too far apart to be one estimate (beyond ``GATE_SIGMAS`` sigma
of their difference) are not fused: the newer one is kept, as before. The fused track
carries the newer one's model, and the larger of the two sighting counts (the overlap is
unknown).

Conventions: positions ``north + i east`` (complex m), velocities complex m/s, times s.
"""

from __future__ import annotations

import math
from dataclasses import replace

from companion.group.messages import Track

CI_STEPS = 20  # weights tried: 0, 1/20, ..., 1
GATE_SIGMAS = 4.0  # two tracks farther apart than this (in sigma of the difference): not fused


def fuse(a: Track, b: Track) -> Track:
    """Covariance intersection of two tracks of one intruder, at the later one's time.

    Args:
        a: one track (a sensor track: ``sightings`` > 0).
        b: another track of the same intruder.

    Returns:
        The fused track at ``max(a.t_s, b.t_s)`` (s): never surer than the surer of the two
        in both blocks together, equal to ``a`` when ``b`` is ``a``; the newer of the two
        when they disagree beyond ``GATE_SIGMAS`` or either is a point (no sightings).
    """
    old, new = (a, b) if a.t_s <= b.t_s else (b, a)
    if old.sightings <= 0 or new.sightings <= 0:
        return new
    old = old.at(new.t_s) if old.t_s < new.t_s else old
    pa, pb = old.pos_sigma_m**2, new.pos_sigma_m**2
    va, vb = old.vel_sigma_m_s**2, new.vel_sigma_m_s**2
    if min(pa, pb, va, vb) <= 0.0:
        return new
    d_pos = abs(old.pos_m - new.pos_m) / math.sqrt(pa + pb)
    d_vel = abs(old.vel_m_s - new.vel_m_s) / math.sqrt(va + vb)
    if max(d_pos, d_vel) > GATE_SIGMAS:
        return new
    best: tuple[float, float, float, float] | None = None
    for k in range(CI_STEPS + 1):
        w = k / CI_STEPS
        p = 1.0 / (w / pa + (1.0 - w) / pb)
        v = 1.0 / (w / va + (1.0 - w) / vb)
        if best is None or p * v < best[1] * best[2] - 1e-15:
            best = (w, p, v, p * v)
    assert best is not None
    w, p, v, _ = best
    pos = p * (w * old.pos_m / pa + (1.0 - w) * new.pos_m / pb)
    vel = v * (w * old.vel_m_s / va + (1.0 - w) * new.vel_m_s / vb)
    return replace(
        new,
        pos_m=complex(pos),
        vel_m_s=complex(vel),
        pos_sigma_m=math.sqrt(p),
        vel_sigma_m_s=math.sqrt(v),
        sightings=max(old.sightings, new.sightings),
    )
