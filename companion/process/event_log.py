"""events.jsonl, the companion's event file: one JSON object per line, appended, flushed
at most every ``EVENT_FLUSH_S`` of wall time (the edge of the process: the Runner writes its
Agent's events here; :mod:`companion.sim.inmemory` records them in memory instead)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

EVENT_FLUSH_S = 0.5  # wall


class EventLog:
    """events.jsonl: one JSON object per line, flushed every ``EVENT_FLUSH_S`` wall s.

    Appends: a companion restarted with the same log folder (after a crash, say) keeps the
    earlier run's events in front of its own.
    """

    def __init__(self, path: str | Path | None, clock: Callable[[], float] = time.monotonic):
        """Open ``path`` for appending (None: keep nothing)."""
        self._fh: TextIO | None = open(path, "a") if path is not None else None  # noqa: SIM115
        self._clock = clock
        self._last_flush = clock()
        self._dirty = False
        self.count = 0

    def write(self, event: dict[str, Any]) -> None:
        """Append one event."""
        self.count += 1
        if self._fh is None:
            return
        self._fh.write(json.dumps(event, separators=(",", ":")) + "\n")
        self._dirty = True
        if self._clock() - self._last_flush >= EVENT_FLUSH_S:
            self.flush()

    def flush(self) -> None:
        """Push buffered events to the file."""
        if self._fh is not None and not self._fh.closed:
            self._fh.flush()
            self._last_flush = self._clock()
            self._dirty = False

    def flush_if_due(self) -> None:
        """Flush buffered events at most ``EVENT_FLUSH_S`` after they were written."""
        if self._dirty and self._clock() - self._last_flush >= EVENT_FLUSH_S:
            self.flush()

    def close(self) -> None:
        """Flush and close."""
        if self._fh is not None and not self._fh.closed:
            self._fh.flush()
            self._fh.close()
