"""One UAV's view of the formation: members' shared states and the splay command.

Pure: the caller passes the time (vehicle seconds) and the states received from the group.
A member's time-phase is extrapolated from its last broadcast at the nominal rate
(``psi_j + 2 pi age / T``), with the age judged by local receipt time (docs/design.md §7).
"""

from __future__ import annotations

import math

import numpy as np

from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, Wind
from companion.guidance.steering import (
    Gains,
    length_scale_m2_s,
    phase_speed_offset,
    speed_holds_phase,
    splay_curvature_m2_s,
    splay_gradient_of,
    steering_turn_rate,
    tracking_gradient,
)


def splay_command(
    patrol: Patrol,
    gains: Gains,
    pos_m: complex,
    heading_rad: float,
    own_phase_rad: float,
    own_centre_m: complex,
    others: list[tuple[float, complex]],
    max_turn_rate_rad_s: float,
    steer_limit_m: float = math.inf,
) -> float:
    """Turn-rate command (rad/s, positive right) of the time-splay law for one UAV.

    Args:
        patrol: loop, airspeed and wind.
        gains: steering gains.
        pos_m: own position (world, complex m).
        heading_rad: own air heading (rad).
        own_phase_rad: own time-phase (rad).
        own_centre_m: own loop centre (world, complex m); used by the mean-centre form.
        others: (phase rad, centre m) of every other active member, already extrapolated.
        max_turn_rate_rad_s: saturation (rad/s).
        steer_limit_m: most slot error (along-track m) left to the steering
            (:func:`steered_phase_gradient`); ``inf``: the paper's acquisition.
    """
    n = len(others) + 1
    grad = splay_gradient_of(own_phase_rad, [p for p, _ in others], _k(patrol, gains, n))
    grad = steered_phase_gradient(patrol, gains, grad, n, steer_limit_m)
    if gains.centre_form == "fixed":
        c_ref = patrol.centre_m  # the fixed centre needs no members' centres
    else:
        c_ref = (own_centre_m + sum(c for _, c in others)) / n
    return steering_turn_rate(patrol, gains, pos_m, heading_rad, grad, c_ref, max_turn_rate_rad_s)


def steered_phase_gradient(
    patrol: Patrol, gains: Gains, grad: float, n: int, steer_limit_m: float = math.inf
) -> float:
    """The part of ``dU/dpsi_k`` (m^2/s) left to the steering when the airspeed holds the
    phase: the slot error the airspeed can take out (``speed_authority_m_s * speed_tau_s``
    of along-track metres) is left to it, softly (``r = e - z tanh(e / z)``), so near the
    splay the aircraft stays on the loop and a larger error (the acquisition) is still flown
    off the loop as the paper's law does. The whole gradient when the airspeed is fixed.

    ``steer_limit_m`` bounds the rest softly (``lim tanh(r / lim)``, along-track m): a
    formation that has formed re-splays along the loop, by airspeed, when a member leaves
    it or comes back, instead of flying off the loop (and out of the sensor's reach of it)
    to take out an error of a fraction of a slot at once."""
    z = gains.speed_authority_m_s * gains.speed_tau_s
    curv = splay_curvature_m2_s(patrol, gains, n)
    if not speed_holds_phase(gains) or curv <= 0.0:
        return grad
    e_m = grad / curv * patrol.length_m / TWO_PI
    if not math.isfinite(steer_limit_m):
        return grad - z * math.tanh(e_m / z) * curv * TWO_PI / patrol.length_m
    rest_m = e_m - z * math.tanh(e_m / z)
    rest_m = steer_limit_m * math.tanh(rest_m / steer_limit_m) if steer_limit_m > 0 else 0.0
    return rest_m * curv * TWO_PI / patrol.length_m


def splay_airspeed(
    patrol: Patrol, gains: Gains, own_phase_rad: float, other_phases_rad: list[float]
) -> float:
    """Airspeed (m/s) for one UAV on patrol: the mission's, changed by at most
    ``gains.speed_authority_m_s`` to hold its time-phase in the splay.

    Args:
        patrol: loop, airspeed and wind.
        gains: steering gains.
        own_phase_rad: own time-phase (rad).
        other_phases_rad: every other active member's time-phase (rad), extrapolated.
    """
    n = len(other_phases_rad) + 1
    grad = splay_gradient_of(own_phase_rad, other_phases_rad, _k(patrol, gains, n))
    curv = splay_curvature_m2_s(patrol, gains, n)
    return patrol.airspeed_m_s + phase_speed_offset(patrol, gains, grad, curv)


def splay_slot_error_m(
    patrol: Patrol, gains: Gains, own_phase_rad: float, other_phases_rad: list[float]
) -> float:
    """This UAV's slot error in the splay (along-track m, positive = ahead of its slot),
    read from the potential's gradient as :func:`phase_speed_offset` reads it; 0 alone."""
    n = len(other_phases_rad) + 1
    curv = splay_curvature_m2_s(patrol, gains, n)
    if curv <= 0.0:
        return 0.0
    grad = splay_gradient_of(own_phase_rad, other_phases_rad, _k(patrol, gains, n))
    return grad / curv * patrol.length_m / TWO_PI


def _k(patrol: Patrol, gains: Gains, n: int) -> float:
    """The splay's harmonic gain ``k`` (m^2/s) of ``n`` members: ``K_m = k`` for ``m < n``,
    ``K_n = -k`` (:func:`companion.guidance.steering.phase_gains_m2_s`)."""
    return gains.phase_gain * length_scale_m2_s(patrol) / n


def track_command(
    patrol: Patrol,
    gains: Gains,
    pos_m: complex,
    heading_rad: float,
    own_phase_rad: float,
    target_phase_rad: float,
    max_turn_rate_rad_s: float,
) -> float:
    """Turn-rate command (rad/s) that brings a UAV onto the loop at a target phase.

    The same Lyapunov design with the single-phase potential ``K_track (1 - cos(psi - psi_t))``
    and the fixed centre: used to fly a returning prosecutor into its virtual particle's slot.
    """
    grad = tracking_gradient(patrol, gains, own_phase_rad, target_phase_rad)
    return steering_turn_rate(
        patrol, gains, pos_m, heading_rad, grad, patrol.centre_m, max_turn_rate_rad_s
    )


SENSITIVITY_PROBE_M_S = 0.1  # size of the wind change probed (m/s)


def slot_shift_per_wind_s(patrol: Patrol, n: int) -> float:
    """Most a change of the fleet's wind moves one slot against another (m per m/s = s).

    The time-phase of a point on the loop depends on the wind, so adopting another wind
    moves every slot along the loop, each by its own amount. At ``n`` points a perfect splay
    apart, the shift of each one's distance along the loop from the first's is linear in a
    small wind change; probed with ``SENSITIVITY_PROBE_M_S`` towards the North and towards
    the East, its size in the worst direction is the length of that gradient. The largest
    over the points, per m/s: about 22 s on the paper's ellipse, 440 s on WPAFB; ``2 R /
    s0`` on a circle in still air. 0 for one member.
    """
    if n < 2:
        return 0.0
    phases = np.arange(n) * TWO_PI / n
    points = patrol.point_at_phase(phases)
    shifts = []
    for dw in (SENSITIVITY_PROBE_M_S, 1j * SENSITIVITY_PROBE_M_S):
        other = patrol.with_wind(Wind.from_vector(patrol.wind.vector + dw))
        moved = np.array([other.phase_of_point(complex(z)) for z in points])
        rel = np.angle(np.exp(1j * ((moved - moved[0]) - (phases - phases[0]))))
        shifts.append(rel * other.length_m / TWO_PI)
    gradient = np.hypot(shifts[0], shifts[1]) / SENSITIVITY_PROBE_M_S
    return float(np.max(gradient))


def wind_rate_limit_m_s2(patrol: Patrol, gains: Gains, n: int) -> float:
    """Fastest the fleet's wind may change (m/s per s) so that the slots it moves can be
    followed by the airspeed alone: ``speed_authority / slot_shift_per_wind``. 0 (no limit)
    when the airspeed does not hold the phase or there is nothing to splay."""
    if not speed_holds_phase(gains):
        return 0.0
    sens = slot_shift_per_wind_s(patrol, n)
    return gains.speed_authority_m_s / sens if sens > 0 else 0.0
