"""Command authority: GUIDED (or PX4's OFFBOARD) gained, lost to a pilot or a failsafe, or
resumed; taking control of an aircraft already flying (never arming), and with consent taking
it back after a failsafe its own silence caused (:mod:`companion.link.failsafe`); PX4's
OFFBOARD entry (setpoints pre-streamed, then the mode asked for, with back-off); what the
aircraft does if the companion falls silent (:mod:`companion.link.fallback`: ArduPlane's
GUIDED target kept on the loop ahead, PX4's offboard-loss action set at take-over); the
GUIDED targets and the reliefs' own take-off and landing (one component of the
:class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

from typing import Any

from companion.agent.agent import Agent
from companion.link import px4
from companion.link.estimate import StateEstimate
from companion.link.failsafe import Failsafe, Loss
from companion.link.ground import GroundSequence
from companion.link.modes import GUIDED, Authority, Transition
from companion.link.outbox import MAV_SEVERITY_WARNING, CommandLong, Statustext
from companion.link.px4_ground import Px4GroundSequence, parked_setpoint
from companion.link.setpoints import PX4_PROFILES
from companion.link.supervision import Issue
from companion.link.targets import GuidedTargets, TargetsOut
from companion.process.config import Counters, RunConfig
from companion.process.events import (
    AuthorityChanged,
    CommandRefused,
    LinkLost,
    LinkRestored,
    OffboardEntryStep,
    Override,
    Resumed,
    RetakeGivenUp,
    Retaking,
    TakeControl,
    TakeControlRefused,
)
from companion.process.fallback import Fallback
from companion.process.health import Health
from companion.process.ports import LinkState
from companion.process.sender import NOTHING, Effect, Effects
from companion.process.setpoint import SetpointChannel
from companion.process.telemetry import Telemetry

MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
MAV_CMD_DO_SET_MODE = 176
MAV_RESULT_ACCEPTED, MAV_RESULT_IN_PROGRESS = 0, 5
TAKE_CONTROL_RETRY_S = 1.0  # wall


class TakingControl:
    """Gaining, losing and taking command of the autopilot.

    Args:
        config: the run configuration (``take_control``, the mission).
        link: what is read of the link (sysid, autopilot type, reconnects).
        telemetry: the aircraft's state (vehicle time).
        channel: the setpoint channel (PX4 or not, profile, shaper, setpoint in force).
        health: the checks (whether the aircraft flies; issues; the airspeed followed).
        authority: command authority, owned here.
        counters: the process's counts (``prestream``).

    Attributes:
        authority: command authority (:class:`companion.link.modes.Authority`).
        targets: the GUIDED airspeed and altitude targets (ArduPilot).
        ground: the reliefs' own take-off and landing (ArduPlane's way; PX4's once PX4 is
            heard, :mod:`companion.link.px4_ground`).
        entry: PX4's OFFBOARD entry.
        prestreaming: PX4's take-over under way: setpoints stream before OFFBOARD.
        refused: why the aircraft was last found not flying (None: it flies, or not asked).
        agent: the Agent, once started (climbed out; its airspeed fixed on a refusal).
        failsafe: the companion's silences, its steps' health, who took the aircraft away
            and whether to take it back (:class:`companion.link.failsafe.Failsafe`).
        fallback: what the aircraft flies if the companion falls silent (ArduPlane's GUIDED
            target on the loop ahead, PX4's offboard-loss action).
    """

    def __init__(
        self,
        config: RunConfig,
        link: LinkState,
        telemetry: Telemetry,
        channel: SetpointChannel,
        health: Health,
        authority: Authority,
        counters: Counters,
    ) -> None:
        """Nothing asked yet."""
        m = config.mission
        self.take_control_on = config.take_control
        self.mission_airspeed_m_s = m.vehicles.airspeed_m_s
        self.link = link
        self.telemetry = telemetry
        self.channel = channel
        self.health = health
        self.authority = authority
        self.counters = counters
        self.targets = GuidedTargets(  # the airspeed and altitude asked of GUIDED
            link, m.vehicles.airspeed_m_s, lambda: m.origin.alt_m + channel.mission_alt_m()
        )
        self.ground: GroundSequence | Px4GroundSequence = GroundSequence()
        self.ground_spares = frozenset(
            sp.sysid for sp in m.vehicles.spares if sp.waits == "ground"
        )  # on PX4 these are taken into OFFBOARD parked on the ground (px4_ground)
        self.entry = px4.OffboardEntry()
        self.prestreaming = False
        self.refused: str | None = None
        self.agent: Agent | None = None
        self.failsafe = Failsafe(config.retake_after_failsafe, config.link.rate_hz)
        self.fallback = Fallback(m, link, telemetry, channel, counters)
        self._link_was_lost = False  # a "link_restored" event is due when the link returns
        self._lost_commanding = False  # the link was lost while commanding
        self._last_try_wall_s = -1e9

    def _at(self) -> dict[str, Any]:
        """An event's stamp now: the latest vehicle time and the autopilot's sysid."""
        return {"t_s": self.telemetry.now_s, "sysid": self.link.sysid}

    def _targets(self, r: TargetsOut) -> Effects:
        """What the targets asked for; the airspeed sent is followed by the checks."""
        if r.airspeed_m_s is not None:
            self.health.airspeed_sent(r.airspeed_m_s)
        return r.out

    def repeat_targets(self, est: StateEstimate) -> Effects:
        """Before a setpoint from ``est``: GUIDED (not in the reliefs' own take-off or
        landing), the targets again if due (ArduPilot); the silent companion's fallback
        kept current (:class:`~companion.process.fallback.Fallback`)."""
        guided = not self.channel.px4 and self.authority.mode == "GUIDED"
        out: list[Effect] = []
        if guided:
            out += self._targets(self.targets.repeat_if_due(est.t_s, self.telemetry.now_s))
        if self.agent is not None:
            out += self.fallback.before_setpoint(est, self.agent, guided)
        return out

    # ---- what the process tells the authority's judges ---------------------------------------
    def position(self, wall_s: float, t_s: float) -> None:
        """A position (vehicle time ``t_s``) arrived at wall time ``wall_s``."""
        self.failsafe.health.position(wall_s, t_s)

    def setpoint_sent(self, t_s: float) -> None:
        """A setpoint from the position at ``t_s`` (vehicle s) left."""
        self.failsafe.silence.setpoint(t_s)

    @property
    def away(self) -> bool:
        """The autopilot took the aircraft away (a pilot, or a failsafe) and the companion
        does not command: it shares that it is out of the formation."""
        return self.failsafe.retake.state != "in_command" and not self.authority.commanding

    def command_speed(self, airspeed_m_s: float, t_s: float) -> Effects:
        """The Agent's airspeed (m/s) at ``t_s`` (vehicle s): a GUIDED target (ArduPilot), or
        the target of the companion's own airspeed hold (PX4)."""
        if not self.channel.px4:
            return self._targets(self.targets.command_speed(airspeed_m_s, t_s))
        offboard = self.channel.offboard
        if airspeed_m_s != offboard.target_airspeed_m_s:  # held by the companion's own loop
            offboard.target_airspeed_m_s = airspeed_m_s
            self.health.airspeed_sent(airspeed_m_s)
        return NOTHING

    # ---- the hooks --------------------------------------------------------------------------
    def on_heartbeat(self, m: Any) -> Effects:
        """HEARTBEAT: command authority from the mode; the reliefs' take-off over (the
        mission's targets again); PX4 in OFFBOARD or not."""
        mode = int(m.custom_mode)
        if self.channel.px4 and not isinstance(self.ground, Px4GroundSequence):
            self.ground = Px4GroundSequence()  # PX4's take-off and landing from now on
        self.authority.own_modes = self.ground.own_modes()
        out = list(self._authority(self.authority.heartbeat(mode, self.link.autopilot)))
        armed = bool(m.base_mode & 128)  # MAV_MODE_FLAG_SAFETY_ARMED
        if self.ground.heartbeat(mode, armed) and self.authority.commanding:
            out += self._commanding()  # climbed: GUIDED's targets, or PX4's holds (OFFBOARD)
            if self.agent is not None:
                self.agent.climbed_out()
        if self.channel.px4:
            out += self._entry_steps(self.entry.heartbeat(px4.is_offboard(mode)))
        return out

    def on_command_ack(self, m: Any) -> Effects:
        """COMMAND_ACK: an airspeed refused or a target unsupported, a refusal logged, PX4's
        answer to DO_SET_MODE OFFBOARD."""
        command, result, now_s = int(m.command), int(m.result), self.telemetry.now_s
        r = self.targets.on_ack(command, result, self.authority.commanding, now_s)
        out = list(self._targets(r))
        if r.denied and self.agent is not None:
            self.agent.fix_airspeed()
        if m.result not in (MAV_RESULT_ACCEPTED, MAV_RESULT_IN_PROGRESS):
            out.append(CommandRefused(**self._at(), command=command, result=result))
        if self.channel.px4 and command == MAV_CMD_DO_SET_MODE and now_s is not None:
            out += self._entry_steps(self.entry.answer(now_s, result))
        return out

    def link_lost(self) -> Effects:
        """No heartbeat for the link's time-out: event, and the authority lost."""
        self._lost_commanding = self._lost_commanding or self.authority.commanding
        silent = self.link.silent_s
        out: list[Effect] = [
            LinkLost(**self._at(), silent_s=None if silent is None else round(silent, 3))
        ]
        self._link_was_lost = True
        out += self._authority(self.authority.link_lost())
        return out

    def _authority(self, tr: Transition | None) -> Effects:
        """A change of authority: logged, told to the pilot (STATUSTEXT); commanding sends the
        mission's targets, leaving it stops the setpoints and restarts the checks."""
        if tr is None:
            return NOTHING
        out: list[Effect] = [
            AuthorityChanged(**self._at(), before=tr.before, after=tr.after, autopilot_mode=tr.mode)
        ]
        if tr.before == "no_link" and self._link_was_lost:
            self._link_was_lost = False
            outage = self.link.last_outage_s
            out.append(
                LinkRestored(
                    **self._at(),
                    reconnects=self.link.counts["reconnects"],
                    outage_s=None if outage is None else round(outage, 3),
                )
            )
        loss = self._loss(tr)
        if tr.after == "commanding":
            out += self._commanding()
        elif tr.before == "commanding":
            self.health.reset()
            self.channel.forget()
        out += self._tell(tr, loss)
        return out

    def _loss(self, tr: Transition) -> Loss | None:
        """Whose doing a change away from the companion's mode was (None: not one): a change
        while commanding, or the link back with the aircraft in another mode after it was
        lost while commanding (:mod:`companion.link.failsafe`)."""
        if tr.after == "commanding":
            self._lost_commanding = False
            self.failsafe.retake.back()
            self.failsafe.silence.reset()
            self.fallback.forget()
            return None
        after_loss = tr.before == "no_link" and tr.after == "waiting" and self._lost_commanding
        if not (tr.after == "overridden" or after_loss):
            return None
        cause, silent_s = self.failsafe.silence.cause(self.telemetry.now_s, after_loss)
        if after_loss and self.link.last_outage_s is not None:
            silent_s = self.link.last_outage_s
        loss = Loss(cause, tr.mode, silent_s)
        self.failsafe.retake.taken(loss)
        return loss

    def _commanding(self) -> Effects:
        """Command gained: the targets in force (PX4: in the setpoints themselves)."""
        self.prestreaming = False
        if self.channel.px4:
            self.channel.offboard.target_airspeed_m_s = self.mission_airspeed_m_s
            self.health.airspeed_sent(self.mission_airspeed_m_s)
            return NOTHING
        return self._targets(self.targets.take_over(self.telemetry.now_s))

    def _tell(self, tr: Transition, loss: Loss | None) -> Effects:
        """The pilot told of a change of authority (and the override or resume logged)."""
        sysid = self.link.sysid
        ours = "OFFBOARD" if self.channel.px4 else "GUIDED"
        if loss is not None:
            self.channel.shaper.reset_sample()
            silent = round(loss.silent_s, 3)
            if loss.cause == "pilot":
                text = f"companion {sysid}: pilot took over ({tr.mode}), holding off"
            else:
                consent = self.failsafe.retake.consent
                then = "retaking when healthy" if consent else "holding off"
                text = f"companion {sysid}: {tr.mode} after {silent:.1f} s silent, {then}"
            return (
                Override(**self._at(), autopilot_mode=tr.mode, cause=loss.cause, silent_s=silent),
                Statustext(text, MAV_SEVERITY_WARNING),
            )
        if tr.after == "commanding" and tr.before == "overridden":
            return (
                Resumed(**self._at()),
                Statustext(f"companion {sysid}: {ours} again, resuming patrol"),
            )
        if tr.after == "commanding":
            return (Statustext(f"companion {sysid}: in command ({ours})"),)
        if tr.after == "waiting":
            return (Statustext(f"companion {sysid}: waiting for {ours} ({tr.mode})"),)
        return NOTHING

    # ---- taking control ---------------------------------------------------------------------
    def take_control(self, wall_s: float, *, paced: bool = True) -> Effects:
        """With ``take_control``, while waiting: the aircraft's mode asked for once it flies
        (GUIDED; PX4: the pre-stream begun), at most every ``TAKE_CONTROL_RETRY_S`` of wall
        time (``wall_s``, s) unless not ``paced``; never arms, never takes a grounded or
        climbing-out aircraft (said once per reason). With the operator's consent the same
        after a loss to the companion's own silence, once :class:`Retake` says so."""
        state, sysid = self.authority.state, self.link.sysid
        first = self.take_control_on and not self.authority.was_commanding and state == "waiting"
        retake = self.failsafe.retake.state
        back = state in ("waiting", "overridden") and retake in ("lost", "retaking")
        if sysid is None or not (first or back):
            return NOTHING
        if paced and wall_s - self._last_try_wall_s < TAKE_CONTROL_RETRY_S:
            return NOTHING
        self._last_try_wall_s = wall_s
        reason = self.health.not_flying_reason()
        if reason is not None and self.parked_spare():
            reason = None  # PX4: a ground spare is taken into OFFBOARD parked (px4_ground)
        if reason is not None:
            out: Effects = NOTHING
            if reason != self.refused:
                self.refused = reason
                out = (
                    TakeControlRefused(**self._at(), reason=reason),
                    Statustext(f"companion {sysid}: not flying: {reason}"),
                )
            self.prestreaming = False
            return out
        self.refused = None
        effects: list[Effect] = []
        if back and not first:
            go, said = self._retake(wall_s, sysid)
            if not go:
                return said
            effects += said
        if self.channel.px4:  # OFFBOARD only once setpoints stream (prestream)
            usable = self.channel.profile in PX4_PROFILES and not self.entry.done
            if usable and not self.prestreaming:
                self.prestreaming = True
                effects.append(TakeControl(**self._at(), action="offboard_prestream"))
            return effects
        effects += [
            TakeControl(**self._at(), action="guided"),
            CommandLong.of(MAV_CMD_DO_SET_MODE, MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED),
        ]
        return effects

    def _retake(self, wall_s: float, sysid: int) -> tuple[bool, Effects]:
        """(whether to ask for the mode back now, what to log and tell) after a loss to the
        companion's own silence (:class:`Retake`); giving up said once."""
        if self.prestreaming and not self.entry.done:
            return False, NOTHING  # PX4's entry under way
        r, was = self.failsafe.retake, self.failsafe.retake.state
        if not r.due(wall_s, True, self.failsafe.health.healthy(wall_s)):
            if was != "held_off" and r.state == "held_off":
                text = f"companion {sysid}: not taking it back again ({r.tries} asks)"
                return False, (
                    RetakeGivenUp(**self._at(), attempts=r.tries),
                    Statustext(text, MAV_SEVERITY_WARNING),
                )
            return False, NOTHING
        if self.channel.px4 and self.entry.done:
            self.entry = px4.OffboardEntry()  # a new entry for this take-over
        ours = "OFFBOARD" if self.channel.px4 else "GUIDED"
        return True, (
            Retaking(**self._at(), autopilot_mode=self.authority.mode, attempt=r.tries),
            Statustext(f"companion {sysid}: link and steps healthy, taking {ours} back"),
        )

    def prestream(self, est: StateEstimate) -> Effects:
        """PX4's take-over: a setpoint continuing the turn it flies (the holds following its
        own pitch and throttle), then DO_SET_MODE OFFBOARD once the stream has lasted."""
        sysid = self.link.sysid
        taking = self.authority.state in ("waiting", "overridden")
        if self.entry.done or not taking or sysid is None:
            self.prestreaming = False
            return NOTHING
        ch = self.channel
        ch.offboard.track(est.t_s)
        out: list[Effect] = [*self.fallback.params(est.t_s)]
        if self.parked_spare():  # on the ground: level, thrust 0
            out.append(parked_setpoint(est.time_boot_ms, sysid))
        else:
            out.append(ch.setpoint(est, est.turn_rate_rad_s or 0.0, sysid))
        self.failsafe.silence.setpoint(est.t_s)
        ch.shaper.reset_sample()
        self.counters.prestream += 1
        out += self._entry_steps(self.entry.streamed(est.t_s))
        out += self._entry_steps(self.entry.poll(est.t_s))
        if self.entry.due(est.t_s):
            out.append(TakeControl(**self._at(), action="offboard", attempt=self.entry.tries))
            out.append(px4.set_offboard_command(sysid))
        return out

    def parked_spare(self) -> bool:
        """PX4: this vehicle is one of the mission's ground spares, disarmed (on the ground):
        the companion takes it into OFFBOARD parked (a level setpoint with thrust 0, which
        moves nothing) so that its take-off is the companion's own when the plan launches it
        (:mod:`companion.link.px4_ground`)."""
        return (
            self.channel.px4
            and self.link.sysid in self.ground_spares
            and self.telemetry.armed is False
        )

    def hold(self, est: StateEstimate, wall_s: float) -> Effects:
        """A step that sends none of the Agent's setpoints (on the ground, or in its own
        take-off): nothing in force; on PX4 parked (disarmed, its own sequence not taking off)
        the parked setpoint, kept in force, which keeps OFFBOARD."""
        ground, sysid = self.ground, self.link.sysid
        if not (isinstance(ground, Px4GroundSequence) and ground.parked) or sysid is None:
            self.channel.forget()
            return NOTHING
        msg = parked_setpoint(est.time_boot_ms, sysid)
        self.channel.in_force(msg, wall_s)
        return (msg,)

    def _entry_steps(self, steps: list[px4.EntryStep]) -> Effects:
        """The OFFBOARD entry's changes logged; a refusal said once, giving up an issue."""
        out: list[Effect] = []
        for st in steps:
            out.append(
                OffboardEntryStep(**self._at(), before=st.before, after=st.after, tries=st.tries)
            )
            if st.after == "backoff" and len(self.entry.refusals) == 1:
                text = f"companion {self.link.sysid}: OFFBOARD refused, retrying with back-off"
                out.append(Statustext(text, MAV_SEVERITY_WARNING))
            elif st.after == "gave_up":
                self.prestreaming = False
                n = len(self.entry.refusals)
                gave_up = Issue("offboard_refused", True, f"OFFBOARD refused {n}x: gave up")
                out += self.health.report(gave_up)
        return out
