"""An intruder's track (pure): where it is, how it moves, how sure we are (paper, footnote on
moving threats: "an estimate of the threat's trajectory, and an intercept modified
accordingly").

A downward sensor sees an intruder for a few seconds per pass (a 50 m footprint at 20 m/s:
up to 5 s, 25 sightings at 5 Hz). :class:`TrackFit` turns the sightings of one pass, on top
of the track known before it (another member's, an earlier pass), into a track: the
constant-velocity fit beside the interacting multiple-model filter of
:mod:`companion.agent.alerts.motion` (constant velocity, coordinated turn, stopped), position
and ground velocity at the time of the
newest sighting, each with its 1-sigma uncertainty, the model in use and the manoeuvre
noise that makes the prediction grow.

The prior without a track is wide on purpose (``FIT_VELOCITY_PRIOR_M_S``, 10 m/s per axis). A
narrow one (3 m/s, a walker's) pulled the estimate of a short pass towards still: a 9.7 m/s
vehicle seen for 1.2 s (6 sightings) was estimated at 4.0 m/s with sigma 2.3 m/s, flown to
where it was not, and cleared without a search (generated mission 72, ``bench/alerts.py``).

A track (:class:`companion.group.messages.Track`, shared in every alert) predicts along its
model (:meth:`~companion.group.messages.Track.predict`) with the uncertainty
:meth:`~companion.group.messages.Track.sigma_m`. Tracks of one intruder from several members
are fused without counting a sighting twice (:mod:`companion.agent.alerts.fusion`).

:func:`track_refusal` is the bad-input check every track from the group passes before it is
flown: finite numbers, a speed an intruder can have, an age within ``max_age_s``, a model
probability in [0, 1], a manoeuvre acceleration and a turn rate an intruder can have.

Conventions: positions ``north + i east`` (complex m), velocities complex m/s, times vehicle
seconds, passed in.
"""

from __future__ import annotations

import math
from dataclasses import replace

from companion.agent.alerts.motion import FIT_VELOCITY_PRIOR_M_S, MotionFilter
from companion.group.messages import SIGHTING_SIGMA_M, Track

__all__ = [
    "FIT_VELOCITY_PRIOR_M_S",
    "MAX_INTRUDER_SPEED_M_S",
    "MAX_MANOEUVRE_M_S2",
    "MAX_TURN_RATE_RAD_S",
    "CvFit",
    "TrackFit",
    "track_refusal",
]

MAX_INTRUDER_SPEED_M_S = 60.0  # a track faster than this is refused as bad input
MAX_TURN_RATE_RAD_S = 2.0  # a track turning faster than this is refused (rad/s)
MAX_MANOEUVRE_M_S2 = 20.0  # a track manoeuvring harder than this is refused (m/s^2)

MAX_SIGHTINGS = 200  # sightings kept per fit (the newest); older ones are dropped
FIT_WINDOW_S = 120.0  # sightings older than this before the newest are dropped (s)
MANOEUVRE_GROWTH_M_S2 = 0.05  # an earlier track's velocity sigma grows by this per second


class CvFit:
    """Weighted least-squares constant-velocity fit of one intruder's sightings, optionally
    on top of an earlier track (another member's, or an earlier pass): the constant-velocity
    model's estimate, exact (a Kalman filter with no process noise within a pass gives the
    same), honest within a pass (``tests/test_tracks.py``).

    The earlier track enters as one more position (its own, at its time, weighted by its
    uncertainty) and as the velocity's prior (its velocity, its sigma grown by
    ``MANOEUVRE_GROWTH_M_S2`` per second since, for an intruder that turns, at most
    ``velocity_prior_m_s``); without one the prior is a still intruder, sigma
    ``velocity_prior_m_s``.

    Args:
        sighting_sigma_m: one sighting's position error per axis (m).
        velocity_prior_m_s: prior sigma of the velocity per axis without a track (m/s).
        prior: an earlier track of the same intruder, or None.
    """

    def __init__(
        self,
        sighting_sigma_m: float = SIGHTING_SIGMA_M,
        velocity_prior_m_s: float = FIT_VELOCITY_PRIOR_M_S,
        prior: Track | None = None,
    ) -> None:
        """No sightings yet."""
        self.sighting_sigma_m = float(sighting_sigma_m)
        self.velocity_prior_m_s = float(velocity_prior_m_s)
        self.prior = prior if prior is not None and prior.sightings > 0 else None
        self._t: list[float] = []
        self._p: list[complex] = []

    def __len__(self) -> int:
        """Sightings held (the prior's not counted)."""
        return len(self._t)

    def add(self, t_s: float, pos_m: complex) -> None:
        """One sighting at ``t_s`` (s) of the intruder at ``pos_m`` (complex m); sightings
        must come in time order (an older one is ignored)."""
        if not (math.isfinite(t_s) and math.isfinite(pos_m.real) and math.isfinite(pos_m.imag)):
            return
        if self._t and t_s < self._t[-1]:
            return
        self._t.append(float(t_s))
        self._p.append(complex(pos_m))
        while len(self._t) > MAX_SIGHTINGS or self._t[-1] - self._t[0] > FIT_WINDOW_S:
            del self._t[0], self._p[0]

    def track(self) -> Track | None:
        """The track at the newest sighting; None with no sighting."""
        n = len(self._t)
        if n == 0:
            return None
        t_new = self._t[-1]
        w_z = 1.0 / self.sighting_sigma_m**2
        ts, ps, ws = list(self._t), list(self._p), [w_z] * n
        v0, var_v0 = 0j, self.velocity_prior_m_s**2
        prior = self.prior if self.prior is not None and self.prior.t_s < self._t[0] else None
        if prior is not None:
            ts.append(prior.t_s)
            ps.append(prior.pos_m)
            ws.append(1.0 / max(prior.pos_sigma_m, 0.1 * self.sighting_sigma_m) ** 2)
            v0 = prior.vel_m_s
            grown = prior.vel_sigma_m_s + MANOEUVRE_GROWTH_M_S2 * (t_new - prior.t_s)
            var_v0 = min(grown, self.velocity_prior_m_s) ** 2
        w_sum = sum(ws)
        t_mean = sum(w * t for w, t in zip(ws, ts, strict=True)) / w_sum
        p_mean = sum(w * p for w, p in zip(ws, ps, strict=True)) / w_sum
        s_tt = sum(w * (t - t_mean) ** 2 for w, t in zip(ws, ts, strict=True))
        s_tp = sum(w * (t - t_mean) * (p - p_mean) for w, t, p in zip(ws, ts, ps, strict=True))
        info_v = s_tt + 1.0 / var_v0  # the velocity's information (s^2 / m^2)
        vel = (s_tp + v0 / var_v0) / info_v
        var_v = 1.0 / info_v
        # position at the newest sighting: the weighted mean moved on by the velocity; its
        # variance is the mean's plus the velocity's over the lever arm to the newest one
        lever = t_new - t_mean
        pos = p_mean + vel * lever
        var_p = 1.0 / w_sum + var_v * lever**2
        seen = n + (prior.sightings if prior is not None else 0)
        return Track(t_new, complex(pos), complex(vel), math.sqrt(var_p), math.sqrt(var_v), seen)


class TrackFit:
    """One contact's track: the constant-velocity fit (:class:`CvFit`) and the
    multiple-model filter (:class:`~companion.agent.alerts.motion.MotionFilter`) side by side
    on the same sightings and prior.

    The track is the fit's position, velocity and sigmas, with the filter's model, its
    probability, its turn rate and its manoeuvre acceleration; where the turn model is the
    most probable (a vehicle turning under the sensor, where a straight fit is wrong) the
    filter's own estimate. Why both: over one pass of a still, walking or straight-driving
    intruder the fit is exact and its sigmas as honest as promised, while the filter's
    mixture is up to 20 % conservative in position (its constant-velocity and stop models
    both explain a still intruder; measured over the trials of ``tests/test_tracks.py``).

    Args:
        sighting_sigma_m: one sighting's position error per axis (m).
        velocity_prior_m_s: prior sigma of the velocity per axis without a track (m/s).
        prior: an earlier track of the same intruder, or None.
    """

    def __init__(
        self,
        sighting_sigma_m: float = SIGHTING_SIGMA_M,
        velocity_prior_m_s: float = FIT_VELOCITY_PRIOR_M_S,
        prior: Track | None = None,
    ) -> None:
        """No sightings yet."""
        self.fit = CvFit(sighting_sigma_m, velocity_prior_m_s, prior)
        self.motion = MotionFilter(sighting_sigma_m, velocity_prior_m_s, prior)
        self.sighting_sigma_m = self.fit.sighting_sigma_m
        self._cache: Track | None = None

    def __len__(self) -> int:
        """Sightings held (the prior's not counted)."""
        return len(self.fit)

    def add(self, t_s: float, pos_m: complex) -> None:
        """One sighting at ``t_s`` (s) of the intruder at ``pos_m`` (complex m), in time
        order."""
        self.fit.add(t_s, pos_m)
        self.motion.add(t_s, pos_m)
        self._cache = None

    def track(self) -> Track | None:
        """The track at the newest sighting; None with no sighting."""
        if self._cache is not None:
            return self._cache
        cv, mm = self.fit.track(), self.motion.track()
        if cv is None or mm is None:
            return cv
        if mm.model == "turn":
            self._cache = mm
        else:
            self._cache = replace(
                cv,
                model=mm.model,
                model_p=mm.model_p,
                turn_rad_s=mm.turn_rad_s,
                manoeuvre_m_s2=mm.manoeuvre_m_s2,
            )
        return self._cache


def track_refusal(track: Track, now_s: float, max_age_s: float) -> str | None:
    """Why a track must not be flown, or None: non-finite numbers, a negative uncertainty, a
    speed no intruder has (above ``MAX_INTRUDER_SPEED_M_S``), a model probability outside
    [0, 1], a turn rate above ``MAX_TURN_RATE_RAD_S`` or a manoeuvre outside
    [0, ``MAX_MANOEUVRE_M_S2``], an age above ``max_age_s`` (s) at ``now_s`` (s)."""
    numbers = (
        track.t_s,
        track.pos_m.real,
        track.pos_m.imag,
        track.vel_m_s.real,
        track.vel_m_s.imag,
        track.pos_sigma_m,
        track.vel_sigma_m_s,
    )
    if not all(math.isfinite(x) for x in numbers):
        return "non-finite track"
    if track.pos_sigma_m < 0.0 or track.vel_sigma_m_s < 0.0:
        return "negative track uncertainty"
    if abs(track.vel_m_s) > MAX_INTRUDER_SPEED_M_S:
        return f"track speed {abs(track.vel_m_s):.0f} m/s above {MAX_INTRUDER_SPEED_M_S:.0f} m/s"
    extra = (track.model_p, track.turn_rad_s, track.manoeuvre_m_s2)
    if not all(math.isfinite(x) for x in extra):
        return "non-finite track"
    if not 0.0 <= track.model_p <= 1.0:
        return f"model probability {track.model_p:.2f} not in [0, 1]"
    if abs(track.turn_rad_s) > MAX_TURN_RATE_RAD_S:
        return f"turn rate {track.turn_rad_s:.1f} rad/s above {MAX_TURN_RATE_RAD_S:.1f} rad/s"
    if not 0.0 <= track.manoeuvre_m_s2 <= MAX_MANOEUVRE_M_S2:
        return f"manoeuvre {track.manoeuvre_m_s2:.1f} m/s^2 not in [0, {MAX_MANOEUVRE_M_S2:.0f}]"
    if now_s - track.t_s > max_age_s:
        return f"track {now_s - track.t_s:.0f} s old (time-out {max_age_s:.0f} s)"
    return None
