"""The companion's two ways to run: its own ``selectors`` loop over the autopilot link and
the group socket (:meth:`run`, :meth:`stop`), or driven from outside by the in-memory engine
(:meth:`begin`, :meth:`on_messages`, :meth:`on_group`, :meth:`tick`); and the shutdown
(:meth:`close`)."""

from __future__ import annotations

import contextlib
import selectors
import time
from typing import Any


class RunnerLoop:
    """The loop, the driven entry points and the shutdown.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def stop(self) -> None:
        """Ask the loop to end (safe from a signal handler)."""
        self._stop = True

    def run(self) -> int:
        """Serve until :meth:`stop`; returns the exit status (0)."""
        self._sel = selectors.DefaultSelector()
        self._log("start", profile=self.config.profile, policy=self.config.policy)
        print(
            f"companion: waiting for the autopilot on {self.link.url}",
            file=self.status_out,
            flush=True,
        )
        try:
            while not self._stop:
                self._poll(0.05)
                if self._stop:
                    break
                self._tick()
        finally:
            self.close()
        return 0

    def begin(self) -> None:
        """Start without the selectors loop: the caller then feeds :meth:`on_messages`,
        :meth:`on_group` and :meth:`tick` and ends with :meth:`close`."""
        self._driven = True
        self._log("start", profile=self.config.profile, policy=self.config.policy)

    def on_messages(self, msgs: list[Any]) -> None:
        """Messages received from the autopilot link, oldest first.

        Behind (a stalled process, a simulator catching up): steer from the newest position
        only; the older ones still feed the estimator.
        """
        self._rx_perf = self.perf()
        last_pos = max(
            (i for i, m in enumerate(msgs) if m.get_type() == "GLOBAL_POSITION_INT"),
            default=-1,
        )
        for i, m in enumerate(msgs):
            self._on_mavlink(m, steer=i == last_pos)

    def on_group(self) -> None:
        """The group has datagrams waiting: hand them to the Agent."""
        if self.group is not None:
            self._on_group()

    def tick(self) -> None:
        """Link supervision, take-control retries, delayed group sends, log flushes."""
        self._tick()

    def close(self) -> None:
        """Final status line and event; flush logs; close the sockets (idempotent)."""
        if self._sel is None and not self._driven:
            return
        self._driven = False
        if self.config.status_interval_s > 0 or self.counters.setpoints:
            self._status(final=True)
        self._log("stop", setpoints=self.counters.setpoints)
        if self.authority.commanding:
            self.link.statustext(f"companion {self.link.sysid}: stopping, setpoints end")
        if self._sel is not None:
            self._sel.close()
        self._sel = None
        if self.group is not None:
            self.group.close()
        self.link.close()
        if self.link.tlog is not None:
            self.link.tlog.close()
        self.events.close()

    def _poll(self, timeout_s: float) -> None:
        sel = self._sel
        fd = self.link.fileno()
        if (fd, self.link.generation) != (self._link_fd, self._link_gen):
            if self._link_fd is not None:
                with contextlib.suppress(KeyError, ValueError, OSError):
                    sel.unregister(self._link_fd)
            if fd is not None:
                sel.register(fd, selectors.EVENT_READ, "link")
            self._link_fd, self._link_gen = fd, self.link.generation
        try:
            ready = sel.select(timeout_s if self._link_fd is not None or self.group else 0.05)
        except InterruptedError:
            return
        if not ready and self._link_fd is None and self.group is None:
            time.sleep(timeout_s)
        for key, _ in ready:
            if key.data == "link":
                self.on_messages(self.link.receive())
            else:
                self._on_group()

    def _tick(self) -> None:
        if self.link.tick() == "lost":
            self._log("link_lost")
            self._link_was_lost = True
            self._authority(self.authority.link_lost())
            self.estimator.reset()
            self.shaper.reset_sample()
        self._take_control()
        self._keepalive()
        if self.group is not None:
            self.group.flush()
        iv = self.config.status_interval_s
        if iv > 0 and self.wall() - self._status_t0 >= iv:
            self._status()
        self.link_flush()
        self.events.flush_if_due()

    def link_flush(self) -> None:
        """Flush the tlog about as often as the events."""
        tl = self.link.tlog
        if tl is not None and self.counters.estimates % 20 == 0:
            tl.flush()
