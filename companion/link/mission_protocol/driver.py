"""The one place the mission-protocol client does I/O: run a sans-IO transfer
(:mod:`~companion.link.mission_protocol.client`, ``params``, ``listen``) over a pymavlink
connection. Wall-clock waits here are link plumbing (an operator command, not flight
logic)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Protocol, TypeVar


class Transfer(Protocol):
    """A sans-IO exchange: messages and time in, messages to send out."""

    @property
    def done(self) -> bool:
        """The exchange is over (its result is set)."""
        ...

    @property
    def deadline_s(self) -> float:
        """When :meth:`tick` acts if nothing comes (s, the driver's clock)."""
        ...

    @property
    def listens(self) -> tuple[str, ...]:
        """The message types awaited now."""
        ...

    def start(self, now_s: float) -> list[Any]:
        """The first messages to send."""
        ...

    def handle(self, m: Any, now_s: float) -> list[Any]:
        """A message received; what to send."""
        ...

    def tick(self, now_s: float) -> list[Any]:
        """The time now; what to send."""
        ...


T = TypeVar("T", bound=Transfer)


def drive(conn: Any, transfer: T, clock: Callable[[], float] = time.monotonic) -> T:
    """Run ``transfer`` to its end over pymavlink connection ``conn`` (``conn.mav.send``,
    ``conn.recv_match``): its messages sent, the awaited types received until its deadline,
    the time told when nothing came. Returns the transfer, its result set."""
    _send(conn, transfer.start(clock()))
    while not transfer.done:
        wait_s = transfer.deadline_s - clock()
        m = None
        if wait_s > 0:
            m = conn.recv_match(type=list(transfer.listens), blocking=True, timeout=wait_s)
        now_s = clock()
        _send(conn, transfer.handle(m, now_s) if m is not None else transfer.tick(now_s))
    return transfer


def _send(conn: Any, msgs: list[Any]) -> None:
    for msg in msgs:
        conn.mav.send(msg)
