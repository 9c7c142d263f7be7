"""A UAV's working state while it is away from the loop (mutable): prosecuting an alert
(intercept, search), tracking its intruder, then flying back into its slot. Shared by
:mod:`companion.agent.alerts.prosecution`, :mod:`companion.agent.alerts.tracker` and
:mod:`companion.agent.rejoin`; which of those it is doing is the Agent's own mode
(:mod:`companion.agent.modes`), not a field here.

Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass

from companion.agent.alerts.search import Search
from companion.guidance.virtual import VirtualParticle
from companion.planner import Plan


@dataclass
class Away:
    """A UAV's working state while away from the loop.

    Attributes:
        alert_id: the alert it is away for.
        site_m: where that alert was reported (complex m).
        virtual: the virtual particle it shares while prosecuting and rejoining: its slot.
        plan, plan_t0_s, last_plan_s, planned_time_s: the path flown (intercept, search leg,
            tracker's pass), when it was made and last re-planned, the first plan's time (s).
        plan_track_t_s: the time of the track the path was planned on (s).
        covered: the sensor has been over the predicted position.
        check_phase_rad: the time-phase (rad) of the loop point past which it checks the
            site from the loop, None when it flies a path to it.
        search: the search, once the intercept found nothing.
        search_outpaced_at_start: a search was needed but outpaced before it began, so
            none was flown (the clear says so).
        rejoin_t0_s: when the rejoin began (s).
        loop_plan, loop_plan_t0_s, loop_phase_rad: the path back onto the loop, when it was
            made (s), and the time-phase of the loop point it ends at (rad).
        last_check_s: the rejoin's last re-plan (s).
        back_on_loop_s: when it was back on the loop (s), None before.
        left_loop_t_s, left_loop_phase_rad: when its sensor last reached the loop before
            it first flew out of reach of it (s), and the time-phase of the loop point it was
            over then (rad): where it left its stretch; None once it tracks (the formation
            has re-splayed without it).
        off_loop: it has flown out of its sensor's reach of the loop since it left.
    """

    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    planned_time_s: float = 0.0
    plan_track_t_s: float = -1e9
    covered: bool = False
    check_phase_rad: float | None = None
    search: Search | None = None
    search_outpaced_at_start: bool = False
    rejoin_t0_s: float = 0.0
    loop_plan: Plan | None = None
    loop_plan_t0_s: float = 0.0
    loop_phase_rad: float = 0.0
    last_check_s: float = -1e9
    back_on_loop_s: float | None = None
    left_loop_t_s: float | None = None
    left_loop_phase_rad: float = 0.0
    off_loop: bool = False
