"""Beside the firmware: the mission's intruders, each aircraft's camera, the telemetry truth.

:class:`FirmwareWorld` is the process beside a fleet of real autopilots (ArduPlane or PX4 SITL):
it connects to a spare MAVLink link of every instance as component 100 of the aircraft's
system (MAV_TYPE_CAMERA), as an onboard camera wired to a spare port would be. The autopilot
forwards a component's broadcast messages to its other links, so the camera's
CAMERA_TRACKING_GEO_STATUS reaches the companion on its own link (measured on ArduPlane
4.8.0-dev and on PX4 main 02e73e3).

Each instance's positions are mapped to vehicle time (s since the fleet epoch) by a
:class:`companion.link.clock.VehicleClock` and interpolated onto a common grid
(``--truth-period``); a row of ``truth.csv`` (the simulator's columns) is written once every
vehicle has reported past that time, and at the same time the world
(:class:`sitl_model.world.World`, the simulator's intruders and sensing, unchanged) is stepped
with those positions: its events go to ``--events-log`` and every sighting is reported by the
seeing aircraft's camera at 5 Hz of vehicle time.

The clocks of separate instances are not one clock: every ``CLOCK_SAMPLE_S`` of wall time the
process estimates each instance's vehicle time at the same wall instant and logs the spread
(the clock skew) and each instance's achieved speed-up to ``--clock-log`` (JSON), and slows the
instances ahead of the slowest (:func:`slewed_speedups`) through the autopilot's own actuator
(:meth:`FirmwareWorld.send_speedup`). It exits when the grid reaches ``--duration`` (s), or on
SIGINT/SIGTERM.

SIGUSR1 starts the **hand-over hold**: the fleet sends it once the aircraft have climbed, just
before it starts the companions. Until every instance reports the mode the companions command
in (``controlled_mode``), or for at most ``HOLD_MAX_WALL_S``, the clocks run at
``--handover-speedup`` instead of ``--speedup``, so the vehicle time at which each companion
takes control no longer depends on how long Python took to start on a busy machine (see
docs/arduplane.md, "Hand-over").

``--pace-file PATH`` caps the clocks' speed-up at the number the fleet writes there when its
companions starve (:class:`companion.sim.pace.PaceMonitor`): read every ``CLOCK_SAMPLE_S``,
each change logged (event ``pace``) and reported (``pace`` in the clock log).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.simulator import TRUTH_COLUMNS, TRUTH_HEADER
from companion.core.wind import Wind
from companion.link.clock import VehicleClock
from companion.mission import Mission, load_mission
from companion.sim.firmware.links import autopilot_messages
from companion.sim.firmware.timebase import (
    CLOCK_SAMPLE_S,
    Sample,
    clocks_now_s,
    handover_cap,
    interpolate,
    slewed_speedups,
)
from sitl_model.geo import LocalFrame
from sitl_model.world import World

CAMERA_COMPID = 100
POSITION_HZ = 10.0
SYSTEM_TIME_HZ = 5.0
CAMERA_PERIOD_S = 0.2  # detection reports at 5 Hz (vehicle time), as our simulator's camera
REQUEST_RETRY_S = 2.0  # wall
SLEW_DEADBAND = 0.005  # SIM_SPEEDUP is re-sent when it should change by more than this fraction
MAX_SAMPLES = 200  # per vehicle, kept for interpolation
PUMP_MAX = 500  # messages read from one link per turn of the loop
HANDOVER_SPEEDUP = 0.5  # SIM_SPEEDUP while the companions start and take control
GROUND_ALT_M = 10.0  # below this above home an aircraft's camera sees nothing (m)
HOLD_MAX_WALL_S = 60.0  # the hand-over hold ends after this long (wall s) in any case
HOLD_SETTLE_WALL_S = 1.0  # after the hold, wall s before the clock skew is logged again


@dataclass
class Link:
    """The camera's and logger's connection to one instance."""

    sysid: int
    port: int
    conn: Any = None
    clock: VehicleClock = field(default_factory=VehicleClock)
    samples: list[Sample] = field(default_factory=list)
    mode: str = "UNKNOWN"
    last_hb: float = -1e9
    last_req: float = -1e9
    got_pos: bool = False
    got_time: bool = False
    sys_times: list[tuple[float, float]] = field(default_factory=list)  # (wall s, vehicle s)
    last_cam_s: float = -1e9
    speedup: float = 0.0  # SIM_SPEEDUP last commanded (0: the start-up value)
    armed: bool | None = None  # HEARTBEAT's armed flag (None: not heard yet)


class FirmwareWorld:
    """The world, the cameras and the truth logger for one fleet run.

    A subclass says how to reach an instance (:meth:`open_link`), which telemetry to ask
    for (:meth:`requests`), what a message other than GLOBAL_POSITION_INT means
    (:meth:`on_message`), a mode's name (:meth:`mode_name`) and how to slow an instance
    (:meth:`send_speedup`).
    """

    controlled_mode = "GUIDED"  # the mode the companions command in
    slew_actuator = "the speed-up"  # what the clock discipline changes, for the report
    truth_source = "telemetry: GLOBAL_POSITION_INT of each SITL instance"
    world_wind_source = "the mission's (the firmware's simulation was not told another)"
    time_base = "each instance's vehicle time minus the epoch; rows on a common grid"

    def __init__(self, args: argparse.Namespace, mission: Mission) -> None:
        """Open the logs and the connections (retried until each instance listens)."""
        self.args = args
        self.mission = mission
        o = mission.origin
        self.frame = LocalFrame(o.lat_deg, o.lon_deg, o.alt_m)
        sysids = [int(x) for x in args.sysids.split(",")]
        ports = [int(x) for x in args.ports.split(",")]
        self.links = [Link(s, p) for s, p in zip(sysids, ports, strict=True)]
        self.world = World(mission.intruders)
        self.clock_log_path = Path(args.clock_log)
        self.radius_m = mission.sensor.footprint_radius_m
        self.epoch = float(args.epoch)
        self.truth = open(args.truth_log, "w")  # noqa: SIM115 - closed in close()
        self.truth.write(TRUTH_HEADER + "\n")
        self.events = open(args.events_log, "w")  # noqa: SIM115 - closed in close()
        self.next_row_s: float | None = None
        self.last_heading: dict[int, tuple[float, float]] = {}
        self.skews: list[tuple[float, float]] = []  # (vehicle s of the slowest, skew s)
        self.slew_range = [args.speedup, args.speedup]  # SIM_SPEEDUP commanded, min and max
        wind = self.true_wind_m_s()
        # the simulated mean wind (gusts aside) where the log has wind columns
        self.wind_cols = (
            f",{wind.real:.3f},{wind.imag:.3f}" if "wind_north_m_s" in TRUTH_COLUMNS else ""
        )
        self.rates: dict[int, tuple[float, float, float, float]] = {}
        self.stop = False
        self.done = False
        self.last_clock_sample = time.monotonic()
        self.hold_until: float | None = None  # wall deadline of the hand-over hold, if held
        self.hold_log: list[dict[str, Any]] = []  # when the hold began and ended
        self.steady_from = 0.0  # wall s from which skews are logged again after the hold
        pace_file = getattr(args, "pace_file", None)
        self.pace_file = Path(pace_file) if pace_file else None
        self.pace = float(args.speedup)  # the cap the fleet set (its slow-downs)
        self.pace_log: list[dict[str, Any]] = []
        for link in self.links:
            self._open(link)

    def _open(self, link: Link) -> None:
        """Open one instance's link (retried for 30 s of wall time while it starts)."""
        deadline = time.monotonic() + 30.0
        while True:
            try:
                link.conn = self.open_link(link)
                link.conn.mav.robust_parsing = True
                return
            except OSError:
                if time.monotonic() > deadline or self.stop:
                    raise
                time.sleep(0.2)

    # ---- what a subclass says ---------------------------------------------------------
    def true_wind_m_s(self) -> complex:
        """The world's mean wind (north + i east, m/s) written in the truth log's wind
        columns: the one set on the firmware's simulation (ArduPlane: ``--world-wind``, the
        fleet's SIM_WIND_SPD and SIM_WIND_DIR), else the mission's."""
        ww = getattr(self.args, "world_wind", None)
        return (self.mission.wind.wind() if ww is None else Wind.from_meteo(*ww)).vector

    def world_wind(self) -> dict[str, Any]:
        """The mean wind the truth log carries (m/s, deg it blows from), where it comes
        from, and the mission's beside it (for the report)."""
        w = Wind.from_vector(self.true_wind_m_s())
        given = getattr(self.args, "world_wind", None) is not None
        mission = self.mission.wind
        return {
            "speed_m_s": round(w.speed_m_s, 3),
            "from_deg": round(w.from_deg % 360.0, 1) if w.speed_m_s else 0.0,
            "source": "set on the firmware's simulation" if given else self.world_wind_source,
            "mission_speed_m_s": mission.speed_m_s,
            "mission_from_deg": mission.from_deg % 360.0,
        }

    def open_link(self, link: Link) -> Any:
        """A pymavlink connection to one instance as its camera (raises OSError)."""
        raise NotImplementedError

    def mode_name(self, custom_mode: int) -> str:
        """The autopilot's name of a HEARTBEAT ``custom_mode``."""
        raise NotImplementedError

    def on_message(self, link: Link, m: Any) -> None:
        """A message of the instance's autopilot other than HEARTBEAT and
        GLOBAL_POSITION_INT (SYSTEM_TIME on ArduPlane)."""

    def on_armed(self, link: Link, armed: bool) -> None:
        """The instance's armed flag changed (nothing by default)."""

    def on_row(self, t_s: float) -> None:
        """A truth row at ``t_s`` (s since the epoch) is about to be written (nothing by
        default)."""

    def send_speedup(self, link: Link, speedup: float) -> None:
        """Run one instance at ``speedup`` (simulated s per wall s) until told otherwise."""
        raise NotImplementedError

    def clock_sample(self, link: Link, vehicle_s: float) -> None:
        """Note that ``link``'s instance was at unix vehicle time ``vehicle_s`` just now
        (wall): the clock estimates and the achieved speed-up come from these."""
        wall = time.monotonic()
        link.sys_times.append((wall, vehicle_s - self.epoch, link.speedup or self.args.speedup))
        del link.sys_times[:-4]
        first = self.rates.get(link.sysid)
        self.rates[link.sysid] = (
            (wall, vehicle_s, wall, vehicle_s)
            if first is None
            else (first[0], first[1], wall, vehicle_s)
        )

    # ---- input ------------------------------------------------------------------------------
    def pump(self, link: Link) -> None:
        """Read what is waiting from one instance, at most PUMP_MAX messages (so that a busy
        link cannot keep the loop from its rows and clocks)."""
        for m in autopilot_messages(link.conn, link.sysid, PUMP_MAX):
            t = m.get_type()
            if t == "HEARTBEAT":
                link.mode = self.mode_name(int(m.custom_mode))
                armed = bool(m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
                if armed != link.armed:
                    self.on_armed(link, armed)
                link.armed = armed
            elif t == "GLOBAL_POSITION_INT":
                link.got_pos = True
                vt = link.clock.to_vehicle_s(int(m.time_boot_ms))
                if vt is None:
                    continue
                self._sample(link, vt - self.epoch, m)
            else:
                self.on_message(link, m)

    def _sample(self, link: Link, t_s: float, m: Any) -> None:
        if link.samples and t_s <= link.samples[-1].t_s:
            return
        pos = self.frame.to_local(m.lat * 1e-7, m.lon * 1e-7)
        vel = complex(m.vx, m.vy) * 1e-2
        course = math.degrees(math.atan2(vel.imag, vel.real)) % 360.0
        hdg = m.hdg * 1e-2 if m.hdg != 65535 else course
        link.samples.append(Sample(t_s, pos, m.relative_alt * 1e-3, hdg, course, abs(vel)))
        del link.samples[:-MAX_SAMPLES]

    # ---- output -----------------------------------------------------------------------------
    def requests(self, now: float) -> None:
        """Camera heartbeats (1 Hz of wall time) and the subclass's telemetry requests."""
        for link in self.links:
            if now - link.last_hb >= 1.0:
                link.last_hb = now
                with contextlib.suppress(OSError):
                    link.conn.mav.heartbeat_send(
                        mav.MAV_TYPE_CAMERA, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE
                    )
            if (not link.got_pos or not link.got_time) and now - link.last_req >= REQUEST_RETRY_S:
                link.last_req = now
                self.request_telemetry(link)

    def request_telemetry(self, link: Link) -> None:
        """Ask one instance for its telemetry (repeated until it flows)."""
        raise NotImplementedError

    def rows(self) -> None:
        """Truth rows, world steps and camera reports up to the newest common time."""
        period = self.args.truth_period
        if any(not link.samples for link in self.links):
            return
        newest_common = min(link.samples[-1].t_s for link in self.links)
        if self.next_row_s is None:
            start = max(link.samples[0].t_s for link in self.links)
            self.next_row_s = math.ceil(start / period) * period
        while self.next_row_s <= newest_common and not self.done:
            t = round(self.next_row_s, 6)
            now = [interpolate(link.samples, t) for link in self.links]
            if any(s is None for s in now):
                self.next_row_s += period  # a gap older than the kept samples: skip
                continue
            self._row(t, now)
            self.next_row_s += period
            if t >= self.args.duration:
                self.done = True

    def _row(self, t: float, now: list[Sample]) -> None:
        lines = []
        for link, s in zip(self.links, now, strict=True):
            prev = self.last_heading.get(link.sysid)
            rate = 0.0
            if prev is not None and t > prev[0]:
                rate = ((s.course_deg - prev[1] + 180.0) % 360.0 - 180.0) / (t - prev[0])
            self.last_heading[link.sysid] = (t, s.course_deg)
            lines.append(
                f"{t:.3f},{link.sysid},{s.pos_m.real:.3f},{s.pos_m.imag:.3f},{s.alt_m:.2f},"
                f"{s.heading_deg:.5f},{s.course_deg:.5f},{s.groundspeed_m_s:.3f},{rate:.4f},"
                f"{link.mode}{self.wind_cols}"
            )
        self.truth.write("\n".join(lines) + "\n")
        self.on_row(t)
        # a camera on the ground sees nothing (as in our simulator)
        pos = np.array([s.pos_m if s.alt_m >= GROUND_ALT_M else complex(math.nan, math.nan)
                        for s in now])  # fmt: skip
        sightings, events = self.world.update(t, pos, self.radius_m)
        for e in events:
            rec: dict[str, Any] = {"t_s": round(e.t_s, 3), "event": e.event}
            if e.index is not None:
                rec["sysid"] = self.links[e.index].sysid
            rec |= {"intruder": e.intruder_id, "north_m": e.pos_m.real, "east_m": e.pos_m.imag}
            self.events.write(json.dumps(rec) + "\n")
        for sg in sightings:
            link = self.links[sg.index]
            if t - link.last_cam_s < CAMERA_PERIOD_S - 1e-6:
                continue
            link.last_cam_s = t
            self._camera(link, sg, now[sg.index].alt_m)

    def _camera(self, link: Link, sg: Any, alt_m: float) -> None:
        lat, lon, alt = self.frame.to_geodetic(
            np.array([sg.pos_m.real]), np.array([sg.pos_m.imag]), np.zeros(1)
        )
        v = sg.vel_m_s
        hdg = math.atan2(v.imag, v.real) if abs(v) > 0 else math.nan
        with contextlib.suppress(OSError):
            link.conn.mav.camera_tracking_geo_status_send(
                mav.CAMERA_TRACKING_STATUS_FLAGS_ACTIVE,
                round(float(lat[0]) * 1e7), round(float(lon[0]) * 1e7), float(alt[0]),
                1.0, 1.0, v.real, v.imag, 0.0, 0.1, math.hypot(sg.distance_m, alt_m), hdg,
                math.nan,
            )  # fmt: skip

    def begin_hold(self) -> None:
        """Start the hand-over hold (on SIGUSR1): clocks at ``--handover-speedup`` until every
        instance is in GUIDED, at most HOLD_MAX_WALL_S of wall time (not with ``--no-slew``,
        which leaves SIM_SPEEDUP alone)."""
        if self.args.slew:
            self.hold_until = time.monotonic() + HOLD_MAX_WALL_S

    def _held_speedup(self, now: float, vehicle_s: float) -> float:
        """The speed-up cap in force (see :func:`handover_cap`), logging the hold's ends."""
        if self.hold_until is None:
            return self.args.speedup
        modes = [link.mode for link in self.links]
        cap, held = handover_cap(now, self.hold_until, modes, self.args.speedup,
                                 self.args.handover_speedup, self.controlled_mode)  # fmt: skip
        if not self.hold_log:
            self._hold_event("handover_hold", vehicle_s)
        if not held:
            self.hold_until = None
            self.steady_from = now + HOLD_SETTLE_WALL_S
            self._hold_event("handover_release", vehicle_s, all_guided=all(
                m == self.controlled_mode for m in modes))  # fmt: skip
        return cap

    def _hold_event(self, name: str, vehicle_s: float, **fields: object) -> None:
        """One end of the hand-over hold, at vehicle time ``vehicle_s`` (s), to the events log
        and the clock report."""
        ev = {"event": name, "t_s": round(vehicle_s, 3), **fields}
        self.hold_log.append(ev)
        self.events.write(json.dumps(ev) + "\n")

    def _pace_cap(self, vehicle_s: float) -> float:
        """The fleet's cap on the speed-up (``--pace-file``; the requested one without),
        each change logged at vehicle time ``vehicle_s`` (s)."""
        if self.pace_file is None:
            return self.pace
        with contextlib.suppress(OSError, ValueError):
            pace = float(self.pace_file.read_text().strip())
            if math.isfinite(pace) and pace > 0 and pace != self.pace:
                self.pace = pace
                ev = {"event": "pace", "t_s": round(vehicle_s, 3), "speedup": pace}
                self.pace_log.append(ev)
                self.events.write(json.dumps(ev) + "\n")
        return self.pace

    def sample_clocks(self, now: float) -> None:
        """Every CLOCK_SAMPLE_S: log the instances' clock skew and slew their SIM_SPEEDUP."""
        if now - self.last_clock_sample < CLOCK_SAMPLE_S:
            return
        self.last_clock_sample = now
        if any(not link.sys_times for link in self.links):
            return
        clocks = clocks_now_s([link.sys_times[-1] for link in self.links], now)
        x = self._held_speedup(now, min(clocks)) if self.args.slew else self.args.speedup
        x = min(x, self._pace_cap(min(clocks)))
        if self.hold_until is not None or now < self.steady_from:
            # the hand-over hold, and HOLD_SETTLE_WALL_S after it: every instance at the cap;
            # the clock estimates lag a change of speed-up, so no skew is logged or slewed
            for link in self.links:
                if link.speedup != x:
                    link.speedup = x
                    self.send_speedup(link, x)
            return
        self.skews.append((min(clocks), max(clocks) - min(clocks)))
        if not self.args.slew:
            return
        for link, want in zip(self.links, slewed_speedups(clocks, x), strict=True):
            current = link.speedup or x
            if abs(want - current) > SLEW_DEADBAND * x:
                link.speedup = want
                self.slew_range = [min(self.slew_range[0], want), max(self.slew_range[1], want)]
                self.send_speedup(link, want)

    def clock_report(self) -> dict[str, Any]:
        """Clock figures: skew (median, p95, max, first and last), achieved speed-ups."""
        rep: dict[str, Any] = {
            "truth_source": self.truth_source,
            "time_base": self.time_base,
            "world_wind": self.world_wind(),
            "speedup_requested": self.args.speedup,
            "handover": self.hold_log,
            "pace": self.pace_log,
        }
        if self.skews:
            sk = np.array([s for _, s in self.skews])
            rep["clock_skew_s"] = {
                "median": round(float(np.median(sk)), 4),
                "p95": round(float(np.percentile(sk, 95)), 4),
                "max": round(float(sk.max()), 4),
                "first": round(float(sk[0]), 4),
                "last": round(float(sk[-1]), 4),
                "samples": int(sk.size),
                "over_vehicle_s": round(self.skews[-1][0] - self.skews[0][0], 1),
            }
        rep["clock_slew"] = (
            f"{self.slew_actuator} of each instance slewed within {self.slew_range[0]:.2f}.."
            f"{self.slew_range[1]:.2f} so that its clock meets the slowest one"
            if self.args.slew
            else "none (free-running instances)"
        )
        rep["achieved_speedup"] = {
            str(s): round((v1 - v0) / (w1 - w0), 3)
            for s, (w0, v0, w1, v1) in self.rates.items()
            if w1 > w0
        }
        return rep

    def tick(self, now: float) -> None:
        """Called every turn of the loop at wall time ``now`` (s): nothing here."""

    def select_timeout_s(self, now: float) -> float:
        """Longest wall wait (s) for telemetry before the next turn of the loop."""
        return 0.05

    def run(self) -> int:
        """Serve until the duration is reached or stopped; returns 0."""
        import selectors

        sel = selectors.DefaultSelector()
        for link in self.links:
            sel.register(link.conn.fd, selectors.EVENT_READ, link)
        try:
            while not self.stop and not self.done:
                for key, _ in sel.select(self.select_timeout_s(time.monotonic())):
                    self.pump(key.data)
                now = time.monotonic()
                self.tick(now)
                self.requests(now)
                self.sample_clocks(now)
                self.rows()
        finally:
            self.close()
        return 0

    def close(self) -> None:
        """Flush the logs, write the clock report, close the connections."""
        with contextlib.suppress(OSError):
            self.clock_log_path.write_text(json.dumps(self.clock_report(), indent=2) + "\n")
        for fh in (self.truth, self.events):
            if not fh.closed:
                fh.close()
        for link in self.links:
            if link.conn is not None:
                with contextlib.suppress(OSError):
                    link.conn.close()


def parser(prog: str, ports_help: str, actuator: str) -> argparse.ArgumentParser:
    """The world process's command line (the options every autopilot's world takes)."""
    p = argparse.ArgumentParser(prog=prog)
    p.add_argument("--mission", required=True)
    p.add_argument("--sysids", required=True, help="comma-separated system ids")
    p.add_argument("--ports", required=True, help=ports_help)
    p.add_argument("--epoch", type=float, required=True, help="unix s of vehicle time 0")
    p.add_argument("--speedup", type=float, required=True)
    p.add_argument("--duration", type=float, required=True, help="vehicle s")
    p.add_argument("--truth-log", required=True)
    p.add_argument("--events-log", required=True)
    p.add_argument("--clock-log", required=True)
    p.add_argument("--truth-period", type=float, default=0.1, help="vehicle s")
    p.add_argument(
        "--world-wind",
        type=_speed_from,
        default=None,
        metavar="SPEED,FROM_DEG",
        help="the mean wind set on the firmware's simulation (m/s, deg it blows from); "
        "default: the mission's",
    )
    p.add_argument("--no-slew", dest="slew", action="store_false", help=f"leave {actuator} alone")
    p.add_argument(
        "--pace-file",
        metavar="PATH",
        help="a speed-up cap the fleet writes here when its companions starve (read each "
        "clock sample)",
    )
    p.add_argument(
        "--handover-speedup",
        type=float,
        default=HANDOVER_SPEEDUP,
        help="the speed-up from SIGUSR1 until every instance is in the companions' mode",
    )
    return p


def _speed_from(text: str) -> tuple[float, float]:
    """``SPEED,FROM_DEG`` -> (m/s, deg); argparse's type for ``--world-wind``."""
    try:
        speed, from_deg = (float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected SPEED,FROM_DEG, got {text!r}") from None
    if not (math.isfinite(speed) and math.isfinite(from_deg)) or speed < 0:
        raise argparse.ArgumentTypeError(f"expected a finite speed >= 0, got {text!r}")
    return speed, from_deg


def serve(cls: type[FirmwareWorld], args: argparse.Namespace) -> int:
    """Run one world process of class ``cls`` with ``args`` (see the module docstring):
    SIGUSR1 starts the hand-over hold, SIGINT/SIGTERM stop it; returns its exit status."""
    mission = load_mission(args.mission)
    holder: list[FirmwareWorld] = []
    early_hold: list[bool] = []  # SIGUSR1 before the connections were open

    def on_hold(_signum: int, _frame: object) -> None:
        if holder:
            holder[0].begin_hold()
        else:
            early_hold.append(True)

    signal.signal(signal.SIGUSR1, on_hold)

    def on_signal(_signum: int, _frame: object) -> None:
        if holder:
            holder[0].stop = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    wp = cls(args, mission)
    holder.append(wp)
    if early_hold:
        wp.begin_hold()
    status = wp.run()
    print(f"world: stopped at {wp.next_row_s or 0:.1f} s", file=sys.stderr)
    return status
