"""What ``companion run`` is asked to do (:class:`RunConfig`), what the companion asks its
autopilot to stream (:func:`telemetry_rates_hz`) and the counts it keeps (:class:`Counters`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from companion.agent.config import AgentConfig
from companion.link import px4
from companion.link.config import LinkConfig
from companion.mission import Mission


def telemetry_rates_hz(position_rate_hz: float, autopilot: int | None = None) -> dict[str, float]:
    """What the companion asks its autopilot of HEARTBEAT type ``autopilot`` to stream
    (message name -> Hz): position and attitude at the control rate, air data and the
    autopilot's wind estimate slower. PX4 has no WIND (WIND_COV instead) and a fixed 1 Hz
    HEARTBEAT; its airspeed feeds the companion's own airspeed hold (10 Hz)."""
    if px4.is_px4(autopilot):
        return {
            "GLOBAL_POSITION_INT": position_rate_hz,
            "ATTITUDE": position_rate_hz,
            "VFR_HUD": 10.0,
            "EXTENDED_SYS_STATE": 1.0,
            "SYSTEM_TIME": 1.0,
            "WIND_COV": 1.0,
        }
    return {
        "GLOBAL_POSITION_INT": position_rate_hz,
        "ATTITUDE": position_rate_hz,
        "HEARTBEAT": position_rate_hz,
        "VFR_HUD": 2.0,
        "EXTENDED_SYS_STATE": 1.0,  # landed state: take over only an aircraft in the air
        "SYSTEM_TIME": 1.0,
        "WIND": 1.0,
    }


@dataclass(frozen=True)
class RunConfig:
    """What ``companion run`` was asked to do.

    Attributes:
        mission: the mission (loop, wind, gains, limits, sensor).
        link: the setpoints: their profile ("auto": from the autopilot's HEARTBEAT type), rate
            and whether the shaper adapts (:class:`~companion.link.config.LinkConfig`).
        agent: how the Agent decides (policy, on_confirm, max_prosecutors,
            member_timeout_s...); its ``lead_s`` and ``hold_s`` follow the control rate
            (:meth:`~companion.agent.config.AgentConfig.at_rate`; the default: ``link``'s default).
        take_control: switch the aircraft to GUIDED at start once it is flying (armed, in the
            air, high and fast enough: never arms, never takes a grounded aircraft).
        state_period_s: member-state broadcast period (vehicle s).
        status_interval_s: wall seconds between status lines on stderr (0: none).
        boot_epoch_s: vehicle time = this (unix s) + ``time_boot_ms``, SYSTEM_TIME ignored
            (a fleet of PX4 SITL instances, whose SYSTEM_TIME is the host's clock); None: from
            SYSTEM_TIME (:class:`companion.link.clock.VehicleClock`).
        retake_after_failsafe: the operator consents to the companion taking its aircraft
            back after a failsafe its own silence caused, once its link and steps are healthy
            (:mod:`companion.link.failsafe`); never after a pilot's mode change.
        group_budget_bytes_s: the group's state budget (bytes/s, all members together;
            ``--group-budget``): the state period and the member time-out then follow the
            members heard (:class:`companion.group.budget.Budget`, ``member_timeout_s`` its
            floor) and states beyond a sender's share are dropped as ``flood``. None: no
            budget, ``state_period_s`` and ``member_timeout_s`` as given.
    """

    mission: Mission
    link: LinkConfig = field(default_factory=LinkConfig)
    agent: AgentConfig = field(
        default_factory=lambda: AgentConfig().at_rate(LinkConfig().rate_hz)
    )
    take_control: bool = False
    state_period_s: float = 0.2
    status_interval_s: float = 0.0
    boot_epoch_s: float | None = None
    group_budget_bytes_s: float | None = None
    retake_after_failsafe: bool = False


LATENCY_WINDOW = 20_000  # latencies kept for the status line's median and 99th percentile


@dataclass
class Counters:
    """Per-process counts for the status line and the final report."""

    setpoints: int = 0
    estimates: int = 0
    detections: int = 0
    states_sent: int = 0
    alerts_sent: int = 0
    skipped: int = 0  # stale estimates not steered from (a newer one was waiting)
    keepalives: int = 0  # setpoints resent because no new one went for KEEPALIVE_WALL_S
    prestream: int = 0  # PX4: setpoints streamed before OFFBOARD was entered
    fallbacks: int = 0  # ArduPlane: GUIDED targets on the loop ahead (DO_REPOSITION) sent
    out_of_formation: int = 0  # states shared as overridden (taken by the autopilot)
    latency_s: list[float] = field(default_factory=list)  # telemetry in -> setpoint out (wall s)

    def note_latency(self, latency_s: float) -> None:
        """One telemetry-to-setpoint latency (wall s), the last ``LATENCY_WINDOW`` or so
        kept."""
        lat = self.latency_s
        lat.append(latency_s)
        if len(lat) > LATENCY_WINDOW:
            del lat[: LATENCY_WINDOW // 2]

    def latency_ms(self) -> tuple[float, float] | None:
        """Median and 99th percentile of telemetry-to-setpoint latency (wall ms)."""
        if not self.latency_s:
            return None
        a = np.asarray(self.latency_s) * 1e3
        return float(np.median(a)), float(np.percentile(a, 99))
