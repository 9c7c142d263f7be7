"""The reliefs' events (typed, as :mod:`companion.agent.events`; docs/energy.md).

Times vehicle s, battery %, rounded where they are made.
"""

from __future__ import annotations

from typing import ClassVar

from companion.agent.events import AgentEvent, _event


@_event
class ReliefLaunched(AgentEvent):
    """This spare launched to relieve ``member_sysid``, which must leave at ``leave_t_s``."""

    name: ClassVar[str] = "relief_launched"
    member_sysid: int
    leave_t_s: float
    battery_pct: float | None = None


@_event
class ReliefInSlot(AgentEvent):
    """This spare holds ``member_sysid``'s slot (``took_s`` after launching; ``reason``:
    ``in_slot``, ``timeout`` or ``member_gone``): it is on station, the member may leave."""

    name: ClassVar[str] = "relief_in_slot"
    member_sysid: int
    took_s: float
    reason: str


@_event
class ReliefStoodDown(AgentEvent):
    """This spare, committed to relieve ``member_sysid``, gave the relief up to
    ``rival_sysid``, which also flies in for it (a lower sysid) or already holds its slot:
    two spares that planned from states a moment apart can both find themselves booked.
    ``airborne``: it had taken off, and flies home to land; else it is a spare again."""

    name: ClassVar[str] = "relief_stood_down"
    member_sysid: int
    rival_sysid: int
    airborne: bool


@_event
class Relieved(AgentEvent):
    """This UAV left the loop for home: relieved by ``spare_sysid`` (0: nobody came in
    time, ``reason`` ``leave_time``), ``margin_s`` before the time it had to leave."""

    name: ClassVar[str] = "relieved"
    spare_sysid: int
    margin_s: float
    reason: str
    battery_pct: float | None = None


@_event
class ReliefLanded(AgentEvent):
    """This UAV landed at its base; ready again (charged) at ``ready_t_s``."""

    name: ClassVar[str] = "relief_landed"
    north_m: float
    east_m: float
    ready_t_s: float
    battery_pct: float | None = None


@_event
class ReliefLate(AgentEvent):
    """This UAV's relief will come ``late_s`` after it must leave (``leave_t_s``); by
    ``spare_sysid`` (0 and ``late_s`` None: no spare at all). Said once per spare, before
    it is late."""

    name: ClassVar[str] = "relief_late"
    spare_sysid: int
    leave_t_s: float
    late_s: float | None = None


@_event
class SpareNoLaunch(AgentEvent):
    """Spare ``spare_sysid``, booked for this UAV, did not launch: passed over."""

    name: ClassVar[str] = "spare_no_launch"
    spare_sysid: int


@_event
class SpareUncharged(AgentEvent):
    """This spare, past its ready time, holds ``battery_pct`` (%), less than the launch
    charge ``need_pct`` (%): it shares ``unavailable`` (never booked) until it is charged.
    Said once each time it falls short."""

    name: ClassVar[str] = "spare_uncharged"
    battery_pct: float
    need_pct: float


@_event
class ReliefRefused(AgentEvent):
    """A state under ``member_sysid`` claiming relief role ``role`` was left out of the
    plan (``reason``: ``not_in_mission``, a sysid the mission does not list): never booked.
    Said once per sysid and role."""

    name: ClassVar[str] = "relief_refused"
    member_sysid: int
    role: str
    reason: str
