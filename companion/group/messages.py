"""What the companions say to each other (frozen dataclasses; the bytes are
:mod:`companion.group.codec`, the wire format ``docs/protocol.md``).

* :class:`MemberState` -- a member's centre, time-phase and mode, at 5 Hz;
* :class:`Alert` -- an intruder alert and its lifecycle messages (new, confirmed, cleared,
  bid, update, lost), each with the intruder's :class:`Track` where the sender has one;
* :class:`WindRecord` -- the fleet's agreed wind, relayed in every state;
* :class:`Energy` -- a member's battery and relief role (docs/energy.md).

Positions are complex ``north + i east`` metres, phases radians, times vehicle seconds.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Literal, get_args

from companion.core.wind import TWO_PI, wrap_2pi


@dataclass(frozen=True)
class WindRecord:
    """An agreed wind.

    Attributes:
        seq: sequence number (0 = the mission's wind).
        proposer: system id of the member that made it (0 for the mission's).
        wind_m_s: wind vector (m/s, towards, ``north + i east``).
        t_eff_s: vehicle time from which it is in force (s).
    """

    seq: int
    proposer: int
    wind_m_s: complex
    t_eff_s: float

    def newer_than(self, other: WindRecord) -> bool:
        """True if this record supersedes ``other`` (higher seq; same seq: lower proposer)."""
        return (self.seq, -self.proposer) > (other.seq, -other.proposer)


class Mode(StrEnum):
    """What a UAV is doing, one word from the wire (``PATROL_MODE``) to the logs and the page.

    ``prosecuting``, ``searching`` (for an intruder not where its track predicted) and
    ``rejoining`` members share their virtual particle, not their real state (docs/design.md §5); a
    ``tracking`` member stays over a persistent intruder and is out of
    the formation (the others splay as N - 1); a ``spare`` is out of it too (waiting,
    flying in to relieve a member, or relieved and flying home; docs/energy.md), and so is an
    ``overridden`` member: its autopilot took it from its companion (a pilot's mode, or a
    failsafe), and its companion says so at once rather than fall silent for the member
    time-out (its real position; docs/companion.md, "When the autopilot takes over"). The
    Agent's finer stages are :class:`companion.agent.modes.OwnMode`.
    """

    PATROL = "patrol"
    PROSECUTING = "prosecuting"
    REJOINING = "rejoining"
    TRACKING = "tracking"
    SEARCHING = "searching"
    SPARE = "spare"
    OVERRIDDEN = "overridden"


OUT_OF_FORMATION = (Mode.TRACKING, Mode.SPARE, Mode.OVERRIDDEN)  # the others splay without

ReliefRole = Literal["on_station", "spare", "relieving", "home", "unavailable"]
RELIEF_ROLES: tuple[ReliefRole, ...] = ("on_station", "spare", "relieving", "home", "unavailable")


@dataclass(frozen=True)
class Energy:
    """What a member shares about its battery and the reliefs (state version 3).

    Attributes:
        role: ``on_station`` (on the loop; ``t_s`` the vehicle time it must leave for
            home), ``spare`` (waiting on the ground or holding; ``t_s`` when it is ready,
            charged), ``relieving`` (launched, flying in for member ``relief_sysid``) or
            ``home`` (relieved, flying home to land) or ``unavailable`` (a spare that could not
            take off: out of the rotation).
        battery_pct: charge left (%), None if unknown.
        t_s: the role's time (vehicle s, see ``role``); None if unknown.
        relief_sysid: ``relieving``: the member it flies in for; ``on_station``: the member
            it has just relieved (0: none).
    """

    role: ReliefRole
    battery_pct: float | None = None
    t_s: float | None = None
    relief_sysid: int = 0


@dataclass(frozen=True)
class MemberState:
    """What a member broadcasts (docs/design.md §5): centre, time-phase and mode.

    Attributes:
        sysid: MAVLink system id.
        t_s: time of the state (s, the member's vehicle time).
        centre_m: loop centre ``c`` (world, complex m); ``c0`` for a virtual particle.
        phase_rad: time-phase ``psi`` (rad).
        mode: ``patrol`` (its real state), ``prosecuting`` (flying to an alert; the state is
            its virtual particle), ``rejoining`` (flying back into its slot; still the
            virtual particle) or ``tracking`` (over a persistent intruder, out of the
            formation; its real state).
        alert_id: the alert it is away for ("" on patrol).
        pos_m: its real position (world, complex m), None if not shared (state version 1).
        wind_est_m_s: its own wind estimate (m/s, towards), None if it has none.
        wind_record: the newest agreed-wind record it knows, None if not shared.
        energy: its battery and relief role (state version 3), None if not shared.
    """

    sysid: int
    t_s: float
    centre_m: complex
    phase_rad: float
    mode: Mode = Mode.PATROL
    alert_id: str = ""
    pos_m: complex | None = None
    wind_est_m_s: complex | None = None
    wind_record: WindRecord | None = None
    energy: Energy | None = None

    def __post_init__(self) -> None:
        """A mode given as its string is taken as the :class:`Mode` (an unknown one raises
        ``ValueError``)."""
        if type(self.mode) is not Mode:
            object.__setattr__(self, "mode", Mode(self.mode))

    def phase_at(self, t_s: float, period_s: float) -> float:
        """Phase extrapolated to ``t_s`` at the nominal rate (rad)."""
        return float(wrap_2pi(self.phase_rad + TWO_PI * (t_s - self.t_s) / period_s))


SIGHTING_SIGMA_M = 3.0  # one sighting's position error per axis (geolocation, GPS), m
VELOCITY_PRIOR_M_S = 3.0  # velocity sigma per axis of a track no sensor made (a point): m/s
MotionModel = Literal["cv", "turn", "stop"]
MODELS: tuple[MotionModel, ...] = get_args(MotionModel)  # PATROL_ALERT track_model 0, 1, 2
MAX_TURN_RAD = math.pi / 2  # a turn track's prediction turns at most this far, then on straight


@dataclass(frozen=True)
class Track:
    """An intruder's estimated state at ``t_s``.

    Attributes:
        t_s: time of the estimate (s, vehicle time): the newest sighting's.
        pos_m: position at ``t_s`` (complex m).
        vel_m_s: ground velocity (complex m/s).
        pos_sigma_m: 1-sigma position error per axis at ``t_s`` (m).
        vel_sigma_m_s: 1-sigma velocity error per axis (m/s).
        sightings: how many sightings it is made of (0: a report with no track, e.g. the
            operator's alert).
        model: the motion model of highest probability (alert version 3;
            :mod:`companion.agent.alerts.motion`): "cv" (constant velocity), "turn"
            (coordinated turn at ``turn_rad_s``) or "stop".
        model_p: that model's probability (0-1).
        turn_rad_s: the turn model's rate (rad/s, positive from north towards east); the
            prediction follows its arc when ``model`` is "turn", for at most
            ``MAX_TURN_RAD``.
        manoeuvre_m_s2: acceleration of a manoeuvre (m/s^2): the prediction's uncertainty
            grows by ``a dt^2 / 2`` on top of the velocity's, at most ``|v| dt``
            (:meth:`sigma_m`); 0 (a version-2 track): the velocity's alone.
    """

    t_s: float
    pos_m: complex
    vel_m_s: complex = 0j
    pos_sigma_m: float = SIGHTING_SIGMA_M
    vel_sigma_m_s: float = VELOCITY_PRIOR_M_S
    sightings: int = 1
    model: MotionModel = "cv"
    model_p: float = 1.0
    turn_rad_s: float = 0.0
    manoeuvre_m_s2: float = 0.0

    def _turn_dt(self, dt: float) -> tuple[float, float]:
        """The part of ``dt`` (s) flown on the turn's arc and the part straight after it."""
        w = abs(self.turn_rad_s)
        if self.model != "turn" or w < 1e-6 or dt <= 0.0:
            return 0.0, dt
        on_arc = min(dt, MAX_TURN_RAD / w)
        return on_arc, dt - on_arc

    def predict(self, t_s: float) -> complex:
        """Predicted position at ``t_s`` (complex m): along the turn's arc for a "turn"
        track (at most ``MAX_TURN_RAD``, then straight), else straight."""
        dt = t_s - self.t_s
        on_arc, straight = self._turn_dt(dt)
        if on_arc == 0.0:
            return self.pos_m + self.vel_m_s * dt
        w = self.turn_rad_s
        rot = cmath.exp(1j * w * on_arc)
        arc = self.vel_m_s * (rot - 1.0) / (1j * w)
        return self.pos_m + arc + self.vel_m_s * rot * straight

    def velocity_at(self, t_s: float) -> complex:
        """Predicted velocity at ``t_s`` (complex m/s): turned along the arc for a "turn"
        track."""
        on_arc, _ = self._turn_dt(t_s - self.t_s)
        return self.vel_m_s * cmath.exp(1j * self.turn_rad_s * on_arc) if on_arc else self.vel_m_s

    def sigma_m(self, t_s: float) -> float:
        """1-sigma position error per axis of the prediction at ``t_s`` (m): the position's,
        the velocity's over the time since, and a manoeuvre's ``a dt^2 / 2`` at most
        ``|v| dt``: a change of the velocity it has (a stop leaves it ``|v| dt`` behind the
        prediction, a turn about as far aside), so a still track grows only by its
        velocity's sigma, as before."""
        dt = t_s - self.t_s
        if self.manoeuvre_m_s2 <= 0.0:
            return math.hypot(self.pos_sigma_m, self.vel_sigma_m_s * dt)
        dt = abs(dt)
        man = min(0.5 * self.manoeuvre_m_s2 * dt * dt, abs(self.vel_m_s) * dt)
        return math.sqrt(self.pos_sigma_m**2 + (self.vel_sigma_m_s * dt) ** 2 + man**2)

    def vel_sigma_at(self, t_s: float) -> float:
        """1-sigma velocity error per axis at ``t_s`` (m/s): grown by the manoeuvre's
        ``a dt``, at most its speed ``|v|``."""
        if self.manoeuvre_m_s2 <= 0.0:
            return self.vel_sigma_m_s
        dt = abs(t_s - self.t_s)
        return math.hypot(self.vel_sigma_m_s, min(self.manoeuvre_m_s2 * dt, abs(self.vel_m_s)))

    def at(self, t_s: float) -> Track:
        """This track predicted to ``t_s`` (s): position, velocity and their sigmas then,
        the same sightings and model."""
        return replace(
            self,
            t_s=t_s,
            pos_m=self.predict(t_s),
            vel_m_s=self.velocity_at(t_s),
            pos_sigma_m=self.sigma_m(t_s),
            vel_sigma_m_s=self.vel_sigma_at(t_s),
        )

    def moving(self) -> bool:
        """Whether the velocity is known to be nonzero (beyond two sigma)."""
        return abs(self.vel_m_s) > 2.0 * self.vel_sigma_m_s


AlertState = Literal["new", "confirmed", "cleared", "bid", "update", "lost"]


@dataclass(frozen=True)
class Alert:
    """An intruder alert as shared over the group.

    Attributes:
        alert_id: unique id (``"<detector sysid>-<sequence>"``).
        site_m: where the intruder was seen (world, complex m).
        detector_sysid: the UAV that reported it (for a confirmation, the confirming UAV).
        t_s: time of the report (s, vehicle time).
        state: "new", "confirmed" (seen again by its prosecutor), "cleared" (not seen
            where it was looked for; from the operator: stop), "bid" (a member's planned
            time under the "fastest" policy; ``detector_sysid`` is the bidder), "update" (a
            newer track from whoever sees it) or "lost" (its tracker lost it).
        bid_s: the bidder's planned time (s), for "bid" only.
        track: the intruder's track, or None (an operator's alert, a clear, a bid). When
            given, its time and position are the report's (``t_s``, ``site_m``).
    """

    alert_id: str
    site_m: complex
    detector_sysid: int
    t_s: float
    state: AlertState = "new"
    bid_s: float = 0.0
    track: Track | None = None
