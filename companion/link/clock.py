"""Vehicle time (pure): the autopilot's clock, never the companion's wall clock (docs/design.md §7).

The autopilot stamps telemetry with ``time_boot_ms``; SYSTEM_TIME pairs it with
``time_unix_usec`` (GPS time on a real aircraft; a fixed epoch plus simulated time in the
simulator). Vehicle time is ``time_unix_usec`` extrapolated by ``time_boot_ms``: unix
seconds, shared by every vehicle of the fleet, advancing at the simulator's speed-up.

A reboot (``time_boot_ms`` going backwards) invalidates the offset until the next
SYSTEM_TIME. A SYSTEM_TIME without a unix time (0: no GPS time yet) is ignored.

PX4's SYSTEM_TIME carries the host's clock, not its own: in SITL with a speed factor the two
part (``time_boot_ms`` runs X times faster). With ``anchor_once`` (set for PX4) the offset is
taken from the first SYSTEM_TIME after boot and then kept: vehicle time is the autopilot's
own ``time_boot_ms`` (of ATTITUDE, GLOBAL_POSITION_INT), placed once on the unix scale.

With ``fixed_offset_s`` the offset is given and never changed (SYSTEM_TIME is ignored):
vehicle time is ``fixed_offset_s + time_boot_ms``. A fleet of PX4 SITL instances uses it with
the fleet's epoch, so that every member's vehicle time is its instance's simulated time since
boot on one scale (``companion run --boot-epoch``; docs/px4.md, "Time base").
"""

from __future__ import annotations

REBOOT_BACKSTEP_MS = 5_000  # boot time going back by more than this = the autopilot rebooted


class VehicleClock:
    """Maps ``time_boot_ms`` to vehicle time (unix s)."""

    def __init__(self, *, anchor_once: bool = False, fixed_offset_s: float | None = None) -> None:
        """No time known yet; ``anchor_once``: the offset from the first SYSTEM_TIME only;
        ``fixed_offset_s``: the offset (unix s at boot), known from the start and kept."""
        self.offset_s: float | None = fixed_offset_s  # unix s - boot s
        self.last_boot_ms: int | None = None
        self.anchor_once = anchor_once
        self.fixed = fixed_offset_s is not None

    @property
    def valid(self) -> bool:
        """Whether vehicle time is known."""
        return self.offset_s is not None

    def on_system_time(self, time_unix_usec: int, time_boot_ms: int) -> None:
        """A SYSTEM_TIME message: (unix us, boot ms) taken at the same instant."""
        self._check_reboot(time_boot_ms)
        if self.fixed or time_unix_usec <= 0 or (self.anchor_once and self.offset_s is not None):
            return
        self.offset_s = time_unix_usec * 1e-6 - time_boot_ms * 1e-3

    def to_vehicle_s(self, time_boot_ms: int) -> float | None:
        """Vehicle time (unix s) of a message stamped ``time_boot_ms``, or None if unknown."""
        self._check_reboot(time_boot_ms)
        if self.offset_s is None:
            return None
        return self.offset_s + time_boot_ms * 1e-3

    def boot_ms_at(self, t_s: float) -> int:
        """``time_boot_ms`` at vehicle time ``t_s`` (for outgoing stamps); 0 if unknown."""
        if self.offset_s is None:
            return 0
        return max(0, round((t_s - self.offset_s) * 1e3))

    def _check_reboot(self, time_boot_ms: int) -> None:
        last = self.last_boot_ms
        if last is not None and time_boot_ms < last - REBOOT_BACKSTEP_MS and not self.fixed:
            self.offset_s = None
        if last is None or time_boot_ms > last or self.offset_s is None:
            self.last_boot_ms = time_boot_ms
