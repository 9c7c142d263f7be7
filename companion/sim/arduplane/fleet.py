"""``companion fleet MISSION --autopilot arduplane``: the mission flown by real ArduPlane SITL.

:class:`ArduPlaneFleet` is the :class:`companion.sim.fleet.Fleet` run with one ArduPlane SITL
process per vehicle in place of ``sitl-model``:

1. every instance starts in ``uavN/arduplane/`` (``--wipe``, ``--sysid``, home at the
   vehicle's initial pose in the mission, on the ground, ``--speedup``, ``--start-time`` =
   the fleet epoch) on free TCP ports (:mod:`companion.sim.arduplane.sitl`);
2. over each instance's SERIAL0 the fleet sets the mission's parameters (wind, airspeed,
   roll limit, take-off altitude, GUIDED_TIMEOUT), uploads the perimeter with ``companion
   upload``'s code, arms in TAKEOFF and waits for the climb to the vehicle's altitude;
3. the world process (:mod:`companion.sim.arduplane.world`) on each SERIAL2 plays the intruder
   scenario as each aircraft's camera and logs the telemetry-derived ``truth.csv``;
4. one ``companion run --take-control`` per vehicle on its SERIAL1 (``tcp:``), as with our
   simulator, or with ``companion_link`` ``serial`` on a serial cable: ``socat`` between
   SERIAL1 and a pseudo-terminal at ``uavN/serial1`` (:mod:`companion.sim.firmware.serial_relay`),
   which the tests and the bench pull, plug, cut and mend (:meth:`ArduPlaneFleet.pull_cable`
   ...); the run ends when the world process reaches the duration.

Every process is started in its own session and stopped by the fleet (the instances with
SIGTERM to their process group, then SIGKILL), whatever happens. The clock figures of the
world process and the truth source go to ``run_info.json``, which the report merges into
``metrics.json``.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import time
from typing import Any

from companion.contracts.errors import UserError
from companion.contracts.simulator import PORT_SPACING, SIM_EPOCH_UNIX_S
from companion.link.mission_protocol.transfer import upload_and_verify
from companion.mission import Mission
from companion.mission.perimeter_files import loop_points
from companion.sim.arduplane.bringup import Bringup
from companion.sim.arduplane.sitl import (
    check_ports,
    find_binary,
    free_base,
    instance_argv,
    instance_specs,
    landing_items,
    mission_params,
)
from companion.sim.firmware.serial_relay import find_socat, relay_argv, serial_url, wait_for_link
from companion.sim.fleet import SETUP_TIMEOUT_S, Fleet, FleetConfig

DEFAULT_SPEEDUP = 5.0  # three instances and their companions keep it on two busy cores

STALL_WALL_S = 60.0  # wall s without a new truth row while running = a stalled instance
UPLOAD_POINTS = 16  # as ``companion upload``'s default


def parse_param(text: str) -> str:
    """Check one ``--sim-param NAME=VALUE`` for ArduPlane (the name is checked by the
    instance: a parameter it does not have is never read back)."""
    name, sep, value = text.partition("=")
    name = name.strip()
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    ok = sep and name and len(name) <= 16 and name.replace("_", "").isalnum()
    if not ok or not math.isfinite(number):
        raise UserError(f"--sim-param {text!r}: expected NAME=VALUE (an ArduPlane parameter)")
    return f"{name.upper()}={number:g}"


def battery_pct(mission: Mission, used_mah: tuple[tuple[int, float], ...]) -> dict[int, float]:
    """``--battery-used SYSID=MAH`` as the charge (%) each such battery starts with on
    ArduPlane (its monitor counts the mission's capacity, ``BATT_CAPACITY``).

    Raises:
        UserError: a used battery with no battery section in the mission.
    """
    b = mission.vehicles.battery
    if used_mah and b is None:
        raise UserError("--battery-used: the mission has no battery section (vehicles.battery)")
    own = {sp.sysid: sp.battery for sp in mission.vehicles.spares if sp.battery is not None}
    out = {}
    for sysid, mah in used_mah:
        cap = own.get(sysid, b).capacity_mah
        out[sysid] = max(0.0, min(100.0, 100.0 * (1.0 - mah / cap)))
    return out


class ArduPlaneFleet(Fleet):
    """A fleet run on ArduPlane SITL instances (see the module docstring).

    Args:
        cfg: the fleet options (``lockstep`` and ``sim_params`` do not apply).
        mission: the mission.
        binary: ``--arduplane-bin`` (None: ``$ARDUPLANE_SITL``).
        base_port: first TCP port (None: a free range); 10 ports per instance.
        say: where set-up lines go.
    """

    def __init__(
        self,
        cfg: FleetConfig,
        mission: Mission,
        binary: str | None = None,
        base_port: int | None = None,
        say=print,
    ) -> None:
        """Check the binary and the ports (UserError: nothing started); nothing runs yet."""
        self.binary = find_binary(binary)
        n = len(mission.vehicles.all_sysids)
        if base_port is not None:
            check_ports(base_port, n)
        self.ap_base = base_port if base_port is not None else free_base(n)
        super().__init__(cfg, mission)
        self.say = say
        self.instances: list[Any] = []
        self.bringup: Bringup | None = None
        self.specs = instance_specs(mission, self.ap_base, cfg.out)
        self._truth_size, self._truth_grew = -1, time.monotonic()
        self.socat = find_socat() if cfg.companion_link == "serial" else None

    def start(self) -> None:
        """Instances, take-off, world process, companions (raises UserError on failure)."""
        cfg, m = self.cfg, self.mission
        started = []
        for spec in self.specs:
            spec.workdir.mkdir(parents=True, exist_ok=True)
            log_name = f"uav{spec.sysid}/arduplane.log"
            proc = self._spawn(
                f"arduplane {spec.sysid}",
                instance_argv(self.binary, spec, cfg.speedup, SIM_EPOCH_UNIX_S),
                log_name,
                cwd=spec.workdir,
            )
            self.instances.append(proc)
            started.append((spec, proc.popen, cfg.out / log_name))
        last_port = self.ap_base + PORT_SPACING * len(started) - 7
        self.say(
            f"fleet: {len(started)} ArduPlane SITL instances ({self.binary}) at "
            f"{cfg.speedup:g}x on TCP ports {self.ap_base}..{last_port}"
        )

        landings = landing_items(m)  # every vehicle may land at any spare base

        def upload(conn: Any, sysid: int, index: int) -> tuple[bool, str]:
            pts = loop_points(m, UPLOAD_POINTS, m.vehicles.altitude_m(sysid))
            return upload_and_verify(conn, sysid, pts, 3, landings)  # MAV_AUTOPILOT_ARDUPILOTMEGA

        extra = {k: float(v) for k, _, v in (p.partition("=") for p in cfg.sim_params)}
        self.bringup = Bringup(
            m, started, cfg.speedup, self.timeout_s, upload, self.say, extra,
            battery_pct=battery_pct(m, cfg.battery_used_mah),
        )  # fmt: skip
        # the world's mean wind, as every instance simulates it: the mission's unless
        # --sim-param set another (the truth log and the report's T/N use this one)
        wind = {**mission_params(m, self.specs[0].sysid, self.timeout_s), **extra}
        self.bringup.connect()  # the instances' clocks start here
        self.sitl = self._spawn(
            "world",
            [
                cfg.python,
                "-m",
                "companion.sim.arduplane.world",
                "--mission",
                str(cfg.mission_path),
                "--sysids",
                ",".join(str(s.sysid) for s in self.specs),
                "--ports",
                ",".join(str(s.ports.serial2) for s in self.specs),
                "--epoch",
                str(SIM_EPOCH_UNIX_S),
                "--speedup",
                f"{cfg.speedup:g}",
                "--duration",
                f"{self.duration_s:g}",
                "--truth-log",
                str(cfg.out / "truth.csv"),
                "--events-log",
                str(cfg.out / "sim_events.jsonl"),
                "--clock-log",
                str(cfg.out / "run_info.json"),
                "--pace-file",
                str(self.pace_file),
                "--world-wind",
                f"{wind['SIM_WIND_SPD']:g},{wind['SIM_WIND_DIR']:g}",
            ],
            "world.log",
        )
        t0 = time.monotonic()
        self.bringup.run()
        spares = len(m.vehicles.spares)
        self.say(
            f"fleet: {len(started) - spares} aircraft armed and climbed to their altitudes"
            + (f" ({spares} spares on the ground in GUIDED)" if spares else "")
            + f" in {time.monotonic() - t0:.1f} s of wall time; handing over to the companions"
        )
        self.bringup.close()  # SERIAL0 is free for a ground station from now on
        self.check_alive()
        # the hand-over hold: slow clocks until every companion has taken control
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.sitl.popen.pid, signal.SIGUSR1)
        urls = {s.sysid: f"tcp:127.0.0.1:{s.ports.serial1}" for s in self.specs}
        if self.socat is not None:
            for spec in self.specs:
                urls[spec.sysid] = self.plug_cable(spec.sysid)
        self._start_companions(urls, time.monotonic() + SETUP_TIMEOUT_S)

    # ---- the serial cables (companion_link "serial") ----------------------------------------
    def cable_path(self, sysid: int) -> Any:
        """Where companion ``sysid``'s serial device is reached (a symbolic link)."""
        return self.cfg.out / f"uav{sysid}" / "serial1"

    def plug_cable(self, sysid: int) -> str:
        """A serial cable (socat) between instance ``sysid``'s SERIAL1 and a new
        pseudo-terminal at :meth:`cable_path`; its ``--connect`` URL."""
        spec = next(s for s in self.specs if s.sysid == sysid)
        link = self.cable_path(sysid)
        link.parent.mkdir(parents=True, exist_ok=True)
        assert self.socat is not None
        proc = self._spawn(
            f"serial {sysid}",
            relay_argv(self.socat, link, spec.ports.serial1),
            f"uav{sysid}/serial1.log",
        )
        self.relays[sysid] = proc
        wait_for_link(link, lambda: proc.popen.poll() is None)
        return serial_url(link)

    def pull_cable(self, sysid: int) -> None:
        """The cable pulled: its socat stopped (the pseudo-terminal's node goes)."""
        proc = self.relays.pop(sysid)
        self.procs.remove(proc)
        with contextlib.suppress(ProcessLookupError):
            proc.popen.send_signal(signal.SIGCONT)
            proc.popen.terminate()
        proc.popen.wait(5.0)
        if proc.log:
            proc.log.close()

    def check_alive(self) -> None:
        """Raise if a process died early (naming an instance's last words) or if the truth
        log has not grown for STALL_WALL_S (an instance or the world process stalled)."""
        if not self.stopping and self.bringup is not None:
            self.bringup.check_alive()
        super().check_alive()
        truth = self.cfg.out / "truth.csv"
        if self.stopping or self.observer is None or not truth.is_file():
            return
        now, size = time.monotonic(), truth.stat().st_size
        if size != self._truth_size:
            self._truth_size, self._truth_grew = size, now
        elif now - self._truth_grew > STALL_WALL_S and self.sitl.popen.poll() is None:
            raise UserError(
                f"no telemetry from the ArduPlane instances for {STALL_WALL_S:g} s of wall "
                f"time (see {self.cfg.out}/uav*/arduplane.log and world.log)"
            )

    def stop(self) -> list[tuple[str, int | None]]:
        """Stop the companions and the world process first (the fleet's stop), then every
        instance: SIGTERM to its process group, SIGKILL after 5 s."""
        if self.bringup is not None:
            self.bringup.close()
        others = [p for p in self.procs if all(p is not q for q in self.instances)]
        self.procs = others
        try:
            results = super().stop()
        finally:
            self.procs = others + self.instances
        for p in self.instances:
            if p.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(p.popen.pid, signal.SIGTERM)
        for p in self.instances:
            try:
                rc = p.popen.wait(5.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(p.popen.pid, signal.SIGKILL)
                rc = p.popen.wait()
            if p.log:
                p.log.close()
            results.append((p.name, 0 if rc == -signal.SIGTERM else rc))
        return results
