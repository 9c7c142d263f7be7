"""The pymavlink connection to the companion's own autopilot (the only link I/O here).

:class:`AutopilotLink` opens any ``mavutil`` URL (``udpout:127.0.0.1:5760``, ``udpin:...``,
``tcp:host:port``, a serial device ``/dev/ttyUSB0,921600``) as component 191 (onboard
computer) and:

* sends its own HEARTBEAT (MAV_TYPE_ONBOARD_CONTROLLER) every ``heartbeat_period_s`` of
  wall time -- on ``udpout`` this is also what makes the autopilot send to us;
* accepts the first autopilot heartbeat (component 1, not a GCS or companion; ``sysid``
  if given) and takes its system id;
* asks for the telemetry the companion needs with SET_MESSAGE_INTERVAL (``rates_hz``: a
  table, or a function of the HEARTBEAT ``autopilot`` type: PX4 has no WIND and a fixed 1 Hz
  HEARTBEAT), re-asking every ``REQUEST_RETRY_S`` until each request is acknowledged, and
  giving one up, said once on ``warn``, after ``MAX_REQUEST_TRIES`` (PX4 answers FAILED for
  a stream it does not have, and the ACK does not say which message it answers);
* declares the link lost after ``link_timeout_s`` of wall time without an autopilot heartbeat
  (at once when a serial device hangs up), then re-opens the connection every ``retry_s``
  until heartbeats return (TCP; a serial device only once it failed: :mod:`.serial_device`;
  a UDP socket never: PX4 answers only the source port that first sent to it), and
  asks for the telemetry again (the autopilot may have rebooted); each outage is measured on
  this clock (``silent_s`` when lost, ``last_outage_s`` when heard again);
* always speaks MAVLink 2 (:func:`open_mavlink`): pymavlink otherwise starts in MAVLink 1
  and swaps its encoder on the first MAVLink 2 frame it hears, dropping the signing set on it;
* writes every packet, both directions, to the .tlog;
* with a :class:`~companion.contracts.signing.FrameCheck` (``--link-key-file``), signs every frame
  it sends and refuses received frames that are unsigned, badly signed or replayed (counted
  in ``counts``; see :mod:`companion.contracts.signing`). If the autopilot's heartbeats keep
  failing that check before the link ever came up, :meth:`AutopilotLink.tick` raises a
  :class:`~companion.contracts.errors.UserError` that says why (wrong key, or an autopilot that does
  not sign). Without a key, an autopilot that signs its frames and answers none of our
  commands is the mirror case, and is reported the same way.

The wall clock (injected) is used for link supervision only, never for guidance.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.contracts.signing import COMPANION_LINK_ID, REJECT_REASONS, FrameCheck, Signing
from companion.group.keys import TimestampFile, load_key, timestamp_path
from companion.link.serial_device import SerialDevice, is_serial_url
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
MAX_REQUEST_TRIES = 4  # SET_MESSAGE_INTERVAL sent this often without an ACCEPTED: given up
SIGNING_GIVEUP_S = 5.0  # wall s of refused autopilot heartbeats (or of unanswered commands)
SIGNING_WARN_S = 10.0  # wall s between warnings once the link has been up


def _stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def use_mavlink2() -> None:
    """Make pymavlink encode MAVLink 2 from now on (its switch is the environment variable
    ``MAVLINK20`` read when a dialect is set): signing is MAVLink 2 only, and a connection
    opened in MAVLink 1 replaces its encoder, and the signing on it, when it first hears
    MAVLink 2."""
    os.environ["MAVLINK20"] = "1"
    if not mavutil.mavlink20() or mavutil.mavlink.WIRE_PROTOCOL_VERSION != "2.0":
        mavutil.set_dialect("ardupilotmega")


def open_mavlink(url: str, source_system: int, source_component: int) -> Any:
    """A MAVLink 2 pymavlink connection for ``url`` (any mavutil URL), the ardupilotmega
    dialect: a serial device as :class:`~companion.link.serial_device.SerialDevice`, TCP with
    pymavlink's own reconnect. Raises what pymavlink or pyserial raise for a bad URL."""
    use_mavlink2()
    if is_serial_url(url):
        return SerialDevice(url, source_system, source_component)
    return mavutil.mavlink_connection(
        url,
        source_system=source_system,
        source_component=source_component,
        dialect="ardupilotmega",
        autoreconnect=True,
    )


def link_signing(
    key_file: str | os.PathLike[str],
    sysid: int | None,
    *,
    state_dir: str | os.PathLike[str] | None = None,
    persist: bool = True,
) -> FrameCheck:
    """Signing of the autopilot link with the key in ``key_file`` (UserError if refused).

    The key file is read and checked as the group's (32 raw bytes or 64 hex characters,
    mode 600). With ``persist``, the timestamp bound is kept in
    ``<state_dir or the key's folder>/<key file>.<fingerprint>.sysid<N>.link-signing-ts``
    (N = ``sysid`` or 0), apart from the group's, so the same key may serve both.
    """
    key = load_key(key_file)
    store = None
    if persist:
        path = timestamp_path(key_file, key, sysid or 0, state_dir)
        store = TimestampFile(
            path.with_name(path.name.removesuffix(".signing-ts") + ".link-signing-ts")
        )
    return FrameCheck(Signing(key, time.time, link_id=COMPANION_LINK_ID, store=store))


class AutopilotLink:
    """A companion's MAVLink link to one autopilot.

    Args:
        url: a pymavlink connection string.
        sysid: accept only this autopilot system id (None: the first autopilot heard).
        rates_hz: message name -> rate (Hz) requested with SET_MESSAGE_INTERVAL, or a
            function of the autopilot's HEARTBEAT ``autopilot`` (MAV_AUTOPILOT) giving it.
        tlog: optional .tlog writer.
        stamp_us: () -> timestamp (us since the epoch) for tlog entries.
        clock: monotonic wall clock (s) for heartbeats and link supervision.
        signing: MAVLink 2 signing of the link (None: unsigned, nothing checked).
        warn: where warnings about the link go (one line each; default stderr).
        opener: ``(url, source_system, source_component) -> connection`` with what this
            class uses of a ``mavutil`` connection (``mav``, ``recv_msg``, ``close``);
            default :func:`open_mavlink` (the in-memory engine passes its own).
    """

    def __init__(
        self,
        url: str,
        *,
        sysid: int | None = None,
        rates_hz: dict[str, float] | Callable[[int | None], dict[str, float]] | None = None,
        tlog: TlogWriter | None = None,
        stamp_us: Callable[[], int] | None = None,
        clock: Callable[[], float] = time.monotonic,
        heartbeat_period_s: float = 1.0,
        link_timeout_s: float = 3.0,
        retry_s: float = 2.0,
        signing: FrameCheck | None = None,
        warn: Callable[[str], None] = _stderr,
        opener: Callable[[str, int, int], Any] | None = None,
    ) -> None:
        """Open the connection (no autopilot is needed yet)."""
        self._opener = opener or open_mavlink
        self.url = url
        self.want_sysid = sysid
        self.sysid: int | None = sysid
        self._rates_for = rates_hz if callable(rates_hz) else None
        self.rates_hz: dict[str, float] = {} if callable(rates_hz) else dict(rates_hz or {})
        self.tlog = tlog
        self.stamp_us = stamp_us or (lambda: int(time.time() * 1e6))
        self.clock = clock
        self.heartbeat_period_s = heartbeat_period_s
        self.link_timeout_s = link_timeout_s
        self.retry_s = retry_s
        self.signing = signing
        self.warn = warn
        self.up = False
        self.autopilot: int | None = None  # MAV_AUTOPILOT of our autopilot's last HEARTBEAT
        self.counts = {"rx": 0, "tx": 0, "bad": 0, "send_errors": 0, "reconnects": 0}
        self.counts["device_lost"] = 0  # a serial device hung up or failed
        # our autopilot's frames received, and those missed (gaps in its sequence numbers:
        # lost on the way, or never read); the stream watch tells a slowed stream from loss
        self.counts["ap_frames"] = self.counts["ap_missed"] = 0
        self._ap_seq: int | None = None
        self.counts |= dict.fromkeys(REJECT_REASONS, 0)
        self._ever_up = False
        self._ap_rejects: dict[str, int] = {}  # refused autopilot heartbeats by reason
        self._first_ap_reject = -1e9
        self._last_warn = -1e9
        self._ap_signs = False  # heard signed autopilot frames while we have no key
        self._acked = False  # any COMMAND_ACK from the autopilot since the link came up
        self._up_since = -1e9
        self._last_hb_tx = -1e9
        self._last_ap_hb = -1e9
        self._last_open = -1e9
        self._lost_hb = -1e9  # the last autopilot heartbeat before the link was lost (wall s)
        self.silent_s: float | None = None  # wall s without a heartbeat when last lost
        self.last_outage_s: float | None = None  # wall s of the last outage, once heard again
        self._pending: dict[int, float] = {}  # message id -> last request (wall s)
        self._tries: dict[int, int] = {}  # message id -> requests sent since the link came up
        self.conn: Any = None
        self.generation = 0
        self._open()

    # ---- connection -----------------------------------------------------------------------
    def _open(self) -> None:
        self._last_open = self.clock()
        self.generation += 1  # a new socket may reuse the old descriptor number
        try:
            self.conn = self._opener(self.url, self.sysid or 1, COMPANION_COMPID)
        except Exception as exc:  # pymavlink raises many types for a bad URL or device
            if self.counts["reconnects"] == 0:
                raise UserError(f"--connect {self.url!r}: cannot open: {exc}") from None
            self.conn = None
            return
        if hasattr(self.conn, "port") and hasattr(self.conn.port, "setblocking"):
            with contextlib.suppress(OSError):
                self.conn.port.setblocking(False)
        self.conn.mav.robust_parsing = True
        if self.signing is not None:
            self.signing.install(self.conn.mav)

    @property
    def traffic_bytes(self) -> tuple[int, int]:
        """(received, sent) bytes on the current connection, as pymavlink counts them
        (both 0 when closed; they start again from 0 when the link is re-opened:
        :attr:`generation` changes)."""
        mav_ = getattr(self.conn, "mav", None)
        if mav_ is None:
            return 0, 0
        return int(getattr(mav_, "total_bytes_received", 0)), int(
            getattr(mav_, "total_bytes_sent", 0)
        )

    def fileno(self) -> int | None:
        """Descriptor to select on (None when closed or not selectable)."""
        if self.conn is None:
            return None
        fd = getattr(self.conn, "fd", None)
        if fd is not None:
            return fd
        port = getattr(self.conn, "port", None)
        return port.fileno() if port is not None and hasattr(port, "fileno") else None

    def _check_device(self) -> None:
        """A serial device that hung up or failed is closed (re-opened by :meth:`tick`)."""
        if self.conn is not None and getattr(self.conn, "gone", False):
            self.counts["device_lost"] += 1
            self.close()

    def close(self) -> None:
        """Close the connection (the tlog is the caller's)."""
        if self.conn is not None:
            # pymavlink's TCP link has no socket left after a failed reconnect
            with contextlib.suppress(OSError, AttributeError):
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
                self._check_device()
                break
            if m is None:
                break
            if m.get_type() == "BAD_DATA":
                if self.signing is not None and getattr(m, "reason", "") == "Invalid signature":
                    self._refused(self.signing, m.data)
                else:
                    self.counts["bad"] += 1
                continue
            self.counts["rx"] += 1
            if self.tlog is not None:
                self.tlog.write(self.stamp_us(), m.get_msgbuf())
            self._note(m)
            out.append(m)
        return out

    def _refused(self, check: FrameCheck, frame: bytes) -> None:
        """Count a frame refused by the link's signing ``check``; note it if it is an
        autopilot heartbeat."""
        r = check.rejected(frame)
        self.counts[r.reason] += 1
        is_ap = r.compid == AUTOPILOT_COMPID and r.msg_id == mav.MAVLINK_MSG_ID_HEARTBEAT
        if is_ap and (self.want_sysid is None or r.sysid == self.want_sysid):
            if not self._ap_rejects:
                self._first_ap_reject = self.clock()
            self._ap_rejects[r.reason] = self._ap_rejects.get(r.reason, 0) + 1

    def is_autopilot(self, m: Any) -> bool:
        """Whether ``m`` comes from our autopilot (its system, component 1)."""
        return m.get_srcSystem() == self.sysid and m.get_srcComponent() == AUTOPILOT_COMPID

    def _note(self, m: Any) -> None:
        if m.get_srcSystem() == self.sysid and m.get_srcComponent() == AUTOPILOT_COMPID:
            seq = m.get_seq()
            if self._ap_seq is not None:
                self.counts["ap_missed"] += (seq - self._ap_seq - 1) & 0xFF
            self._ap_seq = seq
            self.counts["ap_frames"] += 1
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
                self.autopilot = int(m.autopilot)
                if self.signing is None and m.get_header().incompat_flags & 1:
                    self._ap_signs = True
                if not self.up:
                    if self._ever_up:  # an outage ends: its length on our clock
                        self.last_outage_s = self._last_ap_hb - self._lost_hb
                    self.up = True
                    self._ever_up = True
                    self._ap_rejects = {}
                    self._up_since = self._last_ap_hb
                    self._acked = False
                    self._request_all()
        elif t == "COMMAND_ACK":
            self._acked |= self.is_autopilot(m)
            if (
                m.command == mav.MAV_CMD_SET_MESSAGE_INTERVAL
                and m.result == mav.MAV_RESULT_ACCEPTED
                and self._pending
            ):
                # the ack does not say which message: clear the oldest request
                pending = self._pending
                pending.pop(min(pending, key=lambda msg_id: pending[msg_id]))

    # ---- sending ----------------------------------------------------------------------------
    def send(self, msg: Any) -> None:
        """Pack and send one message (logged to the tlog)."""
        if self.conn is None:
            return
        try:
            if self.signing is not None:
                self.signing.stamp(self.conn.mav)
            self.conn.mav.send(msg)
            self.counts["tx"] += 1
        except OSError:
            self.counts["send_errors"] += 1
            self._check_device()
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
        self._tries = {}
        if self._rates_for is not None:
            self.rates_hz = dict(self._rates_for(self.autopilot))
        # vehicle time at once, not at the next 1 Hz SYSTEM_TIME
        self.command_long(mav.MAV_CMD_REQUEST_MESSAGE, mav.MAVLINK_MSG_ID_SYSTEM_TIME)
        for name, hz in self.rates_hz.items():
            msg_id = getattr(mav, f"MAVLINK_MSG_ID_{name}")
            self.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)
            self._pending[msg_id] = now
            self._tries[msg_id] = 1

    # ---- supervision ------------------------------------------------------------------------
    def _check_signing(self, now: float) -> None:
        """Raise (never up) or warn (up before) when link signing keeps the autopilot out."""
        unanswered = self._ap_signs and self.up and not self._acked
        if unanswered and now - self._up_since >= SIGNING_GIVEUP_S:
            raise UserError(
                f"the autopilot on {self.url} (system {self.sysid}) signs its MAVLink "
                f"frames and answered none of our commands in {SIGNING_GIVEUP_S:g} s: "
                "give --link-key-file FILE with its signing key"
            )
        if self.up or not self._ap_rejects:
            return
        n = sum(self._ap_rejects.values())
        why = ", ".join(f"{k} {v}" for k, v in sorted(self._ap_rejects.items()))
        fix = (
            "the autopilot does not sign its frames: set its key with SETUP_SIGNING (see "
            "docs/companion.md) or run without --link-key-file"
            if set(self._ap_rejects) == {"unsigned"}
            else "is --link-key-file the autopilot's signing key?"
        )
        text = f"no valid heartbeat from the autopilot on {self.url}: {n} refused ({why}); {fix}"
        if not self._ever_up:
            if now - self._first_ap_reject >= SIGNING_GIVEUP_S:
                raise UserError(text)
        elif now - self._last_warn >= SIGNING_WARN_S:
            self._last_warn = now
            self.warn(f"companion: warning: {text}")

    def tick(self) -> str | None:
        """Heartbeat, request retries and link supervision; "lost" when the link just died.

        Raises :class:`UserError` when link signing keeps the autopilot out (see the module
        docstring).
        """
        now = self.clock()
        self._check_signing(now)
        if self.up and (self.conn is None or now - self._last_ap_hb > self.link_timeout_s):
            return self._lose(now)  # silent for the time-out, or the device hung up
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
                if self._tries.get(msg_id, 0) >= MAX_REQUEST_TRIES:
                    del self._pending[msg_id]
                    self.counts["requests_given_up"] = self.counts.get("requests_given_up", 0) + 1
                    self.warn(
                        f"companion: warning: the autopilot did not accept {name} at "
                        f"{self.rates_hz[name]:g} Hz in {MAX_REQUEST_TRIES} requests; "
                        "not asked again"
                    )
                    continue
                self._tries[msg_id] = self._tries.get(msg_id, 0) + 1
                self.command_long(
                    mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / self.rates_hz[name]
                )
                self._pending[msg_id] = now
        if (
            not self.up
            and self._reopen_on_silence()
            and now - self._last_ap_hb > self.link_timeout_s
            and now - self._last_open >= max(self.retry_s, self.link_timeout_s)
        ):
            self.close()  # re-open: a restarted peer (a serial device only once it failed)
            self.counts["reconnects"] += 1
            self._open()
        return None

    def _reopen_on_silence(self) -> bool:
        """Whether a silent link is re-opened: TCP yes (a restarted peer needs a new
        connection); UDP never: a new socket has a new source port, and PX4 answers only the
        address that first sent to its port (a companion that re-opened after an outage was
        never heard again); a serial device only once it failed."""
        if self.url.startswith(("udp:", "udpin:", "udpout:", "udpbcast:")):
            return False
        return getattr(self.conn, "reopen_on_silence", True)

    def _lose(self, now: float) -> str:
        """The link is lost at wall time ``now`` (s): the silence so far is noted."""
        self.up = False
        self._pending = {}
        self._lost_hb = self._last_ap_hb
        self.silent_s = now - self._last_ap_hb
        return "lost"
