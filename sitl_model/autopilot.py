"""A pure model of one ArduPlane-like autopilot: modes, arming, setpoints, navigation.

No sockets and no clock of its own: every call takes the simulated time ``t_s`` (s) and the
vehicle's measured state :class:`Obs`. :meth:`Autopilot.turn_rate_command` returns the
turn rate (rad/s, positive = right) the physics should fly next step; the physics applies
the turn-rate limit and the response lag.

Conventions: complex positions ``north + i east`` (m), compass angles (rad).

Modes (ArduPlane custom mode numbers) and what they fly:

========  ==  ==========================================================================
MANUAL     0  wings level (no pilot)
CIRCLE     1  constant right turn at half the turn-rate limit
AUTO      10  the stored waypoints in a loop (straight legs, look-ahead guidance)
RTL       11  loiter around home
LOITER    12  loiter around the point where the mode was entered
GUIDED    15  setpoints; holds the entry course until the first one; after GUID_TIMEOUT
              without a setpoint it loiters where it is, until the next setpoint
========  ==  ==========================================================================

Airspeed and altitude (GUIDED): :meth:`Autopilot.airspeed_demand` is the airspeed the
vehicle relaxes to: the cruise ``SIM_AIRSPEED``, a GUIDED_CHANGE_SPEED target, or, while a
SET_ATTITUDE_TARGET forces the pitch (ArduPlane: the attitude bit clear), a decay to
``PITCH_FORCED_AIRSPEED_FRAC`` of cruise with time constant ``PITCH_FORCED_TAU_S`` (measured
on ArduPlane SITL: 19.9 -> 16.6 -> 13.4 -> 11.4 m/s at 10, 30, 60 s with pitch forced to 0).
:attr:`Autopilot.alt_target_m` is a GUIDED_CHANGE_ALTITUDE target (m above the origin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum, IntEnum
from typing import NamedTuple

from sitl_model import guidance
from sitl_model.params import Params

G_M_S2 = 9.80665
LOOP_DT_S = 0.02  # the loop the gains are given for (s): 50 Hz, the physics step
NAV_KP_1_S = 1.0  # course-hold gain of the navigation modes (1/s)
FORCED_HOLD_S = 3.0  # ArduPlane: an attitude override lasts 3 s after the last message
PITCH_FORCED_AIRSPEED_FRAC = 0.55  # airspeed the decay tends to (x cruise; 11/20 measured)
PITCH_FORCED_TAU_S = 21.0  # time constant of that decay (s), fitted to 10/30/60 s figures
SPEED_TAU_S = 3.0  # time constant of an airspeed change asked for (s)
SPEED_RANGE_FRAC = (0.5, 1.5)  # GUIDED_CHANGE_SPEED accepted within these x cruise


class Mode(IntEnum):
    """ArduPlane custom modes this model flies."""

    MANUAL = 0
    CIRCLE = 1
    AUTO = 10
    RTL = 11
    LOITER = 12
    TAKEOFF = 13  # armed on the ground: it takes off (sitl_model.sim), then loiters
    GUIDED = 15


class SetpointKind(Enum):
    """What a GUIDED setpoint commands."""

    TURN_RATE = "turn_rate"  # value: rad/s
    ROLL = "roll"  # value: bank angle phi (rad)
    COURSE = "course"  # value: course over ground (rad)
    HEADING = "heading"  # value: air heading (rad)


@dataclass(frozen=True)
class Setpoint:
    """A GUIDED setpoint. ``accel_limit_m_s2`` (course/heading only): 0 = no extra limit."""

    kind: SetpointKind
    value: float
    accel_limit_m_s2: float = 0.0


class Obs(NamedTuple):
    """The vehicle's measured state (position m, heading/course rad, ground speed m/s).

    A named tuple rather than a frozen dataclass: one is built per vehicle per physics step.
    """

    pos_m: complex
    heading_rad: float
    course_rad: float
    groundspeed_m_s: float
    airspeed_m_s: float = 0.0  # 0: unknown, the cruise SIM_AIRSPEED is used


@dataclass(frozen=True)
class ApEvent:
    """Something notable: ``event`` name for logs, ``text`` for STATUSTEXT (<= 50 chars)."""

    event: str
    text: str
    severity: int = 6  # MAV_SEVERITY_INFO
    data: dict = field(default_factory=dict)


class RefusedError(ValueError):
    """A command the autopilot will not carry out; ``str()`` says why."""


class Autopilot:
    """One vehicle's autopilot. State changes only through the methods below."""

    def __init__(
        self,
        sysid: int,
        params: Params,
        home_m: complex,
        mode: Mode = Mode.GUIDED,
        t_s: float = 0.0,
        course_rad: float = 0.0,
    ) -> None:
        """Armed and flying in ``mode`` at time ``t_s`` (s) on ``course_rad``."""
        self.sysid = sysid
        self.params = params
        self.home_m = home_m
        self.armed = True
        self.mode = mode
        self.nav: list[tuple[int, complex]] = []  # (mission seq, local position m)
        self.current_seq = 0
        self.events: list[ApEvent] = []
        self._setpoint: Setpoint | None = None
        self._last_setpoint_t = t_s
        self._hold_course = course_rad
        self._guided_loiter = False
        self._loiter_centre = home_m
        self._leg_start: complex | None = None
        self._pitch_forced_t = -math.inf  # vehicle time of the last forced pitch (s)
        self.airspeed_target_m_s: float | None = None  # GUIDED_CHANGE_SPEED (m/s)
        self.alt_target_m: float | None = None  # GUIDED_CHANGE_ALTITUDE (m above origin)

    # ----------------------------------------------------------------------------- modes
    def set_mode(self, mode_number: int, t_s: float, obs: Obs) -> None:
        """Change mode; raises :class:`RefusedError` for unknown modes or AUTO without waypoints."""
        try:
            mode = Mode(int(mode_number))
        except ValueError:
            raise RefusedError(f"mode {mode_number} not supported") from None
        if mode is Mode.AUTO and not self.nav:
            raise RefusedError("AUTO refused: no mission")
        if mode is self.mode:
            return  # re-selecting the current mode keeps its state (setpoint, loiter centre)
        old = self.mode
        self.mode = mode
        self._setpoint = None
        self._guided_loiter = False
        self._last_setpoint_t = t_s
        self._hold_course = obs.course_rad
        self._pitch_forced_t = -math.inf
        radius = self.params["WP_LOITER_RAD"]
        if mode in (Mode.LOITER, Mode.TAKEOFF):
            self._loiter_centre = guidance.loiter_centre(obs.pos_m, obs.course_rad, radius, True)
        elif mode is Mode.RTL:
            self._loiter_centre = self.home_m
        elif mode is Mode.AUTO:
            self._leg_start = obs.pos_m
        self.events.append(
            ApEvent("mode_change", f"Mode {mode.name}", data={"from": old.name, "to": mode.name})
        )

    def arm(self, arm: bool, force: bool = False) -> None:
        """Arm, or disarm (refused in flight unless forced; disarmed = wings level, no control)."""
        if arm == self.armed:
            return
        if not arm and not force:
            raise RefusedError("disarm refused: flying (force with 21196)")
        self.armed = arm
        self.events.append(ApEvent("armed" if arm else "disarmed", "Armed" if arm else "Disarmed"))

    # ------------------------------------------------------------------------- setpoints
    def setpoint(self, sp: Setpoint, t_s: float) -> None:
        """Accept a GUIDED setpoint at ``t_s``; raises :class:`RefusedError` outside GUIDED."""
        if self.mode is not Mode.GUIDED:
            raise RefusedError(f"setpoint refused: mode {self.mode.name}, not GUIDED")
        if not self.armed:
            raise RefusedError("setpoint refused: disarmed")
        if not math.isfinite(sp.value) or not math.isfinite(sp.accel_limit_m_s2):
            raise RefusedError("setpoint refused: not finite")
        if sp.kind is SetpointKind.ROLL and abs(sp.value) >= math.radians(89.0):
            raise RefusedError("setpoint refused: roll out of range")
        if sp.accel_limit_m_s2 < 0:
            raise RefusedError("setpoint refused: negative acceleration limit")
        if self._guided_loiter:
            self._guided_loiter = False
            self.events.append(ApEvent("guided_resumed", "GUIDED: setpoints resumed"))
        self._setpoint = sp
        self._last_setpoint_t = t_s

    def force_pitch(self, t_s: float) -> None:
        """A SET_ATTITUDE_TARGET forced the pitch at ``t_s`` (s): the airspeed decays for
        ``FORCED_HOLD_S`` after it (ArduPlane's pitch 0 without TECS). GUIDED only."""
        if self.mode is not Mode.GUIDED:
            raise RefusedError(f"setpoint refused: mode {self.mode.name}, not GUIDED")
        self._pitch_forced_t = t_s

    def change_airspeed(self, airspeed_m_s: float) -> None:
        """GUIDED_CHANGE_SPEED: fly ``airspeed_m_s`` (m/s) in GUIDED; refused outside GUIDED
        or outside ``SPEED_RANGE_FRAC`` of the cruise airspeed."""
        if self.mode is not Mode.GUIDED:
            raise RefusedError(f"speed refused: mode {self.mode.name}, not GUIDED")
        cruise = self.params["SIM_AIRSPEED"]
        lo, hi = SPEED_RANGE_FRAC
        if not (math.isfinite(airspeed_m_s) and lo * cruise <= airspeed_m_s <= hi * cruise):
            raise RefusedError(f"speed refused: outside {lo * cruise:g}-{hi * cruise:g} m/s")
        self.airspeed_target_m_s = float(airspeed_m_s)

    def change_altitude(self, alt_m: float) -> None:
        """GUIDED_CHANGE_ALTITUDE: hold ``alt_m`` (m above the origin); GUIDED only."""
        if self.mode is not Mode.GUIDED:
            raise RefusedError(f"altitude refused: mode {self.mode.name}, not GUIDED")
        if not math.isfinite(alt_m):
            raise RefusedError("altitude refused: not finite")
        self.alt_target_m = float(alt_m)

    def airspeed_demand(self, t_s: float) -> tuple[float, float]:
        """Airspeed (m/s) the vehicle tends to at ``t_s`` (s) and the time constant (s)."""
        cruise = self.params["SIM_AIRSPEED"]
        if self.mode is Mode.GUIDED and self.armed:
            if t_s - self._pitch_forced_t < FORCED_HOLD_S:
                return PITCH_FORCED_AIRSPEED_FRAC * cruise, PITCH_FORCED_TAU_S
            if self.airspeed_target_m_s is not None:
                return self.airspeed_target_m_s, SPEED_TAU_S
        return cruise, SPEED_TAU_S

    # -------------------------------------------------------------------------- missions
    def set_waypoints(self, nav: list[tuple[int, complex]], t_s: float, obs: Obs) -> None:
        """Replace the navigation waypoints ((mission seq, position m) in order)."""
        self.nav = list(nav)
        self.current_seq = self.nav[0][0] if self.nav else 0
        self._leg_start = obs.pos_m

    def set_current(self, seq: int, obs: Obs) -> None:
        """Make mission item ``seq`` current (the next waypoint at or after it)."""
        if not self.nav:
            raise RefusedError("no mission")
        if seq < 0 or seq > max(s for s, _ in self.nav):
            raise RefusedError(f"no mission item {seq}")
        after = [s for s, _ in self.nav if s >= seq]
        self.current_seq = after[0]
        self._leg_start = obs.pos_m

    # ---------------------------------------------------------------------------- flying
    def turn_rate_command(self, t_s: float, obs: Obs, held: int = 1) -> float:
        """Turn rate (rad/s) to fly for the next ``held`` steps of ``LOOP_DT_S``; also records
        events. The course holds' gains are those of the 50 Hz loop held ``held`` steps
        (:func:`sitl_model.guidance.held_gain`)."""
        if not self.armed:
            return 0.0
        p = self.params
        limit = math.radians(p["SIM_TURN_MAX"])
        mode = self.mode
        if mode is Mode.MANUAL:
            return 0.0
        if mode is Mode.CIRCLE:
            return 0.5 * limit
        if mode in (Mode.LOITER, Mode.RTL, Mode.TAKEOFF):
            return self._loiter(obs, self._loiter_centre, limit, held)
        if mode is Mode.AUTO:
            return self._auto(obs, limit, held)
        return self._guided(t_s, obs, limit, held)

    def _loiter(self, obs: Obs, centre: complex, limit: float, held: int) -> float:
        course, ff = guidance.loiter_guidance(
            obs.pos_m, centre, self.params["WP_LOITER_RAD"], True, obs.groundspeed_m_s
        )
        kp = guidance.held_gain(NAV_KP_1_S, LOOP_DT_S, held)
        return guidance.course_hold(course, obs.course_rad, kp, limit, ff)

    def _auto(self, obs: Obs, limit: float, held: int) -> float:
        if not self.nav:
            return self._loiter(obs, self.home_m, limit, held)
        seqs = [s for s, _ in self.nav]
        i = seqs.index(self.current_seq) if self.current_seq in seqs else 0
        target = self.nav[i][1]
        start = self._leg_start if self._leg_start is not None else obs.pos_m
        if guidance.leg_done(obs.pos_m, start, target, self.params["WP_RADIUS"]):
            self.events.append(
                ApEvent(
                    "waypoint_reached",
                    f"Reached waypoint #{self.current_seq}",
                    data={"seq": self.current_seq},
                )
            )
            i = (i + 1) % len(self.nav)
            self.current_seq = self.nav[i][0]
            self._leg_start = target
            start, target = target, self.nav[i][1]
        radius = self.params["SIM_AIRSPEED"] / max(limit, 1e-6)
        course = guidance.track_guidance(obs.pos_m, start, target, 2.0 * radius)
        kp = guidance.held_gain(NAV_KP_1_S, LOOP_DT_S, held)
        return guidance.course_hold(course, obs.course_rad, kp, limit)

    def _guided(self, t_s: float, obs: Obs, limit: float, held: int) -> float:
        p = self.params
        if not self._guided_loiter and t_s - self._last_setpoint_t > p["GUID_TIMEOUT"]:
            self._guided_loiter = True
            self._loiter_centre = guidance.loiter_centre(
                obs.pos_m, obs.course_rad, p["WP_LOITER_RAD"], True
            )
            self.events.append(
                ApEvent(
                    "guided_timeout",
                    f"GUIDED: no setpoint for {p['GUID_TIMEOUT']:g} s, loitering",
                    severity=4,  # MAV_SEVERITY_WARNING
                )
            )
        if self._guided_loiter:
            return self._loiter(obs, self._loiter_centre, limit, held)
        sp = self._setpoint
        if sp is None:
            kp = guidance.held_gain(NAV_KP_1_S, LOOP_DT_S, held)
            return guidance.course_hold(self._hold_course, obs.course_rad, kp, limit)
        if sp.kind is SetpointKind.TURN_RATE:
            return sp.value
        if sp.kind is SetpointKind.ROLL:
            v = obs.airspeed_m_s if obs.airspeed_m_s > 0 else p["SIM_AIRSPEED"]
            lim_phi = math.radians(p["ROLL_LIMIT_DEG"])  # ArduPlane clips nav_roll_cd to it
            phi = max(-lim_phi, min(lim_phi, sp.value))
            return p["SIM_TR_EFF"] * G_M_S2 * math.tan(phi) / v
        lim = limit
        if sp.accel_limit_m_s2 > 0:
            lim = min(limit, sp.accel_limit_m_s2 / p["SIM_AIRSPEED"])
        measured = obs.course_rad if sp.kind is SetpointKind.COURSE else obs.heading_rad
        kp = guidance.held_gain(p["SIM_CRS_KP"], LOOP_DT_S, held)
        return guidance.course_hold(sp.value, measured, kp, lim)

    def timed_change_within(self, t_s: float, h_s: float) -> bool:
        """Whether a timed change falls within the next ``h_s`` seconds after ``t_s``: GUIDED's
        setpoint timeout (then it loiters) or the end of a forced pitch's hold (then the
        airspeed demand changes). A step of ``h_s`` taken at once would see it late."""
        if self.mode is not Mode.GUIDED or not self.armed:
            return False
        timeout = not self._guided_loiter and (
            t_s + h_s - self._last_setpoint_t > self.params["GUID_TIMEOUT"]
        )
        pitch = t_s - self._pitch_forced_t < FORCED_HOLD_S <= t_s + h_s - self._pitch_forced_t
        return timeout or pitch

    @property
    def guided_loitering(self) -> bool:
        """Whether GUIDED has timed out and the vehicle loiters."""
        return self._guided_loiter

    def drain_events(self) -> list[ApEvent]:
        """Events since the last call (oldest first)."""
        ev, self.events = self.events, []
        return ev
