"""Command authority: GUIDED (or PX4's OFFBOARD) gained, lost to a pilot or resumed; taking
control of an aircraft already flying (never arming); PX4's OFFBOARD entry (setpoints
pre-streamed, then the mode asked for, with back-off)."""

from __future__ import annotations

from companion.link import px4
from companion.link.estimate import StateEstimate
from companion.link.modes import GUIDED, Transition
from companion.link.setpoints import PX4_PROFILES
from companion.link.supervision import Issue

MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
TAKE_CONTROL_RETRY_S = 1.0  # wall


class TakingControl:
    """Gaining, losing and taking command of the autopilot.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _authority(self, tr: Transition | None) -> None:
        if tr is None:
            return
        self._log("authority", before=tr.before, after=tr.after, autopilot_mode=tr.mode)
        sysid = self.link.sysid
        if tr.before == "no_link" and self._link_was_lost:
            self._link_was_lost = False
            self._log("link_restored", reconnects=self.link.counts["reconnects"])
        ours = "OFFBOARD" if self.px4 else "GUIDED"
        if tr.after == "commanding":
            self._prestream = False
            if self.px4:  # the targets travel in the setpoints themselves
                self.offboard.target_airspeed_m_s = self.mission.vehicles.airspeed_m_s
                self._airspeed_sent(self.mission.vehicles.airspeed_m_s)
            else:
                self.targets.take_over(self.now_s)  # the mission's airspeed and altitude
        elif tr.before == "commanding":
            self.response.reset()
            self.airspeed.reset()
            self.bank_limit.reset()
            self._last_sp_msg = None
        if tr.after == "overridden":
            self._log("override", autopilot_mode=tr.mode)
            self.link.statustext(f"companion {sysid}: pilot took over ({tr.mode}), holding off")
            self.shaper.reset_sample()
        elif tr.after == "commanding" and tr.before == "overridden":
            self._log("resumed")
            self.link.statustext(f"companion {sysid}: {ours} again, resuming patrol")
        elif tr.after == "commanding":
            self.link.statustext(f"companion {sysid}: in command ({ours})")
        elif tr.after == "waiting":
            self.link.statustext(f"companion {sysid}: waiting for {ours} ({tr.mode})")

    def _take_control(self) -> None:
        if not self.config.take_control or self.authority.was_commanding:
            return
        if self.authority.state != "waiting" or self.link.sysid is None:
            return
        now = self.wall()
        if now - self._last_take_control < TAKE_CONTROL_RETRY_S:
            return
        self._last_take_control = now
        reason = self.not_flying_reason()
        if reason is not None:  # never arm, never take a grounded or climbing-out aircraft
            if reason != self._take_control_refused:
                self._take_control_refused = reason
                self._log("take_control_refused", reason=reason)
                self.link.statustext(f"companion {self.link.sysid}: not flying: {reason}")
            self._prestream = False
            return
        self._take_control_refused = None
        if self.px4:  # OFFBOARD only once setpoints stream (_prestream_step)
            usable = self.profile in PX4_PROFILES and not self.entry.done
            if usable and not self._prestream:
                self._prestream = True
                self._log("take_control", action="offboard_prestream")
            return
        self._log("take_control", action="guided")
        self.link.command_long(176, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED)

    def _px4_found(self) -> None:
        """The autopilot is PX4: its clock, its targets, and a profile it flies (said once
        if the one asked for is not)."""
        self.px4 = True
        self.clock.anchor_once = True  # its SYSTEM_TIME is the host's clock (docs/px4.md)
        self.offboard.target_alt_amsl_m = self.mission.origin.alt_m + self.mission_alt_m()
        self.offboard.target_airspeed_m_s = self.mission.vehicles.airspeed_m_s
        if self.profile is not None and self.profile not in PX4_PROFILES:
            text = f"profile {self.profile} is no PX4 offboard setpoint: use attitude or path"
            self._report(Issue("profile_unsupported", True, text))

    def _entry_steps(self, steps: list[px4.EntryStep]) -> None:
        """Log the OFFBOARD entry's changes; a refusal said once, giving up as an issue."""
        for st in steps:
            self._log("offboard_entry", before=st.before, after=st.after, tries=st.tries)
            sysid = self.link.sysid
            if st.after == "backoff" and len(self.entry.refusals) == 1:
                self.link.statustext(
                    f"companion {sysid}: OFFBOARD refused, retrying with back-off", severity=4
                )
            elif st.after == "gave_up":
                self._prestream = False
                n = len(self.entry.refusals)
                self._report(Issue("offboard_refused", True, f"OFFBOARD refused {n}x: gave up"))

    def _prestream_step(self, est: StateEstimate) -> None:
        """PX4's take-over: a setpoint continuing the turn it flies (the holds following its
        own pitch and throttle), then DO_SET_MODE OFFBOARD once the stream has lasted."""
        sysid = self.link.sysid
        if self.entry.done or self.authority.state != "waiting" or sysid is None:
            self._prestream = False
            return
        self.offboard.track(est.t_s)
        msg = self.shaper.setpoint(
            est.t_s,
            est.turn_rate_rad_s or 0.0,
            est.course_rad,
            est.time_boot_ms,
            sysid,
            pos_m=est.pos_m,
            heading_rad=est.heading_rad,
            wind_m_s=self.estimator.wind.vector,
        )
        self.shaper.reset_sample()
        self.link.send(msg)
        self.counters.prestream += 1
        self._entry_steps(self.entry.streamed(est.t_s))
        self._entry_steps(self.entry.poll(est.t_s))
        if self.entry.due(est.t_s):
            self._log("take_control", action="offboard", attempt=self.entry.tries)
            self.link.send(px4.set_offboard_command(sysid))
