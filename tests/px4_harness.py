"""PX4 SITL (fixed-wing SIH) for the integration tests and the profile measurements.

One real PX4 process per instance (``/work/shared/px4/README.md``): found as ``$PX4_SITL_DIR``
or ``../shared/px4`` next to the repository, started in its own working directory with the
speed factor and parameters given, taken off into AUTO.LOITER over its ground-station port
(``udpout:127.0.0.1:18570+i``), then flown by a real ``companion run`` over the offboard
port (``udpout:127.0.0.1:14580+i``). Everything here is plumbing on wall-clock deadlines;
every process is stopped by its pid (SIGINT, then wait) and only this instance's
``/tmp/px4_lock-<i>`` / ``/tmp/px4-sock-<i>`` are removed.

Measured on the 2-core machine (2026-12, shared with other jobs): see ``docs/px4.md``.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

REPO = Path(__file__).resolve().parents[1]
ENV_VAR = "PX4_SITL_DIR"
AUTO_LOITER = (4 << 16) | (3 << 24)  # 50593792
OFFBOARD = 6 << 16  # 393216
COMPANION_COMPID = 191
# the stock SIH airplane cruises at 12 m/s; with these it loiters at 18-20 m/s (README)
FAST_AIRFRAME = {
    "SIH_T_MAX": "15",
    "FW_AIRSPD_TRIM": "20",
    "FW_AIRSPD_MAX": "25",
    "FW_AIRSPD_MIN": "12",
}


def bin_dir(base: Path, scratch: Path) -> Path:
    """A ``bin`` folder whose ``px4-<command>`` are links to ``px4`` (the start script calls
    them): ``base/bin`` itself when its links are intact, else one made in ``scratch`` (a copy
    that lost its links holds 3-byte text files instead; the shared folder is read-only)."""
    src = base / "bin"
    probe = src / "px4-param"
    if probe.is_symlink() or (probe.is_file() and probe.stat().st_size > 1000):
        return src
    out = scratch / "px4-bin"
    out.mkdir(parents=True, exist_ok=True)
    alias = (src / "px4-alias.sh").read_text()
    names = {
        line.split("=")[0].split()[1] for line in alias.splitlines() if line.startswith("alias ")
    }
    links = [("px4", src / "px4"), ("px4-alias.sh", src / "px4-alias.sh")]
    for link, target in [*links, *((f"px4-{n}", Path("px4")) for n in names)]:
        if not (out / link).is_symlink():
            (out / link).symlink_to(target)
    return out


def px4_dir() -> Path | None:
    """The PX4 SITL folder (``bin/px4``, ``etc``), or None where there is none."""
    env = os.environ.get(ENV_VAR)
    d = Path(env) if env else REPO.parent / "shared" / "px4"
    return d if (d / "bin" / "px4").is_file() else None


@dataclass
class Px4Instance:
    """One PX4 SIH process: instance ``i`` (MAV_SYS_ID i+1, ports + i).

    Attributes:
        i: the instance number (5 and up here: never the other engineers').
        workdir: its working directory (``etc`` linked, parameters, dataman).
        speed: PX4_SIM_SPEED_FACTOR (simulated seconds per wall second).
        params: PX4 parameters set at start (``PX4_PARAM_<name>``).
        home: (lat deg, lon deg, alt m AMSL) of the start point.
    """

    i: int
    workdir: Path
    speed: float = 1.0
    params: dict[str, str] = field(default_factory=dict)
    home: tuple[float, float, float] = (39.8, -84.0, 250.0)
    proc: subprocess.Popen | None = None
    log_path: Path | None = None

    @property
    def sysid(self) -> int:
        """MAV_SYS_ID of the instance."""
        return self.i + 1

    @property
    def offboard_port(self) -> int:
        """The companion ("onboard") link's UDP port PX4 listens on."""
        return 14580 + self.i

    @property
    def gcs_port(self) -> int:
        """The ground-station link's UDP port PX4 listens on."""
        return 18570 + self.i

    def start(self) -> None:
        """Start the process (refuses if this instance's lock exists: someone runs it)."""
        base = px4_dir()
        if base is None:
            raise RuntimeError("no PX4 SITL (set $PX4_SITL_DIR)")
        if Path(f"/tmp/px4_lock-{self.i}").exists():
            raise RuntimeError(f"/tmp/px4_lock-{self.i} exists: instance {self.i} is in use")
        self.workdir.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ)
        env.update(
            PX4_SYS_AUTOSTART="10041",
            PX4_HOME_LAT=str(self.home[0]),
            PX4_HOME_LON=str(self.home[1]),
            PX4_HOME_ALT=str(self.home[2]),
            PX4_SIM_SPEED_FACTOR=f"{self.speed:g}",
            PX4_PARAM_SDLOG_MODE="-1",
        )
        env.update({f"PX4_PARAM_{k}": v for k, v in self.params.items()})
        self.log_path = self.workdir / "px4.log"
        log = open(self.log_path, "w")  # noqa: SIM115 (closed with the process)
        exe = bin_dir(base, self.workdir.parent) / "px4"
        self.proc = subprocess.Popen(
            [str(exe), "-i", str(self.i), "-d", str(base / "etc")],
            cwd=self.workdir,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
        log.close()

    def stop(self, timeout_s: float = 15.0) -> int | None:
        """SIGINT by pid, wait (SIGKILL after ``timeout_s``); remove this instance's lock
        and socket. Returns the exit status (None if it never started)."""
        rc = None
        if self.proc is not None:
            if self.proc.poll() is None:
                self.proc.send_signal(signal.SIGINT)
                try:
                    self.proc.wait(timeout_s)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait(5)
            rc = self.proc.returncode
            self.proc = None
            for p in (f"/tmp/px4_lock-{self.i}", f"/tmp/px4-sock-{self.i}"):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(p)
        return rc


class Gcs:
    """A minimal ground station on the instance's GCS port (take-off only)."""

    def __init__(self, inst: Px4Instance) -> None:
        """Connect (udpout: PX4 answers the first address that sends to it)."""
        self.inst = inst
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{inst.gcs_port}", source_system=255, source_component=190
        )
        self.mode: int | None = None
        self.armed = False
        self.boot_ms = 0
        self.rel_alt_m: float | None = None
        self.home = False
        self.airspeed_m_s: float | None = None
        self._last_hb = 0.0

    def close(self) -> None:
        """Close the socket."""
        self.conn.close()

    def pump(self, duration_s: float = 0.05) -> None:
        """Receive for ``duration_s`` (wall), heartbeating at 1 Hz."""
        end = time.monotonic() + duration_s
        while True:
            now = time.monotonic()
            if now - self._last_hb >= 1.0:
                self._last_hb = now
                self.conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            m = self.conn.recv_match(blocking=True, timeout=max(0.0, min(0.05, end - now)))
            if m is not None:
                self._note(m)
            if time.monotonic() >= end:
                return

    def _note(self, m) -> None:
        if m.get_srcSystem() != self.inst.sysid:
            return
        t = m.get_type()
        if t == "HEARTBEAT" and m.get_srcComponent() == 1:
            self.mode = int(m.custom_mode)
            self.armed = bool(m.base_mode & 128)
        elif t == "GLOBAL_POSITION_INT":
            self.boot_ms = int(m.time_boot_ms)
            self.rel_alt_m = m.relative_alt * 1e-3
        elif t == "HOME_POSITION":
            self.home = True
        elif t == "VFR_HUD":
            self.airspeed_m_s = float(m.airspeed)

    def command(self, command: int, *params: float) -> None:
        """COMMAND_LONG to the autopilot."""
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.conn.mav.command_long_send(self.inst.sysid, 1, command, 0, *p)

    def wait(self, cond, timeout_s: float, what: str) -> None:
        """Pump until ``cond()`` (wall ``timeout_s``; RuntimeError naming ``what``)."""
        end = time.monotonic() + timeout_s
        while not cond():
            if time.monotonic() > end:
                raise RuntimeError(f"PX4 instance {self.inst.i}: timed out waiting for {what}")
            if self.inst.proc is not None and self.inst.proc.poll() is not None:
                raise RuntimeError(f"PX4 instance {self.inst.i} exited ({self.inst.log_path})")
            self.pump(0.1)

    def level_setpoint(self) -> None:
        """SET_ATTITUDE_TARGET level, thrust 0 (type_mask 0x07)."""
        self.conn.mav.set_attitude_target_send(
            self.boot_ms, self.inst.sysid, 1, 0x07, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 0.0
        )

    def take_off(self, min_rel_alt_m: float, timeout_s: float = 180.0) -> float:
        """Take off into AUTO.LOITER as the README says; returns the wall seconds it took.

        Home (the EKF origin) and 20 s of vehicle time; OFFBOARD on the ground for 3 s of
        vehicle time with a level setpoint stream (TECS re-initialises); AUTO.TAKEOFF and arm;
        then wait for AUTO.LOITER above ``min_rel_alt_m`` (m above home).
        """
        t0 = time.monotonic()
        self.wait(lambda: self.home and self.boot_ms > 0, timeout_s, "HOME_POSITION")
        ready_ms = self.boot_ms + 20_000
        self.wait(lambda: self.boot_ms >= ready_ms, timeout_s, "20 s after home")
        start_ms, asked = self.boot_ms, False
        while self.boot_ms < start_ms + 4_000 or self.mode != OFFBOARD:
            self.level_setpoint()
            self.pump(0.05)
            if not asked and self.boot_ms >= start_ms + 1_000:
                self.command(176, 1, 6)
                asked = True
                start_ms = self.boot_ms
            if self.boot_ms > start_ms + 15_000 or time.monotonic() - t0 > timeout_s:
                raise RuntimeError("PX4 did not enter OFFBOARD on the ground")
        self.command(176, 1, 4, 2)  # AUTO.TAKEOFF
        self.pump(0.3)
        self.command(400, 1)  # arm
        self.wait(
            lambda: (
                self.mode == AUTO_LOITER
                and self.rel_alt_m is not None
                and self.rel_alt_m >= min_rel_alt_m
            ),
            timeout_s - (time.monotonic() - t0),
            f"AUTO.LOITER above {min_rel_alt_m:.0f} m",
        )
        return time.monotonic() - t0


def start_companion(
    inst: Px4Instance,
    mission: Path,
    log_dir: Path,
    *extra: str,
    group_port: int = 14900,
) -> subprocess.Popen:
    """``companion run`` against the instance's offboard port with --take-control (its own
    multicast port, unsigned: a test bench); stderr to ``log_dir/companion.err``."""
    log_dir.mkdir(parents=True, exist_ok=True)
    err = open(log_dir / "companion.err", "w")  # noqa: SIM115 (closed with the process)
    proc = subprocess.Popen(
        [
            sys.executable, "-m", "companion", "run",
            "--connect", f"udpout:127.0.0.1:{inst.offboard_port}",
            "--mission", str(mission), "--take-control", "--insecure",
            "--group", f"239.255.14.1:{group_port}", "--log-dir", str(log_dir),
            "--status-interval", "5", *extra,
        ],
        cwd=REPO,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=err,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )  # fmt: skip
    err.close()
    return proc


def stop_process(proc: subprocess.Popen, timeout_s: float = 15.0) -> int:
    """SIGINT by pid, wait; SIGKILL if it does not end. Returns the exit status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
    return int(proc.returncode)


def read_events(log_dir: Path) -> list[dict]:
    """The companion's events.jsonl."""
    import json

    path = log_dir / "events.jsonl"
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


@dataclass(frozen=True)
class Flown:
    """What the aircraft flew while the companion commanded, from the companion's tlog.

    Attributes:
        t_s: vehicle time of each GLOBAL_POSITION_INT (s from the first).
        pos_m: north + i east from the mission origin (m).
        alt_m: altitude above the mission origin (m).
        airspeed_m_s: VFR_HUD airspeed at each position (m/s, last heard).
        setpoints: setpoints sent over the whole run.
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    alt_m: np.ndarray
    airspeed_m_s: np.ndarray
    setpoints: int


def flown_from_tlog(tlog: Path, origin: tuple[float, float, float], sysid: int) -> Flown:
    """Positions, altitudes and airspeeds of our autopilot while in OFFBOARD (tlog order)."""
    import pymap3d

    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    mode = None
    airspeed = math.nan
    ts, pos, alt, air = [], [], [], []
    sent = 0
    while True:
        m = conn.recv_match()
        if m is None:
            break
        t = m.get_type()
        if m.get_srcComponent() == COMPANION_COMPID:
            sent += t in ("SET_ATTITUDE_TARGET", "SET_POSITION_TARGET_GLOBAL_INT")
            continue
        if m.get_srcSystem() != sysid or m.get_srcComponent() != 1:
            continue
        if t == "HEARTBEAT":
            mode = int(m.custom_mode)
        elif t == "VFR_HUD":
            airspeed = float(m.airspeed)
        elif t == "GLOBAL_POSITION_INT" and mode == OFFBOARD:
            n, e, d = pymap3d.geodetic2ned(m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3, *origin)
            ts.append(m.time_boot_ms * 1e-3)
            pos.append(complex(n, e))
            alt.append(-d)
            air.append(airspeed)
    conn.close()
    t = np.asarray(ts)
    return Flown(
        t - (t[0] if len(t) else 0.0), np.asarray(pos), np.asarray(alt), np.asarray(air), sent
    )


def ellipse_cross_track_m(pos_m: np.ndarray, mission) -> np.ndarray:
    """Distance (m) of each position (complex, local) from the mission's ellipse (a polyline
    of 20,000 vertices: under 1 cm of chord error)."""
    e = mission.perimeter.shape
    th = np.linspace(0.0, 2.0 * np.pi, 20_000, endpoint=False)
    rot = np.exp(1j * np.radians(e.major_axis_bearing_deg))
    centre = complex(e.centre_north_m, e.centre_east_m)
    loop = centre + rot * (e.semi_major_m * np.cos(th) + 1j * e.semi_minor_m * np.sin(th))
    out = np.empty(len(pos_m))
    for k in range(0, len(pos_m), 256):
        chunk = pos_m[k : k + 256]
        out[k : k + 256] = np.abs(chunk[:, None] - loop[None, :]).min(axis=1)
    return out


def summary(flown: Flown, mission, settle_s: float) -> dict[str, float]:
    """Cross-track, airspeed and altitude errors after ``settle_s`` of OFFBOARD (s)."""
    keep = flown.t_s >= settle_s
    xt = ellipse_cross_track_m(flown.pos_m[keep], mission)
    air = flown.airspeed_m_s[keep] - mission.vehicles.airspeed_m_s
    alt = flown.alt_m[keep] - mission.vehicles.altitudes_m[0]
    air = air[np.isfinite(air)]
    return {
        "window_s": float(flown.t_s[-1] - settle_s) if len(flown.t_s) else 0.0,
        "xt_median_m": float(np.median(xt)),
        "xt_p95_m": float(np.percentile(xt, 95)),
        "xt_max_m": float(xt.max()),
        "airspeed_err_mean_m_s": float(air.mean()),
        "airspeed_err_p95_abs_m_s": float(np.percentile(np.abs(air), 95)),
        "alt_err_mean_m": float(alt.mean()),
        "alt_err_p95_abs_m": float(np.percentile(np.abs(alt), 95)),
    }
