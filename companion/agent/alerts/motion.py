"""An intruder's motion from its sightings (pure): an interacting multiple-model filter.

Three models of how an intruder moves, run side by side on one state
``x = [north, east, v_north, v_east, turn]`` (m, m/s, rad/s), each a Kalman filter, mixed at
every sighting by the standard IMM cycle (Blom and Bar-Shalom; Bar-Shalom, Li and
Kirubarajan, *Estimation with Applications to Tracking*, 11.6):

* ``cv`` -- nearly constant velocity: a walker on its way, a vehicle on a straight road.
  White-noise acceleration of low spectral density ``Q_CV_M2_S3``, so two passes twenty
  seconds apart still know the velocity well; the turn is held at 0.
* ``turn`` -- a coordinated turn at the estimated rate (extended Kalman filter: the arc
  ``p + v (e^{i w dt} - 1) / (i w)``, the velocity rotated by ``w dt``), the same low
  acceleration noise (``Q_TURN_M2_S3``) and a random-walk turn rate (``Q_W_RAD2_S3``): a
  vehicle at a junction. (More acceleration noise here made it explain a straight walker as
  well as ``cv`` does, and its wide velocity then spoilt the mixture's after two passes.)
* ``stop`` -- still: the position holds, the velocity is drawn afresh each step about 0
  (``STOP_SHUFFLE_M_S``: a walker behind cover shuffles; a zero there made the mixture
  over-sure of a slow walker's velocity, 93 % within three sigma instead of 97 %).

Each model's probability follows the sightings (their likelihoods) and a switching chance
that grows with the time between sightings (a model is kept for about ``SOJOURN_S`` s on
average), so a track that was straight for one pass and is met 30 s later is open to a turn
or a stop. A filter started from an earlier track predicts it to its first sighting with
each model unmixed (mixing across a 20 s gap let the stop model erase a walker's velocity).
Its estimate (:class:`~companion.group.messages.Track`) is the mixture's: its mean and its
spread (the models' covariances and their disagreement), the model of highest probability
(``model``, ``model_p``), the turn model's rate (``turn_rad_s``) and the mixture's manoeuvre
acceleration (``manoeuvre_m_s2``: the prediction's uncertainty grows by ``a dt^2 / 2``, at
most ``|v| dt``: ``Track.sigma_m``). So a prediction that has grown is searched, not
cleared. The mixture is up to 20 % conservative in position for a still intruder (its
constant-velocity and stop models both explain it), so the shared track takes the
constant-velocity fit's position and velocity where the turn model is not in use
(:class:`companion.agent.alerts.track.TrackFit`).

Short sightings stay honest: without an earlier track the velocity starts at 0 with
``velocity_prior_m_s`` (10 m/s) per axis, the floor a vehicle needs: two sightings a fifth
of a second apart cannot know a vehicle's speed, and a 10 m/s vehicle seen for 1 s is not
pulled towards still (``tests/test_tracks.py``).

Measured (2026-12-07, this 2-core machine shared with others, Python 3 with numpy on 5 x 5
matrices, 1000 sightings in a row): one sighting (mix, three predicts, three updates) 0.3-0.5
ms. Tracks are updated only on sightings (5 Hz while an intruder is under a sensor, nothing
otherwise), so at the 10 Hz control step that is at most 0.05 ms a step on average over a
pass and none between passes: within the companion's 0.4 ms budget per step.
Stone Soup 1.9.1 (``pip download stonesoup`` works here) took 1.2 ms for one
constant-velocity Kalman predict and update (its ``KalmanPredictor`` and ``KalmanUpdater``,
300 steps), so an IMM of three would cost about 4 ms per sighting: it does not fit, and
this module is written with numpy.

Conventions: positions ``north + i east`` (complex m), velocities complex m/s, turn rate
positive from north towards east (rad/s), times vehicle seconds, passed in.
"""

from __future__ import annotations

import cmath
import math

import numpy as np

from companion.group.messages import MODELS, SIGHTING_SIGMA_M, Track

FIT_VELOCITY_PRIOR_M_S = 10.0  # prior sigma per axis of an unknown intruder's velocity (m/s)
TURN_PRIOR_RAD_S = 0.1  # prior sigma of the turn rate (rad/s): about 6 deg/s
Q_CV_M2_S3 = 0.001  # cv: acceleration noise spectral density per axis (m^2/s^3)
Q_TURN_M2_S3 = 0.001  # turn: acceleration noise (m^2/s^3)
Q_W_RAD2_S3 = 0.002  # turn: turn-rate noise (rad^2/s^3)
Q_STOP_M2_S = 0.001  # stop: position noise (m^2/s)
STOP_SHUFFLE_M_S = 0.5  # stop: velocity per axis, drawn afresh each step (m/s): a shuffle
SOJOURN_S = {"cv": 60.0, "turn": 20.0, "stop": 60.0}  # mean time in a model (s)
MANOEUVRE_M_S2 = {"cv": 0.3, "turn": 2.0, "stop": 0.3}  # acceleration of a manoeuvre (m/s^2)
START_P = {"cv": 0.9, "turn": 0.05, "stop": 0.05}  # model probabilities without a prior

_H = np.zeros((2, 5))
_H[0, 0] = _H[1, 1] = 1.0
_I5 = np.eye(5)


def _cv_block(q: float, dt: float) -> np.ndarray:
    """Process noise of white acceleration ``q`` (m^2/s^3) over ``dt`` (s) on [p, v] pairs."""
    q_mat = np.zeros((5, 5))
    a, b, c = q * dt**3 / 3.0, q * dt**2 / 2.0, q * dt
    for i in (0, 1):
        q_mat[i, i], q_mat[i, i + 2], q_mat[i + 2, i], q_mat[i + 2, i + 2] = a, b, b, c
    return q_mat


def _predict(model: str, x: np.ndarray, p: np.ndarray, dt: float) -> tuple:
    """One model's prediction of ``(x, P)`` over ``dt`` (s)."""
    if model == "cv":
        f = np.eye(5)
        f[0, 2] = f[1, 3] = dt
        f[4, 4] = 0.0
        q = _cv_block(Q_CV_M2_S3, dt)
        q[4, 4] = (0.1 * TURN_PRIOR_RAD_S) ** 2
        return f @ x, f @ p @ f.T + q
    if model == "stop":
        f = np.zeros((5, 5))
        f[0, 0] = f[1, 1] = 1.0
        v2 = STOP_SHUFFLE_M_S**2
        q = np.diag([Q_STOP_M2_S * dt, Q_STOP_M2_S * dt, v2, v2, (0.1 * TURN_PRIOR_RAD_S) ** 2])
        return f @ x, f @ p @ f.T + q
    w = float(x[4])
    wt = w * dt
    if abs(wt) < 1e-6:
        s_w, c_w = dt, 0.0  # sin(wt)/w, (1 - cos wt)/w
        ds, dc = 0.0, dt * dt / 2.0  # their derivatives in w
    else:
        s_w, c_w = math.sin(wt) / w, (1.0 - math.cos(wt)) / w
        ds = (dt * math.cos(wt) - s_w) / w
        dc = (dt * math.sin(wt) - c_w) / w
    cs, sn = math.cos(wt), math.sin(wt)
    vn, ve = float(x[2]), float(x[3])
    f = np.eye(5)
    f[0, 2], f[0, 3] = s_w, -c_w
    f[1, 2], f[1, 3] = c_w, s_w
    f[2, 2], f[2, 3] = cs, -sn
    f[3, 2], f[3, 3] = sn, cs
    x_new = f @ x
    jac = f.copy()
    jac[0, 4] = ds * vn - dc * ve
    jac[1, 4] = dc * vn + ds * ve
    jac[2, 4] = -dt * sn * vn - dt * cs * ve
    jac[3, 4] = dt * cs * vn - dt * sn * ve
    q = _cv_block(Q_TURN_M2_S3, dt)
    q[4, 4] = Q_W_RAD2_S3 * dt
    return x_new, jac @ p @ jac.T + q


class MotionFilter:
    """The IMM over one intruder's sightings, optionally on top of an earlier track.

    Args:
        sighting_sigma_m: one sighting's position error per axis (m).
        velocity_prior_m_s: prior sigma of the velocity per axis without a track (m/s).
        prior: an earlier track of the same intruder (another member's, an earlier pass),
            or None. It starts the filter (its mean, its sigmas, its model) and is predicted
            to the first sighting by each model, with its manoeuvre noise.
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
        self._r = np.eye(2) * self.sighting_sigma_m**2
        self._x: list[np.ndarray] = []
        self._p: list[np.ndarray] = []
        self._mu = np.array([START_P[m] for m in MODELS])
        self._t: float | None = None
        self._n = 0
        self._cache: Track | None = None

    def __len__(self) -> int:
        """Sightings taken in (the prior's not counted)."""
        return self._n

    def _start(self, t_s: float, pos_m: complex) -> bool:
        """Start from the prior (True: then update with this sighting) or from this sighting
        alone (False)."""
        pr = self.prior
        if pr is not None and pr.t_s < t_s:
            x = np.array([pr.pos_m.real, pr.pos_m.imag, pr.vel_m_s.real, pr.vel_m_s.imag, 0.0])
            x[4] = pr.turn_rad_s
            p = np.diag(
                [
                    pr.pos_sigma_m**2,
                    pr.pos_sigma_m**2,
                    pr.vel_sigma_m_s**2,
                    pr.vel_sigma_m_s**2,
                    TURN_PRIOR_RAD_S**2,
                ]
            )
            self._mu = np.array([START_P[m] for m in MODELS])
            self._x = [x.copy() for _ in MODELS]
            self._p = [p.copy() for _ in MODELS]
            self._t = pr.t_s
            return True
        v2 = self.velocity_prior_m_s**2
        s2 = self.sighting_sigma_m**2
        x = np.array([pos_m.real, pos_m.imag, 0.0, 0.0, 0.0])
        p = np.diag([s2, s2, v2, v2, TURN_PRIOR_RAD_S**2])
        self._x = [x.copy() for _ in MODELS]
        self._p = [p.copy() for _ in MODELS]
        self._p[MODELS.index("stop")][2:4, 2:4] = 0.0
        self._t = t_s
        return False

    def _mix(self, dt: float) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
        """The IMM's mixing over ``dt`` (s): each model's starting mean and covariance, and
        the predicted model probabilities."""
        n = len(MODELS)
        pi = np.empty((n, n))
        for i, m in enumerate(MODELS):
            stay = math.exp(-dt / SOJOURN_S[m])
            pi[i, :] = (1.0 - stay) / (n - 1)
            pi[i, i] = stay
        c = self._mu @ pi
        xs, ps = [], []
        for j in range(n):
            w = pi[:, j] * self._mu / max(c[j], 1e-300)
            x0 = sum(w[i] * self._x[i] for i in range(n))
            p0 = np.zeros((5, 5))
            for i in range(n):
                d = self._x[i] - x0
                p0 += w[i] * (self._p[i] + np.outer(d, d))
            xs.append(x0)
            ps.append(p0)
        return xs, ps, c

    def add(self, t_s: float, pos_m: complex) -> None:
        """One sighting at ``t_s`` (s) of the intruder at ``pos_m`` (complex m); sightings
        must come in time order (an older one, or a non-finite one, is ignored)."""
        if not (math.isfinite(t_s) and math.isfinite(pos_m.real) and math.isfinite(pos_m.imag)):
            return
        if self._t is not None and t_s < self._t:
            return
        self._cache = None
        self._n += 1
        if self._t is None and not self._start(t_s, pos_m):
            return
        assert self._t is not None
        dt = t_s - self._t
        if self._n == 1:  # from the prior: each model predicts it, unmixed, from its time
            xs, ps, c = list(self._x), list(self._p), self._mu
        else:
            xs, ps, c = self._mix(dt)
        z = np.array([pos_m.real, pos_m.imag])
        like = np.empty(len(MODELS))
        for j, m in enumerate(MODELS):
            x, p = _predict(m, xs[j], ps[j], dt) if dt > 0 else (xs[j], ps[j])
            s = p[0:2, 0:2] + self._r
            det = float(s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0])
            s_inv = np.array([[s[1, 1], -s[0, 1]], [-s[1, 0], s[0, 0]]]) / det
            k = p[:, 0:2] @ s_inv
            r = z - x[:2]
            self._x[j] = x + k @ r
            ikh = _I5 - k @ _H
            self._p[j] = ikh @ p @ ikh.T + k @ self._r @ k.T
            m2 = float(r @ s_inv @ r)
            like[j] = math.exp(-0.5 * min(m2, 700.0)) / (2.0 * math.pi * math.sqrt(det))
        mu = like * c
        total = float(mu.sum())
        self._mu = mu / total if total > 0.0 and math.isfinite(total) else c / float(c.sum())
        self._t = t_s

    def probabilities(self) -> dict[str, float]:
        """Each model's probability now."""
        return {m: float(p) for m, p in zip(MODELS, self._mu, strict=True)}

    def track(self) -> Track | None:
        """The mixture's track at the newest sighting; None with no sighting."""
        if self._n == 0 or self._t is None:
            return None
        if self._cache is not None:
            return self._cache
        mu = self._mu
        x = sum(mu[j] * self._x[j] for j in range(len(MODELS)))
        p = np.zeros((5, 5))
        for j in range(len(MODELS)):
            d = self._x[j] - x
            p += mu[j] * (self._p[j] + np.outer(d, d))
        pos_var = 0.5 * float(p[0, 0] + p[1, 1])
        vel_var = float(np.linalg.eigvalsh(p[2:4, 2:4])[-1])
        best = int(np.argmax(mu))
        turn = float(self._x[MODELS.index("turn")][4])
        manoeuvre = float(sum(mu[j] * MANOEUVRE_M_S2[m] for j, m in enumerate(MODELS)))
        seen = self._n + (self.prior.sightings if self.prior is not None else 0)
        self._cache = Track(
            self._t,
            complex(x[0], x[1]),
            complex(x[2], x[3]),
            math.sqrt(max(pos_var, 0.0)),
            math.sqrt(max(vel_var, 0.0)),
            seen,
            model=MODELS[best],
            model_p=float(mu[best]),
            turn_rad_s=turn,
            manoeuvre_m_s2=manoeuvre,
        )
        return self._cache


def arc_m(vel_m_s: complex, turn_rad_s: float, dt_s: float) -> complex:
    """Displacement (complex m) over ``dt_s`` (s) of an intruder at ``vel_m_s`` (m/s) turning
    at ``turn_rad_s`` (rad/s): the coordinated turn's arc (a straight line at no turn)."""
    wt = turn_rad_s * dt_s
    if abs(wt) < 1e-9:
        return vel_m_s * dt_s
    return vel_m_s * (cmath.exp(1j * wt) - 1.0) / (1j * turn_rad_s)
