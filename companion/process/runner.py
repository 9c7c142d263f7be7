"""The companion process: one UAV's Agent flying its autopilot over MAVLink, in the group.

One single-threaded ``selectors`` loop over the autopilot link and the group socket:

* autopilot HEARTBEAT -> command authority (:mod:`companion.link.modes`): setpoints only
  while the vehicle is in GUIDED; leaving GUIDED stops them at once (STATUSTEXT + event),
  GUIDED again resumes. ``take_control`` selects GUIDED once the aircraft flies (never arms);
* PX4 (HEARTBEAT autopilot 12, :mod:`companion.link.px4`): OFFBOARD instead of GUIDED, the
  ``attitude`` or ``path`` profile (:mod:`companion.link.offboard`), vehicle time from its
  own ``time_boot_ms``, no GUIDED targets; ``take_control`` pre-streams setpoints and then
  asks for OFFBOARD (:class:`~companion.link.px4.OffboardEntry`: back-off, reported once,
  given up after a few tries);
* SYSTEM_TIME -> vehicle time (:mod:`companion.link.clock`); the Agent never sees the wall
  clock, so a run at the simulator's speed-up behaves like one at 1x;
* GLOBAL_POSITION_INT -> state estimate -> ``Agent.update`` -> one setpoint in the chosen
  profile (:mod:`companion.link.shaping`, which closes the loop on the achieved turn rate),
  the member state to the group every ``state_period_s`` of vehicle time, alerts, events;
* CAMERA_TRACKING_GEO_STATUS from the vehicle's camera (component 100) -> ``Agent.detect``;
* group datagrams -> ``Agent.receive_state`` / ``receive_alert`` stamped with the latest
  vehicle time.

While the companion does not command (no link, waiting for GUIDED, overridden) the Agent is
not stepped and the UAV does not broadcast its state, so the others re-splay without it.
Stopping (:meth:`Runner.stop`, e.g. from SIGTERM) ends the loop; :meth:`Runner.close` flushes
the logs and closes every socket.

The class is assembled from its parts, one module each: :mod:`~companion.process.loop` (the
loop, the driven entry points, shutdown), :mod:`~companion.process.messages` (the
autopilot's messages), :mod:`~companion.process.control` (command authority, taking control,
PX4's OFFBOARD entry), :mod:`~companion.process.health` (the checks and their issues),
:mod:`~companion.process.step` (one control step), :mod:`~companion.process.group_io` (the
group) and :mod:`~companion.process.status` (events, the status line); its state is all set
in :meth:`Runner.__init__` below. :mod:`~companion.process.config` holds :class:`RunConfig`.
"""

from __future__ import annotations

import selectors
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from companion.agent.agent import Agent
from companion.group.budget import (
    ENERGY_STATE_DATAGRAM_BYTES,
    STATE_DATAGRAM_BYTES,
    Budget,
    Schedule,
)
from companion.group.flood import FloodGate
from companion.group.messages import Mode
from companion.group.transport import Group
from companion.link import px4
from companion.link.battery import BatteryMonitor
from companion.link.clock import VehicleClock
from companion.link.connection import AutopilotLink
from companion.link.estimate import Estimator, StateEstimate
from companion.link.gcs import GcsReport
from companion.link.ground import GroundSequence
from companion.link.modes import Authority
from companion.link.offboard import OffboardSetpoints
from companion.link.setpoints import Profile
from companion.link.supervision import AirspeedMonitor, BankLimitMonitor, ResponseMonitor
from companion.link.targets import GuidedTargets
from companion.process.config import Counters, RunConfig
from companion.process.control import TakingControl
from companion.process.event_log import EventLog
from companion.process.group_io import GroupIO
from companion.process.health import HealthChecks
from companion.process.loop import RunnerLoop
from companion.process.messages import LinkMessages
from companion.process.status import StatusLine
from companion.process.step import ControlStep


class Runner(
    RunnerLoop, LinkMessages, TakingControl, HealthChecks, ControlStep, GroupIO, StatusLine
):
    """One companion: link + group + Agent in one selectors loop.

    Args:
        config: the run configuration.
        link: the autopilot link (already open).
        group_factory: sysid -> the group endpoint (created once the sysid is known).
        events: the event log.
        status_out: where status lines go (stderr).
        wall: monotonic wall clock (s), for I/O pacing and latency only.
        cpu: process CPU time (s), for the status line.
    """

    def __init__(
        self,
        config: RunConfig,
        link: AutopilotLink,
        group_factory: Callable[[int], Group],
        events: EventLog,
        *,
        status_out: TextIO = sys.stderr,
        wall: Callable[[], float] = time.monotonic,
        cpu: Callable[[], float] = time.process_time,
        perf: Callable[[], float] = time.perf_counter,
    ) -> None:
        """Wire the pieces; nothing is sent until :meth:`run`."""
        self.config = config
        self.mission = config.mission
        self.link = link
        self.group_factory = group_factory
        self.group: Group | None = None
        self.events = events
        self.status_out = status_out
        self.wall = wall
        self.cpu = cpu
        self.perf = perf
        m = config.mission
        self.clock = VehicleClock(fixed_offset_s=config.boot_epoch_s)
        self.estimator = Estimator(m.origin, m.vehicles.airspeed_m_s, m.wind.wind())
        self.battery = BatteryMonitor()  # SYS_STATUS / BATTERY_STATUS; the Agent ignores it yet
        # "auto": resolved from the first autopilot HEARTBEAT (a provisional shaper till then)
        self.profile: Profile | None = None if config.profile == "auto" else config.profile
        self.px4 = False  # the autopilot is PX4 (its first HEARTBEAT says)
        self.offboard = OffboardSetpoints(m.origin)  # PX4's profiles: holds and targets
        self.entry = px4.OffboardEntry()  # PX4's take-over: pre-stream, then OFFBOARD
        self._prestream = False  # PX4 take-over under way: setpoints stream before OFFBOARD
        self.shaper = self._make_shaper(self.profile or "turn-rate")
        self.authority = Authority()
        self.ground = GroundSequence()  # the reliefs' own take-off and landing (ArduPlane's way)
        self.gcs = GcsReport()  # STATUSTEXT / NAMED_VALUE_* for ground stations
        # supervision (companion.link.supervision): flight state, airspeed, response
        self.landed_state: int | None = None
        self.rel_alt_m: float | None = None
        self.airspeed = AirspeedMonitor(m.vehicles.airspeed_m_s)
        self.response = ResponseMonitor(max_turn_rate_rad_s=m.vehicles.max_turn_rate_rad_s)
        self.bank_limit = BankLimitMonitor(m.vehicles.max_turn_rate_rad_s)
        self._bank_asks = self._bank_heartbeats = 0  # PARAM_REQUEST_READs of the bank limit
        self.issues: dict[str, str] = {}  # active supervision issues -> text
        self._take_control_refused: str | None = None
        self.targets = GuidedTargets(  # the airspeed and altitude asked of GUIDED
            link,
            m.vehicles.airspeed_m_s,
            lambda: self.mission.origin.alt_m + self.mission_alt_m(),
            self._log,
            self._airspeed_sent,
        )
        self._last_sp_msg: Any = None
        self._last_sp_wall = 0.0
        self.agent: Agent | None = None
        self.now_s: float | None = None  # latest vehicle time (unix s)
        self.last_est: StateEstimate | None = None
        self.agent_mode = Mode.PATROL
        self._link_was_lost = False  # a "link_restored" event is due when the link returns
        self.armed: bool | None = None
        self.counters = Counters()
        self._stop = False
        self._last_state_sent_s = -1e18
        # the group budget (--group-budget): the state period and member time-out follow it
        self.budget: Budget | None = None
        if config.group_budget_bytes_s is not None:
            v = config.mission.vehicles
            shares_energy = v.battery is not None and bool(v.spares)  # version 3 states
            self.budget = Budget(
                config.group_budget_bytes_s,
                config.member_timeout_s,
                ENERGY_STATE_DATAGRAM_BYTES if shares_energy else STATE_DATAGRAM_BYTES,
            )
        self._state_period_s = config.state_period_s
        self._schedule: Schedule | None = None  # the budget's, for the members last heard
        self._flood_gate: FloodGate | None = None
        self._last_take_control = -1e9
        self._status_t0 = wall()
        self._status_sp0 = 0
        self._status_vt0: float | None = None
        self._rx_perf = 0.0
        self._cpu0: float | None = None
        self._wall0 = 0.0
        self._sel: selectors.BaseSelector | None = None
        self._link_fd: int | None = None
        self._link_gen = -1
        self._driven = False  # begun with begin(): no selectors loop
