"""Setpoint encoders (pure): a turn-rate command -> one MAVLink message per profile.

Profiles (docs/design.md §7):

* ``turn-rate``: SET_ATTITUDE_TARGET with ``body_yaw_rate`` (rad/s); the attitude, roll and
  pitch rates and throttle are ignored (type_mask 0xC3). For rate-controlled autopilots that
  follow the MAVLink spec (PX4, our simulator with ``SIM_RATE_OK=1``). ArduPlane never reads
  ``body_yaw_rate``: with 0xC3 it only forces its rudder to the yaw of ``q`` (0) and flies its
  own loiter (docs/arduplane.md).
* ``bank``: SET_ATTITUDE_TARGET with the bank angle ``phi = atan(V u / g)`` in ``q`` (roll
  only: ``q = (cos phi/2, sin phi/2, 0, 0)``) and type_mask 0xFE. ArduPlane inverts the mask
  (0xFE ^ 0xFF = 0x01) and takes the roll from ``q`` when the inverted roll-rate bit or the
  inverted attitude bit is set; pitch (bit 1) and rudder (bit 2) are forced only when their
  own bit or the attitude bit is; throttle only with bit 6. So 0xFE forces the roll alone and
  TECS keeps pitch, throttle and airspeed. (0x7E, "attitude used", also forces pitch 0 and
  rudder 0 on ArduPlane: the airspeed decays.)
* ``heading``: COMMAND_INT MAV_CMD_GUIDED_CHANGE_HEADING (43002), param1 = 0 course over
  ground, param2 = target course (deg, [0, 360)), param3 = the lateral acceleration allowed
  (m/s^2, > 0: ArduPlane barely turns with 0).

PX4 flies neither 0xC3 nor 0xFE (no offboard setpoint: OFFBOARD refused), nor
GUIDED_CHANGE_HEADING; its two profiles (``docs/px4.md``, built by
:mod:`companion.link.offboard`):

* ``attitude``: SET_ATTITUDE_TARGET with roll ``phi = atan(V u / g)`` and the pitch of the
  companion's own height hold in ``q``, and the thrust of its airspeed hold (type_mask 0x07:
  body rates ignored). PX4 holds neither airspeed nor altitude in attitude offboard.
* ``path``: SET_POSITION_TARGET_GLOBAL_INT, position, velocity and acceleration (type_mask
  0xC00) of the look-ahead point of the arc the turn-rate command flies; PX4's path
  controller follows the line through it, the acceleration's normal part as the curvature,
  and TECS holds the altitude given and its own trim airspeed.

The messages are plain pymavlink objects; bytes are made in :mod:`companion.link.connection`.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.attitude_target import arduplane_forced_axes

Profile = Literal["turn-rate", "bank", "heading", "attitude", "path"]
PROFILES: tuple[Profile, ...] = ("turn-rate", "bank", "heading", "attitude", "path")
PX4_PROFILES: tuple[Profile, ...] = ("attitude", "path")  # the offboard setpoints PX4 flies
ProfileChoice = Literal["auto", "turn-rate", "bank", "heading", "attitude", "path"]
PROFILE_CHOICES: tuple[ProfileChoice, ...] = ("auto", *PROFILES)  # auto: by autopilot type

G_M_S2 = 9.80665
AUTOPILOT_COMPID = 1
MASK_TURN_RATE = (
    mav.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
    | mav.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE
    | mav.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
    | mav.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
)  # 0xC3: only body_yaw_rate
MASK_BANK = 0xFE  # ArduPlane: roll from q only (bit 0 clear); pitch, rudder, throttle its own
MASK_ATTITUDE_THRUST = 0x07  # PX4: roll and pitch of q, and thrust; body rates ignored
MASK_POS_VEL_ACC = 0xC00  # position, velocity, acceleration; yaw and yaw rate ignored
MAX_BANK_RAD = math.radians(60.0)
HEADING_COURSE_OVER_GROUND = 0


def bank_angle_rad(turn_rate_rad_s: float, airspeed_m_s: float) -> float:
    """Coordinated-turn bank angle ``phi = atan(V u / g)`` (rad), clipped to +-60 deg."""
    phi = math.atan(airspeed_m_s * turn_rate_rad_s / G_M_S2)
    return max(-MAX_BANK_RAD, min(MAX_BANK_RAD, phi))


def roll_quaternion(roll_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a pure roll ``roll_rad`` (rad), pitch and yaw zero."""
    return (math.cos(roll_rad / 2.0), math.sin(roll_rad / 2.0), 0.0, 0.0)


def euler_quaternion(
    roll_rad: float, pitch_rad: float, yaw_rad: float
) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of Euler angles (rad, ZYX: yaw, then pitch, then roll)."""
    cr, sr = math.cos(roll_rad / 2.0), math.sin(roll_rad / 2.0)
    cp, sp = math.cos(pitch_rad / 2.0), math.sin(pitch_rad / 2.0)
    cy, sy = math.cos(yaw_rad / 2.0), math.sin(yaw_rad / 2.0)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quaternion_pitch_rad(q: tuple[float, float, float, float] | list[float]) -> float:
    """Euler pitch (rad, nose up positive) of a quaternion (w, x, y, z) (ZYX convention)."""
    w, x, y, z = (float(v) for v in q)
    return math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))


def quaternion_roll_rad(q: tuple[float, float, float, float] | list[float]) -> float:
    """Euler roll (rad) of a quaternion (w, x, y, z) (ZYX convention)."""
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))


def turn_rate_setpoint(
    turn_rate_rad_s: float, time_boot_ms: int, target_system: int
) -> mav.MAVLink_set_attitude_target_message:
    """SET_ATTITUDE_TARGET flying ``turn_rate_rad_s`` (rad/s, positive right) as body yaw rate."""
    return mav.MAVLink_set_attitude_target_message(
        int(time_boot_ms) & 0xFFFFFFFF,
        target_system,
        AUTOPILOT_COMPID,
        MASK_TURN_RATE,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        float(turn_rate_rad_s),
        0.0,
    )


def bank_setpoint(
    roll_rad: float, time_boot_ms: int, target_system: int
) -> mav.MAVLink_set_attitude_target_message:
    """SET_ATTITUDE_TARGET with bank ``roll_rad`` (rad, positive right wing down) in ``q``."""
    return mav.MAVLink_set_attitude_target_message(
        int(time_boot_ms) & 0xFFFFFFFF,
        target_system,
        AUTOPILOT_COMPID,
        MASK_BANK,
        list(roll_quaternion(roll_rad)),
        0.0,
        0.0,
        0.0,
        0.0,
    )


def attitude_setpoint(
    roll_rad: float,
    pitch_rad: float,
    yaw_rad: float,
    thrust: float,
    time_boot_ms: int,
    target_system: int,
) -> mav.MAVLink_set_attitude_target_message:
    """SET_ATTITUDE_TARGET for PX4's OFFBOARD: attitude (rad: roll positive right wing down,
    pitch nose up, yaw compass) and ``thrust`` (0..1); body rates ignored (type_mask 0x07)."""
    return mav.MAVLink_set_attitude_target_message(
        int(time_boot_ms) & 0xFFFFFFFF,
        target_system,
        AUTOPILOT_COMPID,
        MASK_ATTITUDE_THRUST,
        list(euler_quaternion(roll_rad, pitch_rad, yaw_rad)),
        0.0,
        0.0,
        0.0,
        float(min(1.0, max(0.0, thrust))),
    )


def path_setpoint(
    lat_e7: int,
    lon_e7: int,
    alt_amsl_m: float,
    vel_ned_m_s: tuple[float, float, float],
    acc_ned_m_s2: tuple[float, float, float],
    time_boot_ms: int,
    target_system: int,
) -> mav.MAVLink_set_position_target_global_int_message:
    """SET_POSITION_TARGET_GLOBAL_INT (frame GLOBAL_INT: altitude above mean sea level, m):
    a point (degE7) on the path, the velocity along it (m/s NED) and its acceleration (m/s^2
    NED); yaw and yaw rate ignored (type_mask 0xC00)."""
    return mav.MAVLink_set_position_target_global_int_message(
        int(time_boot_ms) & 0xFFFFFFFF, target_system, AUTOPILOT_COMPID,
        mav.MAV_FRAME_GLOBAL_INT, MASK_POS_VEL_ACC, int(lat_e7), int(lon_e7),
        float(alt_amsl_m), *(float(v) for v in vel_ned_m_s),
        *(float(a) for a in acc_ned_m_s2), 0.0, 0.0,
    )  # fmt: skip


def heading_setpoint(
    course_rad: float, max_lateral_accel_m_s2: float, target_system: int
) -> mav.MAVLink_command_int_message:
    """COMMAND_INT GUIDED_CHANGE_HEADING: hold ground course ``course_rad`` (rad, compass)."""
    if not max_lateral_accel_m_s2 > 0:
        raise ValueError("the lateral acceleration limit must be > 0 m/s^2")
    return mav.MAVLink_command_int_message(
        target_system,
        AUTOPILOT_COMPID,
        mav.MAV_FRAME_GLOBAL,
        mav.MAV_CMD_GUIDED_CHANGE_HEADING,
        0,
        0,
        float(HEADING_COURSE_OVER_GROUND),
        math.degrees(course_rad) % 360.0,
        float(max_lateral_accel_m_s2),
        0.0,
        0,
        0,
        0.0,
    )


def change_speed_command(
    airspeed_m_s: float, target_system: int
) -> mav.MAVLink_command_int_message:
    """COMMAND_INT MAV_CMD_GUIDED_CHANGE_SPEED: fly ``airspeed_m_s`` (m/s) in GUIDED.

    ArduPlane (GUIDED only): param1 0 = airspeed, param2 the speed (refused outside
    AIRSPEED_MIN..AIRSPEED_MAX), param3 the acceleration (0: as fast as it can); TECS then
    holds it. A repeat of the same speed is accepted and changes nothing.
    """
    return mav.MAVLink_command_int_message(
        target_system, AUTOPILOT_COMPID, 0, mav.MAV_CMD_GUIDED_CHANGE_SPEED, 0, 0,
        0.0, float(airspeed_m_s), 0.0, 0.0, 0, 0, 0.0,
    )  # fmt: skip


def do_change_speed_command(
    airspeed_m_s: float, target_system: int
) -> mav.MAVLink_command_long_message:
    """COMMAND_LONG MAV_CMD_DO_CHANGE_SPEED (airspeed, throttle unchanged): the fallback for
    autopilots without GUIDED_CHANGE_SPEED (ArduPlane takes it in GUIDED and AUTO)."""
    return mav.MAVLink_command_long_message(
        target_system, AUTOPILOT_COMPID, mav.MAV_CMD_DO_CHANGE_SPEED, 0,
        0.0, float(airspeed_m_s), -1.0, 0.0, 0.0, 0.0, 0.0,
    )  # fmt: skip


def change_altitude_command(
    alt_amsl_m: float, target_system: int
) -> mav.MAVLink_command_int_message:
    """COMMAND_INT MAV_CMD_GUIDED_CHANGE_ALTITUDE: hold ``alt_amsl_m`` (m above mean sea level).

    ArduPlane (GUIDED only): the altitude in ``z`` in ``frame`` (MAV_FRAME_GLOBAL: AMSL, so
    it does not depend on where home is), param3 the climb rate (0: as fast as TECS allows).
    """
    return mav.MAVLink_command_int_message(
        target_system, AUTOPILOT_COMPID, mav.MAV_FRAME_GLOBAL,
        mav.MAV_CMD_GUIDED_CHANGE_ALTITUDE, 0, 0,
        0.0, 0.0, 0.0, 0.0, 0, 0, float(alt_amsl_m),
    )  # fmt: skip


def describe(msg: Any) -> dict[str, float | str]:
    """What a setpoint message asks for, decoded (for tests and logs).

    Returns ``{"kind": "turn-rate", "turn_rate_rad_s": ...}``, ``{"kind": "bank",
    "roll_rad": ...}``, ``{"kind": "heading", "course_rad": ..., "accel_m_s2": ...}``,
    ``{"kind": "attitude", "roll_rad": ..., "pitch_rad": ..., "thrust": ...}`` or
    ``{"kind": "path", "lat_deg": ..., "lon_deg": ..., "alt_amsl_m": ..., "vn_m_s": ...,
    "ve_m_s": ..., "an_m_s2": ..., "ae_m_s2": ...}``.
    """
    t = msg.get_type()
    if t == "SET_ATTITUDE_TARGET" and int(msg.type_mask) == MASK_ATTITUDE_THRUST:
        return {
            "kind": "attitude",
            "roll_rad": quaternion_roll_rad(msg.q),
            "pitch_rad": quaternion_pitch_rad(msg.q),
            "thrust": float(msg.thrust),
        }
    if t == "SET_POSITION_TARGET_GLOBAL_INT":
        return {
            "kind": "path",
            "lat_deg": msg.lat_int * 1e-7,
            "lon_deg": msg.lon_int * 1e-7,
            "alt_amsl_m": float(msg.alt),
            "vn_m_s": float(msg.vx),
            "ve_m_s": float(msg.vy),
            "an_m_s2": float(msg.afx),
            "ae_m_s2": float(msg.afy),
        }
    if t == "SET_ATTITUDE_TARGET":
        if arduplane_forced_axes(int(msg.type_mask))["roll"]:
            return {"kind": "bank", "roll_rad": quaternion_roll_rad(msg.q)}
        return {"kind": "turn-rate", "turn_rate_rad_s": float(msg.body_yaw_rate)}
    if t in ("COMMAND_INT", "COMMAND_LONG") and msg.command == mav.MAV_CMD_GUIDED_CHANGE_HEADING:
        return {
            "kind": "heading",
            "course_rad": math.radians(float(msg.param2)),
            "accel_m_s2": float(msg.param3),
        }
    raise ValueError(f"not a setpoint: {t}")
