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

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

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
    """

    t_s: float
    pos_m: complex
    vel_m_s: complex = 0j
    pos_sigma_m: float = SIGHTING_SIGMA_M
    vel_sigma_m_s: float = VELOCITY_PRIOR_M_S
    sightings: int = 1

    def predict(self, t_s: float) -> complex:
        """Predicted position at ``t_s`` (complex m)."""
        return self.pos_m + self.vel_m_s * (t_s - self.t_s)

    def sigma_m(self, t_s: float) -> float:
        """1-sigma position error per axis of the prediction at ``t_s`` (m)."""
        dt = t_s - self.t_s
        return math.hypot(self.pos_sigma_m, self.vel_sigma_m_s * dt)

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
