"""The fleet test harness: the real simulator and six real ``companion run`` processes over
loopback, and the measures judged from the truth log and the companions' events.

Used by the fleet integration tests (``fleet_factory`` fixture in ``tests/conftest.py``) and by
the reliability benches. Every process is stopped in a finaliser, asserting exit status 0
on SIGTERM and that none is left.

Fleets run in lockstep by default (``sitl-model --lockstep``, docs/sitl.md): the simulator
waits for every commanding companion's setpoint, so the figures do not move with the
machine's load and ``SPEEDUP`` is only a ceiling. ``lockstep=False`` runs the simulator free
against the wall clock, for the tests whose subject is wall-clock behaviour (a link cut for
10 s of real time).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from companion.agent.alerts.tasking import next_in_sequence
from companion.contracts.simulator import PORT_SPACING, SIM_EPOCH_UNIX_S
from companion.core.measures import centre_error_m, splay_error_deg
from companion.mission import load_mission
from companion.report.rundata import load_run
from sitl_model.server import free_base_port
from sitl_model.testing import REPO, SitlProcess

FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"
PAPER = REPO / "missions" / "ellipse_6uav.yaml"
# Seven processes at 20x need about 2.4 cores (the simulator ~0.8, each companion ~0.27):
# free-running on a two-core machine the formation then jitters by several metres. At 10x
# they need about 1.2 and the fleet flies as at 1x. In lockstep (the default) this is a
# ceiling: a busy machine runs slower, with the same results.
SPEEDUP = float(os.environ.get("COMPANION_TEST_SPEEDUP", "10"))


STOP_GRACE_S = 60.0  # an interrupted fleet's time to stop what it started before SIGKILL


def run_to_end(cmd: list[str], timeout: float, **kwargs) -> subprocess.CompletedProcess:
    """``subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kwargs)``, but
    a run interrupted (Ctrl-C, the test's SIGINT alone, the timeout) first gets SIGTERM and
    up to ``STOP_GRACE_S`` (s) to stop what it started, then SIGKILL. ``subprocess.run``
    kills at once, and a ``companion fleet`` killed so leaves its firmware instances running
    (measured: a PX4 instance outlived a SIGINT sent to the test's process alone)."""
    with subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs
    ) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except BaseException:
            proc.terminate()
            try:
                proc.communicate(timeout=STOP_GRACE_S)
            except BaseException:
                proc.kill()
            raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def leftovers(tag: str) -> list[str]:
    """Processes whose command line mentions ``tag`` (a run's own folder)."""
    out = subprocess.run(["pgrep", "-af", tag], capture_output=True, text=True).stdout
    return [line for line in out.splitlines() if "pgrep" not in line]


def free_udp_port() -> int:
    """A UDP port free on all interfaces now (for the multicast group)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return s.getsockname()[1]


class Companion:
    """One ``python -m companion run`` subprocess with its stderr collected."""

    def __init__(self, args: list[str], prefix: tuple[str, ...] = ()) -> None:
        """Start it (after ``prefix``, e.g. ``ip netns exec NS``); stderr lines are pumped
        into :attr:`lines`."""
        env = dict(os.environ, PYTHONPATH=str(REPO))
        self.proc = subprocess.Popen(
            [*prefix, sys.executable, "-m", "companion", "run", *args],
            cwd=REPO,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._pump, daemon=True)
        self._t.start()

    def _pump(self) -> None:
        for raw in iter(self.proc.stderr.readline, b""):
            self.lines.append(raw.decode("utf-8", "replace"))

    def wait_ready(self, timeout_s: float = 90.0) -> None:
        """Until it says it is waiting for its autopilot."""
        deadline = time.monotonic() + timeout_s
        while not any("waiting for the autopilot" in ln for ln in self.lines):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError("companion did not start: " + "".join(self.lines))
            time.sleep(0.05)

    def kill(self, save: Path | None = None) -> int:
        """SIGKILL (a crash: no cleanup runs), reap it; the exit status; stderr to ``save``."""
        self.proc.kill()
        self.proc.wait()
        return self.stop(save=save)

    def stop(self, timeout_s: float = 30.0, save: Path | None = None) -> int:
        """SIGTERM, wait (kill after ``timeout_s``: a loaded machine may take a while); the
        exit status; stderr to ``save``."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._t.join(2.0)
        if save is not None:
            save.write_text("".join(self.lines))
        self.proc.stdout.close()
        self.proc.stderr.close()
        return self.proc.returncode


@dataclass
class Fleet:
    """A running simulator and its companions."""

    out: Path
    mission: Path
    base_port: int
    sitl: SitlProcess
    companions: list[Companion]
    killed: list[Companion] = field(default_factory=list)

    def port(self, i: int) -> int:
        """UDP port of vehicle index ``i``."""
        return self.base_port + PORT_SPACING * i

    def wait_sim_time(self, t_s: float, timeout_s: float = 120.0) -> None:
        """Until the truth log reaches simulated time ``t_s``; ``TimeoutError`` if simulated
        time stands still for ``timeout_s`` wall seconds. A lockstepped fleet on a busy
        machine is slow but never stuck, so only a stall fails, not a slow pace."""
        deadline = time.monotonic() + timeout_s
        seen = -1.0
        while (now_s := last_truth_time(self.out / "truth.csv")) < t_s:
            if now_s > seen:
                seen, deadline = now_s, time.monotonic() + timeout_s
            if time.monotonic() > deadline:
                raise TimeoutError(f"simulation stood still at {now_s} s (waiting for {t_s} s)")
            if self.sitl.proc.poll() is not None:
                raise RuntimeError("simulator exited: " + "".join(self.sitl.stderr_lines))
            time.sleep(0.2)

    def kill(self, i: int) -> None:
        """SIGKILL companion index ``i`` (its stderr saved as ``c{i+1}.killed.err``)."""
        c = self.companions[i]
        assert c.kill(save=self.out / f"c{i + 1}.killed.err") == -signal.SIGKILL
        self.killed.append(c)

    def restart(self, i: int) -> Companion:
        """Start companion index ``i`` again with the same arguments (and log folder)."""
        args = list(self.companions[i].proc.args)[4:]  # after python -m companion run
        c = Companion(args)
        c.wait_ready()
        self.companions[i] = c
        return c

    def stop(self) -> list[int]:
        """Stop the companions, then the simulator; their exit statuses."""
        codes = [c.stop(save=self.out / f"c{i + 1}.err") for i, c in enumerate(self.companions)]
        codes.append(self.sitl.stop())
        (self.out / "sitl.err").write_text("".join(self.sitl.stderr_lines))
        return codes


def last_truth_time(path: Path) -> float:
    """Simulated time of the last complete truth row (s), -1 if none."""
    try:
        with open(path, "rb") as fh:
            fh.seek(0, 2)
            size = fh.tell()
            fh.seek(max(0, size - 4096))
            lines = fh.read().decode().splitlines()
    except OSError:
        return -1.0
    for ln in reversed(lines[:-1] if lines else []):
        try:
            return float(ln.split(",")[0])
        except ValueError:
            continue
    return -1.0


def sitl_fleet_args(mission: Path, out: Path, speedup: float) -> list[str]:
    """The simulator's arguments for a test fleet: ``mission`` at ``speedup``, truth and
    events logs in ``out``, and a GUIDED timeout of 10 s (3 s is 0.15 s of wall time at
    20x: a free-running simulator on a loaded machine stalls longer than that).
    ``start_fleet`` adds ``--lockstep`` (``speedup`` is then a ceiling)."""
    return [
        "--mission",
        str(mission),
        "--speedup",
        str(speedup),
        "--truth-log",
        str(out / "truth.csv"),
        "--events-log",
        str(out / "sitl_events.jsonl"),
        "--status-interval",
        "5",
        "--param",
        "GUID_TIMEOUT=10",
    ]


def start_fleet(
    out: Path,
    mission: Path,
    *,
    profile: str = "auto",
    sitl_args: tuple[str, ...] = (),
    companion_args: tuple[str, ...] = (),
    speedup: float = SPEEDUP,
    key_file: Path | None = None,
    connect: dict[int, str] | None = None,
    lockstep: bool = True,
) -> Fleet:
    """Start six companions, then the simulator flying ``mission`` (retried if a port
    chosen free was taken meanwhile by another process). ``connect`` overrides the link URL
    of some companions (by index), e.g. to pass through a test proxy; ``lockstep`` False
    runs the simulator free against the wall clock."""
    if lockstep:
        sitl_args = ("--lockstep", *sitl_args)
    for attempt in range(3):
        try:
            return _start_fleet(
                out, mission, profile, sitl_args, companion_args, speedup, key_file, connect or {}
            )
        except RuntimeError as exc:
            if "already in use" not in str(exc) or attempt == 2:
                raise
    raise AssertionError("unreachable")


def _start_fleet(
    out, mission, profile, sitl_args, companion_args, speedup, key_file, connect
) -> Fleet:
    out.mkdir(parents=True, exist_ok=True)
    base = free_base_port(6)
    group = f"239.255.14.{np.random.randint(2, 250)}:{free_udp_port()}"
    auth = ["--key-file", str(key_file)] if key_file is not None else ["--insecure"]
    companions = []
    try:
        for i in range(6):
            companions.append(
                Companion(
                    [
                        "--connect",
                        connect.get(i, f"udpout:127.0.0.1:{base + PORT_SPACING * i}"),
                        "--mission",
                        str(mission),
                        "--profile",
                        profile,
                        "--group",
                        group,
                        "--log-dir",
                        str(out / f"c{i + 1}"),
                        "--status-interval",
                        "5",
                        # 3 s of vehicle time is 0.15 s of wall time at 20x: too tight for
                        # seven processes on two shared cores
                        "--member-timeout-s",
                        "10",
                        *auth,
                        *companion_args,
                    ]
                )
            )
        for c in companions:
            c.wait_ready()
        sitl = SitlProcess(
            *sitl_fleet_args(mission, out, speedup),
            "--base-port",
            str(base),
            *sitl_args,
            ready_timeout_s=90.0,
        )
    except BaseException:
        for c in companions:
            c.stop()
        raise
    return Fleet(out, mission, base, sitl, companions)


# ---- analysis ----------------------------------------------------------------------------
def companion_events(out: Path) -> list[dict]:
    """All companions' events, ``t_s`` converted to simulated seconds."""
    evs = []
    for path in sorted(out.glob("c*/events.jsonl")):
        for line in path.read_text().splitlines():
            ev = json.loads(line)
            if ev.get("t_s") is not None:
                ev["t_s"] = round(ev["t_s"] - SIM_EPOCH_UNIX_S, 3)
                evs.append(ev)
    return sorted(evs, key=lambda e: e["t_s"])


@dataclass
class Measures:
    """Formation measures from the truth log (arrays over common sample times)."""

    t_s: np.ndarray
    sysids: list[int]
    centres_m: np.ndarray  # (time, vehicle) complex
    phases_rad: np.ndarray  # (time, vehicle)
    pos_m: np.ndarray  # (time, vehicle) complex
    splay_deg: np.ndarray
    centre_m: np.ndarray

    def convergence_time_s(self, t_end_s: float) -> float | None:
        """First time after which splay < 2 deg and centre < 5 m hold until ``t_end_s``."""
        ok = (self.splay_deg < 2.0) & (self.centre_m < 5.0)
        sel = self.t_s <= t_end_s
        t, ok = self.t_s[sel], ok[sel]
        if not ok[-1]:
            return None
        bad = np.flatnonzero(~ok)
        return float(t[bad[-1] + 1]) if len(bad) else float(t[0])


def measures(out: Path, mission_path: Path) -> tuple[Measures, list[dict]]:
    """Truth-log measures and the companions' events of a harness run folder (the events
    merged into its ``events.jsonl``, the mission copied beside them)."""
    shutil.copy(mission_path, out / "mission.yaml")
    events = companion_events(out)
    with open(out / "events.jsonl", "w") as fh:
        for ev in events:
            fh.write(json.dumps(ev) + "\n")
    return truth_measures(out), events


def true_phases_at(out: Path, t_s: float) -> dict[int, float]:
    """Each vehicle's time-phase (rad) read from its true position (the loop point nearest
    it) at the first truth sample at or after ``t_s`` (s), by sysid."""
    run = load_run(out)
    phases = {}
    for s, tr in run.tracks.items():
        k = min(int(np.searchsorted(tr.t_s, t_s)), tr.t_s.size - 1)
        phases[s] = run.mission.patrol.nearest(complex(tr.pos_m[k])).phase_rad
    return phases


def truth_measures(out: Path) -> Measures:
    """The formation measures of a run folder's truth log (``truth.csv``, ``mission.yaml``)."""
    run = load_run(out)
    patrol = run.mission.patrol
    times = run.times_s
    sysids = sorted(run.tracks)
    pos, course = [], []
    for s in sysids:
        tr = run.tracks[s]
        idx = np.searchsorted(tr.t_s, times)
        pos.append(tr.pos_m[idx])
        course.append(tr.course_rad[idx])
    pos_a, course_a = np.array(pos).T, np.array(course).T
    c, ph = patrol.centre_and_phase_from_course(pos_a, course_a)
    splay = np.array([splay_error_deg(p) for p in ph])
    centre = np.array([centre_error_m(cc, patrol.centre_m) for cc in c])
    return Measures(times, sysids, c, ph, pos_a, splay, centre)


def episode(m: Measures, events: list[dict], mission_path: Path, alert_site: complex) -> dict:
    """The prosecution of the first alert at ``alert_site``: who, when, how well."""
    mission = load_mission(mission_path)
    patrol = mission.patrol
    sensor = mission.sensor.footprint_radius_m
    alerts = [
        e
        for e in events
        if e["event"] == "alert_new"
        and abs(complex(e["north_m"], e["east_m"]) - alert_site) < 2 * sensor
    ]
    assert alerts, "no alert for the site"
    alert_id = alerts[0]["alert_id"]
    detector = alerts[0]["detector_sysid"]
    plans = [e for e in events if e["event"] == "plan" and e["alert_id"] == alert_id]
    prosecutors = {e["sysid"] for e in plans}
    tasked = [e for e in events if e["event"] == "alert_tasked" and e["alert_id"] == alert_id]
    first_task = [e for e in tasked if e["sysid"] == e["prosecutor_sysid"]]
    plan = plans[0]
    pro = plan["sysid"]
    t_task = plan["t_s"]
    k = m.sysids.index(pro)
    # who is next in sequence from the truth at tasking (free UAVs, the detector excluded)
    i_task = int(np.searchsorted(m.t_s, t_task))
    free = {s: float(m.phases_rad[i_task, j]) for j, s in enumerate(m.sysids) if s != detector}
    expected = next_in_sequence(float(patrol.nearest(alert_site).phase_rad), free)
    # arrival: closest approach to the site after the plan
    win = (m.t_s >= t_task) & (m.t_s <= t_task + 2.0 * plan["planned_time_s"] + 10)
    d = np.abs(m.pos_m[win, k] - alert_site)
    t_arrive = float(m.t_s[win][np.argmin(d)])
    rejoins = [e for e in events if e["event"] == "rejoined" and e["sysid"] == pro]
    t_back = rejoins[0]["t_s"] if rejoins else float(m.t_s[-1])
    others = [j for j, s in enumerate(m.sysids) if s != pro]
    # the episode ends when the prosecutor is back, or when another UAV leaves for a later alert
    later = [e["t_s"] for e in events if e["event"] == "plan" and e["alert_id"] != alert_id]
    t_end = min([t_back] + [t for t in later if t > t_task])
    ep = (m.t_s >= t_task) & (m.t_s <= t_end)
    other_centre = float(np.max(np.abs(m.centres_m[ep][:, others] - patrol.centre_m)))
    # the same before the tasking, over a window as long as the episode
    before = (m.t_s >= 2 * t_task - t_end) & (m.t_s < t_task)
    other_centre_before = float(np.max(np.abs(m.centres_m[before][:, others] - patrol.centre_m)))
    # where the others really were: distance from the loop during the episode
    at = m.pos_m[ep][:, others].ravel()
    other_offset = max(patrol.nearest(complex(p)).distance_m for p in at)
    ends = [e for e in events if e["event"] == "prosecution_end" and e["alert_id"] == alert_id]
    return {
        "alert_id": alert_id,
        "detector": detector,
        "prosecutors": prosecutors,
        "tasked_by": {e["sysid"]: e["prosecutor_sysid"] for e in tasked},
        "self_tasked": [e["sysid"] for e in first_task],
        "prosecutor": pro,
        "expected": expected,
        "t_task": t_task,
        "planned_s": plan["planned_time_s"],
        "arrive_s": t_arrive - t_task,
        "miss_m": float(np.min(d)),
        "rejoined": rejoins[0] if rejoins else None,
        "rejoin_s": (t_back - ends[0]["t_s"]) if rejoins and ends else None,
        "outcome": ends[0]["outcome"] if ends else None,
        "others_max_centre_m": other_centre,
        "others_max_centre_before_m": other_centre_before,
        "others_max_offset_m": float(other_offset),
        "episode_end_s": t_end,
    }


def report(name: str, data: dict) -> None:
    """Print figures for the test log (pytest -s shows them)."""
    print(f"\n[{name}] " + json.dumps(data, default=str))


def final_status(c: Companion) -> str:
    """The companion's final status line."""
    lines = [ln for ln in c.lines if ln.startswith("companion final")]
    assert lines, "".join(c.lines)
    return lines[-1]


def status_field(line: str, name: str) -> str:
    """``name=value`` from a status line."""
    for part in line.split():
        if part.startswith(name + "="):
            return part.split("=", 1)[1]
    raise KeyError(name)


def companion_cli(*args: str, timeout_s: float = 30.0) -> subprocess.CompletedProcess:
    """Run ``python -m companion ARGS`` to completion, in the environment a user's shell has:
    without the ``MAVLINK20`` that importing the simulator sets in this process (with it,
    a signed upload that chose MAVLink 1 passed here and failed for every user)."""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    env.pop("MAVLINK20", None)
    return subprocess.run(
        [sys.executable, "-m", "companion", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )


def group_listener(group: str) -> socket.socket:
    """A socket joined to the test group on loopback (to capture the operator's datagrams)."""
    addr, port = group.rsplit(":", 1)
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    s.bind((addr, int(port)))
    s.setsockopt(
        socket.IPPROTO_IP,
        socket.IP_ADD_MEMBERSHIP,
        socket.inet_aton(addr) + socket.inet_aton("127.0.0.1"),
    )
    s.setblocking(False)
    return s


def plans_for(out: Path, alert_id: str) -> list[dict]:
    """The companions' plan events for ``alert_id``."""
    return [
        e for e in companion_events(out) if e["event"] == "plan" and e.get("alert_id") == alert_id
    ]


def quiet_mission(folder: Path, duration_s: float = 500.0, source: Path = FAST) -> Path:
    """``source`` (default the fast test mission) without intruders, lasting ``duration_s``
    (simulated s), written into ``folder``."""
    text = source.read_text().split("scenario:")[0] + f"scenario:\n  duration_s: {duration_s}\n"
    path = folder / f"{source.stem}_quiet.yaml"
    path.write_text(text)
    return path
