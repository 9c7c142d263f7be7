"""A serial cable between a companion and a firmware instance: ``socat`` joins the instance's
TCP serial port (ArduPlane SITL's SERIAL1) to a pseudo-terminal, and the companion opens that
as a serial device (``companion fleet --companion-link serial``; the serial tests). The
pseudo-terminal is reached through a symbolic link at a fixed path, as udev names a USB
adapter (``/dev/serial/by-id/...``): the relay stopped (SIGTERM) removes it, the node is gone
(a pulled cable) and a new relay makes a new one at the same path (re-plugged); the relay
paused (SIGSTOP) keeps the node and nothing flows (a cut wire).

``socat`` is Debian's (``apt-get install socat``); nothing here runs it, the caller starts
the command line (:func:`relay_argv`) as it starts its other processes.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

from companion.contracts.errors import UserError

SERIAL_BAUD = 921600  # the companion's baud rate (a pseudo-terminal ignores it)
LINK_WAIT_S = 10.0  # wall s for socat to make its pseudo-terminal


def find_socat() -> str:
    """The ``socat`` executable (UserError saying how to install it when there is none)."""
    path = shutil.which("socat")
    if path is None:
        raise UserError(
            "--companion-link serial or relay needs socat to play the cable: install it "
            "(Debian/Ubuntu: apt-get install socat)"
        )
    return path


def relay_argv(socat: str, link: Path, tcp_port: int) -> list[str]:
    """socat's command line: a raw pseudo-terminal reached at ``link`` <-> TCP
    127.0.0.1:``tcp_port``."""
    return [socat, f"pty,link={link},raw,echo=0", f"tcp:127.0.0.1:{tcp_port}"]


def udp_relay_argv(socat: str, listen_port: int, target_port: int) -> list[str]:
    """socat's command line for a UDP wire (PX4's companion link is UDP): the companion sends
    to 127.0.0.1:``listen_port`` and the relay forwards both ways between it and
    127.0.0.1:``target_port`` from one source port, which PX4 answers (``companion fleet
    --companion-link relay``: the wire cut by pausing it)."""
    return [socat, f"UDP4-LISTEN:{listen_port},bind=127.0.0.1", f"UDP4:127.0.0.1:{target_port}"]


def serial_url(link: Path) -> str:
    """The companion's ``--connect`` for the cable at ``link``."""
    return f"{link},{SERIAL_BAUD}"


def wait_for_link(link: Path, alive, timeout_s: float = LINK_WAIT_S) -> None:
    """Until the pseudo-terminal exists at ``link`` (UserError after ``timeout_s`` wall s, or
    as soon as ``alive()`` says the relay died)."""
    deadline = time.monotonic() + timeout_s
    while not os.path.exists(link):
        if not alive():
            raise UserError(f"socat for {link} exited before making the serial device")
        if time.monotonic() > deadline:
            raise UserError(f"socat made no serial device at {link} in {timeout_s:g} s")
        time.sleep(0.05)
