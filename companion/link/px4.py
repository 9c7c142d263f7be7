"""PX4 as the companion's autopilot (pure): its modes, and how OFFBOARD is entered.

PX4 says who it is in HEARTBEAT (``autopilot`` = MAV_AUTOPILOT_PX4, 12) and packs its mode
into ``custom_mode`` as ``main << 16 | sub << 24``: MANUAL 1, ALTCTL 2, POSCTL 3, AUTO 4 (sub
READY 1, TAKEOFF 2, LOITER 3, MISSION 4, RTL 5, LAND 6), ACRO 5, OFFBOARD 6, STABILIZED 7.
The companion flies the aircraft in OFFBOARD (main mode 6), PX4's counterpart of GUIDED.

PX4 enters OFFBOARD only while valid offboard setpoints already stream (one newer than
COM_OF_LOSS_T, default 1 s): a DO_SET_MODE before that is refused (TEMPORARILY_REJECTED), and
once in OFFBOARD a stream that stops sends it to its failsafe about 1.5 s later
(``docs/px4.md``). So :class:`OffboardEntry` pre-streams: setpoints flow for
``PRESTREAM_S`` at no less than ``MIN_STREAM_HZ`` before MAV_CMD_DO_SET_MODE (param1 1,
param2 6) is sent; a refusal, or no OFFBOARD heartbeat within ``ANSWER_TIMEOUT_S``, is
retried after a growing back-off (``BACKOFF_S``) and given up after ``MAX_TRIES``. Its states
form a table keyed by (state, event), as :mod:`companion.link.modes`; an event the table
does not list for the state raises.

========== ============================================ ====================================
state      meaning                                      next
========== ============================================ ====================================
idle       no setpoint stream (not flying, not asked)   streaming (``stream``)
streaming  pre-streaming, not asked yet                 requested (``ready``), idle (``gap``)
requested  DO_SET_MODE sent, waiting for the answer     backoff / gave_up (``refused``)
backoff    refused: waiting before the next try          requested (``ready``), idle (``gap``)
entered    PX4 reported OFFBOARD                        (final for the take-over)
gave_up    ``MAX_TRIES`` refused: reported, not retried (final)
========== ============================================ ====================================

Times are vehicle seconds, passed in (PX4 judges the stream on its own clock).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from pymavlink.dialects.v20 import ardupilotmega as mav

MAV_AUTOPILOT_PX4 = 12
OFFBOARD_MAIN_MODE = 6
OFFBOARD_CUSTOM_MODE = OFFBOARD_MAIN_MODE << 16  # 393216
MAIN_MODES: dict[int, str] = {
    1: "MANUAL",
    2: "ALTCTL",
    3: "POSCTL",
    4: "AUTO",
    5: "ACRO",
    6: "OFFBOARD",
    7: "STABILIZED",
    8: "RATTITUDE",
    9: "TERMINATION",
}
AUTO_SUB_MODES: dict[int, str] = {
    1: "READY",
    2: "TAKEOFF",
    3: "LOITER",
    4: "MISSION",
    5: "RTL",
    6: "LAND",
    8: "FOLLOW_TARGET",
    9: "PRECLAND",
    10: "VTOL_TAKEOFF",
}

PRESTREAM_S = 1.0  # vehicle s of setpoints before OFFBOARD is asked for
MIN_STREAM_HZ = 2.0  # the stream must not pause longer than 1 / this (vehicle s)
ANSWER_TIMEOUT_S = 3.0  # no OFFBOARD heartbeat (1 Hz) this long after a request: refused
BACKOFF_S = (2.0, 4.0, 8.0, 16.0)  # vehicle s before the 2nd, 3rd, ... try
MAX_TRIES = 5

EntryState = Literal["idle", "streaming", "requested", "backoff", "entered", "gave_up"]
_ANY: tuple[EntryState, ...] = ("idle", "streaming", "requested", "backoff", "entered", "gave_up")

# (state, event) -> next state
TRANSITIONS: dict[tuple[EntryState, str], EntryState] = {
    ("idle", "stream"): "streaming",
    ("streaming", "stream"): "streaming",
    ("requested", "stream"): "requested",
    ("backoff", "stream"): "backoff",
    ("streaming", "ready"): "requested",
    ("backoff", "ready"): "requested",
    ("streaming", "gap"): "idle",
    ("requested", "gap"): "idle",
    ("backoff", "gap"): "idle",
    ("requested", "refused"): "backoff",
    ("requested", "exhausted"): "gave_up",
    **{(s, "offboard"): "entered" for s in _ANY},
    ("entered", "stream"): "entered",
    ("gave_up", "stream"): "gave_up",
}


def is_px4(autopilot: int | None) -> bool:
    """Whether a HEARTBEAT ``autopilot`` (MAV_AUTOPILOT) is PX4."""
    return autopilot == MAV_AUTOPILOT_PX4


def is_offboard(custom_mode: int) -> bool:
    """Whether PX4's ``custom_mode`` is OFFBOARD (main mode 6)."""
    return (int(custom_mode) >> 16) & 0xFF == OFFBOARD_MAIN_MODE


def mode_name(custom_mode: int) -> str:
    """PX4's name of ``custom_mode``: ``OFFBOARD``, ``AUTO.LOITER``, ``MAIN9.3`` if unknown."""
    main = (int(custom_mode) >> 16) & 0xFF
    sub = (int(custom_mode) >> 24) & 0xFF
    name = MAIN_MODES.get(main, f"MAIN{main}")
    if main == 4:
        return f"{name}.{AUTO_SUB_MODES.get(sub, sub)}"
    return name


def set_offboard_command(target_system: int) -> mav.MAVLink_command_long_message:
    """COMMAND_LONG MAV_CMD_DO_SET_MODE: param1 1 (custom mode), param2 6 (OFFBOARD)."""
    return mav.MAVLink_command_long_message(
        target_system, 1, mav.MAV_CMD_DO_SET_MODE, 0,
        float(mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(OFFBOARD_MAIN_MODE),
        0.0, 0.0, 0.0, 0.0, 0.0,
    )  # fmt: skip


@dataclass(frozen=True)
class EntryStep:
    """A change of :class:`OffboardEntry` state and why (for the event log)."""

    before: EntryState
    after: EntryState
    event: str
    tries: int


class OffboardEntry:
    """Pre-stream, then ask for OFFBOARD; retry with back-off; give up after ``max_tries``.

    Args:
        prestream_s: vehicle s of streaming before the first request.
        min_stream_hz: the least stream rate (a longer pause is a ``gap``).
        answer_timeout_s: vehicle s after a request without OFFBOARD: refused.
        backoff_s: waits (vehicle s) before each retry (the last repeats).
        max_tries: requests before giving up.
    """

    def __init__(
        self,
        prestream_s: float = PRESTREAM_S,
        min_stream_hz: float = MIN_STREAM_HZ,
        answer_timeout_s: float = ANSWER_TIMEOUT_S,
        backoff_s: tuple[float, ...] = BACKOFF_S,
        max_tries: int = MAX_TRIES,
    ) -> None:
        """Idle: nothing streamed, nothing asked."""
        self.prestream_s = prestream_s
        self.max_gap_s = 1.0 / min_stream_hz
        self.answer_timeout_s = answer_timeout_s
        self.backoff_s = backoff_s
        self.max_tries = max_tries
        self.state: EntryState = "idle"
        self.tries = 0
        self.refusals: list[int] = []  # MAV_RESULT of each refusal (-1: no answer)
        self._stream_since: float | None = None
        self._last_sp: float | None = None
        self._asked_at: float | None = None
        self._wait_until: float | None = None

    @property
    def done(self) -> bool:
        """Entered or given up: nothing more to do for this take-over."""
        return self.state in ("entered", "gave_up")

    def streamed(self, t_s: float) -> list[EntryStep]:
        """A setpoint left at ``t_s`` (vehicle s); a pause longer than the least rate allows
        restarts the pre-stream."""
        steps: list[EntryStep] = []
        if self._last_sp is not None and t_s - self._last_sp > self.max_gap_s:
            steps += (
                self._step("gap") if self.state in ("streaming", "requested", "backoff") else []
            )
            self._stream_since = None
        self._last_sp = t_s
        if self._stream_since is None:
            self._stream_since = t_s
        return steps + self._step("stream")

    def due(self, t_s: float) -> bool:
        """Whether DO_SET_MODE OFFBOARD should be sent now (then the state is ``requested``)."""
        if self._last_sp is None or t_s - self._last_sp > self.max_gap_s:
            return False
        if self.state == "streaming":
            ready = self._stream_since is not None and t_s - self._stream_since >= self.prestream_s
        elif self.state == "backoff":
            ready = self._wait_until is not None and t_s >= self._wait_until
        else:
            return False
        if not ready:
            return False
        self._step("ready")
        self.tries += 1
        self._asked_at = t_s
        return True

    def answer(self, t_s: float, result: int) -> list[EntryStep]:
        """COMMAND_ACK of DO_SET_MODE with MAV_RESULT ``result`` at ``t_s`` (vehicle s)."""
        if self.state != "requested" or result in (
            mav.MAV_RESULT_ACCEPTED,
            mav.MAV_RESULT_IN_PROGRESS,
        ):
            return []  # accepted: the OFFBOARD heartbeat is what counts
        return self._refused(t_s, result)

    def poll(self, t_s: float) -> list[EntryStep]:
        """No OFFBOARD heartbeat ``answer_timeout_s`` after the request: refused."""
        if self.state == "requested" and t_s - (self._asked_at or t_s) >= self.answer_timeout_s:
            return self._refused(t_s, -1)
        return []

    def heartbeat(self, offboard: bool) -> list[EntryStep]:
        """PX4's heartbeat: in OFFBOARD or not."""
        return self._step("offboard") if offboard and self.state != "entered" else []

    def _refused(self, t_s: float, result: int) -> list[EntryStep]:
        self.refusals.append(int(result))
        if self.tries >= self.max_tries:
            return self._step("exhausted")
        wait = self.backoff_s[min(self.tries - 1, len(self.backoff_s) - 1)]
        self._wait_until = t_s + wait
        return self._step("refused")

    def _step(self, event: str) -> list[EntryStep]:
        key = (self.state, event)
        if key not in TRANSITIONS:
            raise ValueError(f"illegal offboard-entry event {event!r} in state {self.state!r}")
        before, self.state = self.state, TRANSITIONS[key]
        if before == self.state:
            return []
        return [EntryStep(before, self.state, event, self.tries)]
