"""Which autopilots are on a link, as a pure state machine (sans-IO, like
:mod:`~companion.link.mission_protocol.client`): a ground station's HEARTBEAT before each
wait of at most ``POLL_S``, the autopilots' HEARTBEATs (component 1, not a ground station)
collected for ``listen_s``, or until the one asked for is heard. Frames refused by the link
signing check (BAD_DATA "Invalid signature") are counted there."""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.signing import FrameCheck

POLL_S = 0.3
AUTOPILOT_COMPID = 1


class Listen:
    """Autopilots heard within ``listen_s`` (s); ``only``: stop once this system is heard.

    Attributes:
        done: listening is over.
        kinds: each system heard -> its HEARTBEAT ``autopilot`` (MAV_AUTOPILOT).
        signed: whether their heartbeats were signed.
    """

    listens = ("HEARTBEAT", "BAD_DATA")

    def __init__(
        self,
        listen_s: float,
        only: int | None = None,
        check: FrameCheck | None = None,
        *,
        poll_s: float = POLL_S,
    ) -> None:
        """Nothing heard yet."""
        self.listen_s, self.only, self.check, self.poll_s = listen_s, only, check, poll_s
        self.done = False
        self.kinds: dict[int, int] = {}
        self.signed = False
        self.end_s = float("inf")
        self.deadline_s = float("inf")

    @property
    def found(self) -> list[int]:
        """The systems heard, sorted (only ``only`` when it was asked for)."""
        if self.only is not None and self.only in self.kinds:
            return [self.only]
        return sorted(s for s in self.kinds if self.only is None or s == self.only)

    def start(self, now_s: float) -> list[Any]:
        """Listening starts: the first ground-station heartbeat."""
        self.end_s = now_s + self.listen_s
        return self._next(now_s)

    def _next(self, now_s: float) -> list[Any]:
        if now_s >= self.end_s:
            self.done = True
            return []
        self.deadline_s = now_s + self.poll_s
        return [
            mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
        ]

    def handle(self, m: Any, now_s: float) -> list[Any]:
        """A HEARTBEAT (an autopilot's is noted) or a refused frame (counted)."""
        if self.done or m.get_type() not in self.listens:
            return []
        if m.get_type() == "BAD_DATA":
            if self.check is not None and getattr(m, "reason", "") == "Invalid signature":
                self.check.rejected(m.data)
        elif m.get_srcComponent() == AUTOPILOT_COMPID and m.type != mav.MAV_TYPE_GCS:
            self.kinds[m.get_srcSystem()] = int(m.autopilot)
            self.signed |= bool(m.get_header().incompat_flags & 1)
            if self.only is not None and self.only in self.kinds:
                self.done = True
                return []
        return self._next(now_s)

    def tick(self, now_s: float) -> list[Any]:
        """A wait went by: the next heartbeat, or the end."""
        if self.done or now_s < self.deadline_s:
            return []
        return self._next(now_s)
