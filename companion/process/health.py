"""The companion's checks on its autopilot (:mod:`companion.link.supervision`): the setpoint
profile chosen from the first HEARTBEAT, flight state, airspeed and turn response, the issues
raised and cleared (event + STATUSTEXT), and the ``health`` field of the status line."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link import px4
from companion.link.battery import BatteryEstimate
from companion.link.estimate import StateEstimate
from companion.link.setpoints import MAX_BANK_RAD, Profile
from companion.link.shaping import Shaper
from companion.link.supervision import (
    ROLL_LIMIT_PARAMS,
    Issue,
    default_profile,
    not_flying_reason,
)

BANK_LIMIT_ASKS = 4  # PARAM_REQUEST_READs of the bank limit, at most (names in turn)
BANK_LIMIT_ASK_EVERY = 5  # heartbeats between them


class HealthChecks:
    """The checks on the autopilot and the issues they raise.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _make_shaper(self, profile: Profile) -> Shaper:
        m = self.mission
        return Shaper(
            profile,
            m.vehicles.airspeed_m_s,
            m.vehicles.max_turn_rate_rad_s,
            adapt=self.config.adapt,
            offboard=self.offboard,
        )

    def mission_alt_m(self) -> float:
        """This vehicle's mission altitude above the origin (m)."""
        return self.mission.vehicles.altitude_m(self.link.sysid)

    def not_flying_reason(self) -> str | None:
        """None if the aircraft may be taken over; otherwise why not."""
        return not_flying_reason(
            self.armed,
            self.landed_state,
            self.rel_alt_m,
            self.airspeed.last_m_s,
            self.mission_alt_m(),
            self.mission.vehicles.airspeed_m_s,
        )

    @property
    def battery_estimate(self) -> BatteryEstimate | None:
        """The battery as the autopilot last reported it (an input for the Agent's reliefs,
        not used by it yet), or None before any valid report."""
        return self.battery.last

    def health(self) -> str:
        """The status line's health field: ``ok`` or the active issues, comma-separated."""
        names = sorted(self.issues)
        if self._take_control_refused is not None and not self.authority.was_commanding:
            names.append("not_flying")
        return ",".join(names) if names else "ok"

    def _supervise_message(self, m: Any, t: str) -> None:
        if t == "HEARTBEAT" and not self.px4 and px4.is_px4(self.link.autopilot):
            self._px4_found()
        if t == "HEARTBEAT" and self.profile is None:
            self.profile = default_profile(self.link.autopilot)
            self.shaper = self._make_shaper(self.profile)
            self._log("profile", profile=self.profile, autopilot=self.link.autopilot)
        if t == "HEARTBEAT":
            self._ask_bank_limit()
        elif t == "PARAM_VALUE":
            self._on_param_value(m)
        elif t == "EXTENDED_SYS_STATE":
            self.landed_state = int(m.landed_state)
        elif t == "GLOBAL_POSITION_INT":
            self.rel_alt_m = int(m.relative_alt) * 1e-3
        elif t == "VFR_HUD":
            a = float(m.airspeed)
            if self.authority.commanding and self.now_s is not None:
                self._report(self.airspeed.update(self.now_s, a))
            else:
                self.airspeed.last_m_s = a
        elif t == "COMMAND_ACK":
            denied = self.targets.on_ack(
                int(m.command), int(m.result), self.authority.commanding, self.now_s
            )
            if denied and self.agent is not None:
                self.agent.fix_airspeed()

    def _ask_bank_limit(self) -> None:
        """Ask the autopilot its bank limit (ArduPilot ROLL_LIMIT_DEG, then LIM_ROLL_CD if
        unanswered; PX4 FW_R_LIM) for the bank and attitude profiles, every
        ``BANK_LIMIT_ASK_EVERY`` heartbeats, ``BANK_LIMIT_ASKS`` times at most, until it
        answers."""
        names = ROLL_LIMIT_PARAMS.get(self.link.autopilot or 0, ())
        if not names or self.bank_limit.limit_deg is not None:
            return
        if self.shaper.profile not in ("bank", "attitude") or self._bank_asks >= BANK_LIMIT_ASKS:
            return
        self._bank_heartbeats += 1
        if (self._bank_heartbeats - 1) % BANK_LIMIT_ASK_EVERY:
            return
        name = names[self._bank_asks % len(names)][0]  # one name a time: ArduPilot 4.5+'s
        self._bank_asks += 1  # first, so an autopilot that has it refuses nothing
        self.link.send(
            mav.MAVLink_param_request_read_message(self.link.sysid, 1, name.encode(), -1)
        )

    def _on_param_value(self, m: Any) -> None:
        """PARAM_VALUE: the autopilot's bank limit, if that is what it says."""
        name = m.param_id.decode(errors="replace") if isinstance(m.param_id, bytes) else m.param_id
        for param, to_deg in ROLL_LIMIT_PARAMS.get(self.link.autopilot or 0, ()):
            value = float(m.param_value) * to_deg
            if name == param and math.isfinite(value) and 0.0 < value < 90.0:
                self.bank_limit.limit_deg = value
                self.shaper.bank_limit_rad = min(MAX_BANK_RAD, math.radians(value))

    def _airspeed_sent(self, airspeed_m_s: float) -> None:
        """An airspeed was asked of the autopilot (m/s): the monitor and the bank conversion
        follow it."""
        self.airspeed.target_m_s = airspeed_m_s
        self.shaper.airspeed_m_s = airspeed_m_s

    def _supervise_step(self, est: StateEstimate) -> None:
        """Before each setpoint: repeat the targets, check the response to the last one."""
        if not self.px4 and self.authority.mode == "GUIDED":  # not in its own take-off
            self.targets.repeat_if_due(est.t_s, self.now_s)  # or landing (TAKEOFF, AUTO)
        self._report(
            *self.response.update(
                est.t_s,
                self.shaper.x_in_force,
                est.turn_rate_rad_s,
                self.shaper.gain,
                est.groundspeed_m_s,
            )
        )
        if self.shaper.profile in ("bank", "attitude") and self.shaper.adapt:
            self._report(
                self.bank_limit.update(
                    est.t_s,
                    self.shaper.airspeed_m_s,
                    self.shaper.gain,
                    self.shaper.estimate.samples,
                )
            )

    def _report(self, *issues: Issue | None) -> None:
        for iss in issues:
            if iss is None:
                continue
            sysid = self.link.sysid
            if iss.active:
                self.issues[iss.name] = iss.text
                self._log(iss.name, text=iss.text)
                self.link.statustext(f"companion {sysid}: {iss.text}", severity=4)
            else:
                self.issues.pop(iss.name, None)
                self._log(f"{iss.name}_cleared", text=iss.text)
                self.link.statustext(f"companion {sysid}: {iss.text}")
