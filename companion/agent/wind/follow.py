"""One UAV's side of the fleet's wind (pure: times are vehicle seconds, passed in).

Wraps the agreement of :mod:`companion.agent.wind.agreement` for the Agent: it proposes a
wind when this UAV is the proposer (rate-limited so the slots it shifts move no faster than
the airspeed follows, :func:`companion.guidance.formation.wind_rate_limit_m_s2`), hands back
the loop re-timed in the record in force when that record changes (every member switches
at the same vehicle time to the same wind), and says when that wind makes the loop need
more turn rate than the aircraft have. Its typed events (:mod:`companion.agent.events`) are
returned, for the caller to log in order.
"""

from __future__ import annotations

import numpy as np

from companion.agent.events import AgentEvent, LoopFlyable, LoopInfeasible, WindAgreed, WindProposed
from companion.agent.wind.agreement import WindAgreement
from companion.core.patrol import Patrol
from companion.core.wind import Wind
from companion.guidance.formation import wind_rate_limit_m_s2
from companion.guidance.steering import Gains


class FleetWind:
    """The fleet's wind as one member follows it.

    Args:
        sysid: this member's system id.
        airspeed_m_s: the fleet's airspeed (m/s).
        patrol: the loop in the mission's wind (record 0).
        gains: steering gains (the airspeed's authority sets the wind's rate).
        members: the mission's vehicle count.
        max_turn_rate_rad_s: the aircraft's turn-rate limit (rad/s).
    """

    def __init__(
        self,
        sysid: int,
        airspeed_m_s: float,
        patrol: Patrol,
        gains: Gains,
        members: int,
        max_turn_rate_rad_s: float,
    ) -> None:
        """Record 0 (the mission's wind) in force; the loop flyable in it (the loader says
        so)."""
        self.agreement = WindAgreement(
            sysid,
            airspeed_m_s,
            patrol.wind.vector,
            max_rate_m_s2=wind_rate_limit_m_s2(patrol, gains, members),
        )
        self.max_u = max_turn_rate_rad_s
        self.sysid = int(sysid)
        self._in_force = (0, 0)  # (seq, proposer) of the record in force
        self._infeasible = False  # the wind in force asks more turn rate than we have

    def follow(
        self, t_s: float, members: set[int], patrol: Patrol
    ) -> tuple[Patrol | None, list[AgentEvent]]:
        """Propose a wind if this UAV is the proposer (``members``: the others heard); the
        loop re-timed in the record in force at ``t_s`` (s) if that record changed, else
        None; and the events (proposed, agreed, the loop flyable or not), in order."""
        events: list[AgentEvent] = []
        made = self.agreement.step(t_s, members)
        if made is not None:
            events.append(
                WindProposed(
                    t_s=t_s,
                    sysid=self.sysid,
                    seq=made.seq,
                    t_eff_s=round(made.t_eff_s, 3),
                    **wind_fields(made.wind_m_s),
                )
            )
        rec = self.agreement.record_at(t_s)
        if (rec.seq, rec.proposer) == self._in_force:
            return None, events
        self._in_force = (rec.seq, rec.proposer)
        new = patrol.with_wind(Wind.from_vector(rec.wind_m_s))
        events.append(
            WindAgreed(
                t_s=t_s,
                sysid=self.sysid,
                seq=rec.seq,
                proposer=rec.proposer,
                period_s=round(new.period_s, 3),
                **wind_fields(rec.wind_m_s),
            )
        )
        events += self._check_flyable(t_s, new)
        return new, events

    def _check_flyable(self, t_s: float, patrol: Patrol) -> list[AgentEvent]:
        """Say when the loop, in the wind in force, needs more turn rate than the aircraft
        have (``loop_infeasible``: the tips are then flown wide, whatever the gains) and when
        it is flyable again (``loop_flyable``); the loader refused such a loop in the
        mission's wind, but the real wind can make it so in flight."""
        need = patrol.max_required_turn_rate_rad_s()
        infeasible = need > self.max_u
        if infeasible == self._infeasible:
            return []
        self._infeasible = infeasible
        kind = LoopInfeasible if infeasible else LoopFlyable
        return [
            kind(
                t_s=t_s,
                sysid=self.sysid,
                need_deg_s=round(float(np.degrees(need)), 1),
                limit_deg_s=round(float(np.degrees(self.max_u)), 1),
                **wind_fields(patrol.wind.vector),
            )
        ]


def wind_fields(wind_m_s: complex) -> dict[str, float]:
    """Event fields of a wind vector: speed (m/s) and the direction it blows FROM (deg)."""
    w = Wind.from_vector(wind_m_s)
    return {"wind_speed_m_s": round(w.speed_m_s, 3), "wind_from_deg": round(w.from_deg, 2)}
