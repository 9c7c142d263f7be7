"""What the companions say to each other (frozen dataclasses; the bytes are
:mod:`companion.group.codec`, the wire format ``docs/protocol.md``).

* :class:`MemberState` -- a member's centre, time-phase and mode, at 5 Hz;
* :class:`Alert` -- an intruder alert and its lifecycle messages (new, confirmed, cleared, bid);
* :class:`WindRecord` -- the fleet's agreed wind, relayed in every state.

Positions are complex ``north + i east`` metres, phases radians, times vehicle seconds.
"""

from __future__ import annotations

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

    ``prosecuting`` and ``rejoining`` members share their virtual particle, not their real
    state (DESIGN 5); the Agent's finer stages are :class:`companion.agent.modes.OwnMode`.
    """

    PATROL = "patrol"
    PROSECUTING = "prosecuting"
    REJOINING = "rejoining"


@dataclass(frozen=True)
class MemberState:
    """What a member broadcasts (DESIGN section 5): centre, time-phase and mode.

    Attributes:
        sysid: MAVLink system id.
        t_s: time of the state (s, the member's vehicle time).
        centre_m: loop centre ``c`` (world, complex m); ``c0`` for a virtual particle.
        phase_rad: time-phase ``psi`` (rad).
        mode: ``patrol`` (its real state), ``prosecuting`` (flying to an alert; the state is
            its virtual particle) or ``rejoining`` (flying back into its slot; still the
            virtual particle).
        alert_id: the alert it is away for ("" on patrol).
        pos_m: its real position (world, complex m), None if not shared (state version 1).
        wind_est_m_s: its own wind estimate (m/s, towards), None if it has none.
        wind_record: the newest agreed-wind record it knows, None if not shared.
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

    def __post_init__(self) -> None:
        """A mode given as its string is taken as the :class:`Mode` (an unknown one raises
        ``ValueError``)."""
        if type(self.mode) is not Mode:
            object.__setattr__(self, "mode", Mode(self.mode))

    def phase_at(self, t_s: float, period_s: float) -> float:
        """Phase extrapolated to ``t_s`` at the nominal rate (rad)."""
        return float(wrap_2pi(self.phase_rad + TWO_PI * (t_s - self.t_s) / period_s))


AlertState = Literal["new", "confirmed", "cleared", "bid"]


@dataclass(frozen=True)
class Alert:
    """An intruder alert as shared over the group.

    Attributes:
        alert_id: unique id (``"<detector sysid>-<sequence>"``).
        site_m: where the intruder was seen (world, complex m).
        detector_sysid: the UAV that reported it (for a confirmation, the confirming UAV).
        t_s: time of the report (s, vehicle time).
        state: "new", "confirmed" (seen again: task the next UAV), "cleared", or "bid" (a
            member's planned time under the "fastest" policy; ``detector_sysid`` is the bidder).
        bid_s: the bidder's planned time (s), for "bid" only.
    """

    alert_id: str
    site_m: complex
    detector_sysid: int
    t_s: float
    state: AlertState = "new"
    bid_s: float = 0.0
