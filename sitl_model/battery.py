"""Each simulated vehicle's battery: the power it draws, the charge it holds, what it says (pure).

Vectorised over the N vehicles (arrays of shape (N,)); no clock, no randomness: the state
advances only through :meth:`Batteries.step`, with the time step passed in.

Power drawn (W), the electrical power at the battery::

    armed:     P = P_L [ (1 - f) (V / V_ref)^3 + f (V_ref / V) n^2 ] + P_av
    disarmed:  P = P_av                                  (motor off, avionics on)
    n^2 = 1 / cos^2(phi) = 1 + tan^2(phi),   tan(phi) = V u / (g e)

``V`` airspeed (m/s), ``u`` the achieved turn rate (rad/s), ``phi`` the bank the telemetry
reports for it (``SIM_TR_EFF`` = ``e``, as in ATTITUDE), ``n`` the load factor. ``P_L`` =
``SIM_PWR_LEVEL`` is the propulsion power in level flight at ``V_ref`` = ``SIM_PWR_VREF``, of
which the fraction ``f`` = ``SIM_PWR_IND`` is induced; ``P_av`` = ``SIM_PWR_AVION`` the
avionics and payload. This is the drag polar of a fixed-wing ``D = q S C_D0 + (n W)^2 /
(q S pi e_o AR)`` (``q = rho V^2 / 2``) times ``V`` over a constant propulsive efficiency:
the parasitic power grows as ``V^3``, the induced power as ``n^2 / V``, so a 30 deg bank
(``n^2 = 4/3``) costs a third more induced power. Climb power is not modelled (the
altitude changes of this simulator are small and slow).

ArduPlane SITL (``libraries/SITL/SIM_Plane.cpp``) draws ``50 A * throttle^2`` with the voltage
sagging ``0.7 V * throttle`` and leaves the charge to the autopilot's battery monitor, which
integrates the current into consumed mAh against ``BATT_CAPACITY``; the multicopter model
(``SIM_Battery.cpp``) also follows the resting voltage down a state-of-charge table when
``SIM_BATT_CAP_AH`` is set, 0 meaning an unlimited battery. This simulator has no throttle,
so the current comes from the power above, and keeps the same split:

* the cells (``SIM_BATT_CAP_AH``, Ah; 0 = unlimited): open-circuit voltage
  ``V_oc = V_full (a + (1 - a) soc)`` with ``V_full`` = ``SIM_BATT_VOLTAGE``, ``a`` =
  :data:`EMPTY_VOLTAGE_FRAC` (3.3 of 4.2 V a cell: linear in the state of charge ``soc``,
  a straight line through a LiPo's curve) and ``soc = 1 - q / Q``; with an unlimited battery
  ``V_oc = V_full`` (as ArduPilot's). Current ``I = P / V_oc`` (A); the terminal voltage
  reported is ``V_oc - R I`` (``R`` = :data:`RESISTANCE_OHM`); the ``I^2 R`` loss (about 1.5 %
  at cruise) is not charged.
* the autopilot's monitor: consumed charge ``q`` (mAh) = the integral of ``I``, consumed
  energy (Wh) = the integral of ``P``; remaining = ``100 (1 - q / BATT_CAPACITY)`` %, cut to
  0..100 and rounded down (-1, unknown, with ``BATT_CAPACITY`` 0). Below ``BATT_LOW_MAH`` or
  ``BATT_CRT_MAH`` remaining (mAh, 0 = off, ArduPilot's names) it says so once (STATUSTEXT
  and an event); cells run dry (finite ``SIM_BATT_CAP_AH``) once too. This simulator has no
  motor-out glide: an empty vehicle keeps flying, reported empty.

Turnaround: a vehicle disarmed for ``SIM_BATT_SWAP`` s without a break (this simulator has
no landing: disarmed stands for "on the ground") gets a full battery (consumed charge and
energy back to 0, event ``battery_swapped``). Re-armed earlier, it keeps its battery. From
the swap until it is armed again it stands on ground power (a spare waiting on the flight
line): the battery supplies nothing, so its charge stays full however long it waits (before,
its avionics drew 0.8 A from it: a spare swapped and then kept waiting 100 minutes fell
below 90 % and never launched).

Units: W, V, A, mAh, Wh, s throughout; the names carry them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sitl_model.autopilot import G_M_S2
from sitl_model.params import Params

EMPTY_VOLTAGE_FRAC = 3.3 / 4.2  # open-circuit voltage of an empty battery / a full one
RESISTANCE_OHM = 0.02  # internal resistance of the pack (ohm): the sag under load
MIN_AIRSPEED_M_S = 1.0  # the power law is evaluated at no less than this airspeed

# charge levels, as MAV_BATTERY_CHARGE_STATE (OK, LOW, CRITICAL, EMERGENCY)
LEVEL_OK, LEVEL_LOW, LEVEL_CRITICAL, LEVEL_EMPTY = 1, 2, 3, 4
_SEVERITY = {LEVEL_LOW: 4, LEVEL_CRITICAL: 2, LEVEL_EMPTY: 2}  # MAV_SEVERITY WARNING/CRITICAL
_WORD = {LEVEL_LOW: "low", LEVEL_CRITICAL: "critical", LEVEL_EMPTY: "empty"}


@dataclass(frozen=True)
class PowerParams:
    """The power law's constants (see the module docstring).

    Attributes:
        level_w: propulsion power in level flight at ``vref_m_s`` (W), ``SIM_PWR_LEVEL``.
        induced_frac: the induced fraction of it (1), ``SIM_PWR_IND``.
        vref_m_s: the reference airspeed (m/s), ``SIM_PWR_VREF``.
        avionics_w: avionics and payload (W), drawn armed or not, ``SIM_PWR_AVION``.
        turn_eff: achieved / ``g tan(phi) / V`` (1), ``SIM_TR_EFF``: the bank of a turn rate.
    """

    level_w: float
    induced_frac: float
    vref_m_s: float
    avionics_w: float
    turn_eff: float = 1.0

    @classmethod
    def from_params(cls, p: Params) -> PowerParams:
        """The constants set by the ``SIM_PWR_*`` parameters and ``SIM_TR_EFF``."""
        return cls(
            p["SIM_PWR_LEVEL"], p["SIM_PWR_IND"], p["SIM_PWR_VREF"], p["SIM_PWR_AVION"],
            p["SIM_TR_EFF"],
        )  # fmt: skip


def power_w(
    airspeed_m_s: np.ndarray, turn_rate_rad_s: np.ndarray, armed: np.ndarray, pp: PowerParams
) -> np.ndarray:
    """Electrical power each vehicle draws (W): airspeed (m/s), achieved turn rate (rad/s),
    armed (bool); the power law of the module docstring."""
    v = np.maximum(np.asarray(airspeed_m_s, dtype=float), MIN_AIRSPEED_M_S)
    ratio = v / pp.vref_m_s
    tan_phi = v * np.asarray(turn_rate_rad_s, dtype=float) / (G_M_S2 * pp.turn_eff)
    n2 = 1.0 + tan_phi * tan_phi
    f = pp.induced_frac
    prop = pp.level_w * ((1.0 - f) * ratio**3 + f * n2 / ratio)
    return np.where(armed, prop, 0.0) + pp.avionics_w


def open_circuit_v(consumed_mah: np.ndarray, full_v: float, cells_ah: float) -> np.ndarray:
    """Open-circuit voltage (V) after ``consumed_mah`` (mAh) from full cells of ``cells_ah``
    (Ah; 0 = unlimited: always ``full_v``), linear in the state of charge."""
    q = np.asarray(consumed_mah, dtype=float)
    if cells_ah <= 0:
        return np.full(q.shape, float(full_v))
    soc = np.clip(1.0 - q / (1000.0 * cells_ah), 0.0, 1.0)
    return full_v * (EMPTY_VOLTAGE_FRAC + (1.0 - EMPTY_VOLTAGE_FRAC) * soc)


def energy_wh(capacity_mah: float, full_v: float, cells_ah: float) -> float:
    """Energy (Wh) delivered while ``capacity_mah`` (mAh) is drawn from full cells of
    ``cells_ah`` (Ah; 0 = unlimited), at the open-circuit voltage: the integral of
    ``V_oc dq``."""
    c_ah = capacity_mah / 1000.0
    if cells_ah <= 0:
        return c_ah * full_v
    a = EMPTY_VOLTAGE_FRAC
    c = min(c_ah, cells_ah)
    return full_v * (a * c + (1.0 - a) * (c - c * c / (2.0 * cells_ah)))


def level_power_for_endurance(
    endurance_s: float, capacity_mah: float, full_v: float, cells_ah: float
) -> float:
    """The constant power (W) that uses ``capacity_mah`` (mAh) in ``endurance_s`` (s): what a
    mission's endurance figure means for the power law (assembly sets ``SIM_PWR_LEVEL`` from
    it)."""
    return energy_wh(capacity_mah, full_v, cells_ah) * 3600.0 / endurance_s


@dataclass(frozen=True)
class BatteryEvent:
    """A notable change of one vehicle's battery (index 0-based), for STATUSTEXT and logs."""

    index: int
    event: str
    text: str
    severity: int
    data: dict


class Batteries:
    """The batteries of N vehicles, full at the start, and their monitors' readings.

    Attributes (arrays of shape (N,)):
        consumed_mah: charge drawn since the battery was fitted (mAh).
        energy_wh: energy drawn since then (Wh).
        power_w: power drawn at the last step (W).
        current_a: current at the last step (A).
        voltage_v: terminal voltage at the last step (V).
        level: ``LEVEL_OK``, ``LEVEL_LOW``, ``LEVEL_CRITICAL`` or ``LEVEL_EMPTY``.
        disarmed_since_s: when each vehicle was last disarmed (s), NaN while armed,
            infinite once its battery has been swapped (until it is armed again: on ground
            power meanwhile).
        swaps: batteries fitted after the first, per vehicle.
    """

    def __init__(self, n: int, params: Params) -> None:
        """N full batteries at rest."""
        self.consumed_mah = np.zeros(n)
        self.energy_wh = np.zeros(n)
        self.power_w = np.zeros(n)
        self.current_a = np.zeros(n)
        self.voltage_v = np.full(n, params["SIM_BATT_VOLTAGE"])
        self.level = np.full(n, LEVEL_OK, dtype=int)
        self.disarmed_since_s = np.full(n, math.nan)
        self.swaps = np.zeros(n, dtype=int)
        self._pp_version = -1
        self._pp: PowerParams | None = None

    def _power_params(self, p: Params) -> PowerParams:
        if p.version != self._pp_version or self._pp is None:
            self._pp = PowerParams.from_params(p)
            self._pp_version = p.version
        return self._pp

    def step(
        self,
        t_s: float,
        dt_s: float,
        airspeed_m_s: np.ndarray,
        turn_rate_rad_s: np.ndarray,
        armed: np.ndarray,
        p: Params,
    ) -> list[BatteryEvent]:
        """Draw ``dt_s`` (s) of power at time ``t_s`` (s, the step's end); then fit a full
        battery where the turnaround is over. Returns the level changes and swaps."""
        pw = power_w(airspeed_m_s, turn_rate_rad_s, armed, self._power_params(p))
        pw = np.where(np.isinf(self.disarmed_since_s) & ~armed, 0.0, pw)  # on ground power
        full_v, cells_ah = p["SIM_BATT_VOLTAGE"], p["SIM_BATT_CAP_AH"]
        v_oc = open_circuit_v(self.consumed_mah, full_v, cells_ah)
        current = pw / v_oc
        self.power_w = pw
        self.current_a = current
        self.consumed_mah = self.consumed_mah + current * (dt_s / 3.6)  # A s -> mAh
        self.energy_wh = self.energy_wh + pw * (dt_s / 3600.0)
        v_after = open_circuit_v(self.consumed_mah, full_v, cells_ah)
        self.voltage_v = v_after - RESISTANCE_OHM * current
        events = self._levels(p)
        self._turnaround(t_s, armed, p, events)
        return events

    def remaining_mah(self, p: Params) -> np.ndarray:
        """Charge left by the monitor's count (mAh): ``BATT_CAPACITY`` - consumed, >= 0."""
        return np.maximum(p["BATT_CAPACITY"] - self.consumed_mah, 0.0)

    def remaining_pct(self, i: int, p: Params) -> int:
        """Vehicle ``i``'s remaining charge (%, whole, 0..100), or -1 without a capacity."""
        cap = p["BATT_CAPACITY"]
        if cap <= 0:
            return -1
        pct = 100.0 * (1.0 - float(self.consumed_mah[i]) / cap)
        return math.floor(min(max(pct, 0.0), 100.0))

    def time_remaining_s(self, i: int, p: Params) -> int:
        """Seconds to the monitor's 0 % at the present current (0: unknown)."""
        cap, amps = p["BATT_CAPACITY"], float(self.current_a[i])
        if cap <= 0 or amps <= 0:
            return 0
        return int(max(cap - float(self.consumed_mah[i]), 0.0) * 3.6 / amps)

    def _levels(self, p: Params) -> list[BatteryEvent]:
        left = self.remaining_mah(p)
        level = np.full(left.shape, LEVEL_OK, dtype=int)
        low, crt, cells_ah = p["BATT_LOW_MAH"], p["BATT_CRT_MAH"], p["SIM_BATT_CAP_AH"]
        if low > 0:
            level = np.where(left < low, LEVEL_LOW, level)
        if crt > 0:
            level = np.where(left < crt, LEVEL_CRITICAL, level)
        if cells_ah > 0:
            level = np.where(self.consumed_mah >= 1000.0 * cells_ah, LEVEL_EMPTY, level)
        worse = np.flatnonzero(level > self.level)
        events = []
        for i in worse.tolist():
            lv = int(level[i])
            v, used = float(self.voltage_v[i]), float(self.consumed_mah[i])
            events.append(
                BatteryEvent(
                    i,
                    f"battery_{_WORD[lv]}",
                    f"Battery 1 is {_WORD[lv]} {v:.2f}V used {used:.0f} mAh",
                    _SEVERITY[lv],
                    {"voltage_v": round(v, 3), "consumed_mah": round(used, 1)},
                )
            )
        self.level = np.maximum(self.level, level)
        return events

    def _turnaround(
        self, t_s: float, armed: np.ndarray, p: Params, events: list[BatteryEvent]
    ) -> None:
        since = self.disarmed_since_s
        since = np.where(armed, math.nan, np.where(np.isnan(since), t_s, since))
        self.disarmed_since_s = since
        due = np.flatnonzero(t_s - since >= p["SIM_BATT_SWAP"] - 1e-9)  # NaN compares False
        for i in due.tolist():
            used = float(self.consumed_mah[i])
            self.consumed_mah[i] = 0.0
            self.energy_wh[i] = 0.0
            self.level[i] = LEVEL_OK
            self.swaps[i] += 1
            self.disarmed_since_s[i] = math.inf  # one battery per stay; ground power from now
            events.append(
                BatteryEvent(
                    i, "battery_swapped", "Battery swapped: full", 6,
                    {"consumed_mah": round(used, 1), "turnaround_s": p["SIM_BATT_SWAP"]},
                )
            )  # fmt: skip
