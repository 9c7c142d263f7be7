"""What the aircraft flies while its companion is silent, kept sensible by the companion while
it commands (pure: returns the messages to send).

**ArduPlane** (GUIDED). A companion's attitude setpoint is flown for 3 s after the last one
(``mode_guided.cpp``); then ArduPlane navigates to its GUIDED target and circles it, and that
target is, unless told otherwise, where GUIDED was entered: a silent companion's aircraft
banked 42 deg and flew back there, 176-197 m off the loop within 20 s. While it commands,
:class:`GuidedFallback` keeps that target a point of the loop ahead: DO_REPOSITION
(COMMAND_INT in GUIDED: the location becomes the GUIDED target, param3 the loiter radius,
param4 non-zero for a counter-clockwise circle; ``GCS_MAVLink_Plane.cpp``), sent again every
``REFRESH_S`` of vehicle time. The point (:func:`lead_point`) is at most ``LEAD_MAX_S`` of
flight ahead of the aircraft's place on the loop, nearer where the loop curves so that the
straight line to it stays within ``CHORD_OFF_M`` of the loop; it is circled in the loop's
sense at ``LOITER_FACTOR`` times the turn radius of the mission's turn-rate limit. A silent
companion's aircraft so flies on along the loop for up to ``LEAD_MAX_S``, then circles a point
of the loop: within one loiter radius of the loop however long the silence lasts.

**PX4** (OFFBOARD). PX4 leaves OFFBOARD when no setpoint arrived for COM_OF_LOSS_T (1 s by
default) and does what COM_OBL_RC_ACT says. What the companion sets
when it takes over (:func:`px4_loss_params`, :class:`ParamsAtTakeOver`: PARAM_SET until each
is read back): COM_OBL_RC_ACT 5, Hold (AUTO.LOITER: a circle about where it was, on the loop),
with NAV_LOITER_RAD the turn radius of the mission's turn-rate limit (``PX4_LOITER_FACTOR``):
PX4 flew its Hold at 100 m for an NAV_LOITER_RAD of 80 and overshot it to 119 m on the way
out from the centre, so a silent companion's aircraft stays within about 1.5 radii of it.
PX4 stays in Hold when the companion is heard again: taking it back is the companion's own
decision (``--retake-after-failsafe``, :mod:`companion.link.failsafe`).

Times are vehicle seconds, positions world ``north + i east`` metres (the mission's local
frame), passed in.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import pymap3d
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.mission.model import Origin

REFRESH_S = 2.0  # vehicle s between DO_REPOSITIONs while commanding
LEAD_MAX_S = 16.0  # the point at most this much flight ahead (s of the loop's time-phase)
LEAD_MIN_S = 3.0  # and at least this much
LEAD_STEP_S = 1.0  # the leads tried, from the longest down
CHORD_OFF_M = 35.0  # the straight line to the point stays this close to the loop (m)
CHORD_SAMPLES = 8  # points of that line checked
LOITER_FACTOR = 1.25  # loiter radius / the turn radius at the mission's turn-rate limit
PX4_LOITER_FACTOR = 1.0  # PX4 flies its Hold wider than NAV_LOITER_RAD (measured: 100 m for 80)
AUTOPILOT_COMPID = 1
PX4_HOLD = 5  # COM_OBL_RC_ACT: Hold (AUTO.LOITER)


def loiter_radius_m(
    airspeed_m_s: float, max_turn_rate_rad_s: float, factor: float = LOITER_FACTOR
) -> float:
    """The radius (m) the aircraft circles while its companion is silent: ``factor`` times
    ``airspeed / max turn rate`` (m/s, rad/s), rounded to the metre."""
    return float(round(factor * airspeed_m_s / max_turn_rate_rad_s))


def _chord_off_m(patrol: Patrol, a_m: complex, b_m: complex) -> float:
    """The largest distance (m) from the loop of the straight line from ``a_m`` to ``b_m``."""
    worst = 0.0
    for k in range(1, CHORD_SAMPLES):
        p = a_m + (b_m - a_m) * (k / CHORD_SAMPLES)
        worst = max(worst, patrol.phase_and_offset_of_point(complex(p))[1])
    return worst


def lead_point(
    patrol: Patrol,
    pos_m: complex,
    lead_max_s: float = LEAD_MAX_S,
    chord_off_m: float = CHORD_OFF_M,
) -> tuple[complex, float]:
    """(the loop point ahead, its lead in s): the point of ``patrol`` the longest lead (at
    most ``lead_max_s``, at least ``LEAD_MIN_S``, in ``LEAD_STEP_S`` steps) ahead of the loop
    point nearest ``pos_m`` (m) whose straight line from that loop point stays within
    ``chord_off_m`` (m) of the loop."""
    phase0 = patrol.phase_of_point(complex(pos_m))
    start = complex(patrol.point_at_phase(phase0))
    rate = TWO_PI / patrol.period_s
    lead = lead_max_s
    while lead > LEAD_MIN_S:
        ahead = complex(patrol.point_at_phase(phase0 + rate * lead))
        if _chord_off_m(patrol, start, ahead) <= chord_off_m:
            return ahead, lead
        lead -= LEAD_STEP_S
    return complex(patrol.point_at_phase(phase0 + rate * LEAD_MIN_S)), LEAD_MIN_S


def reposition_command(
    origin: Origin,
    point_m: complex,
    alt_amsl_m: float,
    radius_m: float,
    clockwise: bool,
    target_system: int,
) -> mav.MAVLink_command_int_message:
    """COMMAND_INT MAV_CMD_DO_REPOSITION: the GUIDED target at ``point_m`` (m, the mission's
    local frame from ``origin``) and ``alt_amsl_m`` (m above mean sea level, MAV_FRAME_GLOBAL),
    circled at ``radius_m`` (m), clockwise or not (param4: 0 clockwise, 1 counter-clockwise,
    as ArduPlane reads it); param1 -1 (speed unchanged), param2 0 (no mode change: it applies
    in GUIDED only)."""
    lat, lon, _ = pymap3d.ned2geodetic(
        point_m.real, point_m.imag, 0.0, origin.lat_deg, origin.lon_deg, origin.alt_m
    )
    return mav.MAVLink_command_int_message(
        target_system, AUTOPILOT_COMPID, mav.MAV_FRAME_GLOBAL,
        mav.MAV_CMD_DO_REPOSITION, 0, 0,
        -1.0, 0.0, float(radius_m), 0.0 if clockwise else 1.0,
        round(float(lat) * 1e7), round(float(lon) * 1e7), float(alt_amsl_m),
    )  # fmt: skip


@dataclass(frozen=True)
class FallbackTarget:
    """A GUIDED target sent: where (m), its lead (s), the loiter radius (m), when (vehicle s)."""

    point_m: complex
    lead_s: float
    radius_m: float
    t_s: float


class GuidedFallback:
    """ArduPlane's GUIDED target kept on the loop ahead while the companion commands.

    Args:
        origin: the mission's origin (the local frame).
        radius_m: the loiter radius (m), :func:`loiter_radius_m`.
    """

    def __init__(self, origin: Origin, radius_m: float) -> None:
        """Nothing sent yet."""
        self.origin = origin
        self.radius_m = radius_m
        self.last: FallbackTarget | None = None
        self.unsupported = False  # the autopilot answered DO_REPOSITION UNSUPPORTED

    def refresh_if_due(
        self, t_s: float, patrol: Patrol, pos_m: complex, alt_amsl_m: float, sysid: int
    ) -> mav.MAVLink_command_int_message | None:
        """At ``t_s`` (vehicle s), the aircraft at ``pos_m`` (m): the DO_REPOSITION to send
        when ``REFRESH_S`` has passed since the last one (or none was sent), else None; never
        again once the autopilot said it does not know the command."""
        if self.unsupported:
            return None
        if self.last is not None and 0.0 <= t_s - self.last.t_s < REFRESH_S:
            return None
        point, lead = lead_point(patrol, pos_m)
        self.last = FallbackTarget(point, lead, self.radius_m, t_s)
        return reposition_command(
            self.origin, point, alt_amsl_m, self.radius_m, patrol.clockwise, sysid
        )

    def forget(self) -> None:
        """Command lost: the next take-over sends a target at once."""
        self.last = None

    def on_ack(self, command: int, result: int) -> None:
        """A COMMAND_ACK: DO_REPOSITION answered UNSUPPORTED (an autopilot without it, e.g.
        our simulator) is not sent again."""
        if command == mav.MAV_CMD_DO_REPOSITION and result == mav.MAV_RESULT_UNSUPPORTED:
            self.unsupported = True


@dataclass(frozen=True)
class Param:
    """A parameter's value and type (PX4 sends and reads an INT32 parameter's bits in the
    float field, "bytewise"; a float as itself)."""

    value: float
    integer: bool = False

    def encoded(self) -> tuple[float, int]:
        """(param_value, MAV_PARAM_TYPE) as PX4 reads them."""
        if self.integer:
            bits = struct.unpack("<f", struct.pack("<i", int(self.value)))[0]
            return bits, mav.MAV_PARAM_TYPE_INT32
        return float(self.value), mav.MAV_PARAM_TYPE_REAL32

    def decoded(self, param_value: float, param_type: int) -> float:
        """A PARAM_VALUE's value as a number."""
        if param_type == mav.MAV_PARAM_TYPE_INT32:
            return float(struct.unpack("<i", struct.pack("<f", param_value))[0])
        return float(param_value)


def px4_loss_params(radius_m: float) -> dict[str, Param]:
    """The PX4 parameters a companion sets at take-over: the offboard-loss action Hold
    (COM_OBL_RC_ACT 5, an INT32), circled at NAV_LOITER_RAD ``radius_m`` (m)."""
    return {
        "COM_OBL_RC_ACT": Param(float(PX4_HOLD), integer=True),
        "NAV_LOITER_RAD": Param(float(radius_m)),
    }


PARAM_RETRY_S = 1.0  # vehicle s between PARAM_SETs of a parameter not yet read back
PARAM_TRIES = 5


class ParamsAtTakeOver:
    """Parameters set on the autopilot when the companion takes over, each PARAM_SET until
    its PARAM_VALUE reads back the value (at most ``PARAM_TRIES`` times).

    Args:
        params: name -> value and type.
    """

    def __init__(self, params: dict[str, Param]) -> None:
        """Nothing sent yet."""
        self.params = dict(params)
        self.confirmed: dict[str, float] = {}
        self._tries: dict[str, int] = {}
        self._sent_t_s: float | None = None

    @property
    def done(self) -> bool:
        """Every parameter read back, or given up."""
        return all(n in self.confirmed or self._tries.get(n, 0) >= PARAM_TRIES for n in self.params)

    @property
    def refused(self) -> list[str]:
        """The parameters given up (sent ``PARAM_TRIES`` times, never read back)."""
        return [n for n in self.params if n not in self.confirmed and self.done]

    def due(self, t_s: float, sysid: int) -> list[mav.MAVLink_param_set_message]:
        """At ``t_s`` (vehicle s): PARAM_SETs of the parameters not yet read back, at most
        every ``PARAM_RETRY_S``."""
        if self.done or (self._sent_t_s is not None and 0 <= t_s - self._sent_t_s < PARAM_RETRY_S):
            return []
        self._sent_t_s = t_s
        out = []
        for name, param in self.params.items():
            if name in self.confirmed or self._tries.get(name, 0) >= PARAM_TRIES:
                continue
            self._tries[name] = self._tries.get(name, 0) + 1
            value, kind = param.encoded()
            out.append(
                mav.MAVLink_param_set_message(sysid, AUTOPILOT_COMPID, name.encode(), value, kind)
            )
        return out

    def on_param_value(self, name: str, param_value: float, param_type: int) -> bool:
        """A PARAM_VALUE (its name, value field and MAV_PARAM_TYPE): True when it confirms
        one of ours now."""
        want = self.params.get(name)
        if want is None or name in self.confirmed:
            return False
        value = want.decoded(param_value, param_type)
        if math.isfinite(value) and abs(value - want.value) <= 1e-3 * max(1.0, abs(want.value)):
            self.confirmed[name] = value
            return True
        return False
