"""What the simulator and the companion's tools agree on outside MAVLink (pure constants).

* The simulated clock: ``sitl-model`` and ``companion simulate`` put simulated time 0 at
  :data:`SIM_EPOCH_UNIX_S` in SYSTEM_TIME (and in the signing timestamps of the in-memory
  world); subtract it from a vehicle time to get simulated seconds.
* The port layout: vehicle (or ArduPlane SITL instance) ``i`` uses ports from
  ``base + PORT_SPACING * i``, as ArduPilot SITL's ``-I i`` does.
* The ground-truth log (``truth.csv``): its columns, shared by every writer and reader. A
  run whose mission has a battery section (``vehicles.battery``) adds the battery's columns
  (:data:`TRUTH_COLUMNS_ENERGY`); every other run writes :data:`TRUTH_COLUMNS`, unchanged.
"""

from __future__ import annotations

__all__ = [
    "PORT_SPACING",
    "SIM_EPOCH_UNIX_S",
    "TRUTH_COLUMNS",
    "TRUTH_COLUMNS_ENERGY",
    "TRUTH_COLUMNS_NO_WIND",
    "TRUTH_HEADER",
    "TRUTH_HEADER_ENERGY",
]

SIM_EPOCH_UNIX_S = 1_767_225_600  # 2026-01-01T00:00:00Z: simulated t = 0
PORT_SPACING = 10  # ports per vehicle: vehicle i at base + 10 i

# The ground-truth log's columns. The wind (m/s, the air's velocity north and east, gust
# included) is the one that moved the vehicle.
TRUTH_COLUMNS = (
    "t_s",
    "sysid",
    "north_m",
    "east_m",
    "alt_m",
    "heading_deg",
    "course_deg",
    "groundspeed_m_s",
    "turn_rate_deg_s",
    "mode",
    "wind_north_m_s",
    "wind_east_m_s",
)
TRUTH_COLUMNS_NO_WIND = TRUTH_COLUMNS[:-2]  # logs written before the wind columns (2026-12)
TRUTH_HEADER = ",".join(TRUTH_COLUMNS)
# With a battery (sitl_model/battery.py): the monitor's remaining charge (%, not rounded),
# the charge (mAh) and energy (Wh) drawn since the battery was fitted, the terminal voltage (V).
TRUTH_COLUMNS_ENERGY = (
    *TRUTH_COLUMNS,
    "battery_remaining_pct",
    "battery_consumed_mah",
    "battery_energy_wh",
    "battery_voltage_v",
)
TRUTH_HEADER_ENERGY = ",".join(TRUTH_COLUMNS_ENERGY)
