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
"""

from __future__ import annotations

import contextlib
import json
import selectors
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TextIO

import numpy as np

from companion.agent.agent import Agent, OnConfirm, Policy
from companion.group.messages import Alert, MemberState, Mode
from companion.group.transport import Group
from companion.link import px4
from companion.link.battery import BatteryEstimate, BatteryMonitor
from companion.link.clock import VehicleClock
from companion.link.connection import AutopilotLink
from companion.link.estimate import Estimator, StateEstimate
from companion.link.gcs import GcsReport
from companion.link.modes import GUIDED, Authority, Transition
from companion.link.offboard import OffboardSetpoints
from companion.link.setpoints import PX4_PROFILES, Profile, ProfileChoice
from companion.link.shaping import Shaper
from companion.link.supervision import (
    AirspeedMonitor,
    Issue,
    ResponseMonitor,
    default_profile,
    not_flying_reason,
)
from companion.link.targets import GuidedTargets
from companion.mission import Mission
from companion.process.event_log import EventLog

CAMERA_COMPID = 100
TRACKING_ACTIVE = 1  # CAMERA_TRACKING_STATUS_FLAGS_ACTIVE
MAV_MODE_FLAG_SAFETY_ARMED = 128
MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
TAKE_CONTROL_RETRY_S = 1.0  # wall
KEEPALIVE_WALL_S = 0.25  # resend the setpoint in force after this much wall time without one:
# ArduPlane drops an attitude override 3 s (vehicle time) after the last message
LATENCY_WINDOW = 20_000
VEHICLE_COMMANDS = {"takeoff": 22, "land": 21}  # MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_LAND


def telemetry_rates_hz(position_rate_hz: float, autopilot: int | None = None) -> dict[str, float]:
    """What the companion asks its autopilot of HEARTBEAT type ``autopilot`` to stream
    (message name -> Hz): position and attitude at the control rate, air data and the
    autopilot's wind estimate slower. PX4 has no WIND (WIND_COV instead) and a fixed 1 Hz
    HEARTBEAT; its airspeed feeds the companion's own airspeed hold (10 Hz)."""
    if px4.is_px4(autopilot):
        return {
            "GLOBAL_POSITION_INT": position_rate_hz,
            "ATTITUDE": position_rate_hz,
            "VFR_HUD": 10.0,
            "EXTENDED_SYS_STATE": 1.0,
            "SYSTEM_TIME": 1.0,
            "WIND_COV": 1.0,
        }
    return {
        "GLOBAL_POSITION_INT": position_rate_hz,
        "ATTITUDE": position_rate_hz,
        "HEARTBEAT": position_rate_hz,
        "VFR_HUD": 2.0,
        "EXTENDED_SYS_STATE": 1.0,  # landed state: take over only an aircraft in the air
        "SYSTEM_TIME": 1.0,
        "WIND": 1.0,
    }


@dataclass(frozen=True)
class RunConfig:
    """What ``companion run`` was asked to do.

    Attributes:
        mission: the mission (loop, wind, gains, limits, sensor).
        profile: setpoint profile, "turn-rate", "bank" or "heading", or "auto": chosen from
            the autopilot's HEARTBEAT type (:func:`companion.link.supervision.default_profile`).
        policy: tasking policy, "next" or "fastest".
        on_confirm: what the prosecutor that sees the intruder does: "track" (stays over
            it) or "chain" (hands it on, the paper's).
        max_prosecutors: most UAVs away at once.
        member_timeout_s: silence after which a member leaves the formation (vehicle s).
        take_control: switch the aircraft to GUIDED at start once it is flying (armed, in the
            air, high and fast enough: never arms, never takes a grounded aircraft).
        state_period_s: member-state broadcast period (vehicle s).
        status_interval_s: wall seconds between status lines on stderr (0: none).
        adapt: close the loop on the achieved turn rate (online gain estimate).
        lead_s: how far ahead the agent predicts the state before deciding (vehicle s):
            half the setpoint period, so the held command is right on average.
        boot_epoch_s: vehicle time = this (unix s) + ``time_boot_ms``, SYSTEM_TIME ignored
            (a fleet of PX4 SITL instances, whose SYSTEM_TIME is the host's clock); None: from
            SYSTEM_TIME (:class:`companion.link.clock.VehicleClock`).
    """

    mission: Mission
    profile: ProfileChoice = "auto"
    policy: Policy = "next"
    on_confirm: OnConfirm = "track"
    max_prosecutors: int = 1
    member_timeout_s: float = 3.0
    take_control: bool = False
    state_period_s: float = 0.2
    status_interval_s: float = 0.0
    adapt: bool = True
    lead_s: float = 0.05
    boot_epoch_s: float | None = None


@dataclass
class Counters:
    """Per-process counts for the status line and the final report."""

    setpoints: int = 0
    estimates: int = 0
    detections: int = 0
    states_sent: int = 0
    alerts_sent: int = 0
    skipped: int = 0  # stale estimates not steered from (a newer one was waiting)
    keepalives: int = 0  # setpoints resent because no new one went for KEEPALIVE_WALL_S
    prestream: int = 0  # PX4: setpoints streamed before OFFBOARD was entered
    latency_s: list[float] = field(default_factory=list)


class Runner:
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
        self.gcs = GcsReport()  # STATUSTEXT / NAMED_VALUE_* for ground stations
        # supervision (companion.link.supervision): flight state, airspeed, response
        self.landed_state: int | None = None
        self.rel_alt_m: float | None = None
        self.airspeed = AirspeedMonitor(m.vehicles.airspeed_m_s)
        self.response = ResponseMonitor(max_turn_rate_rad_s=m.vehicles.max_turn_rate_rad_s)
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

    # ---- lifecycle --------------------------------------------------------------------------
    def stop(self) -> None:
        """Ask the loop to end (safe from a signal handler)."""
        self._stop = True

    def run(self) -> int:
        """Serve until :meth:`stop`; returns the exit status (0)."""
        self._sel = selectors.DefaultSelector()
        self._log("start", profile=self.config.profile, policy=self.config.policy)
        print(
            f"companion: waiting for the autopilot on {self.link.url}",
            file=self.status_out,
            flush=True,
        )
        try:
            while not self._stop:
                self._poll(0.05)
                if self._stop:
                    break
                self._tick()
        finally:
            self.close()
        return 0

    # ---- driven from outside (the in-memory engine, companion.sim.inmemory) ------------------
    def begin(self) -> None:
        """Start without the selectors loop: the caller then feeds :meth:`on_messages`,
        :meth:`on_group` and :meth:`tick` and ends with :meth:`close`."""
        self._driven = True
        self._log("start", profile=self.config.profile, policy=self.config.policy)

    def on_messages(self, msgs: list[Any]) -> None:
        """Messages received from the autopilot link, oldest first.

        Behind (a stalled process, a simulator catching up): steer from the newest position
        only; the older ones still feed the estimator.
        """
        self._rx_perf = self.perf()
        last_pos = max(
            (i for i, m in enumerate(msgs) if m.get_type() == "GLOBAL_POSITION_INT"),
            default=-1,
        )
        for i, m in enumerate(msgs):
            self._on_mavlink(m, steer=i == last_pos)

    def on_group(self) -> None:
        """The group has datagrams waiting: hand them to the Agent."""
        if self.group is not None:
            self._on_group()

    def tick(self) -> None:
        """Link supervision, take-control retries, delayed group sends, log flushes."""
        self._tick()

    def close(self) -> None:
        """Final status line and event; flush logs; close the sockets (idempotent)."""
        if self._sel is None and not self._driven:
            return
        self._driven = False
        if self.config.status_interval_s > 0 or self.counters.setpoints:
            self._status(final=True)
        self._log("stop", setpoints=self.counters.setpoints)
        if self.authority.commanding:
            self.link.statustext(f"companion {self.link.sysid}: stopping, setpoints end")
        if self._sel is not None:
            self._sel.close()
        self._sel = None
        if self.group is not None:
            self.group.close()
        self.link.close()
        if self.link.tlog is not None:
            self.link.tlog.close()
        self.events.close()

    # ---- the loop ---------------------------------------------------------------------------
    def _poll(self, timeout_s: float) -> None:
        sel = self._sel
        fd = self.link.fileno()
        if (fd, self.link.generation) != (self._link_fd, self._link_gen):
            if self._link_fd is not None:
                with contextlib.suppress(KeyError, ValueError, OSError):
                    sel.unregister(self._link_fd)
            if fd is not None:
                sel.register(fd, selectors.EVENT_READ, "link")
            self._link_fd, self._link_gen = fd, self.link.generation
        try:
            ready = sel.select(timeout_s if self._link_fd is not None or self.group else 0.05)
        except InterruptedError:
            return
        if not ready and self._link_fd is None and self.group is None:
            time.sleep(timeout_s)
        for key, _ in ready:
            if key.data == "link":
                self.on_messages(self.link.receive())
            else:
                self._on_group()

    def _tick(self) -> None:
        if self.link.tick() == "lost":
            self._log("link_lost")
            self._link_was_lost = True
            self._authority(self.authority.link_lost())
            self.estimator.reset()
            self.shaper.reset_sample()
        self._take_control()
        self._keepalive()
        if self.group is not None:
            self.group.flush()
        iv = self.config.status_interval_s
        if iv > 0 and self.wall() - self._status_t0 >= iv:
            self._status()
        self.link_flush()
        self.events.flush_if_due()

    def link_flush(self) -> None:
        """Flush the tlog about as often as the events."""
        tl = self.link.tlog
        if tl is not None and self.counters.estimates % 20 == 0:
            tl.flush()

    # ---- autopilot messages -----------------------------------------------------------------
    def _on_mavlink(self, m: Any, steer: bool = True) -> None:
        link = self.link
        if link.sysid is None or m.get_srcSystem() != link.sysid:
            return
        t = m.get_type()
        comp = m.get_srcComponent()
        if comp == CAMERA_COMPID:
            if t == "CAMERA_TRACKING_GEO_STATUS":
                self._on_detection(m)
            return
        if not link.is_autopilot(m):
            return
        self._supervise_message(m, t)
        if t == "HEARTBEAT":
            self._on_heartbeat(m)
        elif t == "SYSTEM_TIME":
            self.clock.on_system_time(int(m.time_unix_usec), int(m.time_boot_ms))
        elif t == "GLOBAL_POSITION_INT":
            self._on_position(m, steer)
        elif t == "ATTITUDE":
            self.estimator.on_attitude(int(m.time_boot_ms), float(m.yaw))
            if self.px4:
                self.offboard.data.on_attitude(float(m.roll), float(m.pitch), float(m.yaw))
        elif t == "VFR_HUD":
            self.estimator.on_airspeed(float(m.airspeed))
            if self.px4:
                self.offboard.data.on_vfr_hud(float(m.airspeed), float(m.throttle))
        elif t == "WIND" and self.now_s is not None:
            self.estimator.on_autopilot_wind(self.now_s, float(m.speed), float(m.direction))
        elif t == "WIND_COV" and self.now_s is not None:
            self.estimator.on_autopilot_wind_vector(self.now_s, float(m.wind_x), float(m.wind_y))
        elif t == "SYS_STATUS" and self.now_s is not None:
            self.battery.on_sys_status(
                self.now_s, m.voltage_battery, m.current_battery, m.battery_remaining
            )
        elif t == "BATTERY_STATUS" and self.now_s is not None:
            self.battery.on_battery_status(
                self.now_s, m.id, m.voltages, m.current_battery, m.current_consumed,
                m.battery_remaining,
            )  # fmt: skip
        elif t == "COMMAND_ACK":
            if m.result not in (0, 5):  # not ACCEPTED / IN_PROGRESS
                self._log("command_refused", command=int(m.command), result=int(m.result))
            if self.px4 and int(m.command) == 176 and self.now_s is not None:
                self._entry_steps(self.entry.answer(self.now_s, int(m.result)))

    def _on_heartbeat(self, m: Any) -> None:
        if self.agent is None:
            self._start_agent()
        armed = bool(m.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if armed != self.armed:
            if self.armed is not None:
                self._log("armed" if armed else "disarmed")
            self.armed = armed
        self._authority(self.authority.heartbeat(int(m.custom_mode), self.link.autopilot))
        if self.px4:
            self._entry_steps(self.entry.heartbeat(px4.is_offboard(int(m.custom_mode))))

    def _start_agent(self) -> None:
        sysid = int(self.link.sysid)
        cfg = self.config
        self.agent = Agent(
            sysid,
            self.mission,
            policy=cfg.policy,
            on_confirm=cfg.on_confirm,
            member_timeout_s=cfg.member_timeout_s,
            max_prosecutors=cfg.max_prosecutors,
            lead_s=cfg.lead_s,
            hold_s=2.0 * cfg.lead_s,  # the setpoint period: a path's turns are averaged over it
        )
        if not self.targets.free or (self.px4 and self.profile == "path"):
            self.agent.fix_airspeed()  # PX4's path: TECS flies its own trim airspeed
        self._cpu0, self._wall0 = self.cpu(), self.wall()
        self.group = self.group_factory(sysid)
        if self._sel is not None:
            self._sel.register(self.group.fileno(), selectors.EVENT_READ, "group")
        self._log("link_up", autopilot_sysid=sysid)

    def _authority(self, tr: Transition | None) -> None:
        if tr is None:
            return
        self._log("authority", before=tr.before, after=tr.after, autopilot_mode=tr.mode)
        sysid = self.link.sysid
        if tr.before == "no_link" and self._link_was_lost:
            self._link_was_lost = False
            self._log("link_restored", reconnects=self.link.counts["reconnects"])
        ours = "OFFBOARD" if self.px4 else "GUIDED"
        if tr.after == "commanding":
            self._prestream = False
            if self.px4:  # the targets travel in the setpoints themselves
                self.offboard.target_airspeed_m_s = self.mission.vehicles.airspeed_m_s
                self._airspeed_sent(self.mission.vehicles.airspeed_m_s)
            else:
                self.targets.take_over(self.now_s)  # the mission's airspeed and altitude
        elif tr.before == "commanding":
            self.response.reset()
            self.airspeed.reset()
            self._last_sp_msg = None
        if tr.after == "overridden":
            self._log("override", autopilot_mode=tr.mode)
            self.link.statustext(f"companion {sysid}: pilot took over ({tr.mode}), holding off")
            self.shaper.reset_sample()
        elif tr.after == "commanding" and tr.before == "overridden":
            self._log("resumed")
            self.link.statustext(f"companion {sysid}: {ours} again, resuming patrol")
        elif tr.after == "commanding":
            self.link.statustext(f"companion {sysid}: in command ({ours})")
        elif tr.after == "waiting":
            self.link.statustext(f"companion {sysid}: waiting for {ours} ({tr.mode})")

    def _take_control(self) -> None:
        if not self.config.take_control or self.authority.was_commanding:
            return
        if self.authority.state != "waiting" or self.link.sysid is None:
            return
        now = self.wall()
        if now - self._last_take_control < TAKE_CONTROL_RETRY_S:
            return
        self._last_take_control = now
        reason = self.not_flying_reason()
        if reason is not None:  # never arm, never take a grounded or climbing-out aircraft
            if reason != self._take_control_refused:
                self._take_control_refused = reason
                self._log("take_control_refused", reason=reason)
                self.link.statustext(f"companion {self.link.sysid}: not flying: {reason}")
            self._prestream = False
            return
        self._take_control_refused = None
        if self.px4:  # OFFBOARD only once setpoints stream (_prestream_step)
            usable = self.profile in PX4_PROFILES and not self.entry.done
            if usable and not self._prestream:
                self._prestream = True
                self._log("take_control", action="offboard_prestream")
            return
        self._log("take_control", action="guided")
        self.link.command_long(176, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)

    # ---- supervision (companion.link.supervision) --------------------------------------------
    def _make_shaper(self, profile: Profile) -> Shaper:
        m = self.mission
        return Shaper(
            profile,
            m.vehicles.airspeed_m_s,
            m.vehicles.max_turn_rate_rad_s,
            adapt=self.config.adapt,
            offboard=self.offboard,
        )

    def mission_alt_m(self) -> float:
        """This vehicle's mission altitude above the origin (m)."""
        return self.mission.vehicles.altitude_m(self.link.sysid)

    def not_flying_reason(self) -> str | None:
        """None if the aircraft may be taken over; otherwise why not."""
        return not_flying_reason(
            self.armed,
            self.landed_state,
            self.rel_alt_m,
            self.airspeed.last_m_s,
            self.mission_alt_m(),
            self.mission.vehicles.airspeed_m_s,
        )

    @property
    def battery_estimate(self) -> BatteryEstimate | None:
        """The battery as the autopilot last reported it (an input for the Agent's reliefs,
        not used by it yet), or None before any valid report."""
        return self.battery.last

    def health(self) -> str:
        """The status line's health field: ``ok`` or the active issues, comma-separated."""
        names = sorted(self.issues)
        if self._take_control_refused is not None and not self.authority.was_commanding:
            names.append("not_flying")
        return ",".join(names) if names else "ok"

    def _airspeed_txt(self) -> str:
        a = self.airspeed.last_m_s
        return "-" if a is None else f"{a:.1f}"

    def _supervise_message(self, m: Any, t: str) -> None:
        if t == "HEARTBEAT" and not self.px4 and px4.is_px4(self.link.autopilot):
            self._px4_found()
        if t == "HEARTBEAT" and self.profile is None:
            self.profile = default_profile(self.link.autopilot)
            self.shaper = self._make_shaper(self.profile)
            self._log("profile", profile=self.profile, autopilot=self.link.autopilot)
        elif t == "EXTENDED_SYS_STATE":
            self.landed_state = int(m.landed_state)
        elif t == "GLOBAL_POSITION_INT":
            self.rel_alt_m = int(m.relative_alt) * 1e-3
        elif t == "VFR_HUD":
            a = float(m.airspeed)
            if self.authority.commanding and self.now_s is not None:
                self._report(self.airspeed.update(self.now_s, a))
            else:
                self.airspeed.last_m_s = a
        elif t == "COMMAND_ACK":
            denied = self.targets.on_ack(
                int(m.command), int(m.result), self.authority.commanding, self.now_s
            )
            if denied and self.agent is not None:
                self.agent.fix_airspeed()

    def _px4_found(self) -> None:
        """The autopilot is PX4: its clock, its targets, and a profile it flies (said once
        if the one asked for is not)."""
        self.px4 = True
        self.clock.anchor_once = True  # its SYSTEM_TIME is the host's clock (docs/px4.md)
        self.offboard.target_alt_amsl_m = self.mission.origin.alt_m + self.mission_alt_m()
        self.offboard.target_airspeed_m_s = self.mission.vehicles.airspeed_m_s
        if self.profile is not None and self.profile not in PX4_PROFILES:
            text = f"profile {self.profile} is no PX4 offboard setpoint: use attitude or path"
            self._report(Issue("profile_unsupported", True, text))

    def _entry_steps(self, steps: list[px4.EntryStep]) -> None:
        """Log the OFFBOARD entry's changes; a refusal said once, giving up as an issue."""
        for st in steps:
            self._log("offboard_entry", before=st.before, after=st.after, tries=st.tries)
            sysid = self.link.sysid
            if st.after == "backoff" and len(self.entry.refusals) == 1:
                self.link.statustext(
                    f"companion {sysid}: OFFBOARD refused, retrying with back-off", severity=4
                )
            elif st.after == "gave_up":
                self._prestream = False
                n = len(self.entry.refusals)
                self._report(Issue("offboard_refused", True, f"OFFBOARD refused {n}x: gave up"))

    def _prestream_step(self, est: StateEstimate) -> None:
        """PX4's take-over: a setpoint continuing the turn it flies (the holds following its
        own pitch and throttle), then DO_SET_MODE OFFBOARD once the stream has lasted."""
        sysid = self.link.sysid
        if self.entry.done or self.authority.state != "waiting" or sysid is None:
            self._prestream = False
            return
        self.offboard.track(est.t_s)
        msg = self.shaper.setpoint(
            est.t_s,
            est.turn_rate_rad_s or 0.0,
            est.course_rad,
            est.time_boot_ms,
            sysid,
            pos_m=est.pos_m,
            heading_rad=est.heading_rad,
            wind_m_s=self.estimator.wind.vector,
        )
        self.shaper.reset_sample()
        self.link.send(msg)
        self.counters.prestream += 1
        self._entry_steps(self.entry.streamed(est.t_s))
        self._entry_steps(self.entry.poll(est.t_s))
        if self.entry.due(est.t_s):
            self._log("take_control", action="offboard", attempt=self.entry.tries)
            self.link.send(px4.set_offboard_command(sysid))

    def _airspeed_sent(self, airspeed_m_s: float) -> None:
        """An airspeed was asked of the autopilot (m/s): the monitor and the bank conversion
        follow it."""
        self.airspeed.target_m_s = airspeed_m_s
        self.shaper.airspeed_m_s = airspeed_m_s

    def _supervise_step(self, est: StateEstimate) -> None:
        """Before each setpoint: repeat the targets, check the response to the last one."""
        if not self.px4:
            self.targets.repeat_if_due(est.t_s, self.now_s)
        self._report(
            *self.response.update(
                est.t_s,
                self.shaper.x_in_force,
                est.turn_rate_rad_s,
                self.shaper.gain,
                est.groundspeed_m_s,
            )
        )

    def _report(self, *issues: Issue | None) -> None:
        for iss in issues:
            if iss is None:
                continue
            sysid = self.link.sysid
            if iss.active:
                self.issues[iss.name] = iss.text
                self._log(iss.name, text=iss.text)
                self.link.statustext(f"companion {sysid}: {iss.text}", severity=4)
            else:
                self.issues.pop(iss.name, None)
                self._log(f"{iss.name}_cleared", text=iss.text)
                self.link.statustext(f"companion {sysid}: {iss.text}")

    def _send_setpoint(self, msg: Any) -> None:
        self.link.send(msg)
        self._last_sp_msg, self._last_sp_wall = msg, self.wall()

    def _keepalive(self) -> None:
        """Resend the setpoint in force when telemetry (and so the control step) stalls:
        ArduPlane forgets an attitude override 3 s after the last one."""
        msg = self._last_sp_msg
        if msg is None or not self.authority.commanding:
            return
        now = self.wall()
        if now - self._last_sp_wall >= KEEPALIVE_WALL_S:
            self.link.send(msg)
            self._last_sp_wall = now
            self.counters.keepalives += 1

    def _on_detection(self, m: Any) -> None:
        if not m.tracking_status & TRACKING_ACTIVE or self.agent is None or self.now_s is None:
            return
        if not self.authority.commanding:
            return
        site = self.estimator.site_from_geodetic(int(m.lat), int(m.lon))
        self.counters.detections += 1
        self.agent.detect(site, self.now_s)

    def _on_position(self, m: Any, steer: bool = True) -> None:
        t = self.clock.to_vehicle_s(int(m.time_boot_ms))
        if t is None:
            return
        est = self.estimator.from_global_position(
            t, int(m.time_boot_ms), m.lat, m.lon, m.alt, m.vx, m.vy, m.hdg
        )
        if est is None:
            return
        if self.px4:
            self.offboard.data.on_position(int(m.alt), int(m.vz))
        self.now_s = t
        self.last_est = est
        self.counters.estimates += 1
        if self._status_vt0 is None:
            self._status_vt0 = t
        if self.agent is not None and self.authority.commanding:
            if steer:
                self._step(est)
            else:
                self.counters.skipped += 1
                self.shaper.reset_sample()
        elif self._prestream and steer:
            self._prestream_step(est)

    # ---- one control step -------------------------------------------------------------------
    def _step(self, est: StateEstimate) -> None:
        agent = self.agent
        if self.group is not None:
            self._on_group()  # everything the others sent until now, before deciding
        self._supervise_step(est)
        self.shaper.observe(est.t_s, est.turn_rate_rad_s)
        agent.observe_wind(self.estimator.wind_estimator.estimate(est.t_s), est.t_s)
        b = self.battery.last
        if b is not None:
            agent.observe_battery(b.t_s, b.remaining_pct, b.consumed_mah, b.current_a)
        out = agent.update(est.t_s, est.pos_m, est.heading_rad)
        if agent.patrol.wind != self.estimator.wind:  # the fleet switched to another wind
            self.estimator.set_wind(agent.patrol.wind)
        if out.command is not None:  # the reliefs: take off, land (companion/agent/relief)
            self._log("vehicle_command", command=out.command)
            self.link.command_long(VEHICLE_COMMANDS[out.command])
        if out.hold:  # on the ground: no setpoint, nothing to keep alive
            self._last_sp_msg = None
            self._share(out, est)
            self._after_step(out, est)
            return
        if not self.px4:
            self.targets.command_speed(out.airspeed_m_s, est.t_s)
        elif out.airspeed_m_s != self.offboard.target_airspeed_m_s:  # held by our own loop
            self.offboard.target_airspeed_m_s = out.airspeed_m_s
            self._airspeed_sent(out.airspeed_m_s)
        msg = self.shaper.setpoint(
            est.t_s,
            out.turn_rate_rad_s,
            est.course_rad,
            est.time_boot_ms,
            self.link.sysid,
            pos_m=est.pos_m,
            heading_rad=est.heading_rad,
            wind_m_s=self.estimator.wind.vector,
        )
        c = self.counters
        self._share(out, est)
        self._send_setpoint(msg)
        c.setpoints += 1
        if self._rx_perf:
            c.latency_s.append(self.perf() - self._rx_perf)
            if len(c.latency_s) > LATENCY_WINDOW:
                del c.latency_s[: LATENCY_WINDOW // 2]
        self._after_step(out, est)

    def _share(self, out: Any, est: StateEstimate) -> None:
        """The step's state and alerts to the group.

        The group hears this step's state before the autopilot hears its setpoint: a
        lockstepped simulator (docs/sitl.md, "Lockstep") advances on the last setpoint,
        so every member's state of step k is on the group before any member decides k+1.
        The state goes first: a confirmation must not reach the others before the
        prosecutor's new mode, or they keep it "taken" by the prosecutor (see the report on
        Tasking.assign)."""
        group, c = self.group, self.counters
        if group is None:
            return
        if est.t_s - self._last_state_sent_s >= self.config.state_period_s - 1e-6 or (
            out.alerts_out
        ):
            group.send_state(out.broadcast)
            self._last_state_sent_s = est.t_s
            c.states_sent += 1
        for alert in out.alerts_out:
            group.send_alert(alert)
            c.alerts_sent += 1

    def _after_step(self, out: Any, est: StateEstimate) -> None:
        """The step's events, the ground stations' texts and values (the reliefs' too:
        ``relief_late`` before it is late, link/gcs.py), a STATUSTEXT on a new mode."""
        for ev in out.typed_events:
            self.events.write(ev.to_record())
        for gcs_msg in self.gcs.messages(est.t_s, est.time_boot_ms, self.agent, out, est.pos_m):
            self.link.send(gcs_msg)
        if out.mode != self.agent_mode:
            self.agent_mode = out.mode
            self.link.statustext(f"companion {self.link.sysid}: {out.mode}")

    # ---- group ------------------------------------------------------------------------------
    def _on_group(self) -> None:
        group, agent = self.group, self.agent
        got = group.receive(self.now_s)
        if agent is None or self.now_s is None:
            return
        for msg in got:
            if isinstance(msg, MemberState):
                agent.receive_state(msg, self.now_s)
            elif isinstance(msg, Alert):
                agent.receive_alert(msg, self.now_s)  # its events come with the next update

    # ---- logs -------------------------------------------------------------------------------
    def _log(self, event: str, **fields: Any) -> None:
        ev: dict[str, Any] = {
            "t_s": round(self.now_s, 3) if self.now_s is not None else None,
            "event": event,
            "sysid": self.link.sysid,
        }
        ev.update(fields)
        self.events.write(ev)

    def latency_ms(self) -> tuple[float, float] | None:
        """Median and 99th percentile of telemetry-to-setpoint latency (wall ms)."""
        lat = self.counters.latency_s
        if not lat:
            return None
        a = np.asarray(lat) * 1e3
        return float(np.median(a)), float(np.percentile(a, 99))

    def _status(self, final: bool = False) -> None:
        now = self.wall()
        dt = now - self._status_t0
        vt = self.now_s
        rate = 0.0
        if vt is not None and self._status_vt0 is not None and vt > self._status_vt0:
            rate = (self.counters.setpoints - self._status_sp0) / (vt - self._status_vt0)
        agent = self.agent
        members = len(agent.neighbours) + 1 if agent is not None else 0
        g = self.group.stats if self.group is not None else {}
        drops = {k: v for k, v in g.items() if k not in ("accepted", "sent") and v}
        lat = self.latency_ms()
        lat_txt = f" lat_ms={lat[0]:.2f}/{lat[1]:.2f}" if lat else ""
        t_txt = f"{vt:.1f}" if vt is not None else "-"
        if self._cpu0 is not None and now > self._wall0:
            cpu_pct = 100.0 * (self.cpu() - self._cpu0) / (now - self._wall0)
            lat_txt += f" cpu_pct={cpu_pct:.2f}"
        print(
            f"companion{' final' if final else ''} sysid={self.link.sysid} t={t_txt} "
            f"auth={self.authority.state} ap_mode={self.authority.mode} mode={self.agent_mode} "
            f"members={members} sp/s={rate:.1f} setpoints={self.counters.setpoints} "
            f"link_rx={self.link.counts['rx']} group_rx={g.get('accepted', 0)} "
            f"group_tx={g.get('sent', 0)} drops={json.dumps(drops, separators=(',', ':'))} "
            f"profile={self.profile or '-'} gain={self.shaper.gain:.3f} "
            f"airspeed={self._airspeed_txt()} health={self.health()}"
            f"{lat_txt} cpu={self.cpu():.2f}s wall={dt:.1f}s",
            file=self.status_out,
            flush=True,
        )
        self._status_t0, self._status_sp0, self._status_vt0 = now, self.counters.setpoints, vt
