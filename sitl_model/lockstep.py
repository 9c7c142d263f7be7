"""The lockstep gate: which vehicles the simulator waits for before its next physics step.

Pure: no sockets, no clock of its own; the wall time (s, monotonic) is passed in. The
server (``sitl-model --lockstep``) tells the gate three things and asks one question:

* :meth:`LockstepGate.position_sent` when vehicle ``i``'s GLOBAL_POSITION_INT left for
  its peers (the telemetry a companion answers with one setpoint);
* :meth:`LockstepGate.setpoint` when vehicle ``i`` received a GUIDED setpoint
  (SET_ATTITUDE_TARGET or MAV_CMD_GUIDED_CHANGE_HEADING, from any peer);
* :meth:`LockstepGate.blocked` before every physics step, with each vehicle's "in GUIDED"
  flag: True while some vehicle must still answer.

A vehicle is *waited for* when it is in GUIDED, is *live* (it has a controlling peer: a
setpoint arrived since it last entered GUIDED, and it has answered every position report
since then or caught up), and its latest position report is still unanswered. The wait is
bounded: ``wait_bound_s`` wall seconds after the report left, the gate gives up on that
vehicle, counts one timeout and marks it not live, so a silent companion costs one bound
and then the world goes on without it (its autopilot loiters after GUID_TIMEOUT simulated
seconds, exactly as without lockstep). The next setpoint from it makes it live again and
ends the episode: at most one timeout per vehicle per silent episode.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

# wall seconds the simulator waits for one answer: long enough that a companion descheduled on
# a loaded 2-core machine is not left behind (which would change the run), short enough that
# a killed one costs the others little (one bound per silent episode)
DEFAULT_WAIT_BOUND_S = 2.0


@dataclass(frozen=True)
class WaitTimeout:
    """The gate gave up waiting for vehicle ``index`` after ``waited_s`` wall seconds."""

    index: int
    waited_s: float


@dataclass
class LockstepGate:
    """Per-vehicle answer bookkeeping for ``n`` vehicles (see the module docstring).

    Attributes:
        n: number of vehicles.
        wait_bound_s: longest wall wait for one answer (s, > 0).
        timeouts: waits that hit the bound so far (one per silent episode per vehicle).
        waited_s: total wall time (s) during which the gate held the simulation.
    """

    n: int
    wait_bound_s: float = DEFAULT_WAIT_BOUND_S
    timeouts: int = 0
    waited_s: float = 0.0
    _live: list[bool] = field(init=False)
    _pending_since: list[float | None] = field(init=False)  # wall s the report left
    _blocked_since: float | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        """Validate the bound; every vehicle starts not live, nothing pending."""
        if not (math.isfinite(self.wait_bound_s) and self.wait_bound_s > 0):
            raise ValueError(f"lockstep wait bound must be > 0 s, got {self.wait_bound_s}")
        self._live = [False] * self.n
        self._pending_since = [None] * self.n

    # ---- what happened ------------------------------------------------------------------
    def position_sent(self, i: int, wall_s: float) -> None:
        """Vehicle ``i``'s position report left at ``wall_s``: an answer is due."""
        self._pending_since[i] = wall_s

    def setpoint(self, i: int) -> None:
        """Vehicle ``i`` got a setpoint: its latest report is answered and it is live."""
        self._pending_since[i] = None
        self._live[i] = True

    # ---- the question -------------------------------------------------------------------
    def waiting_for(self, guided: Sequence[bool]) -> list[int]:
        """Indices of the vehicles the next step waits for (no side effects)."""
        return [
            i
            for i in range(self.n)
            if guided[i] and self._live[i] and self._pending_since[i] is not None
        ]

    def blocked(self, wall_s: float, guided: Sequence[bool]) -> tuple[bool, list[WaitTimeout]]:
        """Whether the next physics step must wait, and the waits that just timed out.

        ``guided[i]``: vehicle ``i`` is in GUIDED now. A vehicle out of GUIDED stops being
        live (a pilot took it; its controller must send a setpoint again after GUIDED
        returns before it is waited for). A wait older than the bound times out: counted,
        reported once, and the vehicle is no longer live.
        """
        timed_out: list[WaitTimeout] = []
        waiting = False
        for i in range(self.n):
            if not guided[i]:
                self._live[i] = False
                continue
            since = self._pending_since[i]
            if not self._live[i] or since is None:
                continue
            if wall_s - since >= self.wait_bound_s:
                self._live[i] = False
                self.timeouts += 1
                timed_out.append(WaitTimeout(i, wall_s - since))
            else:
                waiting = True
        if waiting and self._blocked_since is None:
            self._blocked_since = wall_s
        elif not waiting and self._blocked_since is not None:
            self.waited_s += max(0.0, wall_s - self._blocked_since)
            self._blocked_since = None
        return waiting, timed_out

    def next_deadline_s(self, guided: Sequence[bool]) -> float | None:
        """Wall time (s) at which the earliest current wait times out; None if none."""
        times = [self._pending_since[i] for i in self.waiting_for(guided)]
        return min(times) + self.wait_bound_s if times else None  # type: ignore[type-var]
