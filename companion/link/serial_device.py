"""A serial device as the autopilot link: pymavlink's serial port without its two habits that
hurt a companion wired to its autopilot (an edge: it opens devices).

pymavlink's ``mavserial`` prints "Device ... is dead" on stdout when a write fails, and with
``autoreconnect`` it tries to re-open the device inside every failing write; while the device
node is gone (a USB adapter pulled) its descriptor stays readable (hang-up) and the caller's
``select`` returns at once, so the companion spun a full core until its link time-out.
:class:`SerialDevice` keeps pymavlink's opening (pyserial, the baud rate, raw mode) and does
its own I/O on the descriptor, never blocking and never printing:

* a read with nothing waiting returns nothing; a hang-up or an I/O error marks the device
  ``gone`` and raises ``OSError`` (the caller closes it and re-opens it later, paced by its
  own clock: :class:`companion.link.connection.AutopilotLink`);
* a write that does not fit (a cut wire: the far end reads nothing and the buffers fill)
  drops what did not fit and counts it in ``dropped_bytes``; an I/O error marks the device
  ``gone`` and raises ``OSError``.

Two failures, two behaviours (``docs/companion.md``, "Serial links"): a *pulled cable* (the
node is gone or hung up) is re-opened every ``retry_s`` until the device is back; a *cut
wire* (the node stays, nothing flows) is the link time-out alone, and the device is kept
open: re-opening a healthy device cannot help, and closing a pseudo-terminal's last slave
descriptor hangs up its master.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
from typing import Any

from pymavlink import mavutil

SERIAL_SCHEMES = (
    "tcp:",
    "tcpin:",
    "udp:",
    "udpin:",
    "udpout:",
    "udpbcast:",
    "uds:",
    "unix:",
    "ws:",
    "wss:",
    "wsserver:",
)
DEFAULT_BAUD = 115200
_GONE_ERRNOS = {errno.EIO, errno.ENXIO, errno.ENODEV, errno.EBADF, errno.EPIPE}


def is_serial_url(url: str) -> bool:
    """Whether pymavlink reads ``url`` as a serial device (``/dev/ttyUSB0,921600``, ``COM3``):
    no ``scheme:`` and not an existing file (a log)."""
    if url.startswith(SERIAL_SCHEMES) or ":" in url:
        return False
    return not os.path.isfile(url.split(",", 1)[0])


def split_serial_url(url: str) -> tuple[str, int]:
    """(device path, baud rate) of a serial URL ``DEVICE[,BAUD]``; ValueError for a bad baud."""
    device, _, baud = url.partition(",")
    return device, int(baud) if baud else DEFAULT_BAUD


class SerialDevice(mavutil.mavserial):
    """pymavlink's serial port opened as usual, read and written without blocking.

    Args:
        url: ``DEVICE[,BAUD]``.
        source_system: our MAVLink system id.
        source_component: our MAVLink component id.

    Attributes:
        gone: the device hung up or failed: close it and re-open it later.
        dropped_bytes: bytes written that did not fit (the far end not reading).
        reopen_on_silence: False: a silent but healthy device is not re-opened.
    """

    reopen_on_silence = False

    def __init__(self, url: str, source_system: int, source_component: int) -> None:
        """Open the device (pyserial; raises ``serial.SerialException``, an ``OSError``)."""
        device, baud = split_serial_url(url)
        super().__init__(
            device,
            baud=baud,
            autoreconnect=False,
            source_system=source_system,
            source_component=source_component,
        )
        self.gone = False
        self.dropped_bytes = 0

    def _fd(self) -> int:
        fd = self.port.fileno()
        if fd is None or fd < 0:
            self.gone = True
            raise OSError(errno.EBADF, f"{self.device}: not open")
        return fd

    def _failed(self, exc: OSError) -> OSError:
        self.gone = True
        return OSError(exc.errno or errno.EIO, f"{self.device}: {exc.strerror or exc}")

    def recv(self, n: int | None = None) -> bytes:
        """Up to ``n`` bytes waiting (b"" if none); ``OSError`` once the device is gone."""
        fd = self._fd()
        want = self.mav.bytes_needed() if n is None else n
        try:
            ready, _, _ = select.select([fd], [], [], 0)
            if not ready:
                return b""
            data = os.read(fd, max(1, want))
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            raise self._failed(exc) from None
        if not data:  # readable with nothing to read: hung up
            raise self._failed(OSError(errno.EIO, "hung up"))
        return data

    def write(self, buf: Any) -> int:
        """Write what fits now; what does not is dropped (counted). ``OSError`` once the
        device is gone."""
        data = bytes(buf)
        fd = self._fd()
        try:
            n = os.write(fd, data)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            if exc.errno in _GONE_ERRNOS:
                raise self._failed(exc) from None
            raise
        self.dropped_bytes += len(data) - n
        return n

    def close(self) -> None:
        """Close the device (idempotent)."""
        with contextlib.suppress(OSError):
            self.port.close()
