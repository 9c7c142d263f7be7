"""One UAV's part in the reliefs (pure; docs/energy.md, "Reliefs"): the seam the Agent calls.

``Duty(sysid, mission).step(fix, heard, gains, can_leave)`` returns a
:class:`~companion.agent.relief.states.DutyResult`: what the Agent flies (or that it patrols)
and the step's events, which the Agent logs right after the call.

A :class:`Duty` is one of four states, changed only along
:data:`~companion.agent.relief.states.DUTY_TABLE`
(:func:`companion.agent.machine.advance`), each with its record
(:mod:`companion.agent.relief.records`: made by the transition that enters the state,
dropped by the one that leaves it) and its handler (:attr:`Duty._handlers`, keyed by the
state). Relieving and home go through stages of their own, each with its record, along
:data:`~companion.agent.relief.states.RELIEVING_TABLE` (its way in:
:mod:`companion.agent.relief.fly_in`) and :data:`~companion.agent.relief.states.HOME_TABLE`
(its way off the loop: :mod:`companion.agent.relief.fly_home`):

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
from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.energy import Gauge
from companion.agent.relief.events import (
    ReliefInSlot,
    ReliefLanded,
    ReliefLaunched,
    ReliefStoodDown,
    Relieved,
    SpareUncharged,
)
from companion.agent.relief.figures import Figures
from companion.agent.relief.fly_home import way_home
from companion.agent.relief.fly_in import (
    CAPTURE_SPACINGS,
    Approach,
    behind_rad,
    capture,
    captured,
    flight_of,
    fly_for,
    fly_in,
    release,
)
from companion.agent.relief.join import fly_to, inside, orbit, slot_phase
from companion.agent.relief.on_station import relieved_by, say_late, update_leave
from companion.agent.relief.planning import LostWatch, Planner
from companion.agent.relief.records import (
    Committed,
    DutyRecord,
    Flight,
    GoingHome,
    OnStation,
    Relieving,
    Riding,
    Spare,
    Staged,
    StraightHome,
    TakingOff,
)
from companion.agent.relief.relieving import (
    IN_SLOT_M,
    IN_SLOT_S,
    WAIT_PERIODS,
    along_m,
    formation_less,
    in_slot_reason,
    rival,
    steer_into_slot,
    when_to_go,
)
from companion.agent.relief.roster import LAND_MARGIN_S, Roster
from companion.agent.relief.schedule import LAUNCH_GRACE_S, Plan
from companion.agent.relief.states import (
    DUTY_TABLE,
    OFF,
    ON_STATION,
    DutyEvent,
    DutyResult,
    DutyState,
    DutyStep,
    RelievingEvent,
    RelievingStage,
)
from companion.group.messages import Energy, Mode
from companion.guidance.steering import Gains
from companion.guidance.virtual import phase_gap_rad
from companion.mission import Mission

__all__ = [  # and what tests and benches read from here
    "IN_SLOT_S",
    "LAND_MARGIN_S",
    "LAND_RADIUS_M",
    "LAUNCH_TIMEOUT_S",
    "READY_PCT",
    "WAIT_PERIODS",
    "Duty",
]

LAND_RADIUS_M = 40.0  # within this of its base a UAV flying home lands (m)
READY_PCT = 90.0  # a spare launches only with at least this charge (%; avionics drain it)
APPROACH_M = 60.0  # nearer the loop than this, a relieving spare flies the steering law (m)
TURN_IN_M = 25.0  # ... or than this, turning in from its lane
CLAIM_S = 30.0  # a relief shares whom it relieved this long after taking the slot (s)
LAUNCH_TIMEOUT_S = 10.0  # a spare commanded to take off that has not moved by then did not

Handler = Callable[..., DutyResult]


class Duty:
    """One UAV's reliefs (see the module docstring).

    Args:
        sysid: this UAV's system id.
        mission: the mission; without a battery section the duty is off
            (:attr:`enabled` False: always on station, nothing shared).
    """

    def __init__(self, sysid: int, mission: Mission) -> None:
        """On station if ``sysid`` is a patrol UAV, a spare (on the ground or holding) if
        it is one of the mission's spares."""
        self.fig = Figures.of(sysid, mission)
        self.roster = Roster(mission)  # who may take part; the bases, the turnaround
        self.gauge = Gauge()  # its battery as reported
        self.planner = Planner(self.fig.sysid, self.roster)
        self.watch = LostWatch()
        first: DutyRecord = (
            Spare(self.fig.grounded)
            if self.fig.spare
            else OnStation(opening_steps=self.fig.opening_steps)
        )
        self._duty: Staged[DutyState, DutyRecord] = Staged(DUTY_TABLE, first)
        self._handlers: dict[DutyState, Handler] = {
            DutyState.ON_STATION: self._on_station,
            DutyState.HOME: self._home,
            DutyState.SPARE: self._spare,
            DutyState.RELIEVING: self._relieving,
        }
        self._stages: dict[RelievingStage, Handler] = {
            RelievingStage.COMMITTED: self._committed,
            RelievingStage.TAKING_OFF: self._taking_off,
            RelievingStage.TO_LANE: self._flying,
            RelievingStage.TO_LOOP: self._flying,
            RelievingStage.IN_LANE: self._flying,
            RelievingStage.FULL_TURN: self._flying,
            RelievingStage.CAPTURED: self._flying,
        }

    # ---- what others read -----------------------------------------------------------------
    @property
    def sysid(self) -> int:
        """This UAV's system id."""
        return self.fig.sysid

    @property
    def enabled(self) -> bool:
        """Whether the reliefs are on (the mission has a battery and spares)."""
        return self.fig.enabled

    @property
    def max_u(self) -> float:
        """Its turn-rate limit (rad/s)."""
        return self.fig.max_u

    @property
    def lane_m(self) -> float:
        """How far outside the loop its lane is (m)."""
        return self.fig.lane_m

    @property
    def meet_behind_m(self) -> float:
        """How far behind its member's slot a relieving spare turns in (m)."""
        return self.fig.meet_behind_m

    @property
    def state(self) -> DutyState:
        """Its part in the reliefs now."""
        return self._duty.state

    @property
    def record(self) -> DutyRecord:
        """The record of :attr:`state` (:mod:`companion.agent.relief.records`)."""
        return self._duty.record

    @property
    def battery_pct(self) -> float | None:
        """The charge left as last reported (%), None if unknown."""
        return self.gauge.pct

    @property
    def member(self) -> int | None:
        """Relieving: the member it flies in for; on station: whom it relieved (for
        ``CLAIM_S``); else None."""
        rec = self._duty.record
        if isinstance(rec, Relieving):
            return rec.member
        return rec.relieved if isinstance(rec, OnStation) else None

    @property
    def leave_t_s(self) -> float | None:
        """On station: when it must leave (s; None until its battery is known); else None."""
        rec = self._duty.record
        return rec.leave_t_s if isinstance(rec, OnStation) else None

    @property
    def grounded(self) -> bool:
        """A spare (or a committed one) on the ground."""
        rec = self._duty.record
        if isinstance(rec, Relieving):
            rec = rec.stage.record
        return isinstance(rec, Spare | Committed) and rec.grounded

    @property
    def plan(self) -> Plan | None:
        """The fleet's reliefs as this UAV last planned them (None before the first step)."""
        return self.planner.plan

    @property
    def refused(self) -> dict[str, int]:
        """Shared states left out of the plan, by reason (counted each plan)."""
        return self.planner.refused

    @property
    def lost(self) -> dict[int, float]:
        """Members that fell silent on station: sysid -> the time of their last state (s)."""
        return self.watch.lost

    @property
    def off_station(self) -> bool:
        """Whether it is out of the formation (shares mode ``spare``)."""
        return self.enabled and self.state is not DutyState.ON_STATION

    def energy(self) -> Energy | None:
        """What it shares (None when the duty is off)."""
        if not self.enabled:
            return None
        return self._duty.record.energy(self.gauge.pct)

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
        self.gauge.observe(t_s, remaining_pct, consumed_mah, current_a)

    def climbed_out(self) -> None:
        """Its autopilot's own take-off (ArduPlane's TAKEOFF: a climb-out along the runway,
        then GUIDED) is over: a relieving spare whose climb-out took it more than
        ``CLIMB_OUT_M`` from its launch point chooses the lane point it flies to again, from
        there (the point chosen at its launch took no climb-out; our simulator has none)."""
        rec = self._duty.record
        flight = flight_of(rec.stage.record) if isinstance(rec, Relieving) else None
        if flight is not None:  # launched
            flight.reaim = True

    # ---- the step -------------------------------------------------------------------------
    def step(self, fix: Fix, heard: Neighbours, gains: Gains, can_leave: bool) -> DutyResult:
        """Decide at ``fix`` (its patrol the loop), from the members ``heard``; ``can_leave``:
        on patrol (not away on an alert), so it may be relieved. The events come back in
        the order they happened."""
        if not self.enabled:
            return OFF
        rec = self._duty.record
        self.watch.track(heard, rec.relieved if isinstance(rec, OnStation) else None)
        events = self._check_charge(fix.t_s)
        if self.planner.due(fix.t_s):
            if isinstance(rec, OnStation):
                update_leave(rec, self.fig, self.roster, self.gauge, fix.t_s, fix.patrol)
            events += self.planner.replan(fix, heard, self.energy(), self.watch.lost)
        done = self._handlers[self._duty.state](self._duty.record, fix, heard, gains, can_leave)
        return DutyResult(done.step, (*events, *done.events)) if events else done

    def _change(self, event: DutyEvent, record: DutyRecord) -> None:
        """Into the state ``event`` leads to (:data:`DUTY_TABLE`), with its ``record``."""
        self._duty.go(event, record)

    def _check_charge(self, t_s: float) -> list[AgentEvent]:
        """A spare past its ready time (and the lag of a swap's report) still short of
        ``READY_PCT`` is ``uncharged`` (it shares ``unavailable``); said once each time."""
        rec, pct = self._duty.record, self.gauge.pct
        if not isinstance(rec, Spare):
            return []
        short = pct is not None and pct < READY_PCT and t_s >= rec.ready_t_s + LAUNCH_GRACE_S
        said = short and not rec.uncharged
        rec.uncharged = short
        if said and pct is not None:
            return [SpareUncharged(t_s=t_s, sysid=self.sysid, battery_pct=pct,
                                   need_pct=READY_PCT)]  # fmt: skip
        return []

    # ---- on station -----------------------------------------------------------------------
    def _on_station(
        self, rec: OnStation, fix: Fix, heard: Neighbours, gains: Gains, can_leave: bool
    ) -> DutyResult:
        """On the loop: relieved when a UAV it heard flying in for it shares, on patrol, that
        it relieved it; at its leave time, relieved or not (both only on patrol)."""
        t_s = fix.t_s
        if rec.relieved is not None and t_s - rec.in_slot_t_s > CLAIM_S:
            rec.relieved = None  # the member it relieved has had time to hear it
        by = relieved_by(rec, heard, self.sysid)
        events = say_late(rec, self.planner.plan, self.sysid, t_s) if by is None else []
        if not can_leave:
            return DutyResult(ON_STATION, tuple(events))
        due = rec.leave_t_s is not None and t_s >= rec.leave_t_s
        if by is None and not due:
            return DutyResult(ON_STATION, tuple(events))
        margin = round(rec.leave_t_s - t_s, 1) if rec.leave_t_s is not None else 0.0
        events.append(Relieved(t_s=t_s, sysid=self.sysid, spare_sysid=by or 0, margin_s=margin,
                               reason="relieved" if by is not None else "leave_time",
                               battery_pct=self.gauge.pct))  # fmt: skip
        until = rec.leave_t_s if by is not None else None
        first = Riding(until, by) if until is not None and by is not None else StraightHome()
        self._change(DutyEvent.RELIEVED, GoingHome.starting(first))
        return DutyResult(DutyStep(True, 0.0, self.fig.airspeed_m_s), tuple(events))

    # ---- home -----------------------------------------------------------------------------
    def _home(
        self, rec: GoingHome, fix: Fix, heard: Neighbours, gains: Gains, can_leave: bool
    ) -> DutyResult:
        """Off the loop by its stages (:func:`~companion.agent.relief.fly_home.way_home`),
        then straight to the nearest base; within ``LAND_RADIUS_M`` of it, it lands."""
        pos_m = fix.pos_m
        base = min(self.roster.bases, key=lambda b: (abs(b - pos_m), b.real, b.imag))
        step = way_home(rec, self.fig, fix, heard, gains, base)
        if step is not None:
            return DutyResult(step)
        if abs(base - pos_m) > LAND_RADIUS_M:
            u = fly_to(pos_m, fix.heading_rad, base, fix.patrol, self.fig.max_u)
            return DutyResult(DutyStep(True, u, self.fig.airspeed_m_s))
        ready = round(fix.t_s + self.roster.turnaround_s + 2.0, 6)  # 10 Hz sampling of the swap
        self._change(DutyEvent.LANDED, Spare(grounded=True, ready_t_s=ready))
        landed = ReliefLanded(t_s=fix.t_s, sysid=self.sysid, north_m=round(pos_m.real, 1),
                              east_m=round(pos_m.imag, 1), ready_t_s=round(ready, 1),
                              battery_pct=self.gauge.pct)  # fmt: skip
        step = DutyStep(True, 0.0, self.fig.airspeed_m_s, hold=True, command="land")
        return DutyResult(step, (landed,))

    # ---- spare ----------------------------------------------------------------------------
    def _spare(
        self, rec: Spare, fix: Fix, heard: Neighbours, gains: Gains, can_leave: bool
    ) -> DutyResult:
        """Waiting; booked, due and charged, it is committed at once (it shares
        ``relieving``, so nobody books it again)."""
        p, t_s, pct = self.planner.plan, fix.t_s, self.gauge.pct
        mine = p.of_spare(self.sysid) if p is not None else None
        charged = pct is not None and pct >= READY_PCT
        if mine is not None and t_s >= mine.launch_t_s and t_s >= rec.ready_t_s and charged:
            first = Committed(t_s, rec.grounded, rec.ready_t_s)
            self._change(
                DutyEvent.LAUNCHED, Relieving.committed(mine.member, mine.leave_t_s, first)
            )
        return DutyResult(self._wait(fix, rec.grounded))

    def _wait(self, fix: Fix, grounded: bool) -> DutyStep:
        """On the ground (no setpoint) or orbiting its holding point."""
        if grounded:
            return DutyStep(True, 0.0, self.fig.airspeed_m_s, hold=True)
        hold = self.fig.hold_point_m
        target = hold if hold is not None else self.roster.bases[0]
        u = orbit(fix.pos_m, fix.heading_rad, target, fix.patrol, self.fig.max_u)
        return DutyStep(True, u, self.fig.airspeed_m_s)

    # ---- relieving ------------------------------------------------------------------------
    def _relieving(
        self, rec: Relieving, fix: Fix, heard: Neighbours, gains: Gains, can_leave: bool
    ) -> DutyResult:
        """Its stage's step (:attr:`_stages`), unless another spare has its member."""
        other = rival(rec, heard, self.sysid)
        if other is not None:  # two spares booked for one member: the other keeps it
            return self._stand_down(rec, other, fix, heard, gains)
        return self._stages[rec.stage.state](rec, fix, heard, gains)

    def _stand_down(
        self, rec: Relieving, rival_sysid: int, fix: Fix, heard: Neighbours, gains: Gains
    ) -> DutyResult:
        """Give the relief up to ``rival_sysid``: a spare again if it has not left, else
        home."""
        stage = rec.stage.record
        airborne = not isinstance(stage, Committed)
        said = ReliefStoodDown(t_s=fix.t_s, sysid=self.sysid, member_sysid=rec.member or 0,
                               rival_sysid=rival_sysid, airborne=airborne)  # fmt: skip
        if isinstance(stage, Committed):
            self._change(DutyEvent.STOOD_DOWN, Spare(stage.grounded, stage.ready_t_s))
            return DutyResult(self._wait(fix, stage.grounded), (said,))
        home = GoingHome.starting(StraightHome())
        self._change(DutyEvent.TURNED_BACK, home)
        done = self._home(home, fix, heard, gains, True)
        return DutyResult(done.step, (said, *done.events))

    def _committed(self, rec: Relieving, fix: Fix, heard: Neighbours, gains: Gains) -> DutyResult:
        """Committed: it waits until its member's slot comes round
        (:func:`~companion.agent.relief.relieving.when_to_go`), then launches."""
        stage = rec.stage.record
        assert isinstance(stage, Committed)
        go, aim = when_to_go(self.fig, fix, heard.table.get(rec.member), stage.since_t_s)
        if not go:
            return DutyResult(self._wait(fix, stage.grounded))
        return self._launch(rec, stage, fix, aim)

    def _launch(
        self, rec: Relieving, stage: Committed, fix: Fix, aim_m: complex | None
    ) -> DutyResult:
        """Take off (or leave its hold) for its member now, for the lane point ``aim_m``
        (m; None: none kept)."""
        said = ReliefLaunched(t_s=fix.t_s, sysid=self.sysid, member_sysid=rec.member or 0,
                              leave_t_s=round(rec.leave_of_member_s, 1),
                              battery_pct=self.gauge.pct)  # fmt: skip
        flight = Flight(fix.t_s, fix.pos_m)
        if stage.grounded:
            rec.go(RelievingEvent.TAKE_OFF, TakingOff(flight, fix.pos_m, aim_m))
            return DutyResult(
                DutyStep(True, 0.0, self.fig.airspeed_m_s, command="takeoff"), (said,)
            )
        fly_for(rec, flight, aim_m)
        return DutyResult(DutyStep(True, 0.0, self.fig.airspeed_m_s), (said,))

    def _taking_off(self, rec: Relieving, fix: Fix, heard: Neighbours, gains: Gains) -> DutyResult:
        """Asked to take off: airborne once it moves (and on at once); not moved after
        ``LAUNCH_TIMEOUT_S`` it did not take off, and is out of the rotation."""
        stage = rec.stage.record
        assert isinstance(stage, TakingOff)
        took = fix.t_s - stage.flight.launch_t_s
        if abs(fix.pos_m - stage.takeoff_pos_m) > 5.0:
            fly_for(rec, stage.flight, stage.aim_m)
            return self._flying(rec, fix, heard, gains)
        if took <= LAUNCH_TIMEOUT_S:
            return DutyResult(DutyStep(True, 0.0, self.fig.airspeed_m_s))
        said = ReliefInSlot(t_s=fix.t_s, sysid=self.sysid, member_sysid=rec.member or 0,
                            took_s=round(took, 1), reason="no_takeoff")  # fmt: skip
        self._change(DutyEvent.NOT_AIRBORNE, Spare(grounded=True, ready_t_s=math.inf))
        return DutyResult(DutyStep(True, 0.0, self.fig.airspeed_m_s, hold=True), (said,))

    def _flying(self, rec: Relieving, fix: Fix, heard: Neighbours, gains: Gains) -> DutyResult:
        """Flying in: in the slot (held ``IN_SLOT_S``), timed out, or its member gone, it is
        on station; near the loop and the slot, or its member gone, the steering law with the
        formation less that member flies it (captured); else its stage's way in
        (:func:`~companion.agent.relief.fly_in.fly_in`)."""
        flight = flight_of(rec.stage.record)
        assert flight is not None
        t_s, patrol = fix.t_s, fix.patrol
        took = t_s - flight.launch_t_s
        member = heard.table.get(rec.member)
        if member is not None and member.state.mode is not Mode.PATROL:
            member = None  # it left (or is away on an alert): its slot is open
        off_m = fix.loop_offset_m
        along = along_m(member, fix)  # along the loop from the member's slot (m)
        reason = in_slot_reason(flight, fix, member, took, along)
        if reason is not None and (reason != "member_gone" or off_m < IN_SLOT_M):
            return self._in_slot(rec, fix, took, reason)
        others = formation_less(heard, t_s, patrol, rec.member)
        behind = None
        if member is not None:
            behind = behind_rad(self.fig, slot_phase(member, t_s, patrol), patrol)
        ahead = behind is not None and phase_gap_rad(fix.loop_phase_rad, behind) > 0.0
        within = inside(fix.pos_m, patrol)  # flying out from inside the loop (no lane point)
        near = off_m < (TURN_IN_M if flight.laned else APPROACH_M)
        near = near or (within and off_m < self.fig.lane_m)  # from inside: as far in as a lane
        is_captured = near and captured(rec, flight, along, patrol, len(others), ahead)
        if member is None or is_captured or behind is None:
            capture(rec, flight)
            return DutyResult(steer_into_slot(self.fig, fix, gains, others))
        release(rec, flight)
        spacing_m = patrol.length_m / (len(others) + 1)
        turn_in = not ahead and along is not None and along < CAPTURE_SPACINGS * spacing_m
        return DutyResult(fly_in(rec, self.fig, Approach(fix, gains, behind, turn_in, within)))

    def _in_slot(self, rec: Relieving, fix: Fix, took: float, reason: str) -> DutyResult:
        """It holds its member's slot (or takes it as it is): on station, sharing whom it
        relieved; its leave time the rotation's next turn of the slot, if sooner."""
        said = ReliefInSlot(t_s=fix.t_s, sysid=self.sysid, member_sysid=rec.member or 0,
                            took_s=round(took, 1), reason=reason)  # fmt: skip
        battery = self.fig.battery
        beat = self.roster.beat_s(fix.patrol, battery) if battery else None
        beat_t_s = None if beat is None else rec.leave_of_member_s + beat
        on = OnStation(relieved=rec.member, in_slot_t_s=fix.t_s, beat_t_s=beat_t_s)
        self._change(DutyEvent.IN_SLOT, on)
        return DutyResult(ON_STATION, (said,))
