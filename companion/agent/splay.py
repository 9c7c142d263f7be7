"""Flying the loop in the formation (pure): the time-splay law's turn rate and the airspeed
that holds this UAV's place in the splay, on the formation as it hears it (docs/design.md
§4). A component of :class:`companion.agent.agent.Agent`; the patrol mode's handler and the
prosecutor that checks a site from the loop fly it.

Its state: the steering gains (the airspeed's authority is dropped for good when the
autopilot refuses another airspeed), the formed flag (:mod:`companion.agent.formed`) and the
last airspeed computed. Times are vehicle seconds, positions complex north + i east metres.
"""

from __future__ import annotations

from dataclasses import replace

from companion.agent.fix import Fix
from companion.agent.formed import Formed
from companion.agent.neighbours import Neighbours
from companion.guidance.formation import splay_airspeed, splay_command, splay_slot_error_m
from companion.guidance.steering import Gains, speed_holds_phase

AIRSPEED_UPDATE_S = 0.5  # the phase-holding airspeed is recomputed this often (vehicle s)


class Splay:
    """This UAV's place in the splay.

    Args:
        heard: the members heard (their phases and positions).
        gains: the steering gains.
        max_u: the turn-rate limit (rad/s).
    """

    def __init__(self, heard: Neighbours, gains: Gains, max_u: float) -> None:
        """Not formed yet (:class:`~companion.agent.formed.Formed`), no airspeed computed."""
        self.heard = heard
        self.gains = gains
        self.max_u = max_u
        # formed: in its slot once; from then on the formation re-splays along the loop
        self.formed = Formed(gains.speed_authority_m_s * gains.speed_tau_s)
        self._airspeed_at: tuple[float, float] | None = None  # (t_s, m/s) last computed

    def fix_airspeed(self) -> None:
        """Fly the mission's airspeed from now on (the autopilot refused another): the phase
        is then held by steering alone, with the whole phase term (the paper's way)."""
        self.gains = replace(self.gains, speed_authority_m_s=0.0)

    def command(self, fix: Fix) -> float:
        """The time-splay law on the formation as this UAV sees it (rad/s). With the
        airspeed holding the phase, the others' phases are where they are along the loop
        when on it (:meth:`Neighbours.steering_phases`); this UAV's own is the law's."""
        patrol = fix.patrol
        if speed_holds_phase(self.gains):
            others = self.heard.steering_phases(fix.t_s, patrol)
        else:
            others = self.heard.others(fix.t_s, patrol.period_s)
        return splay_command(
            patrol,
            self.gains,
            fix.pos_m,
            fix.heading_rad,
            fix.phase_rad,
            fix.centre_m,
            others,
            self.max_u,
            self.formed.steer_limit_m,
        )

    def airspeed(self, fix: Fix) -> float:
        """The airspeed (m/s) that holds this UAV's place in the splay as it sees it.

        The phases here are where each member is along the loop (its nearest loop point),
        not the course-based phases of the steering law: a gust turns the course by a few
        degrees, which on a long, nearly straight edge moves the course-based phase by
        seconds, while the slot error the airspeed has to take out is along the loop."""
        patrol = fix.patrol
        if not speed_holds_phase(self.gains):
            return patrol.airspeed_m_s
        t_s, last = fix.t_s, self._airspeed_at
        if last is not None and 0.0 <= t_s - last[0] < AIRSPEED_UPDATE_S:
            return last[1]  # the runner sends at most one a second anyway
        own, off_m = fix.loop_phase_rad, fix.loop_offset_m
        others = self.heard.positions_phases(t_s, patrol)
        if not self.formed.formed:
            error_m = splay_slot_error_m(patrol, self.gains, own, others)
            self.formed.note(t_s, bool(self.heard.table), off_m, error_m)
        v = splay_airspeed(patrol, self.gains, own, others)
        self._airspeed_at = (t_s, v)
        return v
