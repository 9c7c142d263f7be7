"""One UAV's decisions (pure): patrol, alerts, tasking, intercept, search, tracking and rejoin
(docs/design.md §4-5).

An :class:`Agent` is fed what its companion hears and sees, always with the vehicle's time
(s) passed in, never read from a clock:

* ``receive_state(MemberState, rx_t_s)`` and ``receive_alert(Alert, rx_t_s)`` from the group;
* ``detect(site_m, t_s)`` for every sighting of its own downward sensor (5 Hz);
* ``update(t_s, pos_m, heading_rad)`` on every new state estimate, which returns the turn-rate
  command, the state to broadcast, the alerts to send and the events to log.

The same class runs inside every ``companion run`` process and, N times over an in-memory
group, inside ``companion simulate``. Its own mode (:mod:`companion.agent.modes`) and each
alert's status (:mod:`companion.agent.alerts.lifecycle`) change only along their tables (an
illegal change raises); who is in the formation is :mod:`companion.agent.neighbours`.

Rules (deterministic from shared state, so exactly one companion takes each alert):

* A member silent for ``member_timeout_s`` (judged by local receipt time) leaves the
  formation; its phase is otherwise extrapolated at the nominal rate. An alert it was
  prosecuting or tracking goes back to the queue, it excluded. A member that tracks an
  intruder is out of the formation too: the others splay as N - 1.
* Every sighting, in every mode, updates a track or raises an alert
  (:mod:`companion.agent.alerts.contacts`): a sighting where an open alert's track predicts
  its intruder refines that track (shared as "update" at most once a second and at the end
  of the pass); anywhere else it raises a new alert carrying its track.
* Alerts (:mod:`companion.agent.alerts.book`): an id seen again is a repeat; a report within
  the gate of an open alert's prediction, or of one cleared after the report was made, is
  merged into it (the earlier report wins); at most ``max_open_alerts`` are open; a track
  that may not be flown (NaN, a speed no intruder has, too old) is refused and counted.
* Tasking, policy "next": the next UAV to pass the site; "fastest": the smallest bid
  (:mod:`companion.agent.alerts.tasking`). At most ``max_prosecutors`` UAVs are away at once
  (flying to an alert, searching, tracking, or flying back into its slot); further alerts
  queue in (time, id) order. A hand-off goes at once.
* A prosecutor shares its virtual particle and flies the minimum-time intercept of the
  intruder's predicted track, re-planned every ``replan_s`` and on every newer track; where
  the intruder is not under the sensor as predicted it searches the track's uncertainty for
  at most ``search_max_s`` before it clears (:mod:`companion.agent.alerts.prosecution`).
* Seen, policy ``on_confirm="track"``: it stays over the intruder
  (:mod:`companion.agent.alerts.tracker`) until the track is lost, the intruder leaves the
  fence or the operator releases it, then rejoins into the widest gap of the formation.
  ``on_confirm="chain"`` (the paper's): it confirms, the next UAV takes the alert, and it
  rejoins.
* The rejoin (:mod:`companion.agent.rejoin`) flies back onto the loop first, then recovers
  its slot along the loop by airspeed, and hands back its real state once in the slot.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import numpy as np

from companion.agent.alert_duty import AlertDuty
from companion.agent.alerts.book import MAX_OPEN_ALERTS, AlertBook
from companion.agent.alerts.contacts import Contacts
from companion.agent.alerts.prosecution import Prosecution
from companion.agent.alerts.search import SEARCH_MAX_S
from companion.agent.alerts.tasking import Policy, Tasking
from companion.agent.alerts.tracker import TRACK_LOST_S, Tracker
from companion.agent.away import Away
from companion.agent.events import (
    AgentEvent,
    MemberJoined,
    MemberLost,
)
from companion.agent.fix import Fix
from companion.agent.formed import Formed
from companion.agent.modes import ModeEvent, OwnMode, next_mode
from companion.agent.neighbours import Neighbour, Neighbours
from companion.agent.output import AgentOutput
from companion.agent.rejoin import (
    TRACKING_WINDOW_PERIODS,
    RejoinContext,
    TrackingAccuracy,
    rejoin_airspeed,
    rejoin_step,
)
from companion.agent.relief.duty import Duty
from companion.agent.relief.states import DutyStep
from companion.agent.wind.follow import FleetWind
from companion.core.particle import ParticleParams, step_one
from companion.core.patrol import Patrol
from companion.group.messages import Alert, MemberState, Mode
from companion.guidance.formation import splay_airspeed, splay_command, splay_slot_error_m
from companion.guidance.steering import speed_holds_phase
from companion.mission import Mission

OnConfirm = Literal["track", "chain"]
AIRSPEED_UPDATE_S = 0.5  # the phase-holding airspeed is recomputed this often (vehicle s)


class Agent(AlertDuty):
    """The decision logic of one companion.

    Args:
        sysid: this UAV's MAVLink system id.
        mission: the mission (loop, gains, limits, sensor).
        policy: tasking policy, "next" (the paper's) or "fastest".
        member_timeout_s: silence after which a member leaves the formation (s).
        replan_s: re-planning period while prosecuting (s).
        rejoin: "slot" keeps sharing the virtual particle until the UAV has flown back into
            its slot (the others never react); "direct" hands back the real state as soon
            as the prosecution ends (the paper's behaviour: the formation reshuffles).
        max_prosecutors: most UAVs away at once (default 1).
        bid_window_s: how long bids are collected under the "fastest" policy (s).
        alert_repeat_s: active alerts are re-sent this often, against packet loss (s).
        lead_s: predict the state this far ahead (s) with the command in force before
            deciding; half the control period removes the zero-order-hold bias.
        hold_s: how long each command is held (s, the control period): a planned path's
            turn rate is averaged over it (:func:`companion.agent.alerts.paths.turn_rate_at`); 0:
            the
            rate at the decision instant.
        max_open_alerts: most alerts open at once (queued or under way); more are dropped.
        merge_hold_s: a finished alert is kept this long to absorb late reports (s).
        on_confirm: "track" (the prosecutor that sees the intruder stays over it) or
            "chain" (the paper's: it confirms and the next UAV takes the alert). Every
            member of a fleet must use the same.
        search_max_s: the longest search of a track's uncertainty (s); never longer than
            ``alert_duty.SEARCH_REVISITS`` ideal revisit times T/N.
        track_lost_s: a tracked intruder not seen for this long is lost (s).
    """

    def __init__(
        self,
        sysid: int,
        mission: Mission,
        *,
        policy: Policy = "next",
        member_timeout_s: float = 3.0,
        replan_s: float = 1.0,
        max_prosecutors: int = 1,
        bid_window_s: float = 1.0,
        alert_repeat_s: float = 1.0,
        rejoin: Literal["slot", "direct"] = "slot",
        lead_s: float = 0.0,
        hold_s: float = 0.0,
        max_open_alerts: int = MAX_OPEN_ALERTS,
        merge_hold_s: float = 10.0,
        on_confirm: OnConfirm = "track",
        search_max_s: float = SEARCH_MAX_S,
        track_lost_s: float = TRACK_LOST_S,
    ) -> None:
        """Start on patrol with an empty formation table."""
        if on_confirm not in ("track", "chain"):
            raise ValueError(f"on_confirm must be 'track' or 'chain', got {on_confirm!r}")
        self.on_confirm = on_confirm
        if not (np.isfinite(search_max_s) and 0.0 <= search_max_s <= 600.0):
            raise ValueError(f"search_max_s must be between 0 and 600 s, got {search_max_s!r}")
        self.search_max_s = search_max_s
        if not (np.isfinite(track_lost_s) and track_lost_s > 0.0):
            raise ValueError(f"track_lost_s must be > 0 s, got {track_lost_s!r}")
        self.track_lost_s = track_lost_s
        if policy not in ("next", "fastest"):
            raise ValueError(f"policy must be 'next' or 'fastest', got {policy!r}")
        if rejoin not in ("slot", "direct"):
            raise ValueError(f"rejoin must be 'slot' or 'direct', got {rejoin!r}")
        self.rejoin = rejoin
        if not (np.isfinite(lead_s) and 0.0 <= lead_s <= 1.0):
            raise ValueError(f"lead_s must be between 0 and 1 s, got {lead_s!r}")
        self.lead_s = lead_s
        if not (np.isfinite(hold_s) and 0.0 <= hold_s <= 2.0):
            raise ValueError(f"hold_s must be between 0 and 2 s, got {hold_s!r}")
        self.hold_s = hold_s
        if max_prosecutors < 1:
            raise ValueError(f"max_prosecutors must be at least 1, got {max_prosecutors!r}")
        self._vehicle = ParticleParams(
            mission.vehicles.airspeed_m_s, mission.vehicles.max_turn_rate_rad_s
        )
        self._last_u: float | None = None
        self.sysid = int(sysid)
        self.mission = mission
        self.patrol = mission.patrol
        self.gains = mission.gains
        self.max_u = mission.vehicles.max_turn_rate_rad_s
        self.sensor_m = mission.sensor.footprint_radius_m
        self.member_timeout_s = member_timeout_s
        self.replan_s = replan_s
        self.alert_repeat_s = alert_repeat_s
        self._heard = Neighbours(self.sysid, member_timeout_s)
        self.neighbours: dict[int, Neighbour] = self._heard.table  # members heard, by sysid
        self.book = AlertBook(
            self.sensor_m,
            self._log,
            sysid=self.sysid,
            max_open=max_open_alerts,
            merge_hold_s=merge_hold_s,
        )
        self.alerts = self.book.records  # open and recently finished alerts, by id
        self.alert_counts = self.book.counts  # see companion.agent.alerts.book.ALERT_COUNTERS
        self.tasking = Tasking(
            self.sysid,
            self.book,
            self._heard,
            policy=policy,
            max_prosecutors=max_prosecutors,
            member_timeout_s=member_timeout_s,
            bid_window_s=bid_window_s,
            fence=mission.fence,
            max_u=self.max_u,
            log=self._log,
            send=self._send,
        )
        self.away: Away | None = None  # set while prosecuting or rejoining
        self._prosecution: Prosecution | None = None  # its path to the site, on self.away
        self._tracker: Tracker | None = None  # over a persistent intruder, on self.away
        self._contacts = Contacts(2.0 * self.sensor_m)  # its own sightings, by intruder
        self._mode = OwnMode.PATROL  # changed only by _on (companion.agent.modes)
        self._seq = 0
        self._outbox: list[Alert] = []
        self._events: list[AgentEvent] = []
        self._detections: list[tuple[complex, float]] = []
        self._rejoin_ctx = RejoinContext(
            self.patrol,
            self.gains,
            self.max_u,
            self.sensor_m,
            self.replan_s,
            hold_s=hold_s,
            sysid=self.sysid,
        )
        # its own centre error on patrol: the rejoin's slot tolerance follows it
        self.tracking = TrackingAccuracy(TRACKING_WINDOW_PERIODS * self.patrol.period_s)
        # the fleet's wind (companion/agent/wind/follow.py); self.wind is its agreement
        self._fleet_wind = FleetWind(
            self.sysid,
            self._vehicle.airspeed_m_s,
            self.patrol,
            self.gains,
            mission.vehicles.count,
            self.max_u,
            self._log,
        )
        self.wind = self._fleet_wind.agreement
        self._own_wind: complex | None = None
        self._airspeed_at: tuple[float, float] | None = None  # (t_s, m/s) last computed
        # formed: in its slot once; from then on the formation re-splays along the loop
        self._formed = Formed(self.gains.speed_authority_m_s * self.gains.speed_tau_s)
        # the reliefs (companion/agent/relief/duty.py): off without a battery and spares
        self.duty = Duty(self.sysid, mission)

    def set_member_timeout(self, member_timeout_s: float) -> None:
        """A new member time-out (s): the formation's and the tasking's (a group budget makes
        it follow the state rate, :class:`companion.group.budget.Budget`)."""
        if not (np.isfinite(member_timeout_s) and member_timeout_s > 0):
            raise ValueError(f"member_timeout_s must be > 0 s, got {member_timeout_s!r}")
        self.member_timeout_s = member_timeout_s
        self._heard.member_timeout_s = member_timeout_s
        self.tasking.member_timeout_s = member_timeout_s

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
        """The autopilot's own take-off is over and it flies in GUIDED again (the relief's
        spare chooses the lane point it flies to again: :meth:`Duty.climbed_out`)."""
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
        """An alert message from the group (new, confirmed, cleared, or a bid)."""
        self._apply_alert(alert, rx_t_s, own=False)

    def detect(self, site_m: complex, t_s: float) -> None:
        """The own downward sensor covers an intruder at ``site_m`` (m) at ``t_s`` (s)."""
        self._detections.append((complex(site_m), float(t_s)))

    # ---- the step -------------------------------------------------------------------------
    def update(self, t_s: float, pos_m: complex, heading_rad: float) -> AgentOutput:
        """Decide the command for a state estimate at ``t_s`` (s).

        Args:
            t_s: vehicle time (s).
            pos_m: own position (world, complex m).
            heading_rad: own air heading (rad).
        """
        if self.lead_s > 0.0 and self._last_u is not None:
            # Decide for the state the command will act on: a command is held until the next
            # one, so predict half a control period ahead with the command in force (removes
            # the zero-order-hold bias: 1.1 m -> 0.04 m of centre error at 10 Hz in process).
            ahead_m, ahead_rad = step_one(
                pos_m,
                heading_rad,
                self._last_u,
                self._vehicle,
                self.patrol.wind.vector,
                self.lead_s,
            )
            t_s, pos_m, heading_rad = t_s + self.lead_s, ahead_m, float(ahead_rad)
        self._expire_members(t_s)
        self._follow_wind(t_s)
        centre, phase = self.patrol.centre_and_phase(pos_m, heading_rad)
        centre, phase = complex(centre), float(phase)
        if self._mode is OwnMode.PATROL:
            self.tracking.add(t_s, abs(centre - self.patrol.centre_m))
        self._handle_detections(t_s, pos_m)
        done = self.duty.step(Fix(t_s, pos_m, heading_rad, self.patrol), self._heard, self.gains,
                              self._mode is OwnMode.PATROL)  # fmt: skip
        self._events.extend(done.events)
        duty = done.step
        if duty.off_station:
            return self._off_station(t_s, pos_m, centre, phase, duty)
        mine = self.tasking.assign(
            self.patrol,
            t_s,
            pos_m,
            heading_rad,
            phase,
            self._own_away(),
            own_tracking=self._mode is OwnMode.TRACKING,
        )
        if mine is not None:
            self._start_prosecution(t_s, mine, pos_m, heading_rad, phase)
        u: float | None = None
        if self._mode.prosecuting:
            u = self._prosecute(t_s, pos_m, heading_rad, centre, phase)
        if u is None and self._mode is OwnMode.TRACKING:
            u = self._track(t_s, pos_m, heading_rad)
        if u is None and self._mode.rejoining:
            u = self._rejoin(t_s, pos_m, heading_rad, centre, phase)
        airspeed = self.patrol.airspeed_m_s
        if self._mode is OwnMode.REJOIN_ALONG_LOOP:
            airspeed = rejoin_airspeed(self._rejoin_ctx, pos_m, self.away.virtual.phase(t_s))
        if u is None:  # on patrol, or just handed back
            u = self._patrol_command(t_s, pos_m, heading_rad, centre, phase)
            airspeed = self._patrol_airspeed(t_s, pos_m)
        self._repeat_alerts(t_s)
        self.book.prune(t_s, keep_id=self.away.alert_id if self.away is not None else None)
        self.book.log_counts(t_s)
        extra = {
            "pos_m": complex(pos_m),
            "wind_est_m_s": self._own_wind,
            "wind_record": self.wind.latest,
            "energy": self.duty.energy(),
        }
        if self.away is None:
            shared = MemberState(self.sysid, t_s, centre, phase, Mode.PATROL, **extra)
        elif self._mode is OwnMode.TRACKING:  # out of the formation: its real state
            shared = MemberState(
                self.sysid, t_s, centre, phase, Mode.TRACKING, self.away.alert_id, **extra
            )
        else:
            shared = MemberState(
                self.sysid,
                t_s,
                self.patrol.centre_m,
                self.away.virtual.phase(t_s),
                self._mode.shared,
                self.away.alert_id,
                **extra,
            )
        self._last_u = float(u)
        out = AgentOutput(
            turn_rate_rad_s=float(u),
            airspeed_m_s=float(airspeed),
            broadcast=shared,
            alerts_out=tuple(self._outbox),
            typed_events=tuple(self._events),
            mode=self.mode,
        )
        self._outbox, self._events = [], []  # events logged on receipt are handed over too
        return out

    def _off_station(
        self, t_s: float, pos_m: complex, centre: complex, phase: float, duty: DutyStep
    ) -> AgentOutput:
        """Out of the formation for the reliefs (a spare, flying in, flying home): the duty's
        command, its real state shared as mode ``spare``; no tasking."""
        self.book.prune(t_s, keep_id=None)
        shared = MemberState(
            self.sysid,
            t_s,
            centre,
            phase,
            Mode.SPARE,
            "",
            pos_m=complex(pos_m),
            wind_est_m_s=self._own_wind,
            wind_record=self.wind.latest,
            energy=self.duty.energy(),
        )
        self._last_u = float(duty.turn_rate_rad_s)
        out = AgentOutput(
            turn_rate_rad_s=float(duty.turn_rate_rad_s),
            airspeed_m_s=float(duty.airspeed_m_s),
            broadcast=shared,
            alerts_out=tuple(self._outbox),
            typed_events=tuple(self._events),
            mode=Mode.SPARE,
            hold=duty.hold,
            command=duty.command,
        )
        self._outbox, self._events = [], []
        return out

    @property
    def mode(self) -> Mode:
        """What this UAV is doing as the group and the logs name it: patrol, prosecuting,
        tracking or rejoining (its finer stage: :attr:`own_mode`)."""
        return self._mode.shared

    @property
    def own_mode(self) -> OwnMode:
        """Its own mode, every stage (:mod:`companion.agent.modes`)."""
        return self._mode

    def _on(self, event: ModeEvent, t_s: float) -> None:
        """Change the own mode by ``event`` (the one place that does; an event the table does
        not allow raises). Entering the rejoin starts its clock at ``t_s`` (s); back on
        patrol, the away record is dropped."""
        before, self._mode = self._mode, next_mode(self._mode, event)
        if self._mode.rejoining and not before.rejoining:
            self.away.rejoin_t0_s = t_s
            self.away.plan = None
            self._prosecution, self._tracker = None, None
        elif self._mode is OwnMode.PATROL:
            self.away, self._prosecution, self._tracker = None, None, None

    # ---- the fleet's wind -----------------------------------------------------------------
    def _follow_wind(self, t_s: float) -> None:
        """Propose a wind if this UAV is the proposer; switch to the record in force at
        ``t_s`` (s): every member switches at the same vehicle time to the same wind."""
        patrol = self._fleet_wind.follow(t_s, set(self.neighbours), self.patrol)
        if patrol is not None:
            self.set_patrol(patrol)

    def set_patrol(self, patrol: Patrol) -> None:
        """Fly by ``patrol`` from now on (the same loop in another wind): time-phase tables,
        steering, tasking, planner and rejoin all follow it."""
        self.patrol = patrol
        self._rejoin_ctx = replace(self._rejoin_ctx, patrol=patrol)

    def fix_airspeed(self) -> None:
        """Fly the mission's airspeed from now on (the autopilot refused another): the phase
        is then held by steering alone, with the whole phase term (the paper's way)."""
        self.gains = replace(self.gains, speed_authority_m_s=0.0)
        self._rejoin_ctx = replace(self._rejoin_ctx, gains=self.gains)

    # ---- formation ------------------------------------------------------------------------
    def _expire_members(self, t_s: float) -> None:
        change = self._heard.expire(t_s)
        for sysid in change.dropped:
            self.wind.forget(sysid)
        members = len(self.neighbours) + 1
        for sysid in change.joined:
            self._log(MemberJoined(t_s=t_s, sysid=self.sysid, member_sysid=sysid, members=members))
        for sysid in change.lost:
            self._log(MemberLost(t_s=t_s, sysid=self.sysid, member_sysid=sysid, members=members))
            self.tasking.requeue_alerts_of(sysid, t_s)

    def _own_away(self) -> str | None:
        """None on patrol; while away, the alert this UAV flies back from when rejoining,
        "" when flying to one (what :meth:`Tasking.assign` counts as away)."""
        if self._mode is OwnMode.PATROL:
            return None
        return self.away.alert_id if self._mode.rejoining else ""  # tracking: away

    # ---- rejoin ---------------------------------------------------------------------------
    def _rejoin(self, t_s, pos_m, heading_rad, centre: complex, phase: float) -> float | None:
        """The rejoin command (rad/s), or None once the real state has been handed back."""
        in_formation = 1 + self._heard.in_formation()
        ctx = replace(
            self._rejoin_ctx,
            tracking_p95_m=self.tracking.p95_m(),
            revisit_s=self.patrol.period_s / in_formation,
        )
        u, events, changes = rejoin_step(
            ctx, self.away, self._mode, t_s, pos_m, heading_rad, centre, phase
        )
        self._log_all(events)
        for change in changes:
            self._on(change, t_s)
        return u

    def _patrol_command(
        self, t_s: float, pos_m: complex, heading_rad: float, centre: complex, phase: float
    ) -> float:
        """The time-splay law on the formation as this UAV sees it (rad/s). With the
        airspeed holding the phase, the others' phases are where they are along the loop
        when on it (:meth:`Neighbours.steering_phases`); this UAV's own is the law's."""
        if speed_holds_phase(self.gains):
            others = self._heard.steering_phases(t_s, self.patrol)
        else:
            others = self._heard.others(t_s, self.patrol.period_s)
        return splay_command(
            self.patrol,
            self.gains,
            pos_m,
            heading_rad,
            phase,
            centre,
            others,
            self.max_u,
            self._formed.steer_limit_m,
        )

    def _patrol_airspeed(self, t_s: float, pos_m: complex) -> float:
        """The airspeed (m/s) that holds this UAV's place in the splay as it sees it.

        The phases here are where each member is along the loop (its nearest loop point),
        not the course-based phases of the steering law: a gust turns the course by a few
        degrees, which on a long, nearly straight edge moves the course-based phase by
        seconds, while the slot error the airspeed has to take out is along the loop."""
        if not speed_holds_phase(self.gains):
            return self.patrol.airspeed_m_s
        last = self._airspeed_at
        if last is not None and 0.0 <= t_s - last[0] < AIRSPEED_UPDATE_S:
            return last[1]  # the runner sends at most one a second anyway
        own, off_m = self.patrol.phase_and_offset_of_point(pos_m)
        others = self._heard.positions_phases(t_s, self.patrol)
        if not self._formed.formed:
            error_m = splay_slot_error_m(self.patrol, self.gains, own, others)
            self._formed.note(t_s, bool(self._heard.table), off_m, error_m)
        v = splay_airspeed(self.patrol, self.gains, own, others)
        self._airspeed_at = (t_s, v)
        return v

    # ---- log --------------------------------------------------------------------------------
    def _log(self, event: AgentEvent) -> None:
        """Log one typed event (:mod:`companion.agent.events`): handed over with the next update."""
        self._events.append(event)

    def _send(self, alert: Alert) -> None:
        """Queue an alert message for the group: handed over with the next update."""
        self._outbox.append(alert)

    def _log_all(self, events: list[AgentEvent]) -> None:
        """Log a seam's events (prosecution, rejoin), already stamped with time, sysid and
        the alert this UAV is away for."""
        self._events.extend(events)
