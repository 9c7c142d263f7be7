"""The autopilot's and the camera's messages, dispatched by type: which component's hook
handles what, in which order (the table the Runner reads, MAVProxy's ``mavlink_packet``
hooks without its shared state).

Each hook takes the message and returns what to send and log
(:data:`companion.process.sender.Effects`), which the Runner sends before the next hook
runs. A GLOBAL_POSITION_INT that makes a state estimate is then handed to the control step
(:meth:`companion.process.step.ControlStep.on_position`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from companion.process.control import TakingControl
from companion.process.health import Health
from companion.process.sender import Effects
from companion.process.setpoint import SetpointChannel
from companion.process.step import ControlStep
from companion.process.telemetry import Telemetry

CAMERA_COMPID = 100

Handler = Callable[[Any], Effects]
"""A hook: one message in, what to send and log out."""

Key = tuple[bool, str]
"""(from the vehicle's camera, the message type)."""


class Routing(Protocol):
    """What the dispatch reads of the link: whose messages are ours."""

    sysid: int | None

    def is_autopilot(self, m: Any) -> bool:
        """Whether ``m`` comes from our autopilot (its system, component 1)."""
        ...


def message_key(link: Routing, m: Any) -> Key | None:
    """Where ``m`` goes in the table: (from the camera, type) for our vehicle's autopilot
    and camera (component 100), None for anything else."""
    header = m.get_header()
    if link.sysid is None or header.srcSystem != link.sysid:
        return None
    if header.srcComponent == CAMERA_COMPID:
        return (True, m.get_type())
    return (False, m.get_type()) if link.is_autopilot(m) else None


def message_table(
    telemetry: Telemetry,
    channel: SetpointChannel,
    health: Health,
    control: TakingControl,
    step: ControlStep,
    start_agent: Handler,
) -> dict[Key, tuple[Handler, ...]]:
    """The hooks of each message type, in the order they run.

    A message of a stream the companion asks for is counted first (its rate watched:
    :mod:`~.streams`).

    A HEARTBEAT: the profile resolved (PX4 found), the checks (a profile PX4 does not fly,
    the bank limit asked), the Agent started (the first), armed or disarmed, command
    authority. A VFR_HUD: the airspeed check first, then the estimator and PX4's holds.
    """
    tm = telemetry
    table: dict[Key, tuple[Handler, ...]] = {
        (False, "HEARTBEAT"): (
            channel.on_heartbeat,
            health.on_heartbeat,
            start_agent,
            tm.on_heartbeat,
            control.on_heartbeat,
        ),
        (False, "SYSTEM_TIME"): (tm.on_system_time,),
        (False, "GLOBAL_POSITION_INT"): (tm.on_position,),
        (False, "ATTITUDE"): (tm.on_attitude, channel.on_attitude),
        (False, "VFR_HUD"): (health.on_vfr_hud, tm.on_vfr_hud, channel.on_vfr_hud),
        (False, "EXTENDED_SYS_STATE"): (tm.on_extended_sys_state,),
        (False, "PARAM_VALUE"): (health.on_param_value, control.fallback.on_param_value),
        (False, "WIND"): (tm.on_wind,),
        (False, "WIND_COV"): (tm.on_wind_cov,),
        (False, "SYS_STATUS"): (tm.on_sys_status,),
        (False, "BATTERY_STATUS"): (tm.on_battery_status,),
        (False, "COMMAND_ACK"): (control.on_command_ack, control.fallback.on_command_ack),
        (True, "CAMERA_TRACKING_GEO_STATUS"): (step.on_detection,),
    }
    for name in STREAMED:
        table[False, name] = (tm.streams.on_message, *table[False, name])
    return table


STREAMED = (
    "HEARTBEAT", "SYSTEM_TIME", "GLOBAL_POSITION_INT", "ATTITUDE", "VFR_HUD",
    "EXTENDED_SYS_STATE", "WIND", "WIND_COV",
)  # fmt: skip
"""Every message :func:`~.config.telemetry_rates_hz` may ask for (ArduPilot's and PX4's)."""
