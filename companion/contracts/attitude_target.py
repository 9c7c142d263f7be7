"""How ArduPlane reads a SET_ATTITUDE_TARGET ``type_mask`` (pure).

Shared by the companion's setpoint encoder (:mod:`companion.link.setpoints`, whose bank
profile relies on it) and the simulator's autopilot (:mod:`sitl_model.link`), so both read
the mask the same way.
"""

from __future__ import annotations

__all__ = ["arduplane_forced_axes"]


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
