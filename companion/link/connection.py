"""The pymavlink connection to the companion's own autopilot (the only link I/O here).

:class:`AutopilotLink` opens any ``mavutil`` URL (``udpout:127.0.0.1:5760``, ``udpin:...``,
``tcp:host:port``, a serial device ``/dev/ttyUSB0,921600``) as component 191 (onboard
computer) and:

* sends its own HEARTBEAT (MAV_TYPE_ONBOARD_CONTROLLER) every ``heartbeat_period_s`` of
  wall time -- on ``udpout`` this is also what makes the autopilot send to us;
* accepts the first autopilot heartbeat (component 1, not a GCS or companion; ``sysid``
  if given) and takes its system id;
* asks for the telemetry the companion needs with SET_MESSAGE_INTERVAL, re-asking until each
  request is acknowledged;
* declares the link lost after ``link_timeout_s`` of wall time without an autopilot heartbeat,
  then closes and re-opens the connection every ``retry_s`` until heartbeats return, and
  asks for the telemetry again (the autopilot may have rebooted);
* writes every packet, both directions, to the .tlog.

The wall clock (injected) is used for link supervision only, never for guidance.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.errors import UserError
from companion.link.tlog import TlogWriter

COMPANION_COMPID = mav.MAV_COMP_ID_ONBOARD_COMPUTER  # 191
AUTOPILOT_COMPID = 1
NON_AUTOPILOT_TYPES = {
    mav.MAV_TYPE_GCS,
    mav.MAV_TYPE_ONBOARD_CONTROLLER,
    mav.MAV_TYPE_GIMBAL,
    mav.MAV_TYPE_CAMERA,
    mav.MAV_TYPE_ADSB,
}
REQUEST_RETRY_S = 2.0


class AutopilotLink:
    """A companion's MAVLink link to one autopilot.

    Args:
        url: a pymavlink connection string.
        sysid: accept only this autopilot system id (None: the first autopilot heard).
        rates_hz: message name -> rate (Hz) requested with SET_MESSAGE_INTERVAL.
        tlog: optional .tlog writer.
        stamp_us: () -> timestamp (us since the epoch) for tlog entries.
        clock: monotonic wall clock (s) for heartbeats and link supervision.
    """

    def __init__(
        self,
        url: str,
        *,
        sysid: int | None = None,
        rates_hz: dict[str, float] | None = None,
        tlog: TlogWriter | None = None,
        stamp_us: Callable[[], int] | None = None,
        clock: Callable[[], float] = time.monotonic,
        heartbeat_period_s: float = 1.0,
        link_timeout_s: float = 3.0,
        retry_s: float = 2.0,
    ) -> None:
        """Open the connection (no autopilot is needed yet)."""
        self.url = url
        self.want_sysid = sysid
        self.sysid: int | None = sysid
        self.rates_hz = dict(rates_hz or {})
        self.tlog = tlog
        self.stamp_us = stamp_us or (lambda: int(time.time() * 1e6))
        self.clock = clock
        self.heartbeat_period_s = heartbeat_period_s
        self.link_timeout_s = link_timeout_s
        self.retry_s = retry_s
        self.up = False
        self.counts = {"rx": 0, "tx": 0, "bad": 0, "send_errors": 0, "reconnects": 0}
        self._last_hb_tx = -1e9
        self._last_ap_hb = -1e9
        self._last_open = -1e9
        self._pending: dict[int, float] = {}  # message id -> last request (wall s)
        self.conn: Any = None
        self.generation = 0
        self._open()

    # ---- connection -----------------------------------------------------------------------
    def _open(self) -> None:
        self._last_open = self.clock()
        self.generation += 1  # a new socket may reuse the old descriptor number
        try:
            self.conn = mavutil.mavlink_connection(
                self.url,
                source_system=self.sysid or 1,
                source_component=COMPANION_COMPID,
                dialect="ardupilotmega",
                autoreconnect=True,
            )
        except Exception as exc:  # pymavlink raises many types for a bad URL or device
            if self.counts["reconnects"] == 0:
                raise UserError(f"--connect {self.url!r}: cannot open: {exc}") from None
            self.conn = None
            return
        if hasattr(self.conn, "port") and hasattr(self.conn.port, "setblocking"):
            with contextlib.suppress(OSError):
                self.conn.port.setblocking(False)
        self.conn.mav.robust_parsing = True

    def fileno(self) -> int | None:
        """Descriptor to select on (None when closed or not selectable)."""
        if self.conn is None:
            return None
        fd = getattr(self.conn, "fd", None)
        if fd is not None:
            return fd
        port = getattr(self.conn, "port", None)
        return port.fileno() if port is not None and hasattr(port, "fileno") else None

    def close(self) -> None:
        """Close the connection (the tlog is the caller's)."""
        if self.conn is not None:
            with contextlib.suppress(OSError):
                self.conn.close()
            self.conn = None

    # ---- receiving --------------------------------------------------------------------------
    def receive(self) -> list[Any]:
        """Every message waiting on the link (drained; non-blocking)."""
        out: list[Any] = []
        if self.conn is None:
            return out
        for _ in range(1000):
            try:
                m = self.conn.recv_msg()
            except (OSError, mav.MAVError):
                self.counts["bad"] += 1
                break
            if m is None:
                break
            if m.get_type() == "BAD_DATA":
                self.counts["bad"] += 1
                continue
            self.counts["rx"] += 1
            if self.tlog is not None:
                self.tlog.write(self.stamp_us(), m.get_msgbuf())
            self._note(m)
            out.append(m)
        return out

    def is_autopilot(self, m: Any) -> bool:
        """Whether ``m`` comes from our autopilot (its system, component 1)."""
        return m.get_srcSystem() == self.sysid and m.get_srcComponent() == AUTOPILOT_COMPID

    def _note(self, m: Any) -> None:
        t = m.get_type()
        if t == "HEARTBEAT" and m.get_srcComponent() == AUTOPILOT_COMPID:
            if m.type in NON_AUTOPILOT_TYPES:
                return
            src = m.get_srcSystem()
            if self.sysid is None and (self.want_sysid is None or src == self.want_sysid):
                self.sysid = src
                self.conn.mav.srcSystem = src
            if src == self.sysid:
                self._last_ap_hb = self.clock()
                if not self.up:
                    self.up = True
                    self._request_all()
        elif (
            t == "COMMAND_ACK"
            and m.command == mav.MAV_CMD_SET_MESSAGE_INTERVAL
            and m.result == mav.MAV_RESULT_ACCEPTED
            and self._pending
        ):
            # the ack does not say which message: clear the oldest request
            self._pending.pop(min(self._pending, key=self._pending.get))

    # ---- sending ----------------------------------------------------------------------------
    def send(self, msg: Any) -> None:
        """Pack and send one message (logged to the tlog)."""
        if self.conn is None:
            return
        try:
            self.conn.mav.send(msg)
            self.counts["tx"] += 1
        except OSError:
            self.counts["send_errors"] += 1
            return
        if self.tlog is not None:
            self.tlog.write(self.stamp_us(), msg.get_msgbuf())

    def command_long(self, command: int, *params: float) -> None:
        """Send COMMAND_LONG to the autopilot (params padded with zeros)."""
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.send(
            mav.MAVLink_command_long_message(self.sysid or 0, AUTOPILOT_COMPID, command, 0, *p)
        )

    def statustext(self, text: str, severity: int = mav.MAV_SEVERITY_NOTICE) -> None:
        """A STATUSTEXT to the autopilot and ground stations (truncated to 50 characters)."""
        self.send(mav.MAVLink_statustext_message(severity, text.encode()[:50]))

    def _request_all(self) -> None:
        now = self.clock()
        self._pending = {}
        # vehicle time at once, not at the next 1 Hz SYSTEM_TIME
        self.command_long(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_SYSTEM_TIME)
        for name, hz in self.rates_hz.items():
            msg_id = getattr(mav, f"MAVLINK_MSG_ID_{name}")
            self.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)
            self._pending[msg_id] = now

    # ---- supervision ------------------------------------------------------------------------
    def tick(self) -> str | None:
        """Heartbeat, request retries and link supervision; "lost" when the link just died."""
        now = self.clock()
        if self.conn is None:
            if now - self._last_open >= self.retry_s:
                self.counts["reconnects"] += 1
                self._open()
            return None
        period = self.heartbeat_period_s if self.up else min(0.05, self.heartbeat_period_s)
        if now - self._last_hb_tx >= period:  # faster while looking for the autopilot
            self._last_hb_tx = now
            self.send(
                mav.MAVLink_heartbeat_message(
                    mav.MAV_TYPE_ONBOARD_CONTROLLER,
                    mav.MAV_AUTOPILOT_INVALID,
                    0,
                    0,
                    mav.MAV_STATE_ACTIVE,
                    3,
                )
            )
        if self.up and self._pending:
            stale = [i for i, t in self._pending.items() if now - t >= REQUEST_RETRY_S]
            for msg_id in stale:
                name = mav.mavlink_map[msg_id].msgname
                self.command_long(
                    mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / self.rates_hz[name]
                )
                self._pending[msg_id] = now
        if self.up and now - self._last_ap_hb > self.link_timeout_s:
            self.up = False
            self._pending = {}
            return "lost"
        if (
            not self.up
            and now - self._last_ap_hb > self.link_timeout_s
            and now - self._last_open >= max(self.retry_s, self.link_timeout_s)
        ):
            self.close()  # re-open: a restarted peer, a re-plugged device
            self.counts["reconnects"] += 1
            self._open()
        return None
