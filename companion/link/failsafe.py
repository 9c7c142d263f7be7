"""Who took the aircraft away from its companion, and whether the companion takes it back
(pure; times passed in).

When the autopilot leaves the companion's mode (GUIDED; PX4: OFFBOARD), or the link comes
back with the aircraft in another mode, the companion judges whose doing it was
(:meth:`Silence.cause`):

* ``own_silence``: the companion itself had been silent: no setpoint for at least
  ``SILENT_S`` of vehicle time within the last ``RECENT_S`` before the change was heard, or
  the link was lost. The autopilot's own failsafe did it (PX4 leaves OFFBOARD after
  COM_OF_LOSS_T without a setpoint; a fence breached while nobody steered). A pilot's change
  made during that silence cannot be told from it;
* ``pilot``: the setpoints flowed: a pilot or a ground station chose another mode. The
  companion holds off until its mode comes back, and never takes it back itself.

With the operator's consent (``companion run --retake-after-failsafe``), :class:`Retake`
says when to take back an aircraft lost to the companion's own silence: once its link is up
and its step rate healthy again (:class:`StepHealth`: positions arriving steadily for
``HEALTHY_WALL_S`` of wall time, the companion's own clock), ``RETAKE_RETRY_WALL_S`` apart, at
most ``RETAKE_MAX`` asks in any ``RETAKE_WINDOW_WALL_S`` (an aircraft that keeps being lost is
then left to its autopilot, said once), and never after a pilot's change.

The states of one loss, as a table (an event not listed raises):

============ ================= ==========================================================
state        meaning           events
============ ================= ==========================================================
in_command   ours, or never    taken_pilot -> held_off, taken_silence -> lost
held_off     a pilot's mode    back -> in_command; taken_* -> held_off / lost
lost         our silence       asked -> retaking, back -> in_command, taken_pilot -> held_off
retaking     asked back        asked -> retaking, back -> in_command, taken_pilot -> held_off,
                               gave_up -> held_off
============ ================= ==========================================================
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from itertools import pairwise
from typing import Literal

SILENT_S = 0.5  # vehicle s without a setpoint: the companion was silent
RECENT_S = 3.0  # vehicle s before a mode change is heard in which a silence counts
# (PX4's HEARTBEAT is 1 Hz: the mode change is heard up to a second after the failsafe,
# and the companion may have streamed again meanwhile)
HEALTHY_WALL_S = 3.0  # wall s of steady positions before a retake
MAX_GAP_WALL_S = 0.5  # wall s: a longer pause between positions is not steady
MAX_GAP_S = 0.5  # vehicle s: nor is a longer hole in the positions' own times
MIN_RATE_FRACTION = 0.6  # of the asked position rate over the window
RETAKE_RETRY_WALL_S = 5.0  # wall s between asks
RETAKE_MAX = 5  # asks at most in any window of
RETAKE_WINDOW_WALL_S = 600.0  # wall s

Cause = Literal["pilot", "own_silence"]
RetakeState = Literal["in_command", "held_off", "lost", "retaking"]

TRANSITIONS: dict[tuple[RetakeState, str], RetakeState] = {
    ("in_command", "taken_pilot"): "held_off",
    ("in_command", "taken_silence"): "lost",
    ("in_command", "back"): "in_command",
    ("held_off", "taken_pilot"): "held_off",
    ("held_off", "taken_silence"): "lost",
    ("held_off", "back"): "in_command",
    ("lost", "taken_pilot"): "held_off",
    ("lost", "taken_silence"): "lost",
    ("lost", "asked"): "retaking",
    ("lost", "back"): "in_command",
    ("retaking", "taken_pilot"): "held_off",
    ("retaking", "taken_silence"): "retaking",
    ("retaking", "asked"): "retaking",
    ("retaking", "back"): "in_command",
    ("retaking", "gave_up"): "held_off",
}


class Silence:
    """The companion's silences towards its autopilot: the gaps between its setpoints
    (vehicle s)."""

    def __init__(self) -> None:
        """No setpoint yet."""
        self.last_t_s: float | None = None
        self._gaps: deque[tuple[float, float]] = deque(maxlen=32)  # (end s, length s)

    def setpoint(self, t_s: float) -> None:
        """A setpoint left at ``t_s`` (vehicle s)."""
        if self.last_t_s is not None and t_s - self.last_t_s >= SILENT_S:
            self._gaps.append((t_s, t_s - self.last_t_s))
        self.last_t_s = t_s

    def recent_s(self, now_s: float | None) -> float:
        """The longest silence (s) that lasted into the last ``RECENT_S`` before ``now_s``
        (vehicle s), the one still running included; 0 without setpoints."""
        if self.last_t_s is None or now_s is None:
            return 0.0
        open_gap = max(0.0, now_s - self.last_t_s)
        ended = [g for end, g in self._gaps if end >= now_s - RECENT_S]
        return max([open_gap, *ended])

    def cause(self, now_s: float | None, link_was_lost: bool) -> tuple[Cause, float]:
        """Whose doing a change heard at ``now_s`` (vehicle s) was, and the silence (s)."""
        silent = self.recent_s(now_s)
        if link_was_lost or silent >= SILENT_S:
            return "own_silence", silent
        return "pilot", silent

    def reset(self) -> None:
        """Forget the setpoints (commanding starts again: the gap before is not a silence)."""
        self.last_t_s = None
        self._gaps.clear()


class StepHealth:
    """Whether the companion hears its autopilot steadily: the positions' arrivals on the
    companion's wall clock and their own vehicle times.

    Args:
        rate_hz: the position rate asked of the autopilot (per vehicle s).
    """

    def __init__(self, rate_hz: float) -> None:
        """Nothing heard yet."""
        self.rate_hz = rate_hz
        self._seen: deque[tuple[float, float]] = deque()  # (wall s, vehicle s)

    def position(self, wall_s: float, t_s: float) -> None:
        """A position at vehicle time ``t_s`` arrived at wall time ``wall_s`` (s)."""
        seen = self._seen
        seen.append((wall_s, t_s))
        while len(seen) > 1 and seen[1][0] < wall_s - HEALTHY_WALL_S:
            seen.popleft()  # the last one before the window is kept

    def healthy(self, wall_s: float) -> bool:
        """Positions came steadily over the last ``HEALTHY_WALL_S`` before ``wall_s``: no wall
        pause longer than ``MAX_GAP_WALL_S`` (the last one included), no hole longer than
        ``MAX_GAP_S`` in their vehicle times, and at least ``MIN_RATE_FRACTION`` of the asked
        rate over the vehicle time they span."""
        start = wall_s - HEALTHY_WALL_S
        before = [(w, t) for w, t in self._seen if w < start][-1:]  # a pause across the start
        window = before + [(w, t) for w, t in self._seen if w >= start]
        if len(window) < 2 or window[0][0] > start + MAX_GAP_WALL_S:
            return False
        if wall_s - window[-1][0] > MAX_GAP_WALL_S:
            return False
        pairs = pairwise(window)
        if any(b[0] - a[0] > MAX_GAP_WALL_S or b[1] - a[1] > MAX_GAP_S for a, b in pairs):
            return False
        span_s = window[-1][1] - window[0][1]
        return span_s > 0 and len(window) - 1 >= MIN_RATE_FRACTION * self.rate_hz * span_s


@dataclass(frozen=True)
class Loss:
    """The aircraft was taken away: by whom, into which mode, after how long a silence (s)."""

    cause: Cause
    mode: str
    silent_s: float


class Retake:
    """One companion's decisions about taking its aircraft back (see the module docstring).

    Args:
        consent: the operator allows it (``--retake-after-failsafe``).
    """

    def __init__(self, consent: bool) -> None:
        """In command (or never was): nothing lost."""
        self.consent = consent
        self.state: RetakeState = "in_command"
        self.loss: Loss | None = None
        self._asked: deque[float] = deque()  # wall s of the asks in the window

    @property
    def tries(self) -> int:
        """Asks in the last window."""
        return len(self._asked)

    def taken(self, loss: Loss) -> None:
        """The autopilot left the companion's mode (or the link came back outside it)."""
        self._step("taken_silence" if loss.cause == "own_silence" else "taken_pilot")
        self.loss = loss

    def back(self) -> None:
        """The companion commands again."""
        self._step("back")
        self.loss = None

    def due(self, wall_s: float, link_up: bool, healthy: bool) -> bool:
        """Whether to ask for the companion's mode now (wall s): consent, a loss to its own
        silence, the link up and the steps healthy, paced; giving up (the state is then
        ``held_off``) once ``RETAKE_MAX`` asks were made in the last window."""
        if not self.consent or self.state not in ("lost", "retaking"):
            return False
        asked = self._asked
        while asked and asked[0] < wall_s - RETAKE_WINDOW_WALL_S:
            asked.popleft()
        if not (link_up and healthy) or (asked and wall_s - asked[-1] < RETAKE_RETRY_WALL_S):
            return False
        if len(asked) >= RETAKE_MAX:
            self._step("gave_up")
            return False
        self._step("asked")
        asked.append(wall_s)
        return True

    def _step(self, event: str) -> None:
        key = (self.state, event)
        if key not in TRANSITIONS:
            raise ValueError(f"illegal retake event {event!r} in state {self.state!r}")
        self.state = TRANSITIONS[key]


class Failsafe:
    """One companion's judges of a loss, together: its silences, its steps' health and the
    retake decisions.

    Args:
        consent: the operator allows retakes (``--retake-after-failsafe``).
        rate_hz: the position rate asked of the autopilot (per vehicle s).
    """

    def __init__(self, consent: bool, rate_hz: float) -> None:
        """In command (or never was), nothing heard."""
        self.silence = Silence()
        self.health = StepHealth(rate_hz)
        self.retake = Retake(consent)
