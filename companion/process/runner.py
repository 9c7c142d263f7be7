"""The companion process: one UAV's Agent flying its autopilot over MAVLink, in the group.

The :class:`Runner` is the composition root: it holds typed components, each owning its
state behind its hooks, and it alone sends (through :class:`~.sender.Sender`) what they
return:

* :class:`~.telemetry.Telemetry` -- vehicle time (SYSTEM_TIME, ``time_boot_ms``; the Agent
  never sees the wall clock), the state estimate, the battery, armed and landed state, and
  the rate of each stream asked for (:class:`~.streams.StreamWatch`: asked again when a
  ground station on the same link slowed it);
* :class:`~.setpoint.SetpointChannel` -- the profile (from the first HEARTBEAT when
  ``auto``; PX4's offboard ones), the shaper, the setpoint in force kept alive;
* :class:`~.health.Health` -- the checks on the autopilot and their issues;
* :class:`~.control.TakingControl` -- command authority (setpoints only in GUIDED, or PX4's
  OFFBOARD; a pilot's override stops them at once), taking control of a flying aircraft
  (never arming), PX4's OFFBOARD entry, the GUIDED targets, the reliefs' ground sequence;
* :class:`~.group_io.GroupIO` -- the members' states and alerts in, this UAV's out;
* :class:`~.step.ControlStep` -- GLOBAL_POSITION_INT -> estimate -> ``Agent.update`` -> the
  state to the group, then one setpoint; the camera's detections -> ``Agent.detect``;
* :class:`~.status.StatusLine` -- the status line on stderr;
* :class:`~.onboard.OnboardStatus` -- the companion's health to ground stations
  (ONBOARD_COMPUTER_STATUS, 1 Hz; the link sends its HEARTBEAT).

Messages are dispatched by type from a table (:mod:`~.messages`). While the companion does
not command (no link, waiting, overridden) the Agent is not stepped and the UAV does not
broadcast its state, so the others re-splay without it. Two ways to run: its own
``selectors`` loop (:meth:`Runner.run` until :meth:`Runner.stop`, e.g. from SIGTERM), or
driven by the in-memory engine (:meth:`Runner.begin`, :meth:`Runner.on_messages`,
:meth:`Runner.on_group`, :meth:`Runner.tick`); :meth:`Runner.close` flushes the logs and
closes every socket. :mod:`~.config` holds :class:`~.config.RunConfig`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from companion.agent.agent import Agent
from companion.group.messages import Mode
from companion.group.transport import Group
from companion.link.battery import BatteryEstimate, BatteryMonitor
from companion.link.connection import AutopilotLink
from companion.link.modes import Authority
from companion.link.outbox import Statustext
from companion.link.serial_device import is_serial_url
from companion.link.setpoints import Profile
from companion.link.shaping import Shaper
from companion.process.config import Counters, RunConfig
from companion.process.control import TakingControl
from companion.process.event_log import EventLog
from companion.process.events import LinkUp, Start, Stop
from companion.process.group_io import GroupIO
from companion.process.health import Health
from companion.process.loop import Poller
from companion.process.messages import message_key, message_table
from companion.process.onboard import OnboardStatus
from companion.process.sender import NOTHING, Effect, Effects, Sender
from companion.process.setpoint import SetpointChannel
from companion.process.status import StatusLine
from companion.process.step import ControlStep
from companion.process.telemetry import Telemetry


class Runner:
    """One companion: link + group + Agent.

    Args:
        config: the run configuration.
        link: the autopilot link (already open).
        group_factory: sysid -> the group endpoint (created once the sysid is known).
        events: the event log.
        status_out: where status lines go (stderr).
        wall: monotonic wall clock (s), for I/O pacing and latency only.
        cpu: process CPU time (s), for the status line.
        perf: high-resolution wall clock (s), for the latency.
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
        """Wire the parts; nothing is sent until :meth:`run` or :meth:`begin`."""
        m, c = config.mission, Counters()
        self.config, self.link, self.events, self.counters = config, link, events, c
        self.wall, self.perf = wall, perf
        self.sender = Sender(link, events)
        self.telemetry = Telemetry(m, config.boot_epoch_s, link, c)
        self.channel = SetpointChannel(
            m, config.link.profile, config.link.adapt, link, self.telemetry, c
        )
        authority = Authority()
        self.checks = Health(m, link, self.telemetry, self.channel, authority)
        self.control = TakingControl(
            config, link, self.telemetry, self.channel, self.checks, authority, c
        )
        self.group_io = GroupIO(config, group_factory, link, self.telemetry, c)
        self.step = ControlStep(
            link, self.telemetry, self.channel, self.checks, self.control, self.group_io, c, wall
        )
        self.status = StatusLine(
            status_out, wall, cpu, link=link, telemetry=self.telemetry, channel=self.channel,
            health=self.checks, control=self.control, group_io=self.group_io, step=self.step,
            counters=c,
        )  # fmt: skip
        self.onboard = OnboardStatus(
            wall, cpu, link, serial=is_serial_url(link.url), group=lambda: self.group_io.group,
            vehicle_s=lambda: self.telemetry.now_s,
        )  # fmt: skip
        self._table = message_table(
            self.telemetry, self.channel, self.checks, self.control, self.step, self._start_agent
        )
        self._poller: Poller | None = None  # run()'s selectors loop
        self._driven = False  # begun with begin(): no selectors loop
        self._stop = False
        self._rx_perf = 0.0  # perf time the last batch of messages arrived

    # ---- the two ways to run ------------------------------------------------------------------
    def run(self) -> int:
        """Serve until :meth:`stop`; returns the exit status (0)."""
        poller = self._poller = Poller(self.link)
        self._start()
        print(f"companion: waiting for the autopilot on {self.link.url}", file=self.status.out,
              flush=True)  # fmt: skip
        try:
            while not self._stop:
                for source in poller.poll(0.05, self.group_io.group):
                    if source == "link":
                        self.on_messages(self.link.receive())
                    else:
                        self.on_group()
                if self._stop:
                    break
                self.tick()
        finally:
            self.close()
        return 0

    def stop(self) -> None:
        """Ask the loop to end (safe from a signal handler)."""
        self._stop = True

    def begin(self) -> None:
        """Start without the selectors loop: the caller then feeds :meth:`on_messages`,
        :meth:`on_group` and :meth:`tick` and ends with :meth:`close`."""
        self._driven = True
        self._start()

    def _start(self) -> None:
        cfg = self.config
        self._send((Start(**self._at(), profile=cfg.link.profile, policy=cfg.agent.policy),))

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
            self._on_message(m, steer=i == last_pos)

    def _on_message(self, m: Any, steer: bool) -> None:
        """One message: its hooks from the table, then the control step on a new estimate."""
        key = message_key(self.link, m)
        if key is None:
            return
        send = self.sender.send
        for handle in self._table.get(key, ()):
            effects = handle(m)
            if effects:  # most hooks return NOTHING
                send(effects)
        est = self.telemetry.take_estimate()
        if est is None:
            return
        stepped = self.step.on_position(m, est, steer)
        self._send(stepped.effects)
        if stepped.setpoint and self._rx_perf:
            self.counters.note_latency(self.perf() - self._rx_perf)
        self._send(stepped.after)

    def _start_agent(self, m: Any) -> Effects:
        """The first heartbeat: the Agent and the group (a HEARTBEAT hook)."""
        sysid, cfg = self.link.sysid, self.config
        if self.step.agent is not None or sysid is None:  # (a message is ours once known)
            return NOTHING
        agent = Agent(sysid, cfg.mission, cfg.agent)
        if not self.control.targets.free or (self.channel.px4 and self.channel.profile == "path"):
            agent.fix_airspeed()  # PX4's path: TECS flies its own trim airspeed
        self.step.agent = self.control.agent = agent
        self.status.started()
        self.sender.group = self.group_io.open(sysid)
        return (LinkUp(**self._at(), autopilot_sysid=sysid),)

    def on_group(self) -> None:
        """The group has datagrams waiting: hand them to the Agent."""
        self.group_io.receive(self.step.agent)

    def take_control(self) -> None:
        """Try to take control now (what :meth:`tick` does every ``TAKE_CONTROL_RETRY_S``)."""
        self._send(self.control.take_control(self.wall(), paced=False))

    def tick(self) -> None:
        """Link supervision, take-control retries, the setpoint kept alive, delayed group
        sends, the companion's health to ground stations, the status line, log flushes."""
        if self.link.tick() == "lost":
            self._send(self.control.link_lost())
            self.telemetry.streams.reset()  # asked for anew when the link is back
            self.telemetry.estimator.reset()
            self.channel.shaper.reset_sample()
        self._send(self.control.take_control(self.wall()))
        resend = self.channel.keepalive(self.wall(), self.control.authority.commanding)
        if resend is not None:  # telemetry (so the control step) stalls
            self._send((resend,))
        if self.group_io.group is not None:
            self.group_io.group.flush()
        self._send(self.onboard.tick())
        if self.status.due(self.config.status_interval_s):
            self.status.print()
        tl = self.link.tlog  # flushed about as often as the events
        if tl is not None and self.counters.estimates % 20 == 0:
            tl.flush()
        self.events.flush_if_due()

    def close(self) -> None:
        """Final status line and event; flush logs; close the sockets (idempotent)."""
        if self._poller is None and not self._driven:
            return
        self._driven = False
        if self.config.status_interval_s > 0 or self.counters.setpoints:
            self.status.print(final=True)
        out: list[Effect] = [Stop(**self._at(), setpoints=self.counters.setpoints)]
        if self.control.authority.commanding:
            out.append(Statustext(f"companion {self.link.sysid}: stopping, setpoints end"))
        self._send(out)
        if self._poller is not None:
            self._poller.close()
        self._poller = None
        if self.group_io.group is not None:
            self.group_io.group.close()
        self.link.close()
        if self.link.tlog is not None:
            self.link.tlog.close()
        self.events.close()

    def _send(self, effects: Effects) -> None:
        if effects:
            self.sender.send(effects)

    def _at(self) -> dict[str, Any]:
        return {"t_s": self.telemetry.now_s, "sysid": self.link.sysid}

    # ---- what others read -------------------------------------------------------------------
    @property
    def agent(self) -> Agent | None:
        """The Agent (None before the first heartbeat)."""
        return self.step.agent

    @property
    def agent_mode(self) -> Mode:
        """The Agent's mode after its last step."""
        return self.step.agent_mode

    @property
    def authority(self) -> Authority:
        """Command authority."""
        return self.control.authority

    @property
    def now_s(self) -> float | None:
        """The latest vehicle time (unix s), None before the first estimate."""
        return self.telemetry.now_s

    @property
    def profile(self) -> Profile | None:
        """The setpoint profile (None until the first heartbeat resolves ``auto``)."""
        return self.channel.profile

    @property
    def px4(self) -> bool:
        """Whether the autopilot is PX4."""
        return self.channel.px4

    @property
    def shaper(self) -> Shaper:
        """The setpoint shaper."""
        return self.channel.shaper

    @property
    def battery(self) -> BatteryMonitor:
        """The battery monitor (SYS_STATUS, BATTERY_STATUS)."""
        return self.telemetry.battery

    @property
    def battery_estimate(self) -> BatteryEstimate | None:
        """The battery as the autopilot last reported it, or None before any valid report."""
        return self.telemetry.battery.last

    @property
    def group(self) -> Group | None:
        """The group endpoint (None before the first heartbeat)."""
        return self.group_io.group

    @property
    def group_factory(self) -> Callable[[int], Group]:
        """sysid -> the group endpoint (replaceable until the first heartbeat)."""
        return self.group_io.group_factory

    @group_factory.setter
    def group_factory(self, factory: Callable[[int], Group]) -> None:
        self.group_io.group_factory = factory

    def health(self) -> str:
        """The status line's health field: ``ok`` or the active issues, comma-separated."""
        return self.status.health()
