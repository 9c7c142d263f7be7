"""The autopilot's battery as the companion hears it (pure): SYS_STATUS and BATTERY_STATUS.

Input, as ArduPilot sends them: SYS_STATUS ``voltage_battery`` (mV, UINT16_MAX unknown),
``current_battery`` (cA, -1 unknown), ``battery_remaining`` (%, -1 unknown); BATTERY_STATUS
of battery ``id`` 0 (the others are not followed): ``voltages`` (mV per cell, UINT16_MAX no
cell; a monitor without cells puts the pack's voltage in the first, spilling into the next
past 65534 mV, so the pack is the sum of the cells present), ``current_battery`` (cA),
``current_consumed`` (mAh, -1 unknown), ``battery_remaining`` (%). The time of a report is
the vehicle time (unix s) the caller passes in.

Output: a :class:`BatteryEstimate`, each field the latest valid report of it. A field out
of range (negative, above 100 %, not finite, or MAVLink's "unknown") is ignored, never acted
on, and counted in :attr:`BatteryMonitor.rejected` by field and reason; the other fields of
the same report still count (an autopilot without a current sensor still reports its
voltage).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

UINT16_UNKNOWN = 0xFFFF  # MAVLink: no voltage / no cell
UNKNOWN = -1  # MAVLink: remaining, current and consumed unknown
FOLLOWED_BATTERY_ID = 0


@dataclass(frozen=True)
class BatteryEstimate:
    """What the autopilot last said about its battery.

    Attributes:
        t_s: vehicle time (unix s) of the last report that carried a valid field.
        remaining_pct: charge left (%, 0..100), or None until reported.
        consumed_mah: charge drawn (mAh), or None until reported (BATTERY_STATUS only).
        voltage_v: the pack's voltage (V), or None until reported.
        current_a: the current drawn (A), or None until reported.
    """

    t_s: float
    remaining_pct: float | None = None
    consumed_mah: float | None = None
    voltage_v: float | None = None
    current_a: float | None = None


def _number(x: object) -> float:
    try:
        return float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan


class BatteryMonitor:
    """Builds :class:`BatteryEstimate` from SYS_STATUS and BATTERY_STATUS.

    Attributes:
        last: the estimate, or None before any valid field.
        reports: reports taken (valid or not).
        rejected: ``"<field>_<reason>"`` -> count; reasons ``unknown`` (MAVLink's -1 or
            UINT16_MAX), ``negative``, ``above_100``, ``not_finite``.
    """

    def __init__(self) -> None:
        """No report yet."""
        self.last: BatteryEstimate | None = None
        self.reports = 0
        self.rejected: dict[str, int] = {}

    def on_sys_status(
        self, t_s: float, voltage_mv: float, current_ca: float, remaining_pct: float
    ) -> BatteryEstimate | None:
        """SYS_STATUS at vehicle time ``t_s`` (unix s): voltage (mV), current (cA),
        remaining (%). Returns the estimate after it."""
        self.reports += 1
        fields = {
            "voltage_v": self._voltage(voltage_mv),
            "current_a": self._scaled("current_a", current_ca, 0.01),
            "remaining_pct": self._pct(remaining_pct),
        }
        return self._take(t_s, fields)

    def on_battery_status(
        self,
        t_s: float,
        battery_id: int,
        voltages_mv: Sequence[float],
        current_ca: float,
        consumed_mah: float,
        remaining_pct: float,
    ) -> BatteryEstimate | None:
        """BATTERY_STATUS at vehicle time ``t_s`` (unix s): cell voltages (mV), current (cA),
        consumed (mAh), remaining (%). Only battery 0 is followed (others: None)."""
        if int(battery_id) != FOLLOWED_BATTERY_ID:
            return None
        self.reports += 1
        fields = {
            "voltage_v": self._pack_voltage(voltages_mv),
            "current_a": self._scaled("current_a", current_ca, 0.01),
            "consumed_mah": self._scaled("consumed_mah", consumed_mah, 1.0),
            "remaining_pct": self._pct(remaining_pct),
        }
        return self._take(t_s, fields)

    # ---- validation -------------------------------------------------------------------
    def _reject(self, name: str, reason: str) -> None:
        key = f"{name}_{reason}"
        self.rejected[key] = self.rejected.get(key, 0) + 1

    def _scaled(self, name: str, raw: object, scale: float) -> float | None:
        """A non-negative count (-1 unknown) times ``scale``, or None (rejected)."""
        x = _number(raw)
        if not math.isfinite(x):
            self._reject(name, "not_finite")
            return None
        if x == UNKNOWN:
            self._reject(name, "unknown")
            return None
        if x < 0:
            self._reject(name, "negative")
            return None
        return x * scale

    def _pct(self, raw: object) -> float | None:
        x = self._scaled("remaining_pct", raw, 1.0)
        if x is not None and x > 100.0:
            self._reject("remaining_pct", "above_100")
            return None
        return x

    def _voltage(self, raw: object) -> float | None:
        """A pack voltage (mV; 0, -1 or UINT16_MAX unknown) in V, or None (rejected)."""
        x = _number(raw)
        if not math.isfinite(x):
            self._reject("voltage_v", "not_finite")
            return None
        if x in (UINT16_UNKNOWN, UNKNOWN, 0):
            self._reject("voltage_v", "unknown")
            return None
        if x < 0:
            self._reject("voltage_v", "negative")
            return None
        return x * 1e-3

    def _pack_voltage(self, cells_mv: Sequence[float]) -> float | None:
        """The sum of the cells present (mV each; UINT16_MAX or 0 = none) in V, or None."""
        total = 0.0
        for raw in cells_mv:
            x = _number(raw)
            if not math.isfinite(x):
                self._reject("voltage_v", "not_finite")
                return None
            if x in (UINT16_UNKNOWN, 0):
                continue
            if x < 0:
                self._reject("voltage_v", "negative")
                return None
            total += x
        if total <= 0:
            self._reject("voltage_v", "unknown")
            return None
        return total * 1e-3

    def _take(self, t_s: float, fields: dict[str, float | None]) -> BatteryEstimate | None:
        valid = {k: v for k, v in fields.items() if v is not None}
        if not valid or not math.isfinite(t_s):
            return self.last
        base = self.last if self.last is not None else BatteryEstimate(t_s)
        self.last = dataclasses.replace(base, t_s=float(t_s), **valid)
        return self.last
