"""The paper's analytic same-direction trochoid solutions (section IV.B, eq. 22-31).

Conventions: complex positions ``north + i east`` (m), compass angles (rad), positive turn
rate = right turn (``delta = +1``, word ``RSR``; ``delta = -1`` is ``LSL``).

The paper works in the trochoidal frame: rotate about the start so the wind ``beta`` lies
along +x; a turn at the maximum rate ``omega`` then traces the trochoid
``z(t) = z_0 + beta t - i delta rho exp(i (delta omega t + phi))``, ``rho = s0 / omega``
(eq. 22-25 written as one complex equation). For ``k in {-3..2}`` and both senses the
connecting straight has the constant direction ``alpha`` (computed with atan2,
docs/design.md §6) and ``t_A`` follows from eq. 29; ``t_A`` is taken modulo ``t_2pi`` in
both places allowed by (28). Candidates are checked against (26)-(28) and timed with (30)-(31).

For a goal moving at constant ground velocity ``v`` the same equations hold in the frame
moving with the goal, with the relative wind ``w - v`` (it must be slower than the airspeed).
Everything is vectorised over the 2 x 6 x 2 candidates.
"""

from __future__ import annotations

import numpy as np

from companion.core.wind import TWO_PI

Candidate = tuple[float, str, tuple[float, ...]]
"""(time_s, word, durations_s): a path word such as ``"RSR"`` and its piece durations."""

_K = np.arange(-3, 3)


def paper_candidates(
    goal_m: complex,
    start_heading_rad: float,
    final_heading_rad: float,
    airspeed_m_s: float,
    max_turn_rate_rad_s: float,
    drift_m_s: complex,
) -> list[Candidate]:
    """All turn-straight-turn paths of eq. 29 that satisfy (26)-(28), fastest first.

    Args:
        goal_m: goal relative to the start at t = 0 (m, complex).
        start_heading_rad: initial air heading ``theta_0`` (rad).
        final_heading_rad: final air heading ``theta_f`` (rad).
        airspeed_m_s: airspeed ``s0`` (m/s).
        max_turn_rate_rad_s: ``omega`` (rad/s).
        drift_m_s: wind relative to the goal's motion, ``w - v_goal`` (m/s, complex);
            its magnitude must be below ``airspeed_m_s``.

    Returns:
        Candidates ``(time_s, word, (t_turn1, t_straight, t_turn2))`` sorted by time.
    """
    s0, om = airspeed_m_s, max_turn_rate_rad_s
    beta = abs(drift_m_s)
    theta_w = float(np.angle(drift_m_s)) if beta > 0 else 0.0
    rho, t2pi = s0 / om, TWO_PI / om
    zf = goal_m * np.exp(-1j * theta_w)  # start at the origin of the trochoidal frame
    delta = np.array([1.0, -1.0])[:, None, None]
    k = _K[None, :, None]
    shift = np.array([0.0, 1.0])[None, None, :]  # t_A and t_A + t_2pi, see (28)

    phi1 = start_heading_rad - theta_w
    phi2 = final_heading_rad - theta_w - delta * TWO_PI
    z10 = 1j * delta * rho * np.exp(1j * phi1)
    z20 = zf + 1j * delta * rho * np.exp(1j * (phi2 + delta * TWO_PI)) - beta * t2pi
    c_k = (phi1 - phi2 + 2.0 * np.pi * k) / (delta * om)  # t_B - t_A
    gap = z20 - z10 + beta * c_k  # B - A, constant for same-sense turns
    alpha = np.arctan2(gap.imag, gap.real)
    t_a = (np.arcsin(beta / s0 * np.sin(alpha)) + alpha - phi1) / (delta * om)  # eq. 29
    t_a = t_a % t2pi + shift * t2pi
    t_b = t_a + c_k

    phi_a = delta * om * t_a + phi1
    vel_a = s0 * np.exp(1j * phi_a) + beta
    phi_b = delta * om * t_b + phi2
    vel_b = s0 * np.exp(1j * phi_b) + beta
    a_pt = z10 + beta * t_a - 1j * delta * rho * np.exp(1j * phi_a)
    z20_t = z20 + beta * t_b - 1j * delta * rho * np.exp(1j * phi_b)
    chord = z20_t - a_pt
    length = np.abs(chord)
    speed = np.abs(vel_a)
    tol = 1e-6 * (1.0 + length)
    ok = (
        (np.abs(vel_a - vel_b) < 1e-6 * s0)  # (26)
        & (np.abs((chord * np.conj(vel_a)).imag) < tol * speed)  # (27): chord along velocity
        & ((chord * np.conj(vel_a)).real >= -tol * speed)  # ... and flown forwards
        & (t_a >= 0.0)
        & (t_a < 2.0 * t2pi)  # (28)
        & (t_b > -t2pi)
        & (t_b <= t2pi + 1e-9)
    )
    t_straight = length / speed
    total = t_a + t_straight + (t2pi - t_b)  # (30), (31)
    out: list[Candidate] = []
    for i, j, m in zip(*np.nonzero(ok), strict=True):
        word = "RSR" if delta[i, 0, 0] > 0 else "LSL"
        durs = (
            float(t_a[i, j, m]),
            float(t_straight[i, j, m]),
            float(max(t2pi - t_b[i, j, m], 0.0)),
        )
        out.append((float(total[i, j, m]), word, durs))
    out.sort(key=lambda c: c[0])
    return out
