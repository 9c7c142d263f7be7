"""The whole simulated fleet on one clock: N autopilots, vectorised physics, the world (pure).

:meth:`Simulation.step` advances simulated time by ``DT_S`` (s): every autopilot computes
its turn-rate command from the measured state, then one vectorised
:func:`companion.core.particle.step` moves all N vehicles. :meth:`Simulation.advance`
takes ``n`` such steps at once, integrated exactly over ``n DT_S`` by
:func:`sitl_model.physics.advance` (the in-memory engine and the lockstepped server step at
the companions' control period, 0.1 s). Sensors are evaluated every ``SENSOR_EVERY``
steps. No sockets, no wall clock; randomness only from the seeded generator. Each
vehicle's battery (:mod:`sitl_model.battery`) draws its power at the sensors' 10 Hz.
Conventions: complex positions ``north + i east`` (m), compass angles (rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from companion.contracts.simulator import TRUTH_HEADER, TRUTH_HEADER_ENERGY
from companion.core.particle import ParticleParams, ParticleState, cap_wind, step
from companion.mission import Intruder
from sitl_model import physics
from sitl_model.autopilot import LOOP_DT_S, ApEvent, Autopilot, Mode, Obs, RefusedError
from sitl_model.battery import Batteries
from sitl_model.disturbances import (
    MAX_WIND_RATIO,
    ErrorParams,
    SensorErrors,
    WindProfile,
    mean_wind_m_s,
)
from sitl_model.fence import FENCE_VERTEX_INCLUSION, breaches, inclusion_polygons
from sitl_model.geo import LocalFrame
from sitl_model.mission_protocol import MissionItem, home_item
from sitl_model.params import Params
from sitl_model.physics import Airspeed
from sitl_model.world import Sighting, World

DT_S = LOOP_DT_S  # physics step (s): 50 Hz, the autopilot's loop
CLIMB_RATE_M_S = 3.0  # vertical speed towards an altitude target (m/s)
SENSOR_EVERY = 5  # sensor evaluation every 5 steps (10 Hz)
TRUTH_EVERY = 5  # truth-log row every 5 steps (10 Hz)
RUNWAY_M = 100.0  # a vehicle landing this near a base lands on its runway (m)


@dataclass(frozen=True)
class VehicleSetup:
    """Initial pose (m, deg) and altitude (m above the origin) of one vehicle; ``grounded``:
    it starts on the ground there (disarmed, a spare at its launch point), flying at
    ``alt_m`` once it takes off."""

    sysid: int
    north_m: float
    east_m: float
    heading_deg: float
    alt_m: float
    grounded: bool = False


@dataclass(frozen=True)
class SimEvent:
    """A notable event: ``sysid`` None for world-wide ones; ``text`` for STATUSTEXT."""

    t_s: float
    event: str
    sysid: int | None = None
    text: str | None = None
    severity: int = 6
    data: dict = field(default_factory=dict)


class Simulation:
    """N vehicles, one world, one simulated clock ``t_s`` (s from start)."""

    def __init__(
        self,
        vehicles: list[VehicleSetup],
        params: Params,
        frame: LocalFrame,
        intruders: tuple[Intruder, ...] = (),
        seed: int = 0,
        start_mode: Mode = Mode.GUIDED,
    ) -> None:
        """Fleet at its initial poses, armed and flying in ``start_mode`` at t = 0."""
        self.setups = list(vehicles)
        self.sysids = [v.sysid for v in vehicles]
        self.index_of = {s: i for i, s in enumerate(self.sysids)}
        self.params = params
        self.frame = frame
        self.alt_m = np.array([v.alt_m for v in vehicles], dtype=float)
        self.t_s = 0.0
        self.steps = 0
        self.rng = np.random.default_rng(seed)
        # sensor errors draw from streams of their own (spawned: the gusts stay as they were)
        gps_rng, wind_rng = self.rng.spawn(2)
        self.world = World(intruders)
        self.sightings: list[Sighting] = []
        self.events: list[SimEvent] = []
        self.fences: list[list[np.ndarray]] = [[] for _ in vehicles]  # inclusion polygons (m)
        self.breached: list[str | None] = [None] * len(vehicles)  # what each one breaches
        self.state = ParticleState.at(
            [v.north_m for v in vehicles],
            [v.east_m for v in vehicles],
            np.radians([v.heading_deg for v in vehicles]),
        )
        # on the ground: disarmed, still, at altitude 0, its sensor off (take_off, land)
        self.grounded = np.array([v.grounded for v in vehicles], dtype=bool)
        self.any_grounded = bool(self.grounded.any())
        self.no_takeoff: set[int] = set()  # a fault: these sysids refuse to take off
        self._pp_version = -1
        self._pp: ParticleParams | None = None
        self._wind = 0j
        self.airspeed_m_s = np.full(len(vehicles), params["SIM_AIRSPEED"], dtype=float)
        self._refresh_physics()
        self._wind_capped = False
        self.wind_true_m_s = self._true_wind()
        self.errors = SensorErrors(self._errp, self.wind_true_m_s, gps_rng, wind_rng)
        self._wind_sampled = self.wind_true_m_s  # the wind estimator's last input
        course = self.course_rad
        self.autopilots = [
            Autopilot(v.sysid, params, 0j, start_mode, 0.0, float(course[i]))
            for i, v in enumerate(vehicles)
        ]
        self.batteries = Batteries(len(vehicles), params)
        self.truth_energy = False  # the truth log carries the battery's columns
        for i in np.flatnonzero(self.grounded).tolist():
            self.autopilots[i].armed = False
            self.alt_m[i] = 0.0
            self.airspeed_m_s[i] = 0.0

    # ------------------------------------------------------------------ the ground
    def take_off(self, i: int) -> None:
        """Vehicle ``i`` (0-based) takes off from where it stands: armed, at its altitude and
        the cruise airspeed at once (this simulator has no climb-out), in its mode.

        Raises:
            RefusedError: it is not on the ground.
        """
        if not self.grounded[i]:
            raise RefusedError("takeoff refused: already flying")
        if self.sysids[i] in self.no_takeoff:
            raise RefusedError("takeoff refused: motor fault")
        self.grounded[i] = False
        self.any_grounded = bool(self.grounded.any())
        ap = self.autopilots[i]
        ap.arm(True)
        self.alt_m[i] = self.setups[i].alt_m
        self.airspeed_m_s[i] = self.params["SIM_AIRSPEED"]
        self._take(ap.sysid, ap.drain_events())
        self.events.append(SimEvent(self.t_s, "takeoff", ap.sysid, "Takeoff", 6))

    def land(self, i: int) -> None:
        """Vehicle ``i`` lands where it is, at once (this simulator has no approach): on the
        ground, disarmed (its battery's turnaround starts), still.

        Raises:
            RefusedError: it is on the ground already.
        """
        if self.grounded[i]:
            raise RefusedError("land refused: on the ground")
        self.grounded[i] = True
        self.any_grounded = True
        ap = self.autopilots[i]
        ap.arm(False, force=True)
        self.alt_m[i] = 0.0
        self.airspeed_m_s[i] = 0.0
        runway = self._runway_at(complex(self.state.pos_m[i]))
        if runway is not None:  # landed on a base's runway: it faces the runway's way
            self.state.heading_rad[i] = runway
            self.state.turn_rate_rad_s[i] = 0.0
        self._take(ap.sysid, ap.drain_events())
        self.events.append(SimEvent(self.t_s, "landed", ap.sysid, "Landed", 6))

    def _runway_at(self, pos_m: complex) -> float | None:
        """The heading (rad) of the runway of the nearest base within ``RUNWAY_M`` of
        ``pos_m`` (m): a base is where a vehicle starts on the ground; None if none is near."""
        near = [
            (abs(complex(v.north_m, v.east_m) - pos_m), math.radians(v.heading_deg))
            for v in self.setups
            if v.grounded
        ]
        near = [n for n in near if n[0] <= RUNWAY_M]
        return min(near)[1] if near else None

    # ------------------------------------------------------------------ derived state
    def _refresh_physics(self) -> None:
        p = self.params
        if p.version == self._pp_version:
            return
        self._pp = ParticleParams(
            p["SIM_AIRSPEED"],
            math.radians(p["SIM_TURN_MAX"]),
            p["SIM_LAG"],
            p["SIM_WIND_TURB"],
            p["SIM_GUST_TAU"],
        )
        self._profile = WindProfile.from_params(p)
        self._wind = mean_wind_m_s(self.t_s, self._profile)
        self._errp = ErrorParams.from_params(p)
        self._pp_version = p.version

    @property
    def wind_m_s(self) -> complex:
        """Mean wind vector now: steady + drift + step, no gusts (m/s, direction blown towards)."""
        return self._wind

    def _true_wind(self) -> np.ndarray:
        """Wind at each vehicle: mean + its gust, capped below the airspeed (complex m/s)."""
        raw = self._wind + self.state.gust_m_s
        s0 = self.airspeed_m_s
        if self.any_grounded:  # the wind on the ground is the air's, not capped at 0 m/s
            s0 = np.where(self.grounded, self.params["SIM_AIRSPEED"], s0)
        w = cap_wind(raw, MAX_WIND_RATIO * s0)
        if w is not raw and not self._wind_capped:
            self._wind_capped = True
            self.events.append(
                SimEvent(self.t_s, "wind_capped", None, None, 4, {"ratio": MAX_WIND_RATIO})
            )
        return w

    @property
    def nav_pos_m(self) -> np.ndarray:
        """Position each autopilot believes and reports: truth + GPS error (complex m)."""
        return self.state.pos_m + self.errors.gps_pos_m

    @property
    def nav_velocity_m_s(self) -> np.ndarray:
        """Ground velocity each autopilot believes and reports: truth + GPS error (m/s)."""
        return self.ground_velocity_m_s + self.errors.gps_vel_m_s

    @property
    def ground_velocity_m_s(self) -> np.ndarray:
        """Ground velocity of each vehicle (complex m/s), gusts included."""
        s0 = self.airspeed_m_s
        v = s0 * np.exp(1j * self.state.heading_rad) + self.wind_true_m_s
        return np.where(self.grounded, 0j, v) if self.any_grounded else v

    @property
    def course_rad(self) -> np.ndarray:
        """Course over ground (rad, compass)."""
        return np.angle(self.ground_velocity_m_s)

    def obs(self, i: int) -> Obs:
        """Measured state of vehicle ``i`` (0-based), GPS errors included."""
        v = complex(self.nav_velocity_m_s[i])
        return Obs(
            complex(self.nav_pos_m[i]),
            float(self.state.heading_rad[i]),
            math.atan2(v.imag, v.real),
            abs(v),
            float(self.airspeed_m_s[i]),
        )

    # ---------------------------------------------------------------------- stepping
    def step(self) -> None:
        """Advance every vehicle and the world by one physics step (``DT_S``)."""
        self.advance(1)

    def advance(self, n: int = 1) -> None:
        """Advance every vehicle and the world by ``n`` physics steps at once (``n DT_S``).

        ``n = 1`` is the 50 Hz model: each autopilot decides its turn rate every 20 ms and
        :func:`companion.core.particle.step` flies it. ``n > 1`` is one step of ``n DT_S``
        (the control period, 0.1 s for ``n = SENSOR_EVERY``): each autopilot decides once,
        its course-hold gains converted so that a held course error decays over the step
        as it does over ``n`` steps of 20 ms (:func:`sitl_model.guidance.held_gain`), and
        :func:`sitl_model.physics.advance` flies the step exactly (lag, airspeed, gusts).
        A step inside which an autopilot's timed change falls (GUIDED's setpoint timeout,
        the end of a forced pitch: :meth:`~sitl_model.autopilot.Autopilot.timed_change_within`)
        is taken as ``n`` steps of 20 ms, so such events keep the 50 Hz model's times.
        Sensors, batteries, the world and the fences are evaluated at the multiples of
        ``SENSOR_EVERY`` steps either way, so ``n`` must divide ``SENSOR_EVERY``.

        Raises:
            ValueError: ``n`` does not divide ``SENSOR_EVERY``.
        """
        if n < 1 or SENSOR_EVERY % n:
            raise ValueError(f"n must divide {SENSOR_EVERY}, got {n!r}")
        h = n * DT_S
        if n > 1 and any(ap.timed_change_within(self.t_s, h) for ap in self.autopilots):
            for _ in range(n):  # a GUIDED timeout or a pitch hold ends inside: as at 50 Hz
                self.advance(1)
            return
        self._refresh_physics()
        st = self.state
        vel = self.nav_velocity_m_s  # the autopilots fly on what they measure
        pos_l = self.nav_pos_m.tolist()
        hdg_l = st.heading_rad.tolist()
        vel_l = vel.tolist()
        air_l = self.airspeed_m_s.tolist()
        t = self.t_s
        cmd = []
        target, tau, alt_target = [], [], []
        for ap, p, hd, v, a in zip(self.autopilots, pos_l, hdg_l, vel_l, air_l, strict=True):
            obs = Obs(p, hd, math.atan2(v.imag, v.real), abs(v), a)
            cmd.append(ap.turn_rate_command(t, obs, n))
            va, ta = ap.airspeed_demand(t)
            target.append(va)
            tau.append(ta)
            alt_target.append(math.nan if ap.alt_target_m is None else ap.alt_target_m)
            if ap.events:
                self._take(ap.sysid, ap.drain_events())
        # airspeed relaxes to each autopilot's demand
        va = np.array(target)
        a0 = self.airspeed_m_s
        if n == 1:  # the 50 Hz model: the particles fly the step's mean airspeed
            a1 = va + (a0 - va) * np.exp(-DT_S / np.array(tau))
            s_mean = 0.5 * (a0 + a1)
            cap = MAX_WIND_RATIO * s_mean
            new = step(st, np.array(cmd), self._pp, self._wind, DT_S, self.rng, s_mean, cap)
        else:
            speed = Airspeed(a0, va, np.array(tau))
            a1 = speed.at(h)
            new = physics.advance(
                st, np.array(cmd), self._pp, self._wind, h, speed, MAX_WIND_RATIO, self.rng
            )
        if self.any_grounded:  # still on the ground (the gusts still draw: same stream)
            g = self.grounded
            new = replace(
                new,
                pos_m=np.where(g, st.pos_m, new.pos_m),
                heading_rad=np.where(g, st.heading_rad, new.heading_rad),
            )
            a1 = np.where(g, 0.0, a1)
        self.state = new
        self.airspeed_m_s = a1
        alt_t = np.array(alt_target)
        dz = CLIMB_RATE_M_S * h  # n steps of at most dz / n each: at most dz in all
        # nan_to_num then clip, without their overhead (an infinity is clipped the same)
        dz_m = alt_t - self.alt_m
        move = np.minimum(np.maximum(np.where(np.isnan(dz_m), 0.0, dz_m), -dz), dz)
        self.alt_m = self.alt_m + move
        if self.any_grounded:  # an altitude asked for waits for the take-off
            self.alt_m = np.where(self.grounded, 0.0, self.alt_m)
        self.steps += n
        self.t_s = self.steps * DT_S
        self._disturb()
        if self.steps % SENSOR_EVERY == 0:
            self._drain(SENSOR_EVERY * DT_S)
            self._sense()
            self._check_fences()

    def _drain(self, dt_s: float) -> None:
        """Every battery supplies the last ``dt_s`` (s) of flight at the present airspeed and
        turn rate (motor off while disarmed); level changes and swaps become events."""
        st = self.state
        u = np.broadcast_to(st.turn_rate_rad_s, st.heading_rad.shape)
        armed = np.array([ap.armed for ap in self.autopilots])
        events = self.batteries.step(self.t_s, dt_s, self.airspeed_m_s, u, armed, self.params)
        for e in events:
            sysid = self.sysids[e.index]
            self.events.append(SimEvent(self.t_s, e.event, sysid, e.text, e.severity, e.data))

    def _disturb(self) -> None:
        """The wind now; every ``SENSOR_EVERY`` steps (the GPS's 10 Hz) the sensor errors."""
        if self._profile.varies:
            self._wind = mean_wind_m_s(self.t_s, self._profile)
        self.wind_true_m_s = self._true_wind()
        if self.steps % SENSOR_EVERY == 0:
            self.errors.step(self._errp, self._wind_sampled, SENSOR_EVERY * DT_S)
            self._wind_sampled = self.wind_true_m_s

    def _take(self, sysid: int, events: list[ApEvent]) -> None:
        for e in events:
            self.events.append(SimEvent(self.t_s, e.event, sysid, e.text, e.severity, e.data))

    def _sense(self) -> None:
        pos = self.state.pos_m
        if self.any_grounded:  # a sensor on the ground sees nothing
            pos = np.where(self.grounded, complex(math.nan, math.nan), pos)
        sightings, events = self.world.update(self.t_s, pos, self.params["SIM_SENS_RAD"])
        self.sightings = sightings
        for e in events:
            sysid = None if e.index is None else self.sysids[e.index]
            data = {"intruder": e.intruder_id, "north_m": e.pos_m.real, "east_m": e.pos_m.imag}
            text = None
            if e.event == "detection":
                text = f"Detected {e.intruder_id} at {e.pos_m.real:.0f},{e.pos_m.imag:.0f} m"
            self.events.append(SimEvent(e.t_s, e.event, sysid, text, 5, data))

    def add_intruder(self, intruder: Intruder) -> None:
        """Add an intruder while running (``ValueError`` if its id is taken)."""
        self.world.add(intruder)
        self.events.append(
            SimEvent(self.t_s, "intruder_added", None, None, 6, {"intruder": intruder.id})
        )

    # ---------------------------------------------------------------------- missions
    def nav_points(self, items: tuple[MissionItem, ...]) -> list[tuple[int, complex]]:
        """AUTO waypoints (mission seq, local position m) of a stored mission.

        Item 0 is home (ArduPilot's convention) and is never flown: AUTO starts at item 1.
        """
        return [
            (it.seq, self.frame.to_local(it.x * 1e-7, it.y * 1e-7))
            for it in items
            if it.is_nav and it.seq != 0
        ]

    def home_item(self) -> MissionItem:
        """Mission item 0: home, where HOME_POSITION says (the origin on the ground, m AMSL)."""
        lat, lon, alt = self.frame.to_geodetic(np.zeros(1), np.zeros(1), np.zeros(1))
        return home_item(float(lat[0]), float(lon[0]), float(alt[0]))

    def patrol_items(self, index: int, points: np.ndarray) -> tuple[MissionItem, ...]:
        """A looped waypoint mission through local ``points`` (complex m) at vehicle altitude:
        home at seq 0, then the points from seq 1 (ArduPilot's layout)."""
        lat, lon, _ = self.frame.to_geodetic(points.real, points.imag, np.zeros(len(points)))
        alt = float(self.alt_m[index])
        items = [self.home_item()]
        for k, (la, lo) in enumerate(zip(lat, lon, strict=True)):
            x, y = round(float(la) * 1e7), round(float(lo) * 1e7)
            items.append(MissionItem(k + 1, 6, 16, int(k == 0), 1, 0.0, 0.0, 0.0, 0.0, x, y, alt))
        return tuple(items)

    def fence_items(self, polygon_m: np.ndarray) -> tuple[MissionItem, ...]:
        """FENCE items (mission_type 1) of one inclusion polygon of local ``polygon_m``
        (complex m): MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, param1 = vertex count."""
        pts = np.asarray(polygon_m, dtype=complex)
        lat, lon, _ = self.frame.to_geodetic(pts.real, pts.imag, np.zeros(len(pts)))
        n = float(len(pts))
        return tuple(
            MissionItem(k, 0, FENCE_VERTEX_INCLUSION, 0, 1, n, 0.0, 0.0, 0.0,
                        round(float(a) * 1e7), round(float(b) * 1e7), 0.0, 1)
            for k, (a, b) in enumerate(zip(lat, lon, strict=True))
        )  # fmt: skip

    def set_fence(self, index: int, items: tuple[MissionItem, ...]) -> None:
        """Vehicle ``index`` stores the FENCE items ``items`` (its inclusion polygons)."""
        self.fences[index] = inclusion_polygons(items, self.frame.to_local)

    def _check_fences(self) -> None:
        """With FENCE_ENABLE, a vehicle that leaves its fence says so (STATUSTEXT and a
        ``fence_breach`` event) and, with FENCE_ACTION 1, switches to RTL (ArduPlane). A
        disarmed vehicle (a spare on the ground, a landed UAV) is not checked: ArduPlane's
        ``Plane::fence_check`` counts it as landed (``landing_or_landed = ... || !armed``)
        and breaches nothing there, so a spare at altitude 0 under FENCE_ALT_MIN is no
        breach and keeps its mode."""
        p = self.params
        if p["FENCE_ENABLE"] < 0.5:
            self.breached = [None] * len(self.sysids)
            return
        kinds = breaches(
            self.state.pos_m, self.alt_m, self.fences, p["FENCE_ALT_MIN"], p["FENCE_ALT_MAX"],
            int(p["FENCE_TYPE"]),
        )  # fmt: skip
        for i, kind in enumerate(kinds):
            if not self.autopilots[i].armed:
                kind = None
            if kind == self.breached[i]:
                continue
            sysid, pos = self.sysids[i], complex(self.state.pos_m[i])
            where = {"north_m": round(pos.real, 1), "east_m": round(pos.imag, 1)}
            if kind is None:
                self.events.append(
                    SimEvent(self.t_s, "fence_breach_cleared", sysid, "Fence breach cleared",
                             5, where)
                )  # fmt: skip
            else:
                act = "RTL" if p["FENCE_ACTION"] >= 0.5 else "report"
                data = {"kind": kind, "action": act, "alt_m": float(self.alt_m[i]), **where}
                text = f"Fence Breached: {kind.replace('_', ' ')}"
                self.events.append(SimEvent(self.t_s, "fence_breach", sysid, text, 2, data))
                ap = self.autopilots[i]
                if act == "RTL" and ap.mode is not Mode.RTL:
                    ap.set_mode(Mode.RTL, self.t_s, self.obs(i))
                    self._take(sysid, ap.drain_events())
            self.breached[i] = kind

    # ------------------------------------------------------------------------- truth
    @property
    def truth_header(self) -> str:
        """The truth log's header line (no newline): with the battery's columns or without."""
        return TRUTH_HEADER_ENERGY if self.truth_energy else TRUTH_HEADER

    def truth_rows(self) -> list[str]:
        """CSV rows for the truth log at the current time (one per vehicle), with the
        battery's columns when :attr:`truth_energy` is set."""
        st = self.state
        vel = self.ground_velocity_m_s
        course = np.degrees(np.angle(vel)) % 360.0
        hdg = np.degrees(st.heading_rad) % 360.0
        gs = np.abs(vel)
        tr = np.degrees(np.broadcast_to(st.turn_rate_rad_s, st.heading_rad.shape))
        t = self.t_s
        rows = [
            f"{t:.3f},{sid},{p.real:.3f},{p.imag:.3f},{a:.2f},{h:.5f},{c:.5f},{g:.3f},{u:.4f},"
            f"{ap.mode.name},{w.real:.3f},{w.imag:.3f}"
            for sid, p, a, h, c, g, u, ap, w in zip(
                self.sysids,
                st.pos_m.tolist(),
                self.alt_m.tolist(),
                hdg.tolist(),
                course.tolist(),
                gs.tolist(),
                tr.tolist(),
                self.autopilots,
                self.wind_true_m_s.tolist(),
                strict=True,
            )
        ]
        if not self.truth_energy:
            return rows
        b, cap = self.batteries, self.params["BATT_CAPACITY"]
        pct = 100.0 * (1.0 - b.consumed_mah / cap) if cap > 0 else np.full(len(rows), -1.0)
        return [
            f"{row},{r:.3f},{q:.2f},{e:.3f},{v:.3f}"
            for row, r, q, e, v in zip(
                rows, pct.tolist(), b.consumed_mah.tolist(), b.energy_wh.tolist(),
                b.voltage_v.tolist(), strict=True,
            )
        ]  # fmt: skip

    def drain_events(self) -> list[SimEvent]:
        """Events since the last call (oldest first)."""
        ev, self.events = self.events, []
        return ev
