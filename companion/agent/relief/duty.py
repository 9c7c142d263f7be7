"""One UAV's part in the reliefs (pure; docs/energy.md, "Reliefs"): the seam the Agent calls.

A :class:`Duty` is one of four states, changed only along
:data:`~companion.agent.relief.states.DUTY_TABLE`
(:func:`companion.agent.machine.advance`):

* ``on_station`` -- on the loop (the Agent patrols). It shares the vehicle time it must
  leave (:mod:`companion.agent.relief.energy`, home being the nearest spare base, from the
  loop's farthest point). A member on patrol that shares it has taken this UAV's slot
  (``relief_sysid``) relieves it; if nobody has by the leave time it leaves anyway.
* ``home`` -- relieved: out of the formation (mode ``spare``); relieved by a spare, it first
  rides the loop, dropping back by its phase hold's airspeed to ``DROP_SENSORS`` sensor
  radii behind its relief (at most half the spacing L/N). That far back it leaves by a way
  out (:func:`~companion.agent.relief.join.way_out`: its base lies outward, and out to its
  lane, a turn and a straight leg to the base keep its sensor off the loop), or else by a
  crossing (:func:`~companion.agent.relief.join.crossing`: across the loop to a point the
  last member has passed and the next will not reach before its sensor is off it, then out
  by a way out from there), or at its leave time straight home. Its sensor so starts no
  member's pass early (a pass of its that runs into one due would; the revisit is counted
  start to start). Within ``LAND_RADIUS_M`` of the nearest base it lands (``land``).
* ``spare`` -- on the ground (or holding): it shares when it is ready (landing plus the
  turnaround); past that time and still short of ``READY_PCT`` (its battery not swapped,
  or drained waiting), it shares ``unavailable``, so nobody books it, and says so
  (``spare_uncharged``) until it is charged. Booked by the fleet's plan
  (:mod:`companion.agent.relief.schedule`), due and charged, it is ``relieving`` at once
  (so nobody books it again) and waits for its member's slot to come round: it takes off
  (``takeoff``) when it would reach its lane (the loop offset outward by its sensor radius
  and ``LANE_MARGIN_M``) from outside, with the traffic, ahead of the slot, no more than
  ``LAUNCH_SLACK_S`` earlier than planned (at most ``WAIT_PERIODS`` T after it was booked);
  if it has not moved ``LAUNCH_TIMEOUT_S`` later it is a spare again, out of the rotation
  (ready never), and the plan books the next.
* ``relieving`` -- flying in for its member: straight to the lane point chosen at its
  take-off, along the lane (its sensor off the loop) until the point ``MEET_BEHIND_M``
  behind its member's slot comes up, then in at 45 deg; near the loop and near the
  member's slot (the splay potential has other minima farther off), the steering law with
  the formation less that member, so it settles into the member's slot (the phase; N does
  not change). Held ``IN_SLOT_S`` within
  ``IN_SLOT_M`` of the member along the loop and of the loop, it is ``on_station`` and
  shares whom it relieved. Two spares that planned from states a moment apart can both be
  committed to one member: one that hears another flying in for its member with a lower
  sysid, or one on station that took that slot, stands down (``relief_stood_down``): a
  spare again if it is still waiting, else home to land.

Every member computes the plan from the shared states (its own included as it shares it),
so the spares agree on who goes. A member last heard on station that falls silent past the
member time-out (its companion died, its link is gone for good) is *lost*: every member
keeps it, with the time of its last state, as a member whose slot is open now
(:attr:`Duty.lost`, the plan's rule 1a), so the first spare to be had launches for it at
once, flies in (its member gone, it takes the slot as the formation leaves it) and shares
that it relieved it; that claim, or the lost member heard again, ends it. A state under a
sysid the mission does not list is left out of the plan (:mod:`companion.agent.relief.roster`),
counted in :attr:`Duty.refused` and logged once (``relief_refused``). Times vehicle s,
positions complex m, battery %.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from companion.agent.events import AgentEvent
from companion.agent.machine import advance
from companion.agent.neighbours import Neighbours
from companion.agent.relief.energy import Drain, leave_time_s
from companion.agent.relief.events import (
    ReliefInSlot,
    ReliefLanded,
    ReliefLate,
    ReliefLaunched,
    ReliefRefused,
    ReliefStoodDown,
    Relieved,
    SpareNoLaunch,
    SpareUncharged,
)
from companion.agent.relief.fly_home import FlyHome
from companion.agent.relief.fly_in import CAPTURE_SPACINGS, FlyIn
from companion.agent.relief.join import (
    fly_to,
    inside,
    orbit,
    slot_phase,
)
from companion.agent.relief.roster import LAND_MARGIN_S, Roster, plan_from
from companion.agent.relief.schedule import LAUNCH_GRACE_S, NoLaunchWatch, Plan
from companion.agent.relief.states import (
    DUTY_TABLE,
    ON_STATION,
    DutyEvent,
    DutyState,
    DutyStep,
)
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_pi
from companion.group.messages import OUT_OF_FORMATION, Energy, Mode
from companion.guidance.formation import splay_airspeed, splay_command
from companion.guidance.steering import Gains, speed_holds_phase
from companion.guidance.virtual import phase_gap_rad
from companion.mission import Mission

PLAN_EVERY_S = 1.0  # the plan is recomputed this often (s)
LAND_RADIUS_M = 40.0  # within this of its base a UAV flying home lands (m)
READY_PCT = 90.0  # a spare launches only with at least this charge (%; avionics drain it)
IN_SLOT_M = 20.0  # along the loop from the member's slot, and off the loop (m)
IN_SLOT_S = 3.0  # held this long (s)
APPROACH_M = 60.0  # nearer the loop than this, a relieving spare flies the steering law (m)
TURN_IN_M = 25.0  # ... or than this, turning in from its lane
MEET_BEHIND_M = 20.0  # a relieving spare turns in from its lane this far behind its slot (m)
LANE_MARGIN_M = 15.0  # its lane: the loop offset outward by its sensor radius + this (m)
EARLY_TURNS = 1.0  # it plans to reach the lane this many turn radii of flight before its slot
CLAIM_S = 30.0  # a relief shares whom it relieved this long after taking the slot (s)
LAUNCH_TIMEOUT_S = 10.0  # a spare commanded to take off that has not moved by then did not
TAKEOVER_LIMIT_PERIODS = 4.0  # after this many T flying in, it takes the slot as it is
WAIT_PERIODS = 1.2  # a committed spare waits at most this many T for its slot to come round
LAUNCH_SLACK_S = 2.0  # ... and goes when it would meet the slot no more than this early (s)


class Duty(FlyIn, FlyHome):
    """One UAV's reliefs (see the module docstring).

    Args:
        sysid: this UAV's system id.
        mission: the mission; without a battery section the duty is off
            (:attr:`enabled` False: always on station, nothing shared).
        log: where its events go (the Agent's log).
    """

    def __init__(self, sysid: int, mission: Mission, log: Callable[[AgentEvent], None]) -> None:
        """On station if ``sysid`` is a patrol UAV, a spare (on the ground or holding) if
        it is one of the mission's spares."""
        v = mission.vehicles
        self.sysid = int(sysid)
        self.enabled = v.battery is not None and bool(v.spares)
        self.battery = v.battery
        self._log = log
        self.airspeed_m_s = v.airspeed_m_s
        self.count = v.count  # N: the slots on the loop
        self.max_u = v.max_turn_rate_rad_s
        self.meet_behind_m = MEET_BEHIND_M
        self.sensor_m = mission.sensor.footprint_radius_m
        self.lane_m = self.sensor_m + LANE_MARGIN_M
        self.early_s = EARLY_TURNS / self.max_u  # margin for what its plan leaves out (s)
        # waiting in its lane it falls back on its slot at about its phase hold's authority
        authority = max(mission.gains.speed_authority_m_s, 1.0)
        self.wait_factor = self.airspeed_m_s / authority - 1.0
        self.roster = Roster(mission)  # who may take part; the bases, the turnaround
        self.bases = self.roster.bases
        self.turnaround_s = self.roster.turnaround_s
        self.refused: dict[str, int] = {}  # shared states left out of the plan, by reason
        mine = next((sp for sp in v.spares if sp.sysid == self.sysid), None)
        self.state = DutyState.SPARE if mine is not None else DutyState.ON_STATION
        self.grounded = mine is not None and mine.waits == "ground"
        self.hold_point_m: complex | None = None  # a holding spare's, where it loiters (m)
        if mine is not None and mine.waits == "holding":
            self.hold_point_m = complex(mine.north_m, mine.east_m)
        self.ready_t_s = 0.0  # a spare: when it is charged (s)
        self.uncharged = False  # a spare past its ready time short of READY_PCT: unavailable
        self.member: int | None = None  # relieving: whom; on station: whom it relieved
        self.leave_t_s: float | None = None  # on station: when it must leave (s)
        self.battery_pct: float | None = None
        self._consumed_mah: float | None = None
        self._drain = Drain()
        self._plan: Plan | None = None
        self._plan_t_s = -math.inf
        self._watch = NoLaunchWatch()
        self._late_said: set[int] = set()
        self._relievers: set[int] = set()  # members heard flying in for it, this stint
        self._in_slot_t_s = -math.inf  # when it took its member's slot (s)
        self._launch_t_s = 0.0
        self._takeoff_pos: complex | None = None
        self._slot_since: float | None = None
        self._capture = False  # relieving: the steering law flies it into the slot
        self._turn_sign = 0.0  # relieving: a big turn's direction (+1 right, -1 left), held
        self._aim: complex | None = None  # relieving: the lane point chosen at its launch (m)
        self._in_lane = False  # relieving: it reached its lane and rides it to its slot
        self._laned = False  # ... it has been in its lane: it turns in before the law takes it
        self._hold_left_rad: float | None = None  # ... turning a full turn in it: left to turn
        self._hold_heading_rad = 0.0  # ... its heading at the last step of that turn (rad)
        self._reaim = False  # choose it again at the next step (its climb-out is over)
        self._launch_pos: complex | None = None  # where it was at its launch (m)
        self._waiting = False  # relieving: committed, waiting for its member's slot to come round
        self._committed_t_s = 0.0
        self._leave_of_member = 0.0  # the planned leave time of the member it relieves (s)
        self._beat_t_s: float | None = None  # on station after a relief: the rotation's (s)
        # a staggered opening: this many beats / N before its battery, its first stint only
        staggered = v.opening == "staggered" and self.sysid in v.sysids
        self._opening_steps = v.count - 1 - v.sysids.index(self.sysid) if staggered else 0
        self._opening_floor_s: float | None = None  # ... and not before (vehicle s)
        self._ride_until_s: float | None = None  # relieved: rides the loop until then (s)
        self._ride_behind: int | None = None  # ... dropping back behind this relief
        self._out_first = False  # relieved, on its way home: out to its lane first
        self._cross_m: complex | None = None  # ... or across the loop by this point (m)
        self._cross_t_s = -math.inf  # when it last looked for that crossing (s)
        self._refused_said: set[tuple[int, str]] = set()
        self._last_heard: dict[int, tuple[str | None, float]] = {}  # sysid -> (role, t_s)
        self.lost: dict[int, float] = {}  # fell silent on station: sysid -> its last t_s (s)

    # ---- inputs ---------------------------------------------------------------------------
    def observe_battery(
        self,
        t_s: float,
        remaining_pct: float | None,
        consumed_mah: float | None,
        current_a: float | None,
    ) -> None:
        """The autopilot's battery at vehicle time ``t_s`` (s): charge left (%), drawn (mAh),
        current (A); None for a field not reported (the estimate drops bad values)."""
        self.battery_pct = remaining_pct
        self._consumed_mah = consumed_mah
        if current_a is not None and current_a > 0.0:
            self._drain.add(t_s, current_a)

    # ---- what it shares -------------------------------------------------------------------
    def energy(self) -> Energy | None:
        """What it shares (None when the duty is off)."""
        if not self.enabled:
            return None
        st = self.state
        if st is DutyState.ON_STATION:
            return Energy(st.value, self.battery_pct, self.leave_t_s, self.member or 0)

        if st is DutyState.SPARE and (math.isinf(self.ready_t_s) or self.uncharged):
            return Energy("unavailable", self.battery_pct, None, 0)
        if st is DutyState.SPARE:
            return Energy(st.value, self.battery_pct, self.ready_t_s, 0)
        return Energy(st.value, self.battery_pct, None, self.member or 0)

    @property
    def plan(self) -> Plan | None:
        """The fleet's reliefs as this UAV last planned them (None before the first step)."""
        return self._plan

    @property
    def off_station(self) -> bool:
        """Whether it is out of the formation (shares mode ``spare``)."""
        return self.enabled and self.state is not DutyState.ON_STATION

    # ---- the step -------------------------------------------------------------------------
    def step(
        self,
        t_s: float,
        pos_m: complex,
        heading_rad: float,
        heard: Neighbours,
        patrol: Patrol,
        gains: Gains,
        can_leave: bool,
    ) -> DutyStep:
        """Decide at vehicle time ``t_s`` (s) at ``pos_m`` (m) with air heading
        ``heading_rad`` (rad), from the members ``heard``; ``can_leave``: on patrol (not
        away on an alert), so it may be relieved."""
        if not self.enabled:
            return ON_STATION
        self._track_lost(heard)
        self._check_charge(t_s)
        if t_s - self._plan_t_s >= PLAN_EVERY_S or self._plan is None:
            self._update_leave(t_s, patrol)
            self._plan = self._make_plan(t_s, pos_m, heard, patrol)
            self._plan_t_s = t_s
        st = self.state
        if st is DutyState.ON_STATION:
            return self._on_station(t_s, heard, can_leave)
        if st is DutyState.HOME:
            return self._home(t_s, pos_m, heading_rad, heard, patrol, gains)
        if st is DutyState.SPARE:
            return self._spare(t_s, pos_m, heading_rad, patrol)
        return self._relieving(t_s, pos_m, heading_rad, heard, patrol, gains)

    def _track_lost(self, heard: Neighbours) -> None:
        """Keep :attr:`lost` from the members heard now against those heard before: a member
        last heard ``on_station`` and gone from ``heard`` is lost (at the vehicle time of its
        last state, the same for every member that heard it); heard again, or claimed by a
        member on station that relieved it (this UAV included), it is not."""
        table = heard.table
        for s in [s for s in self._last_heard if s not in table]:
            role, last_t_s = self._last_heard.pop(s)
            if role == "on_station":
                self.lost[s] = last_t_s
        if not self.lost and len(self._last_heard) == len(table):
            for s, n in table.items():  # the usual case: nobody new, nobody lost
                e = n.state.energy
                self._last_heard[s] = (None if e is None else e.role, n.state.t_s)
            return
        claimed = {self.member} if self.state is DutyState.ON_STATION else set()
        for s, n in table.items():
            e = n.state.energy
            self._last_heard[s] = (None if e is None else e.role, n.state.t_s)
            if e is not None and e.role == "on_station" and e.relief_sysid:
                claimed.add(e.relief_sysid)
        for s in [s for s in self.lost if s in table or s in claimed]:
            del self.lost[s]

    def _check_charge(self, t_s: float) -> None:
        """A spare past its ready time (and the lag of a swap's report) still short of
        ``READY_PCT`` is :attr:`uncharged` (it shares ``unavailable``); said once each time."""
        pct = self.battery_pct
        short = (
            self.state is DutyState.SPARE
            and pct is not None
            and pct < READY_PCT
            and t_s >= self.ready_t_s + LAUNCH_GRACE_S
        )
        if short and not self.uncharged:
            self._log(SpareUncharged(t_s=t_s, sysid=self.sysid, battery_pct=pct,
                                     need_pct=READY_PCT))  # fmt: skip
        self.uncharged = short

    def _change(self, event: DutyEvent) -> None:
        self.state = advance(DUTY_TABLE, self.state, event)

    # ---- on station -----------------------------------------------------------------------
    def _update_leave(self, t_s: float, patrol: Patrol) -> None:
        b = self.battery
        if self.state is not DutyState.ON_STATION or b is None:
            return
        consumed = self._consumed_mah
        if consumed is None and self.battery_pct is not None:
            consumed = b.capacity_mah * (1.0 - self.battery_pct / 100.0)
        if consumed is None:
            return
        current = self._drain.current_a
        if current is None:  # the mission's: the capacity in the endurance
            current = b.capacity_mah / (b.endurance_min * 60.0) * 3.6
        home = self._home_s(patrol)
        t = leave_time_s(t_s, consumed, b.capacity_mah, b.reserve_mah, current, home, LAND_MARGIN_S)
        if self._beat_t_s is not None:  # the slot's next turn in the rotation, if sooner
            t = min(t, self._beat_t_s)
        elif self._opening_steps:  # a first stint of a staggered opening
            t = self._opening_leave_s(t_s, t, patrol)
        self.leave_t_s = round(t, 6)  # as the wire carries it: every member plans on the same

    def _opening_leave_s(self, t_s: float, battery_leave_s: float, patrol: Patrol) -> float:
        """A first stint's leave time in a ``staggered`` opening (vehicle s; docs/energy.md,
        "The opening"): its steps of ``beat / N`` before ``battery_leave_s``, the time its
        battery says, but not before its first plan (at ``t_s``, the first call) plus the
        relief's lead (a spare booked then is in the slot by then) nor after the battery's
        time. Started together and full, the N patrol UAVs then leave one ``beat / N`` apart
        in ``sysids`` order, as the rotation keeps them, instead of all at once."""
        if self._opening_floor_s is None:
            self._opening_floor_s = t_s + self.roster.relief_lead_s(patrol)
        beat = self.roster.beat_s(patrol, self.battery) if self.battery else None
        if beat is None:
            return battery_leave_s
        early = self._opening_steps * beat / len(self.roster.patrol_sysids)
        return min(battery_leave_s, max(battery_leave_s - early, self._opening_floor_s))

    def _home_s(self, patrol: Patrol) -> float:
        """The longest flight home from the loop to its nearest base, in the agreed wind (s)."""
        return self.roster.home_s(patrol)

    def _on_station(self, t_s: float, heard: Neighbours, can_leave: bool) -> DutyStep:
        if self.member is not None and t_s - self._in_slot_t_s > CLAIM_S:
            self.member = None  # the member it relieved has had time to hear it
        for s, n in heard.table.items():  # who has flown in for it, this stint
            e = n.state.energy
            if e is not None and e.role == "relieving" and e.relief_sysid == self.sysid:
                self._relievers.add(s)
        by = next(
            (
                s
                for s, n in sorted(heard.table.items())
                if s in self._relievers
                and n.state.mode is Mode.PATROL
                and n.state.energy is not None
                and n.state.energy.role == "on_station"
                and n.state.energy.relief_sysid == self.sysid
            ),
            None,
        )
        mine = self._plan.of_member(self.sysid) if self._plan is not None else None
        said = (mine.spare or 0) in self._late_said if mine is not None else True
        if by is None and mine is not None and mine.late and not said:
            self._late_said.add(mine.spare or 0)
            late = None if mine.spare is None else round(mine.late_s, 1)
            self._log(ReliefLate(t_s=t_s, sysid=self.sysid, spare_sysid=mine.spare or 0,
                                 leave_t_s=round(mine.leave_t_s, 1), late_s=late))  # fmt: skip
        if not can_leave:
            return ON_STATION
        due = self.leave_t_s is not None and t_s >= self.leave_t_s
        if by is None and not due:
            return ON_STATION
        margin = round(self.leave_t_s - t_s, 1) if self.leave_t_s is not None else 0.0
        self._log(Relieved(t_s=t_s, sysid=self.sysid, spare_sysid=by or 0, margin_s=margin,
                           reason="relieved" if by is not None else "leave_time",
                           battery_pct=self.battery_pct))  # fmt: skip
        self._change(DutyEvent.RELIEVED)
        self._ride_until_s = self.leave_t_s if by is not None else None
        self._ride_behind = by
        self.member, self.leave_t_s, self._beat_t_s = None, None, None
        self._opening_steps = 0  # the opening was its first stint only
        self._late_said.clear()
        self._relievers.clear()
        return DutyStep(True, 0.0, self.airspeed_m_s)

    # ---- home -----------------------------------------------------------------------------
    def _home(
        self,
        t_s: float,
        pos_m: complex,
        heading_rad: float,
        heard: Neighbours,
        patrol: Patrol,
        gains: Gains,
    ) -> DutyStep:
        base = min(self.bases, key=lambda b: (abs(b - pos_m), b.real, b.imag))
        step = self._way_home(t_s, pos_m, heading_rad, heard, patrol, gains, base)
        if step is not None:
            return step
        if abs(base - pos_m) > LAND_RADIUS_M:
            u = fly_to(pos_m, heading_rad, base, patrol, self.max_u)
            return DutyStep(True, u, self.airspeed_m_s)
        self._change(DutyEvent.LANDED)
        self.grounded = True
        self.ready_t_s = round(t_s + self.turnaround_s + 2.0, 6)  # 10 Hz sampling of the swap
        self._log(ReliefLanded(t_s=t_s, sysid=self.sysid, north_m=round(pos_m.real, 1),
                               east_m=round(pos_m.imag, 1), ready_t_s=round(self.ready_t_s, 1),
                               battery_pct=self.battery_pct))  # fmt: skip
        return DutyStep(True, 0.0, self.airspeed_m_s, hold=True, command="land")

    # ---- spare ----------------------------------------------------------------------------
    def _spare(self, t_s: float, pos_m: complex, heading_rad: float, patrol: Patrol) -> DutyStep:
        p = self._plan
        mine = p.of_spare(self.sysid) if p is not None else None
        charged = self.battery_pct is not None and self.battery_pct >= READY_PCT
        if mine is not None and t_s >= mine.launch_t_s and t_s >= self.ready_t_s and charged:
            # committed from here: it shares "relieving" at once, so nobody books it again
            self._change(DutyEvent.LAUNCHED)
            self.member, self._committed_t_s = mine.member, t_s
            self._leave_of_member = mine.leave_t_s
            self._capture, self._turn_sign, self._waiting, self._aim = False, 0.0, True, None
            self._in_lane = self._laned = False
            self._hold_left_rad = None
        return self._wait(pos_m, heading_rad, patrol)

    def _wait(self, pos_m: complex, heading_rad: float, patrol: Patrol) -> DutyStep:
        """On the ground (no setpoint) or orbiting its holding point."""
        if self.grounded:
            return DutyStep(True, 0.0, self.airspeed_m_s, hold=True)
        target = self.hold_point_m if self.hold_point_m is not None else self.bases[0]
        u = orbit(pos_m, heading_rad, target, patrol, self.max_u)
        return DutyStep(True, u, self.airspeed_m_s)

    def _launch(self, t_s: float, pos_m: complex) -> DutyStep:
        """Take off (or leave its hold) for its member now."""
        self._waiting, self._launch_t_s = False, t_s
        self._log(ReliefLaunched(t_s=t_s, sysid=self.sysid, member_sysid=self.member or 0,
                                 leave_t_s=round(self._leave_of_member, 1),
                                 battery_pct=self.battery_pct))  # fmt: skip
        self._launch_pos = pos_m
        if self.grounded:
            self.grounded, self._takeoff_pos = False, pos_m
            return DutyStep(True, 0.0, self.airspeed_m_s, command="takeoff")
        return DutyStep(True, 0.0, self.airspeed_m_s)

    def climbed_out(self) -> None:
        """Its autopilot's own take-off (ArduPlane's TAKEOFF: a climb-out along the runway,
        then GUIDED) is over: a relieving spare whose climb-out took it more than
        ``CLIMB_OUT_M`` from its launch point chooses the lane point it flies to again, from
        there (the point chosen at its launch took no climb-out; our simulator has none)."""
        if self.state is DutyState.RELIEVING and not self._waiting:
            self._reaim = True

    # ---- relieving ------------------------------------------------------------------------
    def _rival(self, heard: Neighbours) -> int | None:
        """Another UAV that has this spare's member: one flying in for it with a lower sysid
        (the tie-break every spare applies the same way), or one on station that says it
        took the slot; its sysid, or None."""
        for s, n in sorted(heard.table.items()):
            e = n.state.energy
            if s == self.sysid or e is None or e.relief_sysid != self.member:
                continue
            if (e.role == "relieving" and s < self.sysid) or e.role == "on_station":
                return s
        return None

    def _stand_down(self, t_s: float, rival: int, pos_m: complex, heading_rad: float,
                    heard: Neighbours, patrol: Patrol, gains: Gains) -> DutyStep:  # fmt: skip
        """Give the relief up to ``rival``: a spare again if it has not left, else home."""
        airborne = not self._waiting
        self._log(ReliefStoodDown(t_s=t_s, sysid=self.sysid, member_sysid=self.member or 0,
                                  rival_sysid=rival, airborne=airborne))  # fmt: skip
        self.member, self._waiting, self._takeoff_pos, self._slot_since = None, False, None, None
        if not airborne:
            self._change(DutyEvent.STOOD_DOWN)
            return self._wait(pos_m, heading_rad, patrol)
        self._change(DutyEvent.TURNED_BACK)
        self._ride_until_s = None
        return self._home(t_s, pos_m, heading_rad, heard, patrol, gains)

    def _relieving(self, t_s, pos_m, heading_rad, heard: Neighbours, patrol, gains) -> DutyStep:
        rival = self._rival(heard)
        if rival is not None:  # two spares booked for one member: the other keeps it
            return self._stand_down(t_s, rival, pos_m, heading_rad, heard, patrol, gains)
        if self._waiting:  # committed: it goes when its member's slot comes round
            member = heard.table.get(self.member) if self.member is not None else None
            found = None
            go = member is None or member.state.mode is not Mode.PATROL  # the slot is open now
            go = go or t_s - self._committed_t_s > WAIT_PERIODS * patrol.period_s
            lane = not inside(pos_m, patrol)  # from inside the loop no lane point fits
            if not go:
                slot = slot_phase(member, t_s, patrol)
                behind = self._behind(slot, patrol)
                if lane:
                    found = self._meet(pos_m, heading_rad, behind, patrol)
                else:
                    back = behind - TWO_PI * self.sensor_m / patrol.length_m
                    found = self._meet_loop(pos_m, heading_rad, back, patrol, True)
                go = found is not None and found[1] <= LAUNCH_SLACK_S
            if not go:
                return self._wait(pos_m, heading_rad, patrol)
            self._aim = found[0] if found is not None and lane else None  # its lane point
            return self._launch(t_s, pos_m)
        took = t_s - self._launch_t_s
        if self._takeoff_pos is not None:  # commanded: airborne once it moves
            if abs(pos_m - self._takeoff_pos) > 5.0:
                self._takeoff_pos = None
            elif took > LAUNCH_TIMEOUT_S:  # it did not take off: a spare no longer
                self._log(ReliefInSlot(t_s=t_s, sysid=self.sysid, member_sysid=self.member or 0,
                                       took_s=round(took, 1), reason="no_takeoff"))  # fmt: skip
                self._change(DutyEvent.NOT_AIRBORNE)
                self.grounded, self._takeoff_pos, self.member = True, None, None
                self.ready_t_s = math.inf  # out of the rotation until someone sees to it
                return DutyStep(True, 0.0, self.airspeed_m_s, hold=True)
            else:
                return DutyStep(True, 0.0, self.airspeed_m_s)
        member = heard.table.get(self.member) if self.member is not None else None
        if member is not None and member.state.mode is not Mode.PATROL:
            member = None  # it left (or is away on an alert): its slot is open
        own_phase, off_m = patrol.phase_and_offset_of_point(pos_m)
        along_m = None  # along the loop from the member's slot (m)
        if member is not None and member.state.pos_m is not None:
            slot = slot_phase(member, t_s, patrol)
            along_m = abs(float(wrap_pi(own_phase - slot))) * patrol.length_m / TWO_PI
        reason = None
        if member is None:
            reason = "member_gone"  # an unplanned loss: the slot the formation leaves open
        elif took > TAKEOVER_LIMIT_PERIODS * patrol.period_s:
            reason = "timeout"
        elif along_m is not None and off_m < IN_SLOT_M:
            if along_m < IN_SLOT_M:
                self._slot_since = t_s if self._slot_since is None else self._slot_since
                if t_s - self._slot_since >= IN_SLOT_S:
                    reason = "in_slot"
            else:
                self._slot_since = None
        if reason is not None and (reason != "member_gone" or off_m < IN_SLOT_M):
            self._log(ReliefInSlot(t_s=t_s, sysid=self.sysid, member_sysid=self.member or 0,
                                   took_s=round(took, 1), reason=reason))  # fmt: skip
            self._change(DutyEvent.IN_SLOT)
            self._slot_since = None
            self._in_slot_t_s = t_s
            beat = self.roster.beat_s(patrol, self.battery) if self.battery else None
            self._beat_t_s = None if beat is None else self._leave_of_member + beat
            return ON_STATION
        others = _formation_less(heard, t_s, patrol, self.member)
        behind = None
        if member is not None:
            behind = self._behind(slot_phase(member, t_s, patrol), patrol)
        ahead = behind is not None and phase_gap_rad(own_phase, behind) > 0.0
        within = inside(pos_m, patrol)  # flying out from inside the loop (no lane point fits)
        near = off_m < (TURN_IN_M if self._laned else APPROACH_M)
        near = near or (within and off_m < self.lane_m)  # from inside: as far in as a lane
        captured = near and self._captured(along_m, patrol, others, ahead)
        if member is None or captured:
            self._in_lane, self._hold_left_rad = False, None
            centre, phase = patrol.centre_and_phase(pos_m, heading_rad)
            u = splay_command(patrol, gains, pos_m, heading_rad, float(phase), complex(centre),
                              others, self.max_u)  # fmt: skip
            v = patrol.airspeed_m_s
            if speed_holds_phase(gains):
                v = splay_airspeed(patrol, gains, own_phase, [ph for ph, _ in others])
            return DutyStep(True, u, v)
        spacing_m = patrol.length_m / (len(others) + 1)
        turn_in = not ahead and along_m is not None and along_m < CAPTURE_SPACINGS * spacing_m
        return self._relieving_step(pos_m, heading_rad, patrol, gains, behind, own_phase, turn_in,
                                    within)  # fmt: skip

    # ---- the plan -------------------------------------------------------------------------
    def _make_plan(self, t_s: float, pos_m: complex, heard: Neighbours, patrol: Patrol) -> Plan:
        states = [(s, n.state.energy, n.state.pos_m) for s, n in heard.table.items()
                  if n.state.energy is not None]  # fmt: skip
        own = self.energy()
        if own is not None:
            states.append((self.sysid, own, pos_m))
        got = self.roster.inputs(t_s, states, patrol, self.lost)
        for r in got.refused:  # never booked: counted each plan, said once per sysid and role
            self.refused[r.reason] = self.refused.get(r.reason, 0) + 1
            if (r.sysid, r.role) not in self._refused_said:
                self._refused_said.add((r.sysid, r.role))
                self._log(ReliefRefused(t_s=t_s, sysid=self.sysid, member_sysid=r.sysid,
                                        role=r.role, reason=r.reason))  # fmt: skip
        p, passed = plan_from(t_s, got, patrol, self._watch)
        for spare, member in sorted(passed.items()):  # said by the member it was booked for
            if member == self.sysid:
                self._log(SpareNoLaunch(t_s=t_s, sysid=self.sysid, spare_sysid=spare))
        return p


def _formation_less(
    heard: Neighbours, t_s: float, patrol: Patrol, member: int | None
) -> list[tuple[float, complex]]:
    """(phase rad, centre m) at ``t_s`` (s) of every heard member in the formation but
    ``member``, in sysid order: the splay a relief settles into, with the member's slot open."""
    out = []
    for s, n in sorted(heard.table.items()):
        if s == member or n.state.mode in OUT_OF_FORMATION:
            continue
        out.append((n.state.phase_at(n.state.t_s + (t_s - n.rx_t_s), patrol.period_s),
                    n.state.centre_m))  # fmt: skip
    return out
