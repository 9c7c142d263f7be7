"""The telemetry the companion asked for, kept at its rate when others share the link (one
component of the :class:`~companion.process.runner.Runner`).

The link asks its autopilot for each stream (:func:`companion.process.config.
telemetry_rates_hz`, SET_MESSAGE_INTERVAL) when it comes up, until the autopilot accepts.
A ground station on the same autopilot link (through a router: docs/gcs.md) may change
those rates afterwards (its own SET_MESSAGE_INTERVAL, or REQUEST_DATA_STREAM, which on
ArduPilot sets every message of a group): the autopilot keeps one rate per message and per
link, so the companion is starved of what it asked (ArduPilot issues 17046 and 19761). This
watch measures the rate it actually receives of each stream and asks again when one slows:

* rates are measured on the autopilot's own clock (``time_boot_ms`` of GLOBAL_POSITION_INT,
  ATTITUDE and SYSTEM_TIME), so at any speed-up and in lockstep alike, over windows of
  :data:`WINDOW_PERIODS` periods of the asked rate (at least :data:`WINDOW_MIN_S`); a window
  in which more than :data:`LOSS_FRACTION` of the autopilot's frames were missed (gaps in
  their sequence numbers: loss, or a stalled companion) is not judged;
* a stream is watched once it has arrived at :data:`OK_FRACTION` of its asked rate over one
  window (a stream the autopilot never gave at that rate cannot be restored by asking);
* it is slow when a window brings less than :data:`SLOW_FRACTION` of the asked rate (halved,
  or stopped); it is then asked again at once (SET_MESSAGE_INTERVAL at the asked rate), and
  again while it stays slow after :data:`BACKOFF_S`, doubling up to :data:`BACKOFF_CAP_S`;
  after :data:`MAX_REQUESTS` requests in one fight it is given up (not asked again until the
  link comes up anew);
* a fight is said once: ``stream_slow`` when it starts, ``stream_restored`` when the stream
  is first back at its rate (``after_s``: vehicle s from the slow window's end to the
  restoring window's end), ``stream_given_up`` at the cap. A stream slowed again within
  :data:`QUIET_S` of its restoring (a ground station that re-asserts its rates) goes on in
  the same fight: asked again after the backoff, not said again.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.outbox import CommandLong
from companion.process.events import StreamGivenUp, StreamRestored, StreamSlow
from companion.process.sender import NOTHING, Effect, Effects

WINDOW_MIN_S = 0.5  # vehicle s: the shortest window a rate is measured over
WINDOW_PERIODS = 4.0  # a window holds at least this many periods of the asked rate
OK_FRACTION = 0.8  # at or above this fraction of the asked rate: at its rate
SLOW_FRACTION = 0.7  # below this fraction: slow (halved, or stopped)
BACKOFF_S = 2.0  # vehicle s before the second request of a fight; doubles after each
BACKOFF_CAP_S = 30.0  # the longest wait between two requests
MAX_REQUESTS = 6  # requests in one fight, then the stream is given up
QUIET_S = 60.0  # vehicle s at its rate after which a new slowing starts a new fight
CLOCK_MESSAGES = frozenset({"GLOBAL_POSITION_INT", "ATTITUDE", "SYSTEM_TIME"})
REBOOT_BACK_S = 1.0  # the autopilot's clock went back more than this: it rebooted
LOSS_FRACTION = 0.25  # a window with more of the autopilot's frames missed is not judged


class RatesAsked(Protocol):
    """What the watch reads of the link: the rates it asked for (the Runner hands the watch
    only its own autopilot's messages: :mod:`~.messages`)."""

    sysid: int | None
    rates_hz: dict[str, float]  # message name -> Hz asked (filled when the link comes up)
    counts: dict[str, int]  # ap_frames, ap_missed: our autopilot's frames and sequence gaps


class State(enum.Enum):
    """A stream's state."""

    WAITING = "waiting"  # not yet seen at its rate: not watched
    AT_RATE = "at_rate"
    SLOW = "slow"  # asked again, not yet back
    GIVEN_UP = "given_up"


@dataclass
class Fight:
    """A stream's slowings close together and the requests they took."""

    requests: int  # SET_MESSAGE_INTERVAL sent in this fight
    last_request_s: float  # vehicle s of the last one
    slow_s: float  # vehicle s the fight's current slowing was found
    restored: bool = False  # said restored once
    restored_s: float = 0.0  # vehicle s it last came back to its rate


@dataclass
class Stream:
    """One stream's asked rate, its current window and its state.

    Attributes:
        name: the message name; hz: the rate asked (Hz).
        start_s: the current window's start (autopilot s), None before the first
            autopilot time after its first message.
        count: messages received in the current window.
        fight: the current fight (None: none, or the last one ended :data:`QUIET_S` ago).
    """

    name: str
    hz: float
    start_s: float | None = None
    count: int = 0
    end_s: float = math.inf  # when the current window may be judged (vehicle s)
    frames0: int = 0  # the link's ap_frames and ap_missed when the window started
    missed0: int = 0
    state: State = State.WAITING
    fight: Fight | None = None

    @property
    def window_s(self) -> float:
        """The window (vehicle s): at least :data:`WINDOW_PERIODS` periods."""
        return max(WINDOW_MIN_S, WINDOW_PERIODS / self.hz)


def backoff_s(requests: int) -> float:
    """Vehicle s to wait after the ``requests``-th request of a fight before the next one."""
    return min(BACKOFF_S * 2.0 ** (requests - 1), BACKOFF_CAP_S)


class StreamWatch:
    """The rate of each stream the companion asked for, and the requests that restore it.

    Args:
        link: the link (its asked rates, its sysid, whose messages are ours).
        now_s: () -> the latest vehicle time (unix s) for the events' stamps, or None.

    Attributes:
        streams: message name -> its :class:`Stream` (made when it is first received).
        clock_s: the autopilot's clock (s since its boot), from the newest message with
            ``time_boot_ms``; None before one.
    """

    def __init__(self, link: RatesAsked, now_s: Callable[[], float | None]) -> None:
        """Nothing received yet."""
        self.link = link
        self.now_s = now_s
        self.streams: dict[str, Stream] = {}
        self.clock_s: float | None = None
        self._next_s = -math.inf  # the earliest window end (autopilot s)

    def reset(self) -> None:
        """The link was lost (or the autopilot rebooted): it asks for everything again when
        it comes back; every stream waits to be seen at its rate anew."""
        self.streams.clear()
        self.clock_s = None
        self._next_s = -math.inf

    def on_message(self, m: Any) -> Effects:
        """One message of a type the companion asks for (a hook, before the others): counted;
        on a new autopilot time, each window that ended is judged (about 1 us a message)."""
        name = m.get_type()
        s = self.streams.get(name)
        if s is None:
            hz = self.link.rates_hz.get(name)
            if not hz:
                return NOTHING
            s = self.streams[name] = Stream(name, hz)
            self._next_s = -math.inf  # its first window starts at the next autopilot time
        s.count += 1
        if name not in CLOCK_MESSAGES:
            return NOTHING
        t = m.time_boot_ms * 1e-3
        clock = self.clock_s
        if clock is not None and t <= clock:
            if t < clock - REBOOT_BACK_S:
                self.reset()  # rebooted: its clock started again
            return NOTHING
        self.clock_s = t
        if t < self._next_s:
            return NOTHING
        out: list[Effect] = []
        for st in self.streams.values():
            if st.start_s is None:
                self._start(st, t)
            elif t >= st.end_s:
                if not self._lossy(st):
                    out += self._judge(st, st.count / (t - st.start_s), t)
                self._start(st, t)
        self._next_s = min(st.end_s for st in self.streams.values())
        return out

    def _start(self, s: Stream, t: float) -> None:
        """Stream ``s``'s next window starts at ``t`` (autopilot s)."""
        s.start_s, s.count, s.end_s = t, 0, t + s.window_s - 1e-6
        s.frames0, s.missed0 = self.link.counts["ap_frames"], self.link.counts["ap_missed"]

    def _lossy(self, s: Stream) -> bool:
        """Whether more than :data:`LOSS_FRACTION` of the autopilot's frames in ``s``'s
        window never arrived (gaps in their sequence numbers: a lossy radio, a stalled
        companion whose socket overflowed): fewer messages then say nothing of the rates."""
        frames = self.link.counts["ap_frames"] - s.frames0
        missed = self.link.counts["ap_missed"] - s.missed0
        return missed > LOSS_FRACTION * (frames + missed)

    def _judge(self, s: Stream, hz: float, t: float) -> Effects:
        """Stream ``s`` received ``hz`` (Hz) over the window that ended at ``t`` (s)."""
        at_rate, slow = hz >= OK_FRACTION * s.hz, hz < SLOW_FRACTION * s.hz
        f = s.fight
        if f is not None and f.restored and s.state is State.AT_RATE and t - f.restored_s > QUIET_S:
            s.fight = f = None  # long enough at its rate: the fight is over
        if s.state is State.WAITING:
            if at_rate:
                s.state = State.AT_RATE
            return NOTHING
        if s.state is State.GIVEN_UP:
            return NOTHING
        if s.state is State.AT_RATE:
            if not slow:
                return NOTHING
            s.state = State.SLOW
            if f is None:  # a new fight: said once, asked at once
                s.fight = Fight(requests=1, last_request_s=t, slow_s=t)
                return (self._slow_event(s, hz), self._request(s))
            f.slow_s = t
            return self._again(s, f, hz, t)
        assert f is not None  # SLOW: within a fight
        if at_rate:
            s.state = State.AT_RATE
            f.restored_s = t
            if f.restored:
                return NOTHING
            f.restored = True
            return (
                StreamRestored(
                    t_s=self.now_s(), sysid=self.link.sysid, stream=s.name, asked_hz=s.hz,
                    received_hz=round(hz, 2), after_s=round(t - f.slow_s, 3),
                    requests=f.requests,
                ),
            )  # fmt: skip
        if slow:
            return self._again(s, f, hz, t)
        return NOTHING  # between the two thresholds: waiting to see

    def _again(self, s: Stream, f: Fight, hz: float, t: float) -> Effects:
        """Slow again within a fight: another request once the backoff has passed, or the
        stream given up at the cap."""
        if t - f.last_request_s < backoff_s(f.requests) - 1e-6:
            return NOTHING
        if f.requests >= MAX_REQUESTS:
            s.state = State.GIVEN_UP
            return (
                StreamGivenUp(
                    t_s=self.now_s(), sysid=self.link.sysid, stream=s.name, asked_hz=s.hz,
                    received_hz=round(hz, 2), requests=f.requests,
                ),
            )  # fmt: skip
        f.requests += 1
        f.last_request_s = t
        return (self._request(s),)

    def _slow_event(self, s: Stream, hz: float) -> StreamSlow:
        return StreamSlow(
            t_s=self.now_s(), sysid=self.link.sysid, stream=s.name, asked_hz=s.hz,
            received_hz=round(hz, 2),
        )  # fmt: skip

    def _request(self, s: Stream) -> CommandLong:
        """SET_MESSAGE_INTERVAL for ``s`` at its asked rate; its next window starts now."""
        s.count = 0
        msg_id = getattr(mav, f"MAVLINK_MSG_ID_{s.name}")
        return CommandLong(mav.MAV_CMD_SET_MESSAGE_INTERVAL, (float(msg_id), 1e6 / s.hz))
