"""The setpoint channel to the autopilot: which profile (chosen from the first HEARTBEAT when
``auto``), whether the autopilot is PX4 (its offboard profiles, :mod:`companion.link.offboard`),
the shaper that turns a turn rate into a setpoint (:mod:`companion.link.shaping`), and the
setpoint in force, resent when telemetry stalls (one component of the
:class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

from typing import Any

from companion.link import px4
from companion.link.estimate import StateEstimate
from companion.link.offboard import OffboardSetpoints
from companion.link.setpoints import Profile, ProfileChoice
from companion.link.shaping import Shaper
from companion.link.supervision import default_profile
from companion.mission import Mission
from companion.process.config import Counters
from companion.process.events import ProfileChosen
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effects
from companion.process.telemetry import Telemetry

KEEPALIVE_WALL_S = 0.25  # resend the setpoint in force after this much wall time without one:
# ArduPlane drops an attitude override 3 s (vehicle time) after the last message


class SetpointChannel:
    """The profile, the shaper and the setpoint in force.

    Args:
        mission: the mission (origin, airspeed, turn-rate limit, altitudes).
        profile: the profile asked for ("auto": from the first HEARTBEAT).
        adapt: close the loop on the achieved turn rate (online gain estimate).
        link: what is read of the link (sysid, autopilot type).
        telemetry: the aircraft's state (vehicle time, for the events' stamps).
        counters: the process's counts (``keepalives``).

    Attributes:
        profile: the profile in use (None until the first HEARTBEAT resolves ``auto``).
        px4: the autopilot is PX4 (its first HEARTBEAT says).
        offboard: PX4's profiles: holds and targets.
        shaper: the setpoint shaper (a provisional turn-rate one until the profile is known).
    """

    def __init__(
        self,
        mission: Mission,
        profile: ProfileChoice,
        adapt: bool,
        link: LinkState,
        telemetry: Telemetry,
        counters: Counters,
    ) -> None:
        """No profile yet if ``auto``; nothing sent."""
        self.mission = mission
        self.adapt = adapt
        self.link = link
        self.telemetry = telemetry
        self.counters = counters
        self.profile: Profile | None = None if profile == "auto" else profile
        self.px4 = False
        self.offboard = OffboardSetpoints(mission.origin)
        self.shaper = self._make_shaper(self.profile or "turn-rate")
        self._last_msg: Any = None  # the setpoint in force (None: none to keep alive)
        self._last_wall_s = 0.0  # wall time it was last sent (s)

    def _make_shaper(self, profile: Profile) -> Shaper:
        v = self.mission.vehicles
        return Shaper(
            profile,
            v.airspeed_m_s,
            v.max_turn_rate_rad_s,
            adapt=self.adapt,
            offboard=self.offboard,
        )

    def mission_alt_m(self) -> float:
        """This vehicle's mission altitude above the origin (m); the first one while the
        autopilot's sysid is unknown."""
        v, sysid = self.mission.vehicles, self.link.sysid
        return v.altitudes_m[0] if sysid is None else v.altitude_m(sysid)

    # ---- the hooks ------------------------------------------------------------------------
    def on_heartbeat(self, m: Any) -> Effects:
        """HEARTBEAT: PX4 found (its targets), the profile resolved (event ``profile``)."""
        autopilot = self.link.autopilot
        if not self.px4 and px4.is_px4(autopilot):
            self.px4 = True
            self.offboard.target_alt_amsl_m = self.mission.origin.alt_m + self.mission_alt_m()
            self.offboard.target_airspeed_m_s = self.mission.vehicles.airspeed_m_s
        if self.profile is not None:
            return NOTHING
        self.profile = default_profile(autopilot)
        self.shaper = self._make_shaper(self.profile)
        return (
            ProfileChosen(
                t_s=self.telemetry.now_s,
                sysid=self.link.sysid,
                profile=self.profile,
                autopilot=autopilot,
            ),
        )

    def on_attitude(self, m: Any) -> Effects:
        """ATTITUDE: roll, pitch and yaw for PX4's holds."""
        if self.px4:
            self.offboard.data.on_attitude(float(m.roll), float(m.pitch), float(m.yaw))
        return NOTHING

    def on_vfr_hud(self, m: Any) -> Effects:
        """VFR_HUD: airspeed and throttle for PX4's holds."""
        if self.px4:
            self.offboard.data.on_vfr_hud(float(m.airspeed), float(m.throttle))
        return NOTHING

    def on_position(self, m: Any) -> None:
        """A GLOBAL_POSITION_INT that made an estimate: altitude and climb for PX4's holds."""
        if self.px4:
            self.offboard.data.on_position(int(m.alt), int(m.vz))

    # ---- setpoints --------------------------------------------------------------------------
    def setpoint(self, est: StateEstimate, turn_rate_rad_s: float, sysid: int) -> Any:
        """The setpoint for ``turn_rate_rad_s`` (rad/s) from estimate ``est``, in the
        profile, to autopilot ``sysid``."""
        return self.shaper.setpoint(
            est.t_s,
            turn_rate_rad_s,
            est.course_rad,
            est.time_boot_ms,
            sysid,
            pos_m=est.pos_m,
            heading_rad=est.heading_rad,
            wind_m_s=self.telemetry.estimator.wind.vector,
        )

    def in_force(self, msg: Any, wall_s: float) -> None:
        """``msg`` is the setpoint in force, sent at wall time ``wall_s`` (s)."""
        self._last_msg, self._last_wall_s = msg, wall_s

    def forget(self) -> None:
        """No setpoint in force (command lost, or the aircraft on the ground)."""
        self._last_msg = None

    def keepalive(self, wall_s: float, commanding: bool) -> Any:
        """The setpoint in force to resend at wall time ``wall_s`` (s) when none went for
        ``KEEPALIVE_WALL_S`` while ``commanding`` (ArduPlane forgets an attitude override
        3 s after the last one), else None."""
        msg = self._last_msg
        if msg is None or not commanding or wall_s - self._last_wall_s < KEEPALIVE_WALL_S:
            return None
        self._last_wall_s = wall_s
        self.counters.keepalives += 1
        return msg
