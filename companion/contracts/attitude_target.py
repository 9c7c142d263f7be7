"""How ArduPlane and PX4 read a SET_ATTITUDE_TARGET ``type_mask`` (pure).

Shared by the companion's setpoint encoder (:mod:`companion.link.setpoints`, whose bank
profile relies on it) and the simulator's autopilot (:mod:`sitl_model.link`), so both read
the mask the same way; PX4's reading (:func:`px4_offboard_axes`) is the companion's alone.
"""

from __future__ import annotations

__all__ = ["arduplane_forced_axes", "px4_offboard_axes"]


def arduplane_forced_axes(type_mask: int) -> dict[str, bool]:
    """What ArduPlane's GUIDED takes from a SET_ATTITUDE_TARGET with ``type_mask``.

    ArduPlane (``GCS_MAVLINK_Plane::handle_set_attitude_target``) inverts the mask and keeps
    bits 0-2 and 7 (``a = ~mask & 0x87``): the roll of ``q`` is forced when ``a & 0x81``,
    the pitch when ``a & 0x82``, the rudder (the yaw of ``q`` used as a rudder demand) when
    ``a & 0x84``; the throttle (``thrust``) when ``~mask & 0x40``. Each override lasts 3 s
    after the last message. The body rates are never read.

    Returns ``{"roll": ..., "pitch": ..., "rudder": ..., "throttle": ...}``.
    """
    inv = (int(type_mask) ^ 0xFF) & 0xFF
    att = inv & 0x87
    return {
        "roll": bool(att & 0x81),
        "pitch": bool(att & 0x82),
        "rudder": bool(att & 0x84),
        "throttle": bool(inv & 0x40),
    }


def px4_offboard_axes(type_mask: int) -> dict[str, bool]:
    """What PX4's OFFBOARD takes from a SET_ATTITUDE_TARGET with ``type_mask``.

    PX4 (``MavlinkReceiver::handle_message_set_attitude_target``, ``offboardCheck.cpp``)
    flies the attitude when bit 7 (ATTITUDE_IGNORE) is clear: roll and pitch of ``q`` on a
    fixed wing, its yaw ignored; else body rates, but only with all three rate bits (0-2)
    clear; anything else (0xC3 "yaw rate only", 0xFE) is no offboard setpoint at all, and
    DO_SET_MODE OFFBOARD is refused. ``thrust`` goes to the motor unless bit 6
    (THROTTLE_IGNORE) is set, and then the thrust is 0, not "kept" (docs/px4.md).

    Returns ``{"attitude": ..., "rates": ..., "thrust": ..., "valid": ...}``.
    """
    m = int(type_mask) & 0xFF
    attitude = not m & 0x80
    rates = not attitude and not m & 0x07
    return {
        "attitude": attitude,
        "rates": rates,
        "thrust": not m & 0x40,
        "valid": attitude or rates,
    }
