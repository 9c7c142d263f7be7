"""The MAVLink mission protocol, client side, as pure state machines (sans-IO): the mirror of
the simulator's side, :mod:`sitl_model.mission_protocol`.

A transfer is fed the messages that arrive and the time, and returns the messages to send;
nothing here reads a socket or a clock. Each has

* ``start(now_s)``: the first messages to send;
* ``handle(m, now_s)``: a message received (of a type in ``listens``; others are ignored);
* ``tick(now_s)``: nothing came by ``deadline_s``: ask again, or give up;
* ``done`` and its result (``error``, ``items``, ...), once over.

The time is any monotonic clock (s). :func:`companion.link.mission_protocol.driver.drive` runs
one over a pymavlink connection; a test wires one to the simulator's
:class:`~sitl_model.mission_protocol.MissionProtocol` in memory.

* :class:`Upload` -- MISSION_COUNT, then each item the autopilot asks for, until its
  MISSION_ACK; the count sent again after ``STEP_TIMEOUT_S`` of silence, ``RETRIES`` times
  in all.
* :class:`Download` -- MISSION_REQUEST_LIST, then MISSION_REQUEST_INT item by item, then
  MISSION_ACK; each question asked ``RETRIES`` times at most (a silence of
  ``STEP_TIMEOUT_S`` or a wrong answer ends a try).

Items go to component 1 (the autopilot) of system ``sysid``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

RETRIES = 5
STEP_TIMEOUT_S = 1.5
AUTOPILOT_COMPID = 1
UPLOAD_ANSWERS = ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK")


class Upload:
    """Upload ``n`` items of ``mission_type`` ``mtype`` to autopilot ``sysid``;
    ``item_at(seq)`` builds item ``seq`` (a MISSION_ITEM_INT).

    Attributes:
        done: the transfer is over.
        error: None when the autopilot accepted the items, else what failed (once done).
        counts_sent: MISSION_COUNTs sent so far.
    """

    listens = UPLOAD_ANSWERS

    def __init__(
        self,
        sysid: int,
        n: int,
        item_at: Callable[[int], Any],
        mtype: int = 0,
        *,
        tries: int = RETRIES,
        step_timeout_s: float = STEP_TIMEOUT_S,
    ) -> None:
        """Nothing sent yet."""
        self.sysid, self.n, self.item_at, self.mtype = sysid, n, item_at, mtype
        self.tries, self.step_timeout_s = tries, step_timeout_s
        self.done = False
        self.error: str | None = None
        self.counts_sent = 0
        self.deadline_s = float("inf")

    def start(self, now_s: float) -> list[Any]:
        """The first MISSION_COUNT."""
        return self._count(now_s)

    def _count(self, now_s: float) -> list[Any]:
        self.counts_sent += 1
        self.deadline_s = now_s + self.step_timeout_s
        return [mav.MAVLink_mission_count_message(self.sysid, AUTOPILOT_COMPID, self.n, self.mtype)]

    def handle(self, m: Any, now_s: float) -> list[Any]:
        """A request (the item asked for goes back) or the MISSION_ACK (the end). Any answer
        restarts the silence timer; one from another system or of another mission type is
        otherwise ignored."""
        if self.done or m.get_type() not in UPLOAD_ANSWERS:
            return []
        self.deadline_s = now_s + self.step_timeout_s
        if m.get_srcSystem() != self.sysid or getattr(m, "mission_type", 0) != self.mtype:
            return []
        if m.get_type() == "MISSION_ACK":
            self.done = True
            if m.type != mav.MAV_MISSION_ACCEPTED:
                self.error = f"upload refused (MISSION_ACK type {m.type})"
            return []
        return [self.item_at(m.seq)] if 0 <= m.seq < self.n else []

    def tick(self, now_s: float) -> list[Any]:
        """No answer by the deadline: the count again, or, after ``tries``, give up."""
        if self.done or now_s < self.deadline_s:
            return []
        if self.counts_sent >= self.tries:
            self.done = True
            self.error = f"no answer to MISSION_COUNT after {self.counts_sent} tries"
            return []
        return self._count(now_s)


class Download:
    """Download the items of ``mission_type`` ``mtype`` stored in autopilot ``sysid``.

    Attributes:
        done: the transfer is over.
        items: the MISSION_ITEM_INTs by seq once done, or None if a question went
            unanswered ``tries`` times.
    """

    def __init__(
        self,
        sysid: int,
        mtype: int = 0,
        *,
        tries: int = RETRIES,
        step_timeout_s: float = STEP_TIMEOUT_S,
    ) -> None:
        """Nothing asked yet."""
        self.sysid, self.mtype = sysid, mtype
        self.tries, self.step_timeout_s = tries, step_timeout_s
        self.done = False
        self.items: list[Any] | None = None
        self.count: int | None = None  # None: the count not known yet
        self._got: list[Any] = []
        self._asked = 0  # tries of the current question
        self.deadline_s = float("inf")

    @property
    def listens(self) -> tuple[str, ...]:
        """The answer awaited: the count, then the items."""
        return ("MISSION_COUNT",) if self.count is None else ("MISSION_ITEM_INT",)

    def start(self, now_s: float) -> list[Any]:
        """MISSION_REQUEST_LIST."""
        return self._ask(now_s)

    def _ask(self, now_s: float) -> list[Any]:
        self._asked += 1
        self.deadline_s = now_s + self.step_timeout_s
        if self.count is None:
            return [mav.MAVLink_mission_request_list_message(self.sysid, 1, self.mtype)]
        seq = len(self._got)
        return [mav.MAVLink_mission_request_int_message(self.sysid, 1, seq, self.mtype)]

    def handle(self, m: Any, now_s: float) -> list[Any]:
        """The count or the item asked for (then the next question, or the final
        MISSION_ACK); any other answer of that type ends the try."""
        if self.done or m.get_type() not in self.listens:
            return []
        if self.count is None:
            if m.get_srcSystem() != self.sysid or m.mission_type != self.mtype:
                return self._again(now_s)
            self.count = int(m.count)
        else:
            if m.get_srcSystem() != self.sysid or m.seq != len(self._got):
                return self._again(now_s)
            self._got.append(m)
        self._asked = 0
        if len(self._got) < self.count:
            return self._ask(now_s)
        self.done, self.items = True, self._got
        return [
            mav.MAVLink_mission_ack_message(self.sysid, 1, mav.MAV_MISSION_ACCEPTED, self.mtype)
        ]

    def tick(self, now_s: float) -> list[Any]:
        """No answer by the deadline: ask again, or, after ``tries``, give up."""
        if self.done or now_s < self.deadline_s:
            return []
        return self._again(now_s)

    def _again(self, now_s: float) -> list[Any]:
        if self._asked >= self.tries:
            self.done = True  # items stays None
            return []
        return self._ask(now_s)
