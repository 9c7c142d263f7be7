"""The mission's figures one UAV's part in the reliefs works with (pure, frozen): read once
from the mission, the same for every state. Positions complex m, times s, rates rad/s."""

from __future__ import annotations

from dataclasses import dataclass

from companion.mission import Mission
from companion.mission.model import Battery

MEET_BEHIND_M = 20.0  # a relieving spare turns in from its lane this far behind its slot (m)
LANE_MARGIN_M = 15.0  # its lane: the loop offset outward by its sensor radius + this (m)
EARLY_TURNS = 1.0  # it plans to reach the lane this many turn radii of flight before its slot


@dataclass(frozen=True)
class Figures:
    """One UAV's figures for the reliefs.

    Attributes:
        sysid: its system id.
        enabled: the mission has a battery and spares (else always on station).
        battery: the mission's battery, or None.
        airspeed_m_s: the mission's airspeed (m/s).
        count: N, the slots on the loop.
        max_u: its turn-rate limit (rad/s).
        sensor_m: its sensor's footprint radius (m).
        lane_m: its lane, the loop offset outward by this (m): the sensor radius and
            ``LANE_MARGIN_M``.
        meet_behind_m: it turns in from its lane this far behind its member's slot (m).
        early_s: it plans to reach its lane this long before its slot (s): a margin for what
            its plan leaves out.
        wait_factor: waiting in its lane it falls back on its slot at about its phase hold's
            authority: each second early costs this many more (airspeed / authority - 1).
        opening_steps: a staggered opening: its first stint leaves this many beats / N
            early (0: as its battery says).
        spare: it is one of the mission's spares.
        grounded: a spare that waits on the ground.
        hold_point_m: a holding spare's holding point (m), else None.
    """

    sysid: int
    enabled: bool
    battery: Battery | None
    airspeed_m_s: float
    count: int
    max_u: float
    sensor_m: float
    lane_m: float
    meet_behind_m: float
    early_s: float
    wait_factor: float
    opening_steps: int
    spare: bool
    grounded: bool
    hold_point_m: complex | None

    @classmethod
    def of(cls, sysid: int, mission: Mission) -> Figures:
        """``sysid``'s figures in ``mission``."""
        v = mission.vehicles
        sysid = int(sysid)
        sensor_m = mission.sensor.footprint_radius_m
        max_u = v.max_turn_rate_rad_s
        authority = max(mission.gains.speed_authority_m_s, 1.0)
        mine = next((sp for sp in v.spares if sp.sysid == sysid), None)
        staggered = v.opening == "staggered" and sysid in v.sysids
        holding = mine is not None and mine.waits == "holding"
        return cls(
            sysid=sysid,
            enabled=v.battery is not None and bool(v.spares),
            battery=v.battery,
            airspeed_m_s=v.airspeed_m_s,
            count=v.count,
            max_u=max_u,
            sensor_m=sensor_m,
            lane_m=sensor_m + LANE_MARGIN_M,
            meet_behind_m=MEET_BEHIND_M,
            early_s=EARLY_TURNS / max_u,
            wait_factor=v.airspeed_m_s / authority - 1.0,
            opening_steps=v.count - 1 - v.sysids.index(sysid) if staggered else 0,
            spare=mine is not None,
            grounded=mine is not None and mine.waits == "ground",
            hold_point_m=complex(mine.north_m, mine.east_m)
            if holding and mine is not None
            else None,
        )
