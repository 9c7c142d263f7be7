"""The disturbance matrix: named worlds that differ from the mission the companions are told.

Each :class:`Scenario` turns the mission's wind (speed m/s, direction it blows FROM, deg)
and the run's duration (s) into simulator parameters (``--sim-param`` of ``companion
fleet``, ``--param`` of ``companion simulate``; names and units in ``sitl_model/params.py``)
and names the companions' setpoint profile. ``bench/robustness.py`` flies this matrix one
scenario per fleet; ``companion campaign`` names its scenarios from it. Measured results of
the matrix: ``docs/robustness.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

ARDU_BANK = {"SIM_LAG": 0.5, "SIM_TR_EFF": 0.75}  # measured on ArduPlane SITL (docs/design.md §7)
ARDU_HEADING = {"SIM_LAG": 0.5, "SIM_CRS_KP": 0.5}
GPS = {"SIM_GPS_NOISE": 2.0, "SIM_GPS_TAU": 30.0, "SIM_GPS_VNOISE": 0.15}
DRIFT = {"SIM_WDRIFT_SPD": 2.0, "SIM_WDRIFT_DIR": 30.0, "SIM_WDRIFT_T": 600.0}
GUSTS = {"SIM_WIND_TURB": 1.5, "SIM_GUST_TAU": 5.0}


@dataclass(frozen=True)
class Scenario:
    """One world: simulator parameters (from the mission's wind and the run's duration, s)
    and the companions' setpoint profile."""

    name: str
    what: str
    # (mission wind speed m/s, mission wind from deg, run duration s) -> {NAME: value}
    params: Callable[[float, float, float], dict[str, float]]
    profile: str = "auto"  # the fleet's default: bank on an ArduPilot-like autopilot


def _wind_off(speed: float, from_deg: float) -> dict[str, float]:
    """The world's wind 3 m/s stronger and 45 deg clockwise of the mission's."""
    return {"SIM_WIND_SPD": speed + 3.0, "SIM_WIND_DIR": (from_deg + 45.0) % 360.0}


def _step(duration_s: float) -> dict[str, float]:
    """A 3 m/s step in wind speed half-way through the run."""
    return {"SIM_WSTEP_T": round(duration_s / 2, 1), "SIM_WSTEP_SPD": 3.0}


SCENARIOS: tuple[Scenario, ...] = (
    Scenario("nominal", "the world as told", lambda v, d, t: {}),
    Scenario("wind_off", "wind +3 m/s, 45 deg off the mission's", lambda v, d, t: _wind_off(v, d)),
    Scenario("wind_drift", "wind drifting +-2 m/s, +-30 deg, 600 s period", lambda v, d, t: DRIFT),
    Scenario("wind_step", "wind speed +3 m/s at half the run", lambda v, d, t: _step(t)),
    Scenario("gusts", "gusts 1.5 m/s per axis, tau 5 s", lambda v, d, t: GUSTS),
    Scenario(
        "ardu_bank", "ArduPlane-like, bank profile", lambda v, d, t: ARDU_BANK, profile="bank"
    ),
    Scenario(
        "ardu_heading",
        "ArduPlane-like, heading profile",
        lambda v, d, t: ARDU_HEADING,
        profile="heading",
    ),
    Scenario("gps", "GPS errors 2 m / 30 s, 0.15 m/s", lambda v, d, t: GPS),
    Scenario(
        "combined",
        "all of the above at once (bank profile)",
        lambda v, d, t: _wind_off(v, d) | DRIFT | _step(t) | GUSTS | ARDU_BANK | ARDU_HEADING | GPS,
        profile="bank",
    ),
)
BY_NAME = {s.name: s for s in SCENARIOS}
