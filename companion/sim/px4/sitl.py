"""PX4 SITL instances (fixed-wing SIH) for a mission: the folder, the instances, their ports.

One ``px4`` process per vehicle (the folder: :func:`find_px4_dir`, docs/px4.md), each in its
own working directory under the run folder (it links ``etc`` there and writes
``parameters.bson`` and ``dataman``; no ULog: ``SDLOG_MODE`` -1), with airframe 10041
(``sihsim_airplane``), home at the mission origin, ``PX4_SIM_SPEED_FACTOR`` = the fleet's
speed-up and the mission's parameters (:func:`mission_params`) set at every start through
``PX4_PARAM_<name>``.

Instance ``i`` (0..9: above 9 PX4 sends every offboard link to the one port 14549) binds UDP
ports (:func:`instance_ports`): the ground-station link 18570+i (the fleet's bring-up), the
companion's ("onboard") link 14580+i, the camera's 14280+i (the world process,
:mod:`companion.sim.px4.world`), the gimbal's 13030+i and the SIH display's 19450+i, and the
files ``/tmp/px4_lock-i`` and ``/tmp/px4-sock-i``. Each port answers one partner for the life
of the process (the first address that sent to it). An instance number whose lock exists or
whose ports are taken is never used.

The mission's parameters for each instance are :mod:`companion.sim.px4.params`; taking the
instances off is :mod:`companion.sim.px4.bringup`.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from companion.contracts.errors import UserError
from companion.process import with_parent

ENV_VAR = "PX4_SITL_DIR"
BUILD_HINT = (
    "build PX4 for SITL with its fixed-wing SIH as docs/px4.md says (PX4-Autopilot, "
    "cmake -DCONFIG=px4_sitl_fwsih, then copy build/px4_sitl_fwsih/bin and etc), then pass "
    f"--px4-dir DIR or set ${ENV_VAR}"
)
AIRFRAME = "10041"  # sihsim_airplane
MAX_INSTANCE = 9  # above 9 every instance's offboard link sends to port 14549


def find_px4_dir(
    explicit: str | os.PathLike[str] | None, env: Mapping[str, str] = os.environ
) -> Path:
    """The PX4 SITL folder (``bin/px4``, ``etc``): ``explicit`` (``--px4-dir``), else
    ``$PX4_SITL_DIR``. :class:`UserError` (one line, what to set and how to get one) when
    neither is given, or when the chosen folder has no executable ``bin/px4`` or no ``etc``."""
    if explicit is not None:
        d, where = Path(explicit), "--px4-dir"
    elif env.get(ENV_VAR):
        d, where = Path(env[ENV_VAR]), f"${ENV_VAR}"
    else:
        raise UserError(
            f"no PX4 SITL folder given: pass --px4-dir DIR or set ${ENV_VAR} to a folder with "
            "bin/px4 and etc/init.d-posix/rcS (how to build one: docs/px4.md)"
        )
    exe = d / "bin" / "px4"
    if not d.is_dir():
        raise UserError(f"no PX4 SITL folder at {d} ({where}): {BUILD_HINT}")
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        raise UserError(f"no executable PX4 SITL binary {exe} ({where}): {BUILD_HINT}")
    if not (d / "etc" / "init.d-posix" / "rcS").is_file():
        raise UserError(f"{d} ({where}) has bin/px4 but no etc/init.d-posix/rcS: {BUILD_HINT}")
    return d


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


def instance_ports(i: int) -> dict[str, int]:
    """The UDP ports instance ``i`` binds, by link name."""
    return {
        "gcs": 18570 + i,
        "offboard": 14580 + i,
        "camera": 14280 + i,
        "gimbal": 13030 + i,
        "sih_display": 19450 + i,
    }


def lock_files(i: int) -> tuple[Path, Path]:
    """Instance ``i``'s lock and socket files."""
    return Path(f"/tmp/px4_lock-{i}"), Path(f"/tmp/px4-sock-{i}")


def udp_port_in_use(port: int) -> bool:
    """Whether UDP ``port`` on 127.0.0.1 is bound by someone now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return True
    return False


def instance_busy(i: int) -> str | None:
    """Why instance number ``i`` cannot be used now (its lock, a port taken), or None."""
    lock, _ = lock_files(i)
    if lock.exists():
        return f"{lock} exists (another PX4 instance {i} runs)"
    for name, port in instance_ports(i).items():
        if udp_port_in_use(port):
            return f"UDP port {port} (instance {i}'s {name} link) is in use"
    return None


def pick_instances(count: int, wanted: list[int] | None = None) -> list[int]:
    """``count`` PX4 instance numbers free now: ``wanted`` (each checked: :class:`UserError`
    naming the lock or port in use), else the lowest free ones in 0..MAX_INSTANCE."""
    if wanted is not None:
        if len(wanted) != count or len(set(wanted)) != count:
            raise UserError(f"{count} distinct PX4 instance numbers needed, got {wanted}")
        for i in wanted:
            if not 0 <= i <= MAX_INSTANCE:
                raise UserError(f"PX4 instance {i}: expected 0..{MAX_INSTANCE}")
            why = instance_busy(i)
            if why is not None:
                raise UserError(f"PX4 instance {i} cannot start: {why}")
        return list(wanted)
    free = [i for i in range(MAX_INSTANCE + 1) if instance_busy(i) is None]
    if len(free) < count:
        raise UserError(
            f"{count} PX4 instances needed but only {len(free)} of 0..{MAX_INSTANCE} are free "
            "(their /tmp/px4_lock-N or UDP ports are taken by other PX4 runs)"
        )
    return free[:count]


@dataclass
class Px4Instance:
    """One PX4 SIH process: instance number ``i`` (ports + i), system id ``sysid``.

    Attributes:
        i: the instance number (0..9).
        sysid: MAV_SYS_ID.
        workdir: its working directory.
        speed: PX4_SIM_SPEED_FACTOR (simulated seconds per wall second).
        params: PX4 parameters set at every start (``PX4_PARAM_<name>``).
        home: (lat deg, lon deg, alt m AMSL) of the start point, on the ground.
    """

    i: int
    sysid: int
    workdir: Path
    speed: float = 1.0
    params: dict[str, float | str] = field(default_factory=dict)
    home: tuple[float, float, float] = (39.8, -84.0, 250.0)
    proc: subprocess.Popen | None = None
    log_path: Path | None = None

    @property
    def ports(self) -> dict[str, int]:
        """The UDP ports it binds (:func:`instance_ports`)."""
        return instance_ports(self.i)

    def env(self, base_env: Mapping[str, str] = os.environ) -> dict[str, str]:
        """The process environment: airframe, home, speed factor, parameters."""
        env = dict(base_env)
        env.update(
            PX4_SYS_AUTOSTART=AIRFRAME,
            PX4_HOME_LAT=f"{self.home[0]:.7f}",
            PX4_HOME_LON=f"{self.home[1]:.7f}",
            PX4_HOME_ALT=f"{self.home[2]:.2f}",
            PX4_SIM_SPEED_FACTOR=f"{self.speed:g}",
        )
        env.update({f"PX4_PARAM_{k}": f"{v:g}" if isinstance(v, float) else str(v)
                    for k, v in self.params.items()})  # fmt: skip
        return env

    def start(self, px4_dir: Path, log_path: Path | None = None) -> subprocess.Popen:
        """Start the process in its own session (refused, :class:`UserError`, if its lock or
        a port is taken); stdout and stderr to ``log_path`` (default ``workdir/px4.log``)."""
        why = instance_busy(self.i)
        if why is not None:
            raise UserError(f"PX4 instance {self.i} cannot start: {why}")
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.log_path = log_path or self.workdir / "px4.log"
        exe = bin_dir(px4_dir, self.workdir.parent) / "px4"
        with open(self.log_path, "w") as log:
            self.proc = subprocess.Popen(  # ends with its starter, even killed
                with_parent.guarded([str(exe), "-i", str(self.i), "-d", str(px4_dir / "etc")]),
                cwd=self.workdir,
                env=self.env(),
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        return self.proc

    def stop(self, timeout_s: float = 15.0) -> int | None:
        """SIGCONT (in case it was paused), SIGINT by pid, wait (SIGKILL after ``timeout_s``);
        remove this instance's lock and socket. The exit status (None if never started)."""
        rc = None
        if self.proc is not None:
            rc = stop_px4(self.proc, timeout_s)
            self.proc = None
            remove_lock_files(self.i)
        return rc


def stop_px4(proc: subprocess.Popen, timeout_s: float = 15.0) -> int:
    """Stop one PX4 process by its pid: SIGCONT (the world process may have paused it), SIGINT
    (PX4 stops cleanly, exit 0), SIGKILL if it has not ended after ``timeout_s`` (wall s)."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGCONT)
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
    return int(proc.returncode)


def remove_lock_files(i: int) -> None:
    """Remove instance ``i``'s lock and socket files (only after its process ended)."""
    for p in lock_files(i):
        with contextlib.suppress(FileNotFoundError):
            os.unlink(p)
