"""``companion fleet MISSION --autopilot px4``: the mission flown by real PX4 SITL (SIH).

:class:`Px4Fleet` is the :class:`companion.sim.fleet.Fleet` run with one PX4 SITL process per
vehicle in place of ``sitl-model``:

1. the PX4 folder is found (``--px4-dir`` or ``$PX4_SITL_DIR``) and one free
   instance number per vehicle chosen (:mod:`companion.sim.px4.sitl`); every instance starts
   in ``uavN/px4/`` with home at the mission origin, ``PX4_SIM_SPEED_FACTOR`` = the
   speed-up, its system id and the mission's airspeed, roll limit and take-off altitude, the
   airframe's thrust raised (:func:`~companion.sim.px4.params.mission_params`);
2. the world process (:mod:`companion.sim.px4.world`) on each instance's camera link plays
   the intruder scenario, logs the telemetry-derived ``truth.csv`` and keeps the instances'
   clocks together;
3. over each ground-station link the fleet uploads the perimeter and fence (verified by
   download), takes off into AUTO.LOITER and moves each loiter over the vehicle's initial
   position in the mission (:class:`~companion.sim.px4.bringup.Bringup`, :func:`loiter_points`);
4. one ``companion run --take-control --boot-epoch EPOCH`` per vehicle on its offboard link
   (``udpout:127.0.0.1:14580+i``): the companion pre-streams and enters OFFBOARD itself;
   the run ends when the world process reaches the duration.

Every process is started in its own session and stopped by its pid, whatever happens: the
companions and the world process first, then every PX4 instance (SIGCONT, SIGINT, SIGKILL
after 15 s), whose lock and socket files are then removed.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from typing import Any

import numpy as np

from companion.contracts.errors import UserError
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.link.mission_protocol.vehicle import upload_perimeter
from companion.link.px4 import MAV_AUTOPILOT_PX4
from companion.mission import Mission
from companion.sim.firmware.serial_relay import find_socat, udp_relay_argv
from companion.sim.fleet import SETUP_TIMEOUT_S, Fleet, FleetConfig, free_udp_port
from companion.sim.px4.bringup import UPLOAD_POINTS, Bringup
from companion.sim.px4.params import mission_params, takeoff_alt_m
from companion.sim.px4.sitl import Px4Instance, find_px4_dir, pick_instances
from sitl_model.geo import LocalFrame

DEFAULT_SPEEDUP = 3.0  # three instances and their companions keep it on two busy cores
STALL_WALL_S = 60.0  # wall s without a new truth row while running = a stalled instance
COMPANION_START_WALL_S = 3 * SETUP_TIMEOUT_S  # six Pythons starting on two busy cores


def loiter_points(mission: Mission) -> list[tuple[float, float, float]]:
    """Where each aircraft loiters before the hand-over (lat deg, lon deg, alt m AMSL): over
    its initial position in the mission at its altitude. PX4's take-off climbs straight ahead
    of home (500-700 m north for 100-150 m), near or beyond the fence of the paper's ellipse,
    and the formation then converged across the fence (PX4 held, then returned)."""
    o = mission.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    v = mission.vehicles
    north = np.array([p.north_m for p in v.initial])
    east = np.array([p.east_m for p in v.initial])
    lat, lon, _ = frame.to_geodetic(north, east, np.zeros(len(north)))
    return [
        (float(a), float(b), o.alt_m + h) for a, b, h in zip(lat, lon, v.altitudes_m, strict=True)
    ]


def spare_homes(mission: Mission) -> dict[int, tuple[float, float, float]]:
    """Where each spare's instance starts (sysid -> lat deg, lon deg, alt m AMSL): on the
    ground at its launch point (PX4's SIH has no start heading: every instance starts facing
    north, so the runway's heading is not flown; docs/px4.md, "Reliefs on PX4").

    Raises:
        UserError: a spare waits holding in the air (a PX4 instance starts on the ground).
    """
    o = mission.origin
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
    out = {}
    for sp in mission.vehicles.spares:
        if sp.waits != "ground":
            raise UserError(
                f"spare {sp.sysid} waits holding in the air: with --autopilot px4 a spare "
                "waits on the ground (vehicles.spares: ground:)"
            )
        lat, lon, _ = frame.to_geodetic(np.array([sp.north_m]), np.array([sp.east_m]), np.zeros(1))
        out[sp.sysid] = (float(lat[0]), float(lon[0]), o.alt_m)
    return out


def battery_pct(mission: Mission, used_mah: tuple[tuple[int, float], ...]) -> dict[int, float]:
    """``--battery-used SYSID=MAH`` as the charge (%) each such battery starts with on PX4
    (the share of the mission's capacity left; set once the aircraft is armed,
    :meth:`~companion.sim.px4.bringup.Bringup.use_batteries`).

    Raises:
        UserError: a used battery with no battery section in the mission, or on a spare (PX4's
            battery simulator is full whenever the aircraft is disarmed).
    """
    b = mission.vehicles.battery
    if used_mah and b is None:
        raise UserError("--battery-used: the mission has no battery section (vehicles.battery)")
    spares = {sp.sysid for sp in mission.vehicles.spares}
    out = {}
    for sysid, mah in used_mah:
        if sysid in spares:
            raise UserError(
                f"--battery-used {sysid}=...: UAV {sysid} is a spare, on the ground and "
                "disarmed, and PX4's battery simulator is full whenever it is disarmed"
            )
        assert b is not None
        out[sysid] = max(0.0, min(100.0, 100.0 * (1.0 - mah / b.capacity_mah)))
    return out


def parse_param(text: str) -> str:
    """Check one ``--sim-param NAME=VALUE`` for PX4 (set at every start as
    ``PX4_PARAM_NAME``; PX4 says in ``uavN/px4.log`` if it has no such parameter)."""
    name, sep, value = text.partition("=")
    name = name.strip()
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    ok = sep and name and len(name) <= 16 and name.replace("_", "").isalnum()
    if not ok or not math.isfinite(number):
        raise UserError(f"--sim-param {text!r}: expected NAME=VALUE (a PX4 parameter)")
    return f"{name.upper()}={number:g}"


class Px4Fleet(Fleet):
    """A fleet run on PX4 SITL instances (see the module docstring).

    Args:
        cfg: the fleet options (``lockstep`` and ``link_signing`` do not apply; ``sim_params``
            are PX4 parameters set on every instance after the mission's).
        mission: the mission.
        px4_dir: ``--px4-dir`` (None: ``$PX4_SITL_DIR``).
        instances: PX4 instance numbers to use (None: the lowest free ones).
        say: where set-up lines go.
    """

    def __init__(
        self,
        cfg: FleetConfig,
        mission: Mission,
        px4_dir: str | None = None,
        instances: list[int] | None = None,
        say=print,
    ) -> None:
        """Find PX4 and free instances (UserError: nothing started); nothing runs yet."""
        if cfg.link_signing:
            raise UserError("--link-signing: this PX4 SITL build's links are unsigned")
        self.px4_dir = find_px4_dir(px4_dir)
        homes = spare_homes(mission)  # UserError for a spare PX4 cannot have
        self.battery_pct = battery_pct(mission, cfg.battery_used_mah)
        sysids = mission.vehicles.all_sysids  # the patrol's, then the spares'
        numbers = pick_instances(len(sysids), instances)
        super().__init__(cfg, mission)
        self.say = say
        o = mission.origin
        extra = {k: float(v) for k, _, v in (p.partition("=") for p in cfg.sim_params)}
        self.instances = [
            Px4Instance(
                i,
                sysid,
                cfg.out / f"uav{sysid}" / "px4",
                cfg.speedup,
                {**mission_params(mission, sysid), **extra},
                homes.get(sysid, (o.lat_deg, o.lon_deg, o.alt_m)),
            )
            for i, sysid in zip(numbers, sysids, strict=True)
        ]
        self.bringup: Bringup | None = None
        self.companion_args = ["--boot-epoch", str(SIM_EPOCH_UNIX_S)]
        self._truth_size, self._truth_grew = -1, time.monotonic()

    def start(self) -> None:
        """Instances, world process, upload and take-off, companions (UserError on failure)."""
        cfg, m = self.cfg, self.mission
        for inst in self.instances:
            inst.start(self.px4_dir, cfg.out / f"uav{inst.sysid}" / "px4.log")
        nums = ",".join(str(inst.i) for inst in self.instances)
        self.say(
            f"fleet: {len(self.instances)} PX4 SITL instances ({self.px4_dir}, numbers {nums}) "
            f"at speed factor {cfg.speedup:g}; still air (PX4's SIH has no wind)"
        )
        self.sitl = self._spawn(
            "world",
            [
                cfg.python, "-m", "companion.sim.px4.world",
                "--mission", str(cfg.mission_path),
                "--sysids", ",".join(str(i.sysid) for i in self.instances),
                "--ports", ",".join(str(i.ports["camera"]) for i in self.instances),
                "--pids", ",".join(str(i.proc.pid) for i in self.instances if i.proc),
                "--epoch", str(SIM_EPOCH_UNIX_S),
                "--speedup", f"{cfg.speedup:g}",
                "--duration", f"{self.duration_s:g}",
                "--truth-log", str(cfg.out / "truth.csv"),
                "--events-log", str(cfg.out / "sim_events.jsonl"),
                "--clock-log", str(cfg.out / "run_info.json"),
                "--pace-file", str(self.pace_file),
            ],
            "world.log",
        )  # fmt: skip

        def upload(conn: Any, sysid: int, index: int) -> tuple[bool, str]:
            return upload_perimeter(
                conn, sysid, MAV_AUTOPILOT_PX4, m, None, UPLOAD_POINTS, enable_fence=True
            )

        t0 = time.monotonic()
        alts = [m.vehicles.altitude_m(i.sysid) for i in self.instances]
        spares = frozenset(sp.sysid for sp in m.vehicles.spares)
        drain = mission_params(m, m.vehicles.sysids[0]).get("SIM_BAT_DRAIN")
        self.bringup = Bringup(
            self.instances, alts, cfg.speedup, upload, self.say, loiter_at=loiter_points(m),
            spares=spares, battery_pct=self.battery_pct, drain_s=drain,
            relief_takeoff_m={
                s: takeoff_alt_m(m, s, relief=True) for s in m.vehicles.sysids
            } if spares else None,
        )  # fmt: skip
        self.bringup.connect()
        self.bringup.run()
        for sysid, line in self.bringup.upload_lines.items():
            (cfg.out / f"upload_{sysid}.log").write_text(f"sysid {sysid}: {line}\n")
        used = ", ".join(f"UAV {s} {p:.0f} %" for s, p in sorted(self.battery_pct.items()))
        self.say(
            f"fleet: {len(self.instances) - len(spares)} aircraft took off into AUTO.LOITER"
            + (f" ({len(spares)} spares on the ground, disarmed)" if spares else "")
            + (f"; used batteries: {used}" if used else "")
            + f" in {time.monotonic() - t0:.1f} s of wall time; handing over to the companions"
        )
        self.bringup.close()  # the ground-station links are free from now on
        self.check_alive()
        # No hand-over hold (ArduPlane's SIGUSR1): run at 0.5x by pausing, PX4 delivered its
        # telemetry in bursts and six starved companions broke off their pre-streams until the
        # hold timed out (measured once, load 19). The aircraft loiter meanwhile.
        urls = {i.sysid: f"udpout:127.0.0.1:{i.ports['offboard']}" for i in self.instances}
        if self.cfg.companion_link == "relay":  # a UDP wire the tests and the bench cut
            socat = find_socat()
            for inst in self.instances:
                port = free_udp_port()
                argv = udp_relay_argv(socat, port, inst.ports["offboard"])
                self.relays[inst.sysid] = self._spawn(
                    f"relay {inst.sysid}", argv, f"uav{inst.sysid}/relay.log"
                )
                urls[inst.sysid] = f"udpout:127.0.0.1:{port}"
        self._start_companions(urls, time.monotonic() + COMPANION_START_WALL_S)

    def check_alive(self) -> None:
        """Raise if an instance or another process died early, or if the truth log has not
        grown for STALL_WALL_S (an instance or the world process stalled)."""
        if not self.stopping:
            for inst in self.instances:
                p = inst.proc
                if p is not None and p.poll() is not None:
                    raise UserError(
                        f"PX4 instance {inst.i} (sysid {inst.sysid}) exited with status "
                        f"{p.returncode} (see {inst.log_path})"
                    )
        super().check_alive()
        if not self.stopping and self.observer is not None:
            self._check_refusals()
        truth = self.cfg.out / "truth.csv"
        if self.stopping or self.observer is None or not truth.is_file():
            return
        now, size = time.monotonic(), truth.stat().st_size
        if size != self._truth_size:
            self._truth_size, self._truth_grew = size, now
        elif now - self._truth_grew > STALL_WALL_S and self.sitl.popen.poll() is None:
            raise UserError(
                f"no telemetry from the PX4 instances for {STALL_WALL_S:g} s of wall time "
                f"(see {self.cfg.out}/uav*/px4.log and world.log)"
            )

    def _check_refusals(self) -> None:
        """While the companions take control: :class:`UserError` naming one whose PX4
        refused OFFBOARD until it gave up (its ``offboard_refused`` issue)."""
        if set(self.progress.phases) >= {i.sysid for i in self.instances}:
            return
        for inst in self.instances:
            path = self.cfg.out / f"uav{inst.sysid}" / "events.jsonl"
            if inst.sysid in self.progress.phases or not path.is_file():
                continue
            for line in path.read_text().splitlines():
                with contextlib.suppress(json.JSONDecodeError):
                    ev = json.loads(line)
                    if ev.get("event") == "offboard_refused":
                        raise UserError(
                            f"PX4 sysid {inst.sysid} refused OFFBOARD: {ev.get('text', '')} "
                            f"(see {path.parent}/companion.log and {inst.log_path})"
                        )

    def stop(self) -> list[tuple[str, int | None]]:
        """Stop the companions and the world process (the fleet's stop), then every
        instance by its pid (SIGCONT, SIGINT, SIGKILL after 15 s); their exit statuses."""
        if self.bringup is not None:
            self.bringup.close()
        results = super().stop()
        for inst in self.instances:
            if inst.proc is not None:
                results.append((f"px4 {inst.sysid}", inst.stop()))
        return results
