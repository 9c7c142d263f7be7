"""The records an :class:`companion.agent.Agent` keeps, and what one update returns.

Plain mutable dataclasses (the agent's working state) plus the frozen :class:`AgentOutput`.
Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from companion.alerts import Alert
from companion.core.formation import MemberState
from companion.core.virtual import VirtualParticle
from companion.planner import Plan

Mode = Literal["patrol", "prosecuting", "rejoining"]
Event = dict[str, object]


@dataclass
class Neighbour:
    state: MemberState
    rx_t_s: float


@dataclass
class AlertRecord:
    """One distinct alert (duplicates are merged into it, never given a record of their own).

    ``done_t_s`` is the time (s) it was cleared (the message's, at most its receipt's);
    ``site_phase_rad`` caches the time-phase of the loop point nearest the site.
    """

    alert: Alert
    status: Literal["queued", "bidding", "taken", "done"] = "queued"
    prosecutor: int | None = None
    bids: dict[int, float] = field(default_factory=dict)
    bid_deadline_s: float = 0.0
    rebroadcast_s: float = -1e9
    taken_t_s: float = 0.0
    started: bool = False
    excluded: set[int] = field(default_factory=set)
    done_t_s: float | None = None
    site_phase_rad: float | None = None
    t0_s: float = 0.0  # time of the first report (s): which of two reports of a site wins
    fence_checked: bool = False  # the geofence check has been made (Agent._fence_refuses)

    def inherit(self, other: AlertRecord) -> None:
        """Take over ``other``'s tasking (an earlier report of the same site replaces it)."""
        self.status, self.prosecutor, self.started = other.status, other.prosecutor, other.started
        self.taken_t_s, self.excluded, self.bids = other.taken_t_s, set(other.excluded), {}
        self.bid_deadline_s = other.bid_deadline_s
        if other.status == "bidding":
            self.status = "queued"  # bids were made for the other id: bid again for this one


@dataclass
class Away:
    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    planned_time_s: float = 0.0
    rejoining: bool = False
    covered: bool = False
    rejoin_t0_s: float = 0.0
    merge: Plan | None = None  # the path that meets the slot on time
    merge_t0_s: float = 0.0
    meet_t_s: float = 0.0  # when the path meets the slot (s)
    merged: bool = False  # met the slot: the tracking law finishes the job
    wait: Plan | None = None  # back over the site while the slot comes round
    wait_t0_s: float = 0.0
    last_check_s: float = -1e9


@dataclass(frozen=True)
class AgentOutput:
    """What one ``update`` produces.

    Attributes:
        turn_rate_rad_s: turn-rate command (rad/s, positive right, within the limit).
        broadcast: the state to share with the group.
        alerts_out: alerts to send to the group.
        events: events to log (``t_s``, ``event``, ``sysid``, ``alert_id`` ...).
        mode: "patrol", "prosecuting" or "rejoining".
    """

    turn_rate_rad_s: float
    broadcast: MemberState
    alerts_out: tuple[Alert, ...]
    events: tuple[Event, ...]
    mode: Mode
