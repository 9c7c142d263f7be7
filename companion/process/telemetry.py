"""What the autopilot says of its aircraft: vehicle time, the state estimate, the battery,
armed and landed state, height above home, and whether its streams come at the rates asked
(one component of the :class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

from typing import Any

from companion.link import px4
from companion.link.battery import BatteryMonitor
from companion.link.clock import VehicleClock
from companion.link.estimate import Estimator, StateEstimate
from companion.mission import Mission
from companion.process.config import Counters
from companion.process.events import Armed, Disarmed
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effects
from companion.process.streams import StreamWatch

MAV_MODE_FLAG_SAFETY_ARMED = 128


class Telemetry:
    """The aircraft's state as its autopilot streams it.

    Args:
        mission: the mission (origin, airspeed, wind).
        boot_epoch_s: vehicle time = this (unix s) + ``time_boot_ms`` (None: from
            SYSTEM_TIME, :class:`companion.link.clock.VehicleClock`).
        link: what is read of the link (the autopilot's sysid and type).
        counters: the process's counts (``estimates``).

    Attributes:
        now_s: the latest vehicle time (unix s), that of the newest estimate; None before.
        first_s: the vehicle time of the first estimate (s), or None.
        last_est: the newest estimate.
        armed: the autopilot's armed flag (None before its first heartbeat).
        landed_state: EXTENDED_SYS_STATE's MAV_LANDED_STATE (None: not heard).
        rel_alt_m: height above home (m), from GLOBAL_POSITION_INT.
        streams: the rate of each stream asked for (:mod:`~.streams`; its hook runs first
            for each streamed message, :mod:`~.messages`).
    """

    def __init__(
        self, mission: Mission, boot_epoch_s: float | None, link: LinkState, counters: Counters
    ) -> None:
        """Nothing heard yet."""
        self.clock = VehicleClock(fixed_offset_s=boot_epoch_s)
        self.estimator = Estimator(
            mission.origin, mission.vehicles.airspeed_m_s, mission.wind.wind()
        )
        self.battery = BatteryMonitor()  # SYS_STATUS / BATTERY_STATUS; the Agent ignores it yet
        self.link = link
        self.counters = counters
        self.now_s: float | None = None
        self.first_s: float | None = None
        self.last_est: StateEstimate | None = None
        self.armed: bool | None = None
        self.landed_state: int | None = None
        self.rel_alt_m: float | None = None
        self._fresh: StateEstimate | None = None  # made by the last position, not yet used
        self.streams = StreamWatch(link, lambda: self.now_s)

    # ---- the hooks, one per message type (companion.process.messages) ------------------------
    def on_heartbeat(self, m: Any) -> Effects:
        """HEARTBEAT: PX4's clock (its SYSTEM_TIME is the host's, docs/px4.md); ``armed`` or
        ``disarmed`` when the flag changes (not for the first heartbeat)."""
        if px4.is_px4(self.link.autopilot):
            self.clock.anchor_once = True
        armed = bool(m.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        if armed == self.armed:
            return NOTHING
        before, self.armed = self.armed, armed
        if before is None:
            return NOTHING
        kind = Armed if armed else Disarmed
        return (kind(t_s=self.now_s, sysid=self.link.sysid),)

    def on_system_time(self, m: Any) -> Effects:
        """SYSTEM_TIME: the vehicle clock's offset."""
        self.clock.on_system_time(int(m.time_unix_usec), int(m.time_boot_ms))
        return NOTHING

    def on_position(self, m: Any) -> Effects:
        """GLOBAL_POSITION_INT: height above home and, once vehicle time is known, a state
        estimate (then :attr:`now_s` moves on; :meth:`take_estimate` hands it on)."""
        self.rel_alt_m = int(m.relative_alt) * 1e-3
        t = self.clock.to_vehicle_s(int(m.time_boot_ms))
        if t is None:
            return NOTHING
        est = self.estimator.from_global_position(
            t, int(m.time_boot_ms), m.lat, m.lon, m.alt, m.vx, m.vy, m.hdg
        )
        if est is None:
            return NOTHING
        self.now_s = t
        self.last_est = self._fresh = est
        self.counters.estimates += 1
        if self.first_s is None:
            self.first_s = t
        return NOTHING

    def take_estimate(self) -> StateEstimate | None:
        """The estimate the last GLOBAL_POSITION_INT made, once (None: none new)."""
        est, self._fresh = self._fresh, None
        return est

    def on_attitude(self, m: Any) -> Effects:
        """ATTITUDE: the yaw, for the air heading."""
        self.estimator.on_attitude(int(m.time_boot_ms), float(m.yaw))
        return NOTHING

    def on_vfr_hud(self, m: Any) -> Effects:
        """VFR_HUD: the airspeed, for the air heading."""
        self.estimator.on_airspeed(float(m.airspeed))
        return NOTHING

    def on_extended_sys_state(self, m: Any) -> Effects:
        """EXTENDED_SYS_STATE: the landed state."""
        self.landed_state = int(m.landed_state)
        return NOTHING

    def on_wind(self, m: Any) -> Effects:
        """WIND (ArduPilot): the autopilot's wind estimate (speed m/s, from deg)."""
        if self.now_s is not None:
            self.estimator.on_autopilot_wind(self.now_s, float(m.speed), float(m.direction))
        return NOTHING

    def on_wind_cov(self, m: Any) -> Effects:
        """WIND_COV (PX4): the autopilot's wind vector (m/s, north and east)."""
        if self.now_s is not None:
            self.estimator.on_autopilot_wind_vector(self.now_s, float(m.wind_x), float(m.wind_y))
        return NOTHING

    def on_sys_status(self, m: Any) -> Effects:
        """SYS_STATUS: the battery's voltage, current and remaining."""
        if self.now_s is not None:
            self.battery.on_sys_status(
                self.now_s, m.voltage_battery, m.current_battery, m.battery_remaining
            )
        return NOTHING

    def on_battery_status(self, m: Any) -> Effects:
        """BATTERY_STATUS: the battery's cells, current, consumed and remaining."""
        if self.now_s is not None:
            self.battery.on_battery_status(
                self.now_s, m.id, m.voltages, m.current_battery, m.current_consumed,
                m.battery_remaining,
            )  # fmt: skip
        return NOTHING
