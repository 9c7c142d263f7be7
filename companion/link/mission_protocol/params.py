"""A parameter read or set, client side, as a pure state machine (sans-IO, like
:mod:`~companion.link.mission_protocol.client`): PARAM_REQUEST_READ or PARAM_SET, answered by
the parameter's PARAM_VALUE; asked again after ``PARAM_TIMEOUT_S``, ``PARAM_TRIES`` times.

PX4 carries an integer parameter's bits in PARAM_VALUE's and PARAM_SET's float field
("bytewise" encoding; ArduPilot sends the number as a float): GF_ACTION 3 sent as the float
3.0 arrives as the integer 1077936128 and is refused (measured on PX4 SITL, main 02e73e3).
:func:`encode_param` and :func:`decode_param` do the conversion by the type the autopilot
reported.
"""

from __future__ import annotations

import struct
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

PARAM_TRIES = 3
PARAM_TIMEOUT_S = 1.0

INT_TYPES = {
    mav.MAV_PARAM_TYPE_UINT8: "<B",
    mav.MAV_PARAM_TYPE_INT8: "<b",
    mav.MAV_PARAM_TYPE_UINT16: "<H",
    mav.MAV_PARAM_TYPE_INT16: "<h",
    mav.MAV_PARAM_TYPE_UINT32: "<I",
    mav.MAV_PARAM_TYPE_INT32: "<i",
}


def encode_param(value: float, param_type: int, bytewise: bool) -> float:
    """The float field of a PARAM_SET for ``value`` of ``param_type``: the number itself, or
    (``bytewise``, PX4) an integer's bits read as a float32."""
    fmt = INT_TYPES.get(param_type)
    if not bytewise or fmt is None:
        return float(value)
    raw = struct.pack(fmt, round(value)).ljust(4, b"\0")
    return struct.unpack("<f", raw)[0]


def decode_param(raw: float, param_type: int, bytewise: bool) -> float:
    """The number in a PARAM_VALUE's float field ``raw`` of ``param_type`` (the inverse of
    :func:`encode_param`)."""
    fmt = INT_TYPES.get(param_type)
    if not bytewise or fmt is None:
        return float(raw)
    data = struct.pack("<f", raw)[: struct.calcsize(fmt)]
    return float(struct.unpack(fmt, data)[0])


class ParamExchange:
    """Read (``value`` None) or set parameter ``name`` of ``param_type`` on autopilot
    ``sysid``; ``bytewise``: PX4's encoding of integers (:func:`encode_param`).

    Attributes:
        done: the exchange is over.
        result: (the value as the autopilot reports it, its type) once done, or None when
            it never answered (no such parameter, or the link is down).
    """

    listens = ("PARAM_VALUE",)

    def __init__(
        self,
        sysid: int,
        name: str,
        value: float | None = None,
        bytewise: bool = False,
        param_type: int = mav.MAV_PARAM_TYPE_REAL32,
        *,
        tries: int = PARAM_TRIES,
        timeout_s: float = PARAM_TIMEOUT_S,
    ) -> None:
        """Nothing asked yet."""
        self.sysid, self.name, self.value = sysid, name, value
        self.bytewise, self.param_type = bytewise, param_type
        self.tries, self.timeout_s = tries, timeout_s
        self.done = False
        self.result: tuple[float, int] | None = None
        self.asked = 0
        self.deadline_s = float("inf")

    def start(self, now_s: float) -> list[Any]:
        """The first request."""
        return self._ask(now_s)

    def _ask(self, now_s: float) -> list[Any]:
        self.asked += 1
        self.deadline_s = now_s + self.timeout_s  # other parameters' values do not move it
        name = self.name.encode()
        if self.value is None:
            return [mav.MAVLink_param_request_read_message(self.sysid, 1, name, -1)]
        raw = encode_param(self.value, self.param_type, self.bytewise)
        return [mav.MAVLink_param_set_message(self.sysid, 1, name, raw, self.param_type)]

    def handle(self, m: Any, now_s: float) -> list[Any]:
        """A PARAM_VALUE: the answer if it is this parameter's, from this autopilot."""
        if self.done or m.get_type() != "PARAM_VALUE":
            return []
        if m.get_srcSystem() == self.sysid and m.param_id == self.name:
            ptype = int(m.param_type)
            self.done = True
            self.result = decode_param(float(m.param_value), ptype, self.bytewise), ptype
        return []

    def tick(self, now_s: float) -> list[Any]:
        """No answer by the deadline: ask again, or, after ``tries``, give up."""
        if self.done or now_s < self.deadline_s:
            return []
        if self.asked >= self.tries:
            self.done = True
            return []
        return self._ask(now_s)
