"""The one-command mission run: a simulator, N companions, the mission's scenario, a report.

:class:`Fleet` owns every process it starts and stops all of them, whatever happens:
``sitl-model`` for the mission's vehicles, its spares included (after the patrol's, on the
ground or holding, as in memory: ``Vehicles.all_sysids``); the perimeter and geofence
uploaded to every vehicle at once (``companion upload``'s code, one thread per vehicle, each
verified by download; a spare flies the same loop and must keep to the same fence); then
one ``companion run --take-control`` per vehicle, spares too, on a fresh fleet key (a
grounded spare's companion takes nothing: it waits, sharing its state, until the fleet's
plan launches it). A grounded spare sends no setpoint, so the lockstep does not wait for it
until it has taken off and steers.
The simulator starts at 1x while the fleet sets up and is switched to the requested
speed-up once every companion has taken control, so the scenario's clock runs fast only
when the companions steer. By default the simulator runs in lockstep (``sitl-model
--lockstep``): it advances only when every companion in command has answered its latest
position report, so the run gives the same result on a busy machine as on an idle one, as
fast as the slowest companion allows (``speedup`` is then a ceiling;
:data:`LOCKSTEP_MAX_SPEEDUP` = no ceiling). ``lockstep`` False runs free against the wall
clock, as a real flight would.
With ``link_signing`` a second fresh key, ``link.key``, signs every autopilot link (MAVLink 2
signing): the simulator, the uploads and the companions all get it.

The run's progress is read passively from the signed group (the fleet holds the key): the
members' time-phases give the splay error, their alerts the alert states; and from the
simulator's truth log as it is written: each UAV's true cross-track and the longest time any
loop point has gone unseen (:class:`companion.report.coverage.LiveCoverage`). At the end the
simulator's and the companions' events are merged in simulated time into ``events.jsonl``
and ``metrics.json`` and the plots are written.
"""

from __future__ import annotations

import contextlib
import json
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from companion.agent.config import AGENT_OPTIONS, AgentConfig
from companion.contracts.errors import UserError
from companion.contracts.options import as_argv
from companion.contracts.simulator import PORT_SPACING, SIM_EPOCH_UNIX_S
from companion.core.measures import splay_error_deg
from companion.group.address import (
    DEFAULT_KEY_EXPR,
    GroupAddress,
    MulticastGroup,
    ZenohGroup,
    parse_group,
)
from companion.group.keys import generate_key_file, signing_from_key_file
from companion.group.transport import Group, open_group
from companion.link.config import LinkConfig
from companion.link.mission_protocol.vehicle import upload_vehicle
from companion.mission import Mission
from companion.process import with_parent
from companion.report.coverage import LiveCoverage
from companion.report.metrics import loop_geometry
from companion.sim.pace import MAX_GAP_S, PaceMonitor
from sitl_model.server import free_base_port

OBSERVER_SYSID = 254  # the fleet's passive place in the group (it never sends)
SETUP_TIMEOUT_S = 60.0  # wall seconds for uploads and take-over
STOP_TIMEOUT_S = 10.0
TIMEOUT_WALL_S = 0.5  # wall seconds a member or a GUIDED setpoint stream may stall
LOCKSTEP_MAX_SPEEDUP = 1e6  # lockstep without a ceiling: as fast as the companions answer
FOLLOW_S = 0.2  # wall seconds between reads of the truth log's tail (and progress lines)


@dataclass
class FleetConfig:
    """Options of a fleet run (see ``companion fleet --help``)."""

    mission_path: Path
    out: Path
    speedup: float = 20.0
    duration_s: float | None = None
    link: LinkConfig = field(default_factory=LinkConfig)  # every companion's setpoints
    agent: AgentConfig = field(default_factory=AgentConfig)  # every companion's options
    faults: str | None = None
    group_address: str = "239.255.14.1"
    group: str | None = None  # --group text; None: multicast on group_address, a free port
    iface: str = "127.0.0.1"
    python: str = sys.executable
    link_signing: bool = False  # sign the autopilot links with a fresh link.key
    dashboard_port: int | None = None  # serve the live page on 127.0.0.1:PORT beside the run
    lockstep: bool = True  # the simulator waits for the companions' setpoints
    sim_params: tuple[str, ...] = ()  # "NAME=VALUE" for the simulator only (its world)
    battery_used_mah: tuple[tuple[int, float], ...] = ()  # (sysid, mAh): used batteries
    group_budget_bytes_s: float | None = None  # --group-budget of every companion
    observer_group: str | None = None  # --observer-group: the fleet's own way into a Zenoh group
    companion_link: str = "tcp"  # "serial" (ArduPlane) / "relay" (PX4): a cable played by socat
    retake_after_failsafe: bool = False  # every companion's --retake-after-failsafe


@dataclass
class _Proc:
    name: str
    popen: subprocess.Popen
    log: object = None


@dataclass
class Progress:
    """What the fleet has seen of the group so far."""

    t_s: float = 0.0  # simulated time of the newest member state (s)
    phases: dict[int, tuple[float, float]] = field(default_factory=dict)  # sysid -> (t, psi)
    alerts: dict[str, str] = field(default_factory=dict)  # alert_id -> latest state
    modes: dict[int, str] = field(default_factory=dict)
    cross_track_m: dict[int, float] = field(default_factory=dict)  # sysid -> true, latest (m)
    unseen_s: float | None = None  # longest a loop point has gone unseen, now (s)

    def cross_track_max_m(self) -> float | None:
        """Largest latest true cross-track of the UAVs on patrol (m); None before any."""
        xt = [d for s, d in self.cross_track_m.items() if self.modes.get(s, "patrol") == "patrol"]
        return max(xt) if xt else None

    def splay_deg(self, period_s: float) -> float | None:
        """Splay error of the latest phases of the members on the loop (a spare, waiting
        or flying in or home, is not), extrapolated to the newest time (deg)."""
        two_pi = 6.283185307179586
        psi = [
            (p + two_pi * (self.t_s - t) / period_s)
            for s, (t, p) in self.phases.items()
            if self.modes.get(s) != "spare"
        ]
        if not psi:
            return None
        return splay_error_deg(psi)


class TruthTail:
    """Reads the rows appended to a truth log since the last call (a partial last line
    waits for its end)."""

    def __init__(self, path: Path) -> None:
        """Open ``path`` (a ``truth.csv`` being written)."""
        self._fh = open(path)  # noqa: SIM115 - closed in close()
        self._rest = ""
        self._cols: dict[str, int] | None = None

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """New rows: times (s), sysids, true positions (complex north + i east, m)."""
        lines = (self._rest + self._fh.read()).split("\n")
        self._rest = lines.pop()
        if self._cols is None and lines:
            self._cols = {name: i for i, name in enumerate(lines.pop(0).split(","))}
        rows = []
        if self._cols is not None:
            c = self._cols
            idx = (c["t_s"], c["sysid"], c["north_m"], c["east_m"])
            for line in lines:
                with contextlib.suppress(ValueError, IndexError):
                    f = line.split(",")
                    rows.append(tuple(float(f[i]) for i in idx))
        a = np.array(rows, dtype=float).reshape(-1, 4)
        return a[:, 0], a[:, 1].astype(int), a[:, 2] + 1j * a[:, 3]

    def close(self) -> None:
        """Close the file."""
        self._fh.close()


def free_udp_port() -> int:
    """A UDP port free on all interfaces now (for the multicast group)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def free_tcp_port() -> int:
    """A TCP port free on loopback now (for the observer's Zenoh endpoint)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def fleet_groups(cfg: FleetConfig) -> tuple[GroupAddress, GroupAddress]:
    """(the companions' group, the observer's) of one run.

    Multicast: ``cfg.group``, else ``cfg.group_address`` on a free port, the same for both.
    Zenoh: the observer (this process) listens on a free loopback TCP endpoint and every
    companion connects to it besides ``cfg.group``'s own endpoints; the peers then meet
    there. The default key expression becomes the run's own (``patrol/run-<8 random hex>``),
    so two runs on one network never hear each other. ``cfg.observer_group`` (Zenoh) is
    where the observer joins instead, on the companions' key: e.g. the router's ground-side
    endpoint when the companions reach the router through a radio.
    """
    where = parse_group(cfg.group) if cfg.group is not None else None
    if cfg.observer_group is not None and not isinstance(where, ZenohGroup):
        raise UserError("--observer-group needs a Zenoh --group (zenoh:... or zenoh-client:...)")
    if where is None or isinstance(where, MulticastGroup):
        where = where or MulticastGroup(cfg.group_address, free_udp_port())
        return where, where
    assert isinstance(where, ZenohGroup)
    if where.key_expr == DEFAULT_KEY_EXPR:
        where = replace(where, key_expr=f"patrol/run-{secrets.token_hex(4)}")
    if cfg.observer_group is not None:  # e.g. the router's ground side, off the radio
        observer = parse_group(cfg.observer_group)
        if not isinstance(observer, ZenohGroup):
            raise UserError(f"--observer-group {cfg.observer_group!r}: expected zenoh...")
        if observer.key_expr not in (DEFAULT_KEY_EXPR, where.key_expr):
            raise UserError(
                f"--observer-group {cfg.observer_group!r}: key {observer.key_expr!r} is not "
                f"the companions' ({where.key_expr!r})"
            )
        return where, replace(observer, key_expr=where.key_expr)
    here = f"tcp/127.0.0.1:{free_tcp_port()}"
    return replace(where, connect=(*where.connect, here)), replace(where, listen=(here,))


class Fleet:
    """One run of a mission: processes, progress, logs (see the module docstring)."""

    def __init__(self, cfg: FleetConfig, mission: Mission) -> None:
        """Prepare the output folder; nothing is started yet."""
        self.cfg = cfg
        self.mission = mission
        self.duration_s = cfg.duration_s if cfg.duration_s is not None else mission.duration_s
        self.procs: list[_Proc] = []
        self.sitl: _Proc | None = None
        self.progress = Progress()
        self.observer: Group | None = None
        self.stopping = False
        points, polyline = loop_geometry(mission.patrol)
        self.live = LiveCoverage(points, polyline, mission.sensor.footprint_radius_m)
        self._truth: TruthTail | None = None
        self._truth_due = 0.0  # monotonic s: the truth log's tail is next read then
        cfg.out.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(cfg.mission_path, cfg.out / "mission.yaml")
        if cfg.sim_params:  # the world the simulator was given beyond the mission
            (cfg.out / "sim_params.txt").write_text("".join(f"{p}\n" for p in cfg.sim_params))
        self.key_file = cfg.out / "fleet.key"
        if not self.key_file.exists():
            generate_key_file(self.key_file)
        self.link_key_file: Path | None = None
        if cfg.link_signing:
            self.link_key_file = cfg.out / "link.key"
            if not self.link_key_file.exists():
                generate_key_file(self.link_key_file)
        self.sysids = mission.vehicles.all_sysids  # the simulator's vehicles, spares last
        self.base_port = free_base_port(len(self.sysids))
        # Timeouts in vehicle seconds that stay at least TIMEOUT_WALL_S of wall time: at 40x the
        # usual 3 s is 75 ms, and a scheduling hiccup of a 2-core host would drop members
        # from the formation and put autopilots into their GUIDED-timeout loiter.
        # In lockstep simulated time waits for the companions: the usual 3 s holds.
        self.timeout_s = 3.0 if cfg.lockstep else max(3.0, TIMEOUT_WALL_S * cfg.speedup)
        member_timeout_s = max(cfg.agent.member_timeout_s, self.timeout_s)
        self.agent = replace(cfg.agent, member_timeout_s=member_timeout_s)  # every companion's
        self.group, self.observer_group = fleet_groups(cfg)
        self.companion_args: list[str] = []  # more ``companion run`` options (PX4: its clock)
        # free-running firmware: the companions' pace, slowed through the world's pace file
        budget = cfg.group_budget_bytes_s is not None  # states then less often than 5 Hz
        self.pace = PaceMonitor(cfg.speedup, 2.0 if budget else MAX_GAP_S)
        self.pace_file = cfg.out / "pace.txt"
        self.relays: dict[int, _Proc] = {}  # sysid -> the socat playing its companion's cable

    # ---- processes ---------------------------------------------------------------------
    def _spawn(self, name: str, args: list[str], log_name: str, **kw) -> _Proc:
        """Start ``args`` in a session of its own (a Ctrl-C in the terminal reaches only the
        fleet, which stops its processes in order), its output to ``log_name``. Started from
        the main thread, it is also sent SIGTERM if this process ends without stopping it
        (killed, say): see :mod:`companion.process.with_parent`."""
        log = open(self.cfg.out / log_name, "w")  # noqa: SIM115 - closed in stop()
        out = kw.pop("stdout", log)
        popen = subprocess.Popen(
            with_parent.guarded(args), stdout=out, stderr=log, start_new_session=True, **kw
        )
        proc = _Proc(name, popen, log)
        self.procs.append(proc)
        return proc

    def _companion_cmd(self, *args: str) -> list[str]:
        return [self.cfg.python, "-m", "companion", *args]

    def _link_key_args(self, flag: str) -> list[str]:
        """``[flag, link.key]`` when the autopilot links are signed, else nothing."""
        return [flag, str(self.link_key_file)] if self.link_key_file is not None else []

    def start(self) -> None:
        """Start the simulator, upload the perimeter, start the companions, then speed up."""
        cfg = self.cfg
        self.sitl = self._spawn(
            "sitl-model",
            [
                cfg.python,
                "-m",
                "sitl_model",
                "--mission",
                str(cfg.mission_path),
                "--base-port",
                str(self.base_port),
                "--speedup",
                "1",
                "--truth-log",
                str(cfg.out / "truth.csv"),
                "--events-log",
                str(cfg.out / "sim_events.jsonl"),
                "--duration",
                f"{self.duration_s:g}",
                "--status-interval",
                "5",
                "--param",
                f"GUID_TIMEOUT={self.timeout_s:g}",
                *self._link_key_args("--signing-key-file"),
                *(["--lockstep"] if cfg.lockstep else []),
                *[a for s, mah in cfg.battery_used_mah for a in ("--battery-used", f"{s}={mah:g}")],
                *[arg for p in cfg.sim_params for arg in ("--param", p)],
            ],
            "sitl.log",
            stdin=subprocess.PIPE,
        )
        time.sleep(0.5)
        self.check_alive()
        ports = {s: self.base_port + PORT_SPACING * i for i, s in enumerate(self.sysids)}
        deadline = time.monotonic() + SETUP_TIMEOUT_S
        self._upload({s: f"udpout:127.0.0.1:{p}" for s, p in ports.items()}, deadline)
        self._start_companions({s: f"udpout:127.0.0.1:{p}" for s, p in ports.items()}, deadline)
        self.sitl.popen.stdin.write(f"speedup {cfg.speedup:g}\n".encode())
        self.sitl.popen.stdin.flush()

    def _upload(self, urls: dict[int, str], deadline: float) -> None:
        """The perimeter and its geofence (switched on) to every vehicle (sysid -> link URL),
        verified by download: ``companion upload``'s code, one thread per vehicle, each
        vehicle's line in ``upload_<sysid>.log``. Each waits for its vehicle's first HEARTBEAT
        until ``deadline`` (``time.monotonic`` s; it goes on as soon as one is heard): a
        simulator starting on a busy machine can take several seconds to import and bind, and
        ``companion upload``'s own 2 s made a fleet fail there (CI at load 11). Raises
        :class:`UserError` on a failure."""
        key = str(self.link_key_file) if self.link_key_file is not None else None
        listen_s = max(2.0, deadline - time.monotonic())

        def one(sysid: int, url: str) -> tuple[bool, str]:
            try:
                return upload_vehicle(
                    url,
                    sysid,
                    self.cfg.mission_path,
                    enable_fence=True,
                    link_key_file=key,
                    listen_s=listen_s,
                )
            except UserError as exc:
                return False, f"sysid {sysid}: {exc}"

        with ThreadPoolExecutor(max_workers=len(urls)) as pool:
            done = {s: pool.submit(one, s, url) for s, url in urls.items()}
            results = {s: f.result() for s, f in done.items()}
        for s, (ok, line) in results.items():
            log = self.cfg.out / f"upload_{s}.log"
            log.write_text(line + "\n")
            if not ok:
                self.check_alive()  # a simulator that died says so first
                raise UserError(f"upload {s} failed: {line} (see {log})")

    def _start_companions(self, urls: dict[int, str], deadline: float) -> None:
        """One ``companion run --take-control`` per vehicle (sysid -> autopilot link URL),
        the fleet's passive place in the group, then wait until every one is heard there."""
        cfg = self.cfg
        group = str(self.group)
        signing = signing_from_key_file(self.key_file, OBSERVER_SYSID, state_dir=cfg.out)
        # first, so that the companions' Zenoh sessions find its endpoint listening
        self.observer = open_group(self.observer_group, OBSERVER_SYSID, signing, iface=cfg.iface)
        for s, url in urls.items():
            log_dir = cfg.out / f"uav{s}"
            args = [
                "run",
                "--connect",
                url,
                "--mission",
                str(cfg.mission_path),
                "--sysid",
                str(s),
                "--group",
                group,
                "--group-iface",
                cfg.iface,
                "--key-file",
                str(self.key_file),
                "--state-dir",
                str(cfg.out),
                "--log-dir",
                str(log_dir),
                "--take-control",
                *as_argv(cfg.link, ("profile",)),  # at the rate of companion run's default
                *as_argv(self.agent, AGENT_OPTIONS),
                *self.companion_args,
            ]
            if cfg.faults:
                args += ["--faults", cfg.faults]
            if cfg.group_budget_bytes_s is not None:
                args += ["--group-budget", f"{cfg.group_budget_bytes_s:g}"]
            if cfg.retake_after_failsafe:
                args.append("--retake-after-failsafe")
            args += self._link_key_args("--link-key-file")
            log_dir.mkdir(exist_ok=True)
            self._spawn(f"companion {s}", self._companion_cmd(*args), f"uav{s}/companion.log")
        if cfg.dashboard_port is not None:
            # beside the observer when it has its own way in (off the radio)
            self._start_dashboard(str(self.observer_group) if cfg.observer_group else group)
        self._wait_for_members(urls, deadline)

    def _start_dashboard(self, group: str) -> None:
        """``companion dashboard`` on 127.0.0.1:``dashboard_port``, on the run's group and key
        (stopped with every other process; its log is ``dashboard.log``)."""
        cfg = self.cfg
        args = ["dashboard", "--group", group, "--group-iface", cfg.iface]
        args += ["--key-file", str(self.key_file), "--state-dir", str(cfg.out)]
        args += ["--mission", str(cfg.mission_path), "--port", str(cfg.dashboard_port)]
        self._spawn("dashboard", self._companion_cmd(*args), "dashboard.log")

    def _wait_for_members(self, ports: dict[int, int], deadline: float) -> None:
        """Until every companion is heard on the group (it has the vehicle and steers)."""
        t0 = time.monotonic()
        while set(self.progress.phases) != set(ports):
            self.check_alive()
            if time.monotonic() > deadline:
                missing = sorted(set(ports) - set(self.progress.phases))
                raise UserError(
                    f"companions {missing} did not join the group within "
                    f"{time.monotonic() - t0:.0f} s (see their companion.log)"
                )
            self.poll(0.1)

    def check_alive(self) -> None:
        """Raise if a process died early (the simulator ending at its duration is fine)."""
        for p in self.procs:
            rc = p.popen.poll()
            if p is self.sitl and rc == 0 and self.progress.t_s > 0:
                continue
            if rc is not None and not self.stopping:
                raise UserError(f"{p.name} exited with status {rc} (see {self.cfg.out})")

    # ---- running ------------------------------------------------------------------------
    def poll(self, timeout_s: float) -> bool:
        """Read the group for up to ``timeout_s`` wall seconds and update the progress;
        whether it is time to redraw: the truth log's tail was read now (at most every
        ``FOLLOW_S`` of wall time, however often the group's datagrams wake the caller), or
        there is no group yet and the whole timeout was slept."""
        import select

        if self.observer is None:
            time.sleep(timeout_s)
            return True
        ready, _, _ = select.select([self.observer.fileno()], [], [], timeout_s)
        wall = time.monotonic()
        due = wall >= self._truth_due  # the group's datagrams come hundreds a second
        if due:
            self._truth_due = wall + FOLLOW_S
            self._read_truth()
        if not ready:
            return due
        for msg in self.observer.receive():
            if hasattr(msg, "phase_rad"):
                t = msg.t_s - SIM_EPOCH_UNIX_S
                if msg.mode != "overridden":  # a member's control steps (not while away)
                    self.pace.state(wall, msg.sysid, t)
                self.progress.t_s = max(self.progress.t_s, t)
                self.progress.phases[msg.sysid] = (t, msg.phase_rad)
                self.progress.modes[msg.sysid] = msg.mode
            elif getattr(msg, "state", "") != "bid":
                self.progress.alerts[msg.alert_id] = msg.state
        return due

    def _read_truth(self) -> None:
        """The truth log's new rows -> the live cross-track and unseen time."""
        if self._truth is None:
            if not (self.cfg.out / "truth.csv").is_file():
                return
            self._truth = TruthTail(self.cfg.out / "truth.csv")
        t, sysid, pos = self._truth.read()
        if t.size:
            self.pace.truth(time.monotonic(), float(t[-1]))
            self.live.update(t, sysid, pos)
            self.progress.cross_track_m = dict(self.live.cross_track_m)
            self.progress.unseen_s = self.live.longest_unseen_now_s()

    def keep_pace(self, say=print) -> float | None:
        """Free-running firmware: slow the clocks (the world's pace file) when the companions
        starve (:class:`~companion.sim.pace.PaceMonitor`); the new pace, said, or None."""
        if self.cfg.lockstep:
            return None
        pace = self.pace.slow_down(time.monotonic())
        if pace is None:
            return None
        self.pace_file.write_text(f"{pace:g}\n")
        why = self.pace.slowed[-1][2]
        say(f"\nfleet: the companions fall behind ({why}): slowing to {pace:g}x")
        return pace

    def cut_wire(self, sysid: int) -> None:
        """Companion ``sysid``'s cable cut: its socat paused (nothing flows; a serial
        device's node stays)."""
        self.relays[sysid].popen.send_signal(signal.SIGSTOP)

    def mend_wire(self, sysid: int) -> None:
        """The cable mended: its socat runs again."""
        self.relays[sysid].popen.send_signal(signal.SIGCONT)

    def sim_done(self) -> bool:
        """Whether the simulator has reached the run's duration and exited."""
        return self.sitl is not None and self.sitl.popen.poll() is not None

    def stop(self) -> list[tuple[str, int | None]]:
        """Stop every process (SIGINT, then SIGKILL after a timeout); their exit statuses."""
        self.stopping = True
        for relay in self.relays.values():  # a cut cable must not hold the stop up
            with contextlib.suppress(ProcessLookupError):
                relay.popen.send_signal(signal.SIGCONT)
        for p in self.procs:
            if p.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    p.popen.send_signal(signal.SIGINT)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        out = []
        for p in self.procs:
            try:
                rc = p.popen.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.popen.kill()
                rc = p.popen.wait()
            out.append((p.name, rc))
            if p.popen.stdin:
                with contextlib.suppress(OSError):
                    p.popen.stdin.close()
            if p.log:
                p.log.close()
        if self.observer is not None:
            self.observer.close()
            self.observer = None
        if self._truth is not None:
            self._truth.close()
        return out

    # ---- logs ---------------------------------------------------------------------------
    def merge_events(self) -> int:
        """Simulator and companion events, in simulated time, into ``events.jsonl``."""
        return merge_events(self.cfg.out, self.sysids)


def merge_events(out: Path, sysids: list[int] | tuple[int, ...]) -> int:
    """``out/sim_events.jsonl`` and every ``out/uavN/events.jsonl``, in simulated time (s),
    into ``out/events.jsonl``; returns the number of events. Every instant of a companion's
    event (``t_s`` and the other fields named ``*_t_s``, such as a pass's ``first_t_s``) is
    moved from vehicle time to simulated time."""
    events: list[dict] = []
    sources = [(out / "sim_events.jsonl", 0.0)] + [
        (out / f"uav{s}" / "events.jsonl", SIM_EPOCH_UNIX_S) for s in sysids
    ]
    for path, epoch in sources:
        if not path.is_file():
            continue
        with open(path) as fh:
            for line in fh:
                with contextlib.suppress(json.JSONDecodeError, TypeError, KeyError):
                    ev = json.loads(line)
                    if ev.get("t_s") is None:
                        continue
                    for key, value in ev.items():  # t_s and every other instant (*_t_s)
                        if key.endswith("t_s") and isinstance(value, (int, float)):
                            ev[key] = round(float(value) - epoch, 3)
                    ev.setdefault("source", "sim" if epoch == 0.0 else "companion")
                    events.append(ev)
    events.sort(key=lambda e: e["t_s"])
    with open(out / "events.jsonl", "w") as fh:
        for ev in events:
            fh.write(json.dumps(ev, sort_keys=True) + "\n")
    return len(events)
