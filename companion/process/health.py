"""The companion's checks on its autopilot (:mod:`companion.link.supervision`): a profile PX4
does not fly, the bank limit asked and read, airspeed and turn response, whether the
aircraft flies (may be taken over), and the issues raised and cleared (event + STATUSTEXT)
(one component of the :class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.estimate import StateEstimate
from companion.link.modes import Authority
from companion.link.outbox import MAV_SEVERITY_WARNING, Statustext
from companion.link.setpoints import MAX_BANK_RAD, PX4_PROFILES
from companion.link.supervision import (
    ROLL_LIMIT_PARAMS,
    AirspeedMonitor,
    BankLimitMonitor,
    Issue,
    ResponseMonitor,
    not_flying_reason,
)
from companion.mission import Mission
from companion.process.events import IssueCleared, IssueRaised
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effect, Effects
from companion.process.setpoint import SetpointChannel
from companion.process.telemetry import Telemetry

BANK_LIMIT_ASKS = 4  # PARAM_REQUEST_READs of the bank limit, at most (names in turn)
BANK_LIMIT_ASK_EVERY = 5  # heartbeats between them


class Health:
    """The checks on the autopilot and the issues they raise.

    Args:
        mission: the mission (airspeed, turn-rate limit, altitudes).
        link: what is read of the link (sysid, autopilot type).
        telemetry: the aircraft's state (vehicle time, armed, landed, height).
        channel: the setpoint channel (its shaper's profile, gain and airspeed).
        authority: command authority (read only: whether the companion commands).

    Attributes:
        issues: the active issues, name -> text.
        airspeed: the airspeed monitor (its ``last_m_s`` is the latest VFR_HUD airspeed).
    """

    def __init__(
        self,
        mission: Mission,
        link: LinkState,
        telemetry: Telemetry,
        channel: SetpointChannel,
        authority: Authority,
    ) -> None:
        """No issue; the bank limit not asked yet."""
        v = mission.vehicles
        self.mission = mission
        self.link = link
        self.telemetry = telemetry
        self.channel = channel
        self.authority = authority
        self.issues: dict[str, str] = {}
        self.airspeed = AirspeedMonitor(v.airspeed_m_s)
        self.response = ResponseMonitor(max_turn_rate_rad_s=v.max_turn_rate_rad_s)
        self.bank_limit = BankLimitMonitor(v.max_turn_rate_rad_s)
        self._bank_asks = self._bank_heartbeats = 0  # PARAM_REQUEST_READs of the bank limit
        self._px4_checked = False

    def not_flying_reason(self) -> str | None:
        """None if the aircraft may be taken over; otherwise why not."""
        tm = self.telemetry
        return not_flying_reason(
            tm.armed,
            tm.landed_state,
            tm.rel_alt_m,
            self.airspeed.last_m_s,
            self.channel.mission_alt_m(),
            self.mission.vehicles.airspeed_m_s,
        )

    # ---- the hooks --------------------------------------------------------------------------
    def on_heartbeat(self, m: Any) -> Effects:
        """HEARTBEAT: a profile PX4 does not fly (said once, when PX4 is found); the bank
        limit asked."""
        out: list[Effect] = []
        ch = self.channel
        if ch.px4 and not self._px4_checked:
            self._px4_checked = True
            if ch.profile is not None and ch.profile not in PX4_PROFILES:
                text = f"profile {ch.profile} is no PX4 offboard setpoint: use attitude or path"
                out += self.report(Issue("profile_unsupported", True, text))
        out += self._ask_bank_limit()
        return out

    def _ask_bank_limit(self) -> Effects:
        """Ask the autopilot its bank limit (ArduPilot ROLL_LIMIT_DEG, then LIM_ROLL_CD if
        unanswered; PX4 FW_R_LIM) for the bank and attitude profiles, every
        ``BANK_LIMIT_ASK_EVERY`` heartbeats, ``BANK_LIMIT_ASKS`` times at most, until it
        answers."""
        names = ROLL_LIMIT_PARAMS.get(self.link.autopilot or 0, ())
        if not names or self.bank_limit.limit_deg is not None:
            return NOTHING
        profile = self.channel.shaper.profile
        if profile not in ("bank", "attitude") or self._bank_asks >= BANK_LIMIT_ASKS:
            return NOTHING
        self._bank_heartbeats += 1
        if (self._bank_heartbeats - 1) % BANK_LIMIT_ASK_EVERY:
            return NOTHING
        name = names[self._bank_asks % len(names)][0]  # one name a time: ArduPilot 4.5+'s
        self._bank_asks += 1  # first, so an autopilot that has it refuses nothing
        return (mav.MAVLink_param_request_read_message(self.link.sysid, 1, name.encode(), -1),)

    def on_param_value(self, m: Any) -> Effects:
        """PARAM_VALUE: the autopilot's bank limit, if that is what it says."""
        name = m.param_id.decode(errors="replace") if isinstance(m.param_id, bytes) else m.param_id
        for param, to_deg in ROLL_LIMIT_PARAMS.get(self.link.autopilot or 0, ()):
            value = float(m.param_value) * to_deg
            if name == param and math.isfinite(value) and 0.0 < value < 90.0:
                self.bank_limit.limit_deg = value
                self.channel.shaper.bank_limit_rad = min(MAX_BANK_RAD, math.radians(value))
        return NOTHING

    def on_vfr_hud(self, m: Any) -> Effects:
        """VFR_HUD: the airspeed, checked against the target while commanding."""
        a = float(m.airspeed)
        now_s = self.telemetry.now_s
        if self.authority.commanding and now_s is not None:
            return self.report(self.airspeed.update(now_s, a))
        self.airspeed.last_m_s = a
        return NOTHING

    # ---- around a control step --------------------------------------------------------------
    def supervise(self, est: StateEstimate) -> Effects:
        """Before each setpoint: the response to the last one, the bank limit."""
        sh = self.channel.shaper
        out = self.report(
            *self.response.update(
                est.t_s, sh.x_in_force, est.turn_rate_rad_s, sh.gain, est.groundspeed_m_s
            )
        )
        if sh.profile in ("bank", "attitude") and sh.adapt:
            out += self.report(
                self.bank_limit.update(est.t_s, sh.airspeed_m_s, sh.gain, sh.estimate.samples)
            )
        return out

    def airspeed_sent(self, airspeed_m_s: float) -> None:
        """An airspeed was asked of the autopilot (m/s): the monitor and the bank conversion
        follow it."""
        self.airspeed.target_m_s = airspeed_m_s
        self.channel.shaper.airspeed_m_s = airspeed_m_s

    def reset(self) -> None:
        """Command lost: the response, airspeed and bank-limit checks start again."""
        self.response.reset()
        self.airspeed.reset()
        self.bank_limit.reset()

    def report(self, *issues: Issue | None) -> list[Effect]:
        """Issues raised (event named after the issue, a warning STATUSTEXT) or cleared
        (``<name>_cleared``, a notice); Nones skipped."""
        out: list[Effect] = []
        for iss in issues:
            if iss is None:
                continue
            t_s, sysid = self.telemetry.now_s, self.link.sysid
            if iss.active:
                self.issues[iss.name] = iss.text
                out.append(IssueRaised(t_s=t_s, sysid=sysid, issue=iss.name, text=iss.text))
                out.append(Statustext(f"companion {sysid}: {iss.text}", MAV_SEVERITY_WARNING))
            else:
                self.issues.pop(iss.name, None)
                out.append(IssueCleared(t_s=t_s, sysid=sysid, issue=iss.name, text=iss.text))
                out.append(Statustext(f"companion {sysid}: {iss.text}"))
        return out
