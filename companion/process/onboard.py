"""The companion's health for ground stations: ONBOARD_COMPUTER_STATUS once a second (one
component of the :class:`~companion.process.runner.Runner`; it returns the message, the
Runner sends it).

The companion's HEARTBEAT (MAV_TYPE_ONBOARD_CONTROLLER, component 191, 1 Hz) is the
link's own (:class:`companion.link.connection.AutopilotLink`: it is also what makes a UDP
autopilot send to us); a ground station that stops hearing it knows the companion is gone.
This message says how it is doing, in the fields ONBOARD_COMPUTER_STATUS (id 390, common.xml)
has; every other field carries its "unused" value:

============== ==============================================================================
field          what the companion puts there
============== ==============================================================================
time_usec      vehicle time (unix us) once known, before it the uptime (us; the message's
               own rule: a receiver tells the two apart by magnitude)
uptime         ms since the companion started (its wall clock)
type           0 (mission computer, primary)
cpu_cores[0]   the companion process's CPU load over the last period (% of one core, 0-100)
link_type[0]   the autopilot link: 0 (UART) on a serial device, 10 (wired network) otherwise
link_rx_rate[0], link_tx_rate[0]
               its MAVLink traffic over the last period (KiB/s, rounded up: 0 only when
               nothing at all moved)
link_type[1]   the group (the members' signed states and alerts): 40 (mesh)
link_rx_rate[1], link_tx_rate[1]
               its datagrams' bytes over the last period (KiB/s, rounded up); UINT32_MAX
               (unused) before the group is opened (before the first autopilot heartbeat)
status_flags   0 (no flag of COMPUTER_STATUS_FLAGS applies)
============== ==============================================================================

The members heard and the patrol's mode are NAMED_VALUE_INT ``pp_members`` and ``pp_mode``
(:mod:`companion.link.gcs`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.process.sender import NOTHING, Effects

STATUS_PERIOD_S = 1.0  # wall s between ONBOARD_COMPUTER_STATUS
LINK_UART, LINK_NETWORK, LINK_MESH = 0, 10, 40  # ONBOARD_COMPUTER_STATUS.link_type
U8_UNUSED, I8_UNUSED, I16_UNUSED, U32_UNUSED = 0xFF, 0x7F, 0x7FFF, 0xFFFFFFFF


class Traffic(Protocol):
    """What is read of the autopilot link: its bytes and which connection carries them."""

    sysid: int | None  # the autopilot's system id, ours too (None: not heard yet)
    generation: int  # changes when the connection is re-opened (the counts restart)

    @property
    def traffic_bytes(self) -> tuple[int, int]:
        """(received, sent) bytes on the current connection."""
        ...


class GroupTraffic(Protocol):
    """What is read of the group endpoint: its datagram bytes."""

    rx_bytes: int
    tx_bytes: int


def kib_s(n_bytes: int, dt_s: float) -> int:
    """``n_bytes`` over ``dt_s`` seconds in KiB/s, rounded up (0 only for no byte at all)."""
    if n_bytes <= 0 or dt_s <= 0:
        return 0
    return min(math.ceil(n_bytes / 1024.0 / dt_s), U32_UNUSED - 1)


class OnboardStatus:
    """ONBOARD_COMPUTER_STATUS every ``period_s`` of wall time.

    Args:
        wall: monotonic wall clock (s); the uptime counts from construction.
        cpu: this process's CPU time (s).
        link: the autopilot link (its traffic).
        serial: whether the link is a serial device (its ``link_type``).
        group: () -> the group endpoint, or None before it is opened.
        vehicle_s: () -> the latest vehicle time (unix s), or None before it is known.
        period_s: wall s between messages.
    """

    def __init__(
        self,
        wall: Callable[[], float],
        cpu: Callable[[], float],
        link: Traffic,
        *,
        serial: bool,
        group: Callable[[], GroupTraffic | None],
        vehicle_s: Callable[[], float | None],
        period_s: float = STATUS_PERIOD_S,
    ) -> None:
        """The first message is due at once; its rates count from now."""
        self.wall, self.cpu, self.link, self.group = wall, cpu, link, group
        self.vehicle_s = vehicle_s
        self.link_type = LINK_UART if serial else LINK_NETWORK
        self.period_s = period_s
        self._t0 = wall()
        self._last_s = self._t0
        self._due_s = self._t0
        self._cpu0 = cpu()
        self._gen = link.generation
        self._link0 = link.traffic_bytes
        self._group0: tuple[int, int] | None = None

    def tick(self) -> Effects:
        """The message when one is due, else nothing (nothing before the autopilot's first
        heartbeat: until then the companion's system id is not known)."""
        now = self.wall()
        if now < self._due_s or self.link.sysid is None:
            return NOTHING
        self._due_s += self.period_s
        if self._due_s <= now:  # after a stall: one message, not a burst
            self._due_s = now + self.period_s
        return (self.message(now),)

    def message(self, now: float) -> Any:
        """The ONBOARD_COMPUTER_STATUS for the period ending at wall time ``now`` (s)."""
        dt = now - self._last_s
        cpu = self.cpu()
        load = 100.0 * (cpu - self._cpu0) / dt if dt > 0 else 0.0
        self._last_s, self._cpu0 = now, cpu
        rx, tx = self.link.traffic_bytes
        if self.link.generation != self._gen:  # re-opened: its counts started again
            self._gen, self._link0 = self.link.generation, (0, 0)
        rates_rx = [kib_s(rx - self._link0[0], dt)] + [U32_UNUSED] * 5
        rates_tx = [kib_s(tx - self._link0[1], dt)] + [U32_UNUSED] * 5
        self._link0 = (rx, tx)
        group = self.group()
        if group is not None:
            g0 = self._group0 or (0, 0)
            rates_rx[1] = kib_s(group.rx_bytes - g0[0], dt)
            rates_tx[1] = kib_s(group.tx_bytes - g0[1], dt)
            self._group0 = (group.rx_bytes, group.tx_bytes)
        uptime_ms = int((now - self._t0) * 1e3) & 0xFFFFFFFF
        vt = self.vehicle_s()
        time_usec = round(vt * 1e6) if vt is not None else uptime_ms * 1000
        return mav.MAVLink_onboard_computer_status_message(
            time_usec,
            uptime_ms,
            0,  # mission computer, primary
            [min(max(round(load), 0), 100)] + [U8_UNUSED] * 7,
            [U8_UNUSED] * 10,
            [U8_UNUSED] * 4,
            [U8_UNUSED] * 10,
            I8_UNUSED,
            [I8_UNUSED] * 8,
            [I16_UNUSED] * 4,
            U32_UNUSED,
            U32_UNUSED,
            [U32_UNUSED] * 4,
            [U32_UNUSED] * 4,
            [U32_UNUSED] * 4,
            [self.link_type, LINK_MESH, 0, 0, 0, 0],
            rates_tx,
            rates_rx,
            [U32_UNUSED] * 6,
            [U32_UNUSED] * 6,
            0,
        )
