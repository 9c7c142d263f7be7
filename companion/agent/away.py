"""What a UAV holds while it is away from the loop: one record per own mode (mutable), made
by the transition that enters the mode and dropped by the one that leaves it.

==================== ============== ===========================================================
mode                 record         what it holds (beside the alert it is away for)
==================== ============== ===========================================================
patrol               none           (the formation's state is the Agent's)
prosecuting          Prosecuting    the site, its virtual particle, the intercept flown, the
                                    longest search it may fly, where it left its stretch
searching            Searching      the same, the search instead of the intercept
tracking             Tracking       when it began, the pass flown
rejoin_to_loop       Rejoining      its virtual particle, when the rejoin began, and the stage
                                    :class:`ToLoop` (the path back, where it left its stretch)
rejoin_along_loop    Rejoining      the same without a stage: the airspeed recovers the slot
==================== ============== ===========================================================

What carries over from one mode to the next is handed on by the constructor the transition
calls (:meth:`Searching.begin`, :meth:`Tracking.begin`, :meth:`Rejoining.after`,
:meth:`Rejoining.after_tracking`, :meth:`Rejoining.on_loop`): the alert id, the virtual particle,
where it left its stretch of the loop, the plan's first time. :class:`OwnState` is the one
place that changes the mode (:data:`companion.agent.modes.MODE_TABLE`) and swaps the record;
a record that is not the entered mode's raises.

The rejoin's two stages share one record: the second (along the loop) has no data of its
own, only what both read (the alert, the slot's virtual particle, the rejoin's start), so the
first stage's data is a sub-record, :class:`ToLoop`, that the ``on_loop`` transition drops.
Two records would be a copy of the shared three fields and an empty class.

Times are vehicle seconds, positions complex north + i east metres, phases radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from companion.agent.alerts.search import Search
from companion.agent.fix import Fix
from companion.agent.modes import ModeEvent, OwnMode, next_mode
from companion.guidance.virtual import VirtualParticle
from companion.planner import Plan


@dataclass
class LeftLoop:
    """Where the UAV left its stretch of the loop: when its sensor last reached the loop
    before it first flew out of reach of it (s, None: never since it left), the time-phase
    of the loop point it was over then (rad), and whether it has flown out of reach since."""

    t_s: float | None = None
    phase_rad: float = 0.0
    off: bool = False

    def note(self, fix: Fix, sensor_m: float) -> None:
        """One look at ``fix`` with a sensor of radius ``sensor_m`` (m). A later pass near the
        loop elsewhere (a search) does not move it: the stretch after it is still unseen."""
        if self.off:
            return
        if fix.loop_offset_m <= sensor_m:
            self.t_s, self.phase_rad = fix.t_s, fix.loop_phase_rad
        else:
            self.off = True


@dataclass
class Prosecuting:
    """Flying the intercept of an alert's predicted track (mode ``prosecuting``).

    Attributes:
        alert_id: the alert (renamed when an earlier report of its site replaces it).
        site_m: where it was first reported (complex m).
        virtual: the virtual particle it shares: its slot.
        search_max_s: the longest search it may fly (s).
        plan, plan_t0_s, last_plan_s, plan_track_t_s: the intercept flown, when it was made
            and last re-planned, and the time of the track it was planned on (s).
        planned_time_s: the first plan's time (s).
        covered: the sensor has been over the predicted position.
        check_phase_rad: the time-phase (rad) of the loop point past which it checks the
            site from the loop, None when it flies a path to it.
        outpaced_at_start: a search was needed but outpaced before it began (the clear says
            so).
        left_fence: the intercept meets the intruder outside the fence or nearer its edge
            than a turn radius (it leaves the defended region first): nothing to fly.
        left: where it left its stretch of the loop.
    """

    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    search_max_s: float
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    plan_track_t_s: float = -1e9
    planned_time_s: float = 0.0
    covered: bool = False
    check_phase_rad: float | None = None
    outpaced_at_start: bool = False
    left_fence: bool = False
    left: LeftLoop = field(default_factory=LeftLoop)


@dataclass
class Searching:
    """Searching the track's uncertainty where the intercept did not see the intruder (mode
    ``searching``): the alert, site, virtual particle, first plan's time, coverage and where
    it left the loop as in :class:`Prosecuting`; the search and its current leg."""

    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    search: Search
    planned_time_s: float
    covered: bool
    left: LeftLoop
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9

    @classmethod
    def begin(cls, away: Prosecuting, search: Search) -> Searching:
        """The record of ``search``, begun where the intercept ``away`` ended (``path_flown``)."""
        return cls(
            away.alert_id,
            away.site_m,
            away.virtual,
            search,
            away.planned_time_s,
            away.covered,
            away.left,
        )


@dataclass
class Tracking:
    """Staying over its intruder (mode ``tracking``): out of the formation, so no virtual
    particle; when it began (s) and the pass flown (as :class:`Prosecuting`'s plan)."""

    alert_id: str
    t0_s: float
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    plan_track_t_s: float = -1e9

    @classmethod
    def begin(cls, away: Prosecuting | Searching, t_s: float) -> Tracking:
        """Tracking ``away``'s alert from ``t_s`` (s) (``tracker``): the formation re-splays
        without it, so where it left its stretch is forgotten."""
        return cls(away.alert_id, t_s)


@dataclass
class ToLoop:
    """The rejoin's first stage: the path back onto the loop, when it was made (s), the
    time-phase of the loop point it ends at (rad), the last re-plan (s); and where the UAV
    left its stretch (a short excursion flies back there)."""

    left: LeftLoop
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    loop_phase_rad: float = 0.0
    last_check_s: float = -1e9


@dataclass
class Rejoining:
    """Flying back into its slot (modes ``rejoin_to_loop`` and ``rejoin_along_loop``): the
    alert it flies back from, the virtual particle of its slot, when the rejoin began (s),
    and the first stage's record (None along the loop)."""

    alert_id: str
    virtual: VirtualParticle
    t0_s: float
    to_loop: ToLoop | None

    @classmethod
    def after(cls, away: Prosecuting | Searching, t_s: float) -> Rejoining:
        """The rejoin from the prosecution ``away``, ended at ``t_s`` (s) (``ended``): the
        same slot, back towards where it left the loop."""
        return cls(away.alert_id, away.virtual, t_s, ToLoop(away.left))

    @classmethod
    def after_tracking(
        cls, away: Tracking, phase_rad: float, t_s: float, period_s: float
    ) -> Rejoining:
        """The rejoin from the tracking ``away``, ended at ``t_s`` (s) (``track_ended``): its
        new slot is where it joins the loop, the time-phase ``phase_rad`` (rad) of a loop of
        period ``period_s`` (s): the formation, splayed as N - 1 without it, makes room."""
        return cls(
            away.alert_id, VirtualParticle(phase_rad, t_s, period_s), t_s, ToLoop(LeftLoop())
        )

    def on_loop(self) -> Rejoining:
        """Back on the loop (``on_loop``): the first stage dropped."""
        return replace(self, to_loop=None)


AwayRecord = Prosecuting | Searching | Tracking | Rejoining

RECORD_OF: dict[OwnMode, type | None] = {
    OwnMode.PATROL: None,
    OwnMode.PROSECUTING: Prosecuting,
    OwnMode.SEARCHING: Searching,
    OwnMode.TRACKING: Tracking,
    OwnMode.REJOIN_TO_LOOP: Rejoining,
    OwnMode.REJOIN_ALONG_LOOP: Rejoining,
}
"""The record type each own mode holds (None: none)."""


def belongs(mode: OwnMode, record: AwayRecord | None) -> bool:
    """Whether ``record`` is the record of ``mode`` (:data:`RECORD_OF`; a rejoin's first
    stage has its :class:`ToLoop`, the second none)."""
    kind = RECORD_OF[mode]
    if kind is None or record is None:
        return kind is None and record is None
    if type(record) is not kind:
        return False
    if isinstance(record, Rejoining):
        return (record.to_loop is not None) == (mode is OwnMode.REJOIN_TO_LOOP)
    return True


@dataclass
class OwnState:
    """A UAV's own mode and that mode's record (:data:`RECORD_OF`): patrol, with none, at first."""

    mode: OwnMode = OwnMode.PATROL
    record: AwayRecord | None = None

    def change(self, event: ModeEvent, record: AwayRecord | None) -> None:
        """Change the mode by ``event`` and hold ``record``, the entered mode's record (made
        by the transition from what carries over); the left mode's record is dropped.

        Raises:
            IllegalTransitionError: ``event`` is not allowed in the mode
                (:func:`companion.agent.modes.next_mode`).
            TypeError: ``record`` is not the entered mode's.
        """
        mode = next_mode(self.mode, event)
        if not belongs(mode, record):
            raise TypeError(f"mode {mode.value!r} does not hold a {type(record).__name__}")
        self.mode, self.record = mode, record
