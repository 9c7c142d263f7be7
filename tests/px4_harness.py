"""PX4 SITL (fixed-wing SIH) for the integration tests and the profile measurements.

One real PX4 process per instance (docs/px4.md), started and taken off by the product's own
code (:mod:`companion.sim.px4.sitl` and :mod:`~companion.sim.px4.bringup`, which ``companion
fleet --autopilot px4`` uses): found as
``$PX4_SITL_DIR`` (``tests/conftest.py`` sets it to ``../shared/px4`` beside the clone where
that exists, :mod:`tests.firmware_env`), started in
its own working directory with the speed factor and parameters given, taken off into
AUTO.LOITER over its ground-station port (``udpout:127.0.0.1:18570+i``), then flown by a real
``companion run`` over the offboard port (``udpout:127.0.0.1:14580+i``). Everything here is
plumbing on wall-clock deadlines; every process is stopped by its pid (SIGINT, then wait) and
only this instance's
``/tmp/px4_lock-<i>`` / ``/tmp/px4-sock-<i>`` are removed.

Measured on the 2-core machine (2026-12, shared with other jobs): see ``docs/px4.md``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from companion.contracts.errors import UserError
from companion.link.px4 import OFFBOARD_CUSTOM_MODE
from companion.sim.px4 import bringup, sitl

REPO = Path(__file__).resolve().parents[1]
ENV_VAR = sitl.ENV_VAR
AUTO_LOITER = bringup.AUTO_LOITER  # 50593792
OFFBOARD = OFFBOARD_CUSTOM_MODE  # 393216
# the stock SIH airplane cruises at 12 m/s; with these it loiters at 18-20 m/s (README)
FAST_AIRFRAME = {
    "SIH_T_MAX": "15",
    "FW_AIRSPD_TRIM": "20",
    "FW_AIRSPD_MAX": "25",
    "FW_AIRSPD_MIN": "12",
}


def px4_dir() -> Path | None:
    """The PX4 SITL folder (``bin/px4``, ``etc``) as the product finds it
    (:func:`companion.sim.px4.sitl.find_px4_dir`), or None where there is none."""
    try:
        return sitl.find_px4_dir(None)
    except UserError:
        return None


def px4_missing() -> str | None:
    """Why the product finds no PX4 SITL folder here (its own message, for a skip's reason),
    None where it finds one."""
    try:
        sitl.find_px4_dir(None)
    except UserError as exc:
        return str(exc)
    return None


class Px4Instance(sitl.Px4Instance):
    """The product's PX4 instance with the tests' defaults: MAV_SYS_ID i+1 (the start
    script's), no ULog, the folder from :func:`px4_dir`.

    Args:
        i: the instance number (5 and up here: never the fleet's lowest free ones).
        workdir: its working directory.
        speed: PX4_SIM_SPEED_FACTOR.
        params: PX4 parameters set at start.
        home: (lat deg, lon deg, alt m AMSL) of the start point.
    """

    def __init__(
        self,
        i: int,
        workdir: Path,
        speed: float = 1.0,
        params: dict[str, str] | None = None,
        home: tuple[float, float, float] = (39.8, -84.0, 250.0),
    ) -> None:
        """Nothing is started yet."""
        super().__init__(i, i + 1, workdir, speed, {"SDLOG_MODE": "-1", **(params or {})}, home)

    @property
    def offboard_port(self) -> int:
        """The companion ("onboard") link's UDP port PX4 listens on."""
        return self.ports["offboard"]

    @property
    def gcs_port(self) -> int:
        """The ground-station link's UDP port PX4 listens on."""
        return self.ports["gcs"]

    def start(self) -> None:  # type: ignore[override]
        """Start the process (RuntimeError without PX4; UserError if the instance is busy)."""
        base = px4_dir()
        if base is None:
            raise RuntimeError(f"no PX4 SITL (set ${ENV_VAR})")
        super().start(base)


class Gcs:
    """A ground station on the instance's GCS port: the product's take-off
    (:class:`companion.sim.px4.bringup.Bringup`, no upload), then its link state."""

    def __init__(self, inst: Px4Instance) -> None:
        """Connect (udpout: PX4 answers the first address that sends to it)."""
        self.inst = inst
        self.bringup = bringup.Bringup([inst], [0.0], inst.speed, lambda *_: (True, "no upload"))
        self.bringup.connect()
        self._v = self.bringup.v[0]
        self.conn = self._v.conn

    @property
    def mode(self) -> int | None:
        """The latest HEARTBEAT's custom_mode."""
        return self._v.mode

    @property
    def boot_ms(self) -> int:
        """The latest GLOBAL_POSITION_INT's time_boot_ms."""
        return self._v.boot_ms

    def close(self) -> None:
        """Close the socket."""
        self.bringup.close()

    def pump(self, duration_s: float = 0.05) -> None:
        """Receive for ``duration_s`` (wall), heartbeating at 1 Hz."""
        end = time.monotonic() + duration_s
        while True:
            self.bringup.pump()
            if time.monotonic() >= end:
                return
            time.sleep(min(0.02, max(0.0, end - time.monotonic())))

    def take_off(self, min_rel_alt_m: float, timeout_s: float = 180.0) -> float:
        """Take off into AUTO.LOITER as the README says (the fleet's bring-up); returns the
        wall seconds it took. ``min_rel_alt_m``: m above home, reached at
        ``bringup.CLIMB_FRACTION`` of it; ``timeout_s`` is the product's (vehicle time) now."""
        t0 = time.monotonic()
        self.bringup.altitudes_m = [min_rel_alt_m / bringup.CLIMB_FRACTION]
        try:
            self.bringup.run()
        except UserError as exc:
            raise RuntimeError(str(exc)) from None
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
    """SIGINT by pid, wait; SIGKILL if it does not end (the product's
    :func:`companion.sim.px4.sitl.stop_px4`). Returns the exit status."""
    return sitl.stop_px4(proc, timeout_s)


def read_events(log_dir: Path) -> list[dict]:
    """The companion's events.jsonl."""
    import json

    path = log_dir / "events.jsonl"
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
