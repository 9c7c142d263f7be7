"""One UAV's decisions (pure): patrol, alerts, tasking, intercept, search, tracking and rejoin
(docs/design.md §4-5).

An :class:`Agent` is fed what its companion hears and sees, always with the vehicle's time
(s) passed in, never read from a clock:

* ``receive_state(MemberState, rx_t_s)`` and ``receive_alert(Alert, rx_t_s)`` from the group;
* ``detect(site_m, t_s)`` for every sighting of its own downward sensor (5 Hz);
* ``update(Fix)`` on every new state estimate (:class:`companion.agent.fix.Fix`), which
  returns the turn-rate command, the state to broadcast, the alerts to send and the events
  to log (:class:`companion.agent.output.AgentOutput`).

The same class runs in every ``companion run`` and, N times over an in-memory group, in
``companion simulate``: typed parts, each with its own state, and ``update`` a line through them:

* :class:`~companion.agent.neighbours.Neighbours` -- who is in the formation (a member silent
  for ``member_timeout_s`` leaves it); :class:`~companion.agent.wind.follow.FleetWind` -- the
  fleet's one wind (the loop re-timed when the agreed record changes);
* :class:`~companion.agent.alert_duty.AlertDuty` -- the alerts it knows, raises and shares;
* :class:`~companion.agent.relief.duty.Duty` -- the reliefs (a spare, or a UAV flying in or
  home, is out of the formation); :class:`~companion.agent.alerts.tasking.Tasking` -- who
  answers each queued alert (the same rules on the same shared state in every companion);
* :class:`~companion.agent.pilot.Pilot` -- its own mode (:mod:`companion.agent.modes`), the
  mode's record (:mod:`companion.agent.away`) and the mode's handler: the splay on patrol
  (:class:`~companion.agent.splay.Splay`), the intercept and search, the tracking, the rejoin.

Its options are one :class:`~companion.agent.config.AgentConfig`.
"""

from __future__ import annotations

import math
from typing import Any

from companion.agent.alert_duty import AlertDuty
from companion.agent.alerts.tasking import Tasking
from companion.agent.away import AwayRecord
from companion.agent.config import AgentConfig, OnConfirm, Policy
from companion.agent.events import AgentEvent, MemberJoined, MemberLost
from companion.agent.fix import Fix
from companion.agent.modes import OwnMode
from companion.agent.neighbours import Neighbour, Neighbours
from companion.agent.output import AgentOutput
from companion.agent.pilot import Flight, Pilot
from companion.agent.relief.duty import Duty
from companion.agent.relief.states import DutyStep
from companion.agent.splay import Splay
from companion.agent.wind.follow import FleetWind
from companion.core.particle import ParticleParams, step_one
from companion.core.patrol import Patrol
from companion.group.messages import Alert, MemberState, Mode
from companion.mission import Mission

__all__ = ["Agent", "AgentConfig", "OnConfirm", "Policy"]


class Agent:
    """The decision logic of one companion.

    Args:
        sysid: this UAV's MAVLink system id.
        mission: the mission (loop, gains, limits, sensor).
        config: its options (:class:`~companion.agent.config.AgentConfig`; None: defaults).

    Its parts are typed attributes (see the module's text); :attr:`patrol` is the loop in
    the fleet's wind in force, :attr:`neighbours` the members heard by sysid, :attr:`wind` the
    fleet's wind agreement (:class:`~companion.agent.wind.agreement.WindAgreement`).
    """

    def __init__(self, sysid: int, mission: Mission, config: AgentConfig | None = None) -> None:
        """Start on patrol with an empty formation table."""
        self.config = config if config is not None else AgentConfig()
        self.sysid = int(sysid)
        self.patrol: Patrol = mission.patrol
        v = mission.vehicles
        self._vehicle = ParticleParams(v.airspeed_m_s, v.max_turn_rate_rad_s)
        self._last_u: float | None = None
        self._heard = Neighbours(self.sysid, self.config.member_timeout_s)
        self.neighbours: dict[int, Neighbour] = self._heard.table  # members heard, by sysid
        self.alerts = AlertDuty(self.sysid, mission.sensor.footprint_radius_m, self.config)
        self.tasking = Tasking(
            self.sysid,
            self.alerts.book,
            self._heard,
            policy=self.config.policy,
            max_prosecutors=self.config.max_prosecutors,
            member_timeout_s=self.config.member_timeout_s,
            bid_window_s=self.config.bid_window_s,
            fence=mission.fence,
            max_u=v.max_turn_rate_rad_s,
        )
        self.splay = Splay(self._heard, mission.gains, v.max_turn_rate_rad_s)
        self.pilot = Pilot(self.sysid, mission, self.config, self.alerts, self._heard, self.splay)
        self._fleet_wind = FleetWind(
            self.sysid, v.airspeed_m_s, self.patrol, mission.gains, v.count, v.max_turn_rate_rad_s
        )
        self.wind = self._fleet_wind.agreement
        self._own_wind: complex | None = None
        self._events: list[AgentEvent] = []  # handed over with the next update
        # the reliefs (companion/agent/relief/duty.py): off without a battery and spares
        self.duty = Duty(self.sysid, mission)

    @property
    def member_timeout_s(self) -> float:
        """The silence after which a member leaves the formation (s)."""
        return self._heard.member_timeout_s

    def set_member_timeout(self, member_timeout_s: float) -> None:
        """A new member time-out (s): the formation's and the tasking's (a group budget makes
        it follow the state rate, :class:`companion.group.budget.Budget`)."""
        if not (math.isfinite(member_timeout_s) and member_timeout_s > 0):
            raise ValueError(f"member_timeout_s must be > 0 s, got {member_timeout_s!r}")
        self._heard.member_timeout_s = member_timeout_s
        self.tasking.member_timeout_s = member_timeout_s

    def fix_airspeed(self) -> None:
        """Fly the mission's airspeed from now on (the autopilot refused another): the phase
        is then held by steering alone, with the whole phase term (the paper's way)."""
        self.splay.fix_airspeed()

    @property
    def mode(self) -> Mode:
        """What this UAV is doing as the group and the logs name it: patrol, prosecuting,
        tracking or rejoining (its finer stage: :attr:`own_mode`)."""
        return self.pilot.state.mode.shared

    @property
    def own_mode(self) -> OwnMode:
        """Its own mode, every stage (:mod:`companion.agent.modes`)."""
        return self.pilot.state.mode

    @property
    def away(self) -> AwayRecord | None:
        """Its own mode's record (:mod:`companion.agent.away`), None on patrol."""
        return self.pilot.away

    # ---- inputs -------------------------------------------------------------------------
    def receive_state(self, state: MemberState, rx_t_s: float) -> None:
        """A member's broadcast state, received at local vehicle time ``rx_t_s`` (s)."""
        if not self._heard.hear(state, rx_t_s):
            return
        self.wind.member_estimate(state.sysid, state.wind_est_m_s, rx_t_s)
        self.wind.member_record(state.wind_record)

    def observe_wind(self, wind_m_s: complex | None, t_s: float) -> None:
        """This UAV's own wind estimate (m/s, towards; None: none yet) at ``t_s`` (s)."""
        self._own_wind = wind_m_s if self.wind.own_estimate(wind_m_s, t_s) else None

    def climbed_out(self) -> None:
        """The autopilot's own take-off is over, GUIDED again: :meth:`Duty.climbed_out`."""
        self.duty.climbed_out()

    def observe_battery(
        self,
        t_s: float,
        remaining_pct: float | None,
        consumed_mah: float | None,
        current_a: float | None,
    ) -> None:
        """The autopilot's battery at ``t_s`` (s): charge left (%), drawn (mAh), current (A),
        each None if not reported; for the reliefs (:mod:`companion.agent.relief.duty`)."""
        self.duty.observe_battery(t_s, remaining_pct, consumed_mah, current_a)

    def receive_alert(self, alert: Alert, rx_t_s: float) -> None:
        """An alert message from the group (new, confirmed, cleared, bid...) at ``rx_t_s`` (s)."""
        renamed, events = self.alerts.receive(alert, rx_t_s)
        self._events += events
        if renamed is not None:
            self.pilot.rename(*renamed)

    def detect(self, site_m: complex, t_s: float) -> None:
        """The own downward sensor covers an intruder at ``site_m`` (m) at ``t_s`` (s)."""
        self.alerts.detect(site_m, t_s)

    # ---- the step -------------------------------------------------------------------------
    def update(self, fix: Fix) -> AgentOutput:
        """Decide the command for the state estimate ``fix`` (its time, position and air
        heading; read against :attr:`patrol`)."""
        fix = self._ahead(fix)
        self.pilot.observe(fix)
        self._sightings(fix)
        done = self.duty.step(fix, self._heard, self.splay.gains, self.own_mode is OwnMode.PATROL)
        self._events += done.events
        duty = done.step
        if duty.off_station:
            return self._off_station(fix, duty)
        assigned = self.tasking.assign(fix, self.pilot.away)
        self._events += assigned.events
        self.alerts.send(assigned.send)
        if assigned.mine is not None:
            self._events += self.pilot.start(fix, assigned.mine)
        flight, events = self.pilot.fly(fix)
        self._events += events
        self.alerts.repeat(fix.t_s)
        away = self.pilot.away
        self.alerts.prune(fix.t_s, away.alert_id if away is not None else None)
        self._events += self.alerts.counts_due(fix.t_s)
        centre, phase, mode, alert_id = self.pilot.sharing(fix)
        return self._output(flight, self._share(fix, centre, phase, mode, alert_id), self.mode)

    def _ahead(self, fix: Fix) -> Fix:
        """The fix to decide for, read against the loop in the wind in force then.

        A command is held until the next one, so with ``lead_s`` it decides for the state
        the command will act on: ``lead_s`` ahead with the command in force, in the wind
        flown until now (removes the zero-order-hold bias: 1.1 m -> 0.04 m of centre error at
        10 Hz in process). At that time the formation's members time out and the fleet's
        wind is followed (proposed if this UAV is the proposer; the loop re-timed, and the
        steering, tasking, planner and rejoin with it, when the record in force changes)."""
        lead_s = self.config.lead_s
        t_s, pos_m, heading_rad = fix.t_s, fix.pos_m, fix.heading_rad
        if lead_s > 0.0 and self._last_u is not None:
            pos_m, ahead_rad = step_one(
                pos_m, heading_rad, self._last_u, self._vehicle, self.patrol.wind.vector, lead_s
            )
            t_s, heading_rad = t_s + lead_s, float(ahead_rad)
            fix = Fix(t_s, pos_m, heading_rad, self.patrol)
        self._expire_members(t_s)
        # every member switches at the same vehicle time to the same wind: the loop re-timed
        patrol, events = self._fleet_wind.follow(t_s, set(self.neighbours), self.patrol)
        self._events += events
        self.patrol = patrol if patrol is not None else self.patrol
        return fix.against(self.patrol)

    def _sightings(self, fix: Fix) -> None:
        """Every sighting since the last update, in every mode (:meth:`AlertDuty.sightings`);
        the alert this UAV flies to, seen, ends the prosecution (:meth:`Pilot.seen`)."""
        away = self.pilot.away
        found = self.alerts.sightings(fix.t_s, away.alert_id if away is not None else None)
        self._events += found.events
        for renamed in found.renamed:
            self.pilot.rename(*renamed)
        if found.seen is not None:
            self._events += self.pilot.seen(fix, found.seen)

    def _off_station(self, fix: Fix, duty: DutyStep) -> AgentOutput:
        """Out of the formation for the reliefs (a spare, flying in, flying home): the duty's
        command, its real state shared as mode ``spare``; no tasking."""
        self.alerts.prune(fix.t_s, None)
        shared = self._share(fix, fix.centre_m, fix.phase_rad, Mode.SPARE, "")
        flight = Flight(duty.turn_rate_rad_s, duty.airspeed_m_s)
        return self._output(flight, shared, Mode.SPARE, duty.hold, duty.command)

    def _share(
        self, fix: Fix, centre_m: complex, phase_rad: float, mode: Mode, alert_id: str
    ) -> MemberState:
        """The state to broadcast (centre m, phase rad, mode, alert id as :meth:`Pilot.sharing`
        says), with its position, wind and energy."""
        return MemberState(
            self.sysid,
            fix.t_s,
            centre_m,
            phase_rad,
            mode,
            alert_id,
            pos_m=complex(fix.pos_m),
            wind_est_m_s=self._own_wind,
            wind_record=self.wind.latest,
            energy=self.duty.energy(),
        )

    def _output(
        self,
        flight: Flight,
        shared: MemberState,
        mode: Mode,
        hold: bool = False,
        command: str | None = None,
    ) -> AgentOutput:
        """The step's output; the alerts and the events queued since the last one go with it
        (events logged on receipt are handed over too)."""
        self._last_u = float(flight.turn_rate_rad_s)
        out = AgentOutput(
            turn_rate_rad_s=float(flight.turn_rate_rad_s),
            airspeed_m_s=float(flight.airspeed_m_s),
            broadcast=shared,
            alerts_out=self.alerts.take_outbox(),
            typed_events=tuple(self._events),
            mode=mode,
            hold=hold,
            command=command,
        )
        self._events.clear()
        return out

    # ---- the formation ---------------------------------------------------------------------
    def _expire_members(self, t_s: float) -> None:
        """Members silent too long at ``t_s`` (s) leave the formation (an alert they held goes
        back to the queue); new ones join it."""
        change = self._heard.expire(t_s)
        for sysid in change.dropped:
            self.wind.forget(sysid)
        if not (change.joined or change.lost):
            return
        members = len(self.neighbours) + 1
        head: dict[str, Any] = {"t_s": t_s, "sysid": self.sysid, "members": members}
        self._events += [MemberJoined(member_sysid=s, **head) for s in change.joined]
        for sysid in change.lost:
            self._events.append(MemberLost(member_sysid=sysid, **head))
            self._events += self.tasking.requeue_alerts_of(sysid, t_s)
