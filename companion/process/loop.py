"""The companion's own ``selectors`` loop over the autopilot link and the group socket
(:meth:`companion.process.runner.Runner.run`): which of them has data waiting."""

from __future__ import annotations

import contextlib
import selectors
import time
from typing import Protocol


class Polled(Protocol):
    """What the loop reads of the autopilot link: its descriptor, and a generation that
    changes on every reconnect (the descriptor may then be reused)."""

    generation: int

    def fileno(self) -> int | None:
        """The socket's descriptor (None: not open)."""
        ...


class Readable(Protocol):
    """The group's socket."""

    def fileno(self) -> int:
        """The socket's descriptor."""
        ...


class Poller:
    """Waits for the link or the group, following the link across reconnects.

    Args:
        link: the autopilot link.
    """

    def __init__(self, link: Polled) -> None:
        """Nothing registered yet."""
        self.link = link
        self._sel = selectors.DefaultSelector()
        self._link_fd: int | None = None
        self._link_gen = -1
        self._group = False  # the group's socket registered

    def poll(self, timeout_s: float, group: Readable | None) -> list[str]:
        """Wait up to ``timeout_s`` (wall s) for data: ``"link"``, ``"group"`` or both
        (``group``, once there is one, is watched from then on)."""
        sel = self._sel
        fd = self.link.fileno()
        if (fd, self.link.generation) != (self._link_fd, self._link_gen):
            if self._link_fd is not None:
                with contextlib.suppress(KeyError, ValueError, OSError):
                    sel.unregister(self._link_fd)
            if fd is not None:
                sel.register(fd, selectors.EVENT_READ, "link")
            self._link_fd, self._link_gen = fd, self.link.generation
        if group is not None and not self._group:
            sel.register(group.fileno(), selectors.EVENT_READ, "group")
            self._group = True
        try:
            ready = sel.select(timeout_s if self._link_fd is not None or group else 0.05)
        except InterruptedError:
            return []
        if not ready and self._link_fd is None and group is None:
            time.sleep(timeout_s)
        return [key.data for key, _ in ready]

    def close(self) -> None:
        """Close the selector."""
        self._sel.close()
