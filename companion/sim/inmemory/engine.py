"""The in-memory engine: the simulator's vehicles and N real companions, lockstepped.

The same objects as a UDP run on both sides, with the sockets replaced by queues:

* the simulator is :func:`sitl_model.assembly.assemble`'s :class:`~sitl_model.sim.Simulation`,
  :class:`~sitl_model.link.VehicleLink` (telemetry, mission protocol, parameters) and what
  :func:`sitl_model.outputs.after_step` emits after each 50 Hz step, packed by the
  simulator's :class:`~sitl_model.codec.Encoder` (autopilot and camera component 100) and
  decoded by its :class:`~sitl_model.codec.Decoder`;
* every companion is a :class:`companion.process.runner.Runner` with its real
  :class:`~companion.link.connection.AutopilotLink` (heartbeats, SET_MESSAGE_INTERVAL
  requests, link-loss supervision, optional MAVLink 2 signing) on a
  :class:`~companion.sim.inmemory.wires.MemoryConn` instead of a pymavlink socket, and a real
  :class:`~companion.group.transport.Group` (codec, fleet-key signing, optional faults) on a
  :class:`~companion.sim.inmemory.wires.BusSocket`.

One :meth:`Engine.step` is one physics step, then in this order: the simulator's outputs
go out (bytes queued to each vehicle's companion), every companion in sysid order reads
its group datagrams, then its autopilot messages, and ticks; every vehicle then decodes
and handles what its companion sent (a setpoint sent after telemetry of step k flies from
step k + 1); then the group datagrams sent during the step are delivered, in sender order,
to every other member. Every clock is simulated time: ``t_s`` for link supervision,
take-control retries and log flushes, ``SIM_EPOCH_UNIX_S + t_s`` for signing timestamps. The
same mission, seed and parameters therefore give byte-identical ``truth.csv`` and
``events.jsonl``.

The run folder is the one ``companion fleet`` writes (``truth.csv``, ``sim_events.jsonl``,
``uavN/events.jsonl``, merged ``events.jsonl``), so ``companion report DIR`` reads it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.agent.config import AgentConfig
from companion.contracts.signing import COMPANION_LINK_ID, VEHICLE_LINK_ID, FrameCheck, Signing
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.group.codec import COMPID_OPERATOR, OPERATOR_SYSID, encode
from companion.group.faults import FaultModel
from companion.group.messages import Alert
from companion.group.transport import Group
from companion.link.config import LinkConfig
from companion.link.connection import AutopilotLink
from companion.mission import Mission, load_mission
from companion.process.config import RunConfig, telemetry_rates_hz
from companion.process.event_log import EventLog
from companion.process.runner import Runner
from companion.sim.fleet import merge_events
from companion.sim.inmemory.wires import GroupBus, Sink, Stopwatch, VehiclePort, fleet_key
from sitl_model.assembly import WorldSpec, assemble
from sitl_model.codec import MAV_COMP_ID_AUTOPILOT1, Encoder
from sitl_model.outputs import after_step, event_record
from sitl_model.sim import DT_S, SENSOR_EVERY, Simulation

__all__ = ["Engine", "EngineConfig"]

GCS_SYSID = 255  # a ground station's system and component ids (pilot commands)
GCS_COMPID = 190
TICK_EVERY = 5  # physics steps between companion ticks when no message came (10 Hz)


@dataclass
class EngineConfig:
    """What to simulate (see ``companion simulate --help``).

    Attributes:
        mission_path: the mission YAML.
        out: run folder (None: write nothing; events are still kept in memory).
        seed: seed of the simulator's one random generator.
        params: simulator parameters set at start (NAME -> value), after the mission's.
        link: every companion's setpoints (``companion run``'s ``--profile``, ``--rate-hz``;
            "auto": bank on the simulator, which says it is ArduPilot).
        agent: how every companion decides (``companion run``'s ``--policy``,
            ``--on-confirm``, ...); its ``lead_s`` and ``hold_s`` follow ``link.rate_hz``.
        faults: group faults (loss, jitter... in vehicle s; seeded) for every member.
        link_signing: sign every autopilot link with a key derived from the seed.
        battery_used_mah: ``(sysid, mAh)``: that vehicle starts with a used battery
            (as ``sitl-model --battery-used``).
        group_budget_bytes_s: ``--group-budget`` of every companion (bytes/s; None: none).
        physics_every: physics steps of ``DT_S`` (20 ms) taken at once, 1 or 5
            (:meth:`sitl_model.sim.Simulation.advance`); None: 5 (0.1 s, the sensors' and
            the telemetry's period) when the control period ``1 / rate_hz`` is a multiple
            of 0.1 s, else 1.
        wire: how autopilot messages cross: "bytes" (packed and parsed, as over UDP),
            "objects" (the message objects as decoded, :mod:`~companion.sim.inmemory.wires`;
            the same values, not with ``link_signing``) or "auto" (objects unless the
            links are signed).
        start_s: companion sysid -> simulated time (s) it starts (default 0: at once);
            until then its vehicle flies uncommanded (GUIDED: its timeout, then a loiter),
            as while ``companion fleet`` sets up.
    """

    mission_path: Path
    out: Path | None = None
    seed: int = 0
    params: dict[str, float] = field(default_factory=dict)
    link: LinkConfig = field(default_factory=LinkConfig)
    agent: AgentConfig = field(default_factory=AgentConfig)
    faults: FaultModel | None = None
    link_signing: bool = False
    start_s: dict[int, float] = field(default_factory=dict)
    battery_used_mah: tuple[tuple[int, float], ...] = ()
    group_budget_bytes_s: float | None = None
    wire: str = "auto"
    physics_every: int | None = None

    def __post_init__(self) -> None:
        """Check ``wire`` and ``physics_every``.

        Raises:
            ValueError: an unknown ``wire``, or "objects" with ``link_signing``, or a
                ``physics_every`` that does not divide ``SENSOR_EVERY``.
        """
        n = self.physics_every
        if n is not None and (n < 1 or SENSOR_EVERY % n):
            raise ValueError(f"physics_every must divide {SENSOR_EVERY}, got {n!r}")
        if self.wire not in ("auto", "bytes", "objects"):
            raise ValueError(f"wire must be auto, bytes or objects, got {self.wire!r}")
        if self.wire == "objects" and self.link_signing:
            raise ValueError("signed links carry bytes: wire='bytes' or 'auto'")

    @property
    def steps_at_once(self) -> int:
        """Physics steps taken at once (``physics_every``, or its automatic choice)."""
        if self.physics_every is not None:
            return self.physics_every
        period_steps = 1.0 / (self.link.rate_hz * DT_S)
        k = period_steps / SENSOR_EVERY
        return SENSOR_EVERY if abs(k - round(k)) < 1e-9 and round(k) >= 1 else 1

    @property
    def objects(self) -> bool:
        """Whether autopilot messages cross as objects."""
        return self.wire == "objects" or (self.wire == "auto" and not self.link_signing)


class _Recorder(EventLog):
    """An event log that also keeps the events (dicts) in memory."""

    def __init__(self, path: Path | None, clock: Callable[[], float], into: list[dict]) -> None:
        super().__init__(path, clock)
        self._into = into

    def write(self, event: dict[str, Any]) -> None:
        """Keep and append one event."""
        self._into.append(event)
        super().write(event)


class Engine:
    """The simulator and one :class:`Runner` per vehicle in one process, on simulated time.

    Use :meth:`run` (or :meth:`step` repeatedly), then :meth:`close` to write the run folder.
    ``sim_events`` and ``companion_events`` hold every event (dicts, simulator times in s,
    companion times in unix s of vehicle time), ``time_sim_s``, ``time_transport_s`` and
    ``time_companion_s`` the time spent in the simulator, on the autopilot links' wires
    (packing and parsing, or passing objects on) and in the companions (s, ``perf_counter``;
    CPU time on an idle machine; the group's codec and signing count as the companions').
    """

    def __init__(self, cfg: EngineConfig, status_out: TextIO | None = None) -> None:
        """Build the simulator exactly as ``sitl-model --mission`` does, then the companions."""
        self.cfg = cfg
        spec = WorldSpec(
            mission_path=str(cfg.mission_path),
            params=tuple((name, float(value)) for name, value in cfg.params.items()),
            seed=cfg.seed,
            battery_used_mah=cfg.battery_used_mah,
        )
        self.sim: Simulation
        self.sim, self.links = assemble(spec)
        self.mission: Mission = load_mission(cfg.mission_path)
        self.sysids = list(self.sim.sysids)
        self.key = fleet_key(cfg.seed)
        self.link_key = hashlib.sha256(self.key).digest() if cfg.link_signing else None
        self._operator_signing = Signing(self.key, self._unix)  # sysid 255's stream
        self._operator_seq = 0
        self.stopwatch = Stopwatch()
        self.ports = [
            VehiclePort(link, self._vehicle_check, cfg.objects, self.stopwatch)
            for link in self.links
        ]
        self.bus = GroupBus()
        self.gcs = Sink()
        self._gcs_enc = Encoder(GCS_SYSID, GCS_COMPID, self._vehicle_check())
        self.sim_events: list[dict[str, Any]] = []
        self.companion_events: list[dict[str, Any]] = []
        self.frozen: set[int] = set()
        self.killed: set[int] = set()  # SIGKILLed and not restarted: never closed cleanly
        self._time_sim_s = 0.0  # wall time in each part, the wires' time included
        self._time_companion_s = 0.0
        self._sim_wire_s = 0.0  # the simulator's side of the wires
        self._companion_wire_s = 0.0  # the companions' side
        self._files: list[Any] = []
        self._truth: TextIO | None = None
        self._sim_log: TextIO | None = None
        self._status: list[TextIO] = []
        out = cfg.out
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(cfg.mission_path, out / "mission.yaml")
            self._truth = open(out / "truth.csv", "w", buffering=1 << 16)  # noqa: SIM115
            self._truth.write(self.sim.truth_header + "\n")
            self._sim_log = open(out / "sim_events.jsonl", "w", buffering=1 << 16)  # noqa: SIM115
        self.runners: list[Runner] = []
        for i, sysid in enumerate(self.sysids):
            self.runners.append(self._runner(i, sysid, status_out))
        self._closed = False
        self._n = cfg.steps_at_once
        self._steps_goal = 1 << 62  # step(): whole control periods
        self._waiting = {s: t for s, t in cfg.start_s.items() if t > 0}  # not started yet
        for sysid, r in zip(self.sysids, self.runners, strict=True):
            if sysid not in self._waiting:
                self._start(r)
        self._vehicles_receive()

    def _start(self, r: Runner) -> None:
        r.begin()
        r.tick()  # the first heartbeat: the vehicle learns its peer

    # ---- clocks -----------------------------------------------------------------------------
    @property
    def time_transport_s(self) -> float:
        """Time (s) spent on the autopilot links' wires, on both sides."""
        return self.stopwatch.s

    @property
    def time_sim_s(self) -> float:
        """Time (s) spent in the simulator, its side of the wires excluded."""
        return self._time_sim_s - self._sim_wire_s

    @property
    def time_companion_s(self) -> float:
        """Time (s) spent in the companions, their side of the wires excluded."""
        return self._time_companion_s - self._companion_wire_s

    @property
    def t_s(self) -> float:
        """Simulated time (s from the start)."""
        return self.sim.t_s

    def _mono(self) -> float:
        return self.sim.t_s

    def _unix(self) -> float:
        return SIM_EPOCH_UNIX_S + self.sim.t_s

    def _vehicle_check(self) -> FrameCheck | None:
        if self.link_key is None:
            return None
        return FrameCheck(Signing(self.link_key, self._unix, link_id=VEHICLE_LINK_ID))

    # ---- construction -------------------------------------------------------------------------
    def _runner(
        self, i: int, sysid: int, status_out: TextIO | None, restart: bool = False
    ) -> Runner:
        cfg = self.cfg
        port = self.ports[i]
        link_check = None
        if self.link_key is not None:
            link_check = FrameCheck(Signing(self.link_key, self._unix, link_id=COMPANION_LINK_ID))
        link = AutopilotLink(
            f"memory:{sysid}",
            sysid=sysid,
            rates_hz=telemetry_rates_hz(cfg.link.rate_hz),
            stamp_us=lambda: round(self._unix() * 1e6),
            clock=self._mono,
            signing=link_check,
            warn=lambda text: print(text, file=sys.stderr),
            opener=lambda _url, src, comp: port.connect(src, comp),
        )
        events_path = None
        if cfg.out is not None:
            (cfg.out / f"uav{sysid}").mkdir(exist_ok=True)
            events_path = cfg.out / f"uav{sysid}" / "events.jsonl"
            if not restart:  # a fresh run: not appended to an earlier run in the same folder
                events_path.unlink(missing_ok=True)
            log = cfg.out / f"uav{sysid}" / "companion.log"
            status = open(log, "a" if restart else "w")  # noqa: SIM115
            self._status.append(status)
        else:
            status = status_out or _NullOut()
        events = _Recorder(events_path, self._mono, self.companion_events)

        def group_factory(member: int) -> Group:
            signing = Signing(self.key, self._unix)
            return Group(
                member, signing, faults=cfg.faults, clock=self._unix, sock=self.bus.join(member)
            )

        run_cfg = RunConfig(
            mission=self.mission,
            link=cfg.link,
            agent=cfg.agent.at_rate(cfg.link.rate_hz),
            take_control=True,
            group_budget_bytes_s=cfg.group_budget_bytes_s,
        )
        return Runner(
            run_cfg,
            link,
            group_factory,
            events,
            status_out=status,
            wall=self._mono,
            cpu=time.process_time,
            perf=time.perf_counter,
        )

    # ---- stepping -----------------------------------------------------------------------------
    def step(self) -> None:
        """One physics step (``EngineConfig.steps_at_once`` steps of ``DT_S`` at once) and
        everything that follows it (see the module docstring)."""
        perf = time.perf_counter  # not process_time: a syscall, costly on a busy machine
        watch = self.stopwatch
        w0 = watch.s
        t0 = perf()
        sim = self.sim
        n = self._n
        if n > 1 and (sim.steps % n or self._steps_goal - sim.steps < n):
            n = 1  # a run that ends between two control periods
        sim.advance(n)
        out = after_step(sim, self.links)
        if out.events:
            self._sim_events(out.events)
        ports = self.ports
        for i, msg, camera in out.sends:
            ports[i].send(msg, None, camera)
        if out.truth and self._truth is not None:
            self._truth.write("\n".join(out.truth) + "\n")
        t1 = perf()
        w1 = watch.s
        tick = sim.steps % TICK_EVERY == 0
        socks = self.bus.members
        for k, r in enumerate(self.runners):
            if self._waiting:
                at = self._waiting.get(self.sysids[k])
                if at is not None:
                    if sim.t_s + 1e-9 < at:
                        continue
                    del self._waiting[self.sysids[k]]
                    self._start(r)
            if self.sysids[k] in self.frozen:
                continue
            sock = socks.get(self.sysids[k])
            if sock is not None and sock.inbox:
                r.on_group()
            conn = r.link.conn
            msgs = r.link.receive() if conn is not None and conn.pending else None
            if msgs:
                r.on_messages(msgs)
            if msgs or tick:
                r.tick()
        t2 = perf()
        w2 = watch.s
        self._vehicles_receive()
        if tick:
            for i, link in enumerate(self.links):
                for reply, to in link.tick(sim.t_s):
                    ports[i].send(reply, to)
        self.bus.deliver()
        self._time_sim_s += t1 - t0 + perf() - t2
        self._time_companion_s += t2 - t1
        self._sim_wire_s += w1 - w0 + watch.s - w2
        self._companion_wire_s += w2 - w1

    def _vehicles_receive(self) -> None:
        for port in self.ports:
            events = port.process(self.sim.t_s)
            if events:
                self._sim_events(
                    [event_record(self.sim.t_s, n, port.link.sysid, d) for n, d in events]
                )

    def _sim_events(self, records: Iterable[dict[str, Any]]) -> None:
        for rec in records:
            self.sim_events.append(rec)
            if self._sim_log is not None:
                self._sim_log.write(json.dumps(rec) + "\n")

    def run(self, duration_s: float, progress: Callable[[float], None] | None = None) -> None:
        """Step until simulated time reaches ``duration_s`` (s); ``progress(t_s)`` each 10 s."""
        steps = round(duration_s / DT_S)
        self._steps_goal = steps
        every = round(10.0 / DT_S)
        try:
            while self.sim.steps < steps:
                before = self.sim.steps
                self.step()
                if progress is not None and self.sim.steps // every != before // every:
                    progress(self.sim.t_s)
        finally:
            self._steps_goal = 1 << 62

    # ---- what a test or an operator does --------------------------------------------------------
    def freeze(self, sysid: int) -> None:
        """Stop running companion ``sysid`` (as SIGSTOP): it reads, sends and ticks nothing,
        and what is sent to it meanwhile is lost (its socket buffers overflowed)."""
        self.frozen.add(sysid)
        r = self.runners[self.sysids.index(sysid)]
        r.link.conn.deaf = True
        if sysid in self.bus.members:
            self.bus.members[sysid].deaf = True

    def thaw(self, sysid: int) -> None:
        """Run companion ``sysid`` again (SIGCONT)."""
        self.frozen.discard(sysid)
        r = self.runners[self.sysids.index(sysid)]
        if r.link.conn is not None:
            r.link.conn.deaf = False
        if sysid in self.bus.members:
            self.bus.members[sysid].deaf = False

    def kill(self, sysid: int) -> None:
        """SIGKILL companion ``sysid``: it stops at once, says nothing more (no ``stop``
        event) and what is sent to it is lost; :meth:`restart` starts a new one."""
        self.freeze(sysid)
        self.killed.add(sysid)
        self.runners[self.sysids.index(sysid)].events.close()  # what it wrote stays

    def restart(self, sysid: int) -> None:
        """Start a new companion ``sysid`` (after :meth:`kill`), as ``companion run`` again:
        a fresh process state on a new link and group socket, its events and status
        appended to the first one's files."""
        i = self.sysids.index(sysid)
        old = self.runners[i]
        old.link.close()
        self.frozen.discard(sysid)
        self.killed.discard(sysid)
        r = self._runner(i, sysid, None, restart=True)
        self.runners[i] = r
        self._start(r)

    def gcs_command(self, sysid: int, command: int, *params: float) -> None:
        """A ground station's COMMAND_LONG to vehicle ``sysid``, through its link (bytes)."""
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        msg = mav.MAVLink_command_long_message(sysid, MAV_COMP_ID_AUTOPILOT1, command, 0, *p)
        port = self.ports[self.sysids.index(sysid)]
        port.inbox.append((self.gcs, self._gcs_enc.pack(msg)))
        self._vehicles_receive()

    def set_mode(self, sysid: int, custom_mode: int) -> None:
        """The pilot switches vehicle ``sysid`` to ArduPlane mode ``custom_mode``."""
        self.gcs_command(sysid, mav.MAV_CMD_DO_SET_MODE, mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                         custom_mode)  # fmt: skip

    def operator_alert(self, alert_id: str, north_m: float, east_m: float) -> None:
        """``companion alert``: an operator's signed new alert to the group, stamped with the
        vehicle time as when the tool hears a member first (site in metres, north and east
        of the mission origin)."""
        a = Alert(alert_id, complex(north_m, east_m), OPERATOR_SYSID, self._unix(), "new")
        self.operator_send(a)

    def operator_send(self, alert: Alert) -> None:
        """An operator's alert as given, signed with the fleet key and posted to the group:
        a "new" report with its own time (``alert.t_s``, vehicle unix s, as ``bench/storm.py
        inject`` sends a storm), or "cleared" (the dashboard's cancel). Delivered to every
        member at the end of the step. The operator keeps one signing state, so any number
        of alerts in one step carry rising timestamps.

        Raises:
            ValueError: the alert's detector is not the operator (sysid 255).
        """
        if alert.detector_sysid != OPERATOR_SYSID:
            raise ValueError(f"an operator's alert has detector {OPERATOR_SYSID}, got {alert}")
        signing, seq = self._operator_signing, self._operator_seq
        frame = encode(alert, OPERATOR_SYSID, signing, compid=COMPID_OPERATOR, seq=seq)
        self._operator_seq = (seq + 1) % 256
        self.bus.post(OPERATOR_SYSID, frame)

    # ---- the end ------------------------------------------------------------------------------
    def close(self) -> int | None:
        """Stop the companions, close the logs and merge the events (the number merged)."""
        if self._closed:
            return None
        self._closed = True
        for sysid, r in zip(self.sysids, self.runners, strict=True):
            if sysid in self._waiting:  # never started
                r.link.close()
                r.events.close()
            elif sysid in self.killed:  # its end was the kill
                r.link.close()
            else:
                r.close()
        self._vehicles_receive()
        for f in (self._truth, self._sim_log, *self._status):
            if f is not None:
                f.close()
        if self.cfg.out is None:
            return None

        return merge_events(self.cfg.out, self.sysids)

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        with contextlib.suppress(Exception):
            self.close()


class _NullOut:
    """A text sink."""

    def write(self, _text: str) -> int:
        return 0

    def flush(self) -> None:
        """Nothing to flush."""
