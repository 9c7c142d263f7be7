"""MAVLink telemetry log (.tlog): every message of the autopilot link, both directions.

The format pymavlink's ``mavlogdump.py`` reads: for each message, an 8-byte big-endian
timestamp (microseconds since the Unix epoch) followed by the raw MAVLink packet. The stamp
is the vehicle time when it is known (so the log lines up with the autopilot's own clock
and the simulator's truth log), the wall clock before that.
"""

from __future__ import annotations

import struct
from pathlib import Path


class TlogWriter:
    """Appends packets to a .tlog file; flushed by :meth:`flush` and on :meth:`close`."""

    def __init__(self, path: str | Path) -> None:
        """Open ``path`` for appending: a restarted companion keeps the earlier run's packets."""
        self.path = Path(path)
        self._fh = open(self.path, "ab")  # noqa: SIM115 - closed in close()
        self.count = 0

    def write(self, unix_us: int, packet: bytes) -> None:
        """One packet with its timestamp (us since the Unix epoch)."""
        if self._fh.closed:
            return
        self._fh.write(struct.pack(">Q", max(0, int(unix_us))) + bytes(packet))
        self.count += 1

    def flush(self) -> None:
        """Push buffered packets to the file."""
        if not self._fh.closed:
            self._fh.flush()

    def close(self) -> None:
        """Flush and close."""
        if not self._fh.closed:
            self._fh.flush()
            self._fh.close()
