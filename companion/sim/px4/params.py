"""The mission's PX4 parameters for each instance (set at every start through
``PX4_PARAM_<name>``, :class:`companion.sim.px4.sitl.Px4Instance`) and each one's take-off
altitude: what makes PX4's SIH airframe fly the mission's aircraft."""

from __future__ import annotations

import math

from companion.mission import Mission

SIH_THRUST_N = 15.0  # SIH_T_MAX: the stock 6 N only reaches 12 m/s; 15 N cruises 18-20 m/s
RELIEF_CLIMB_FRACTION = 0.6  # a relief's take-off climbs to this of the vehicle's altitude


def takeoff_alt_m(mission: Mission, sysid: int, relief: bool | None = None) -> float:
    """MIS_TAKEOFF_ALT (m above home) of vehicle ``sysid``: its altitude for the fleet's own
    take-off of the patrol; ``RELIEF_CLIMB_FRACTION`` of it for a relief's take-off (a spare's
    from the start; ``relief`` None: whether ``sysid`` is a spare). PX4's take-off climbs
    straight ahead at about 5.7 m/s and 23.5 m/s over the ground (measured: 545 m for 130 m)
    and hands over only at its end (landed state TAKEOFF until then): to the full 130 m it
    ended at the default fence of ``tests/data/ellipse_3uav_relief.yaml`` and the companion's
    first turn crossed it (PX4 held, then returned). The companion takes over above half its
    altitude and climbs the rest itself."""
    v = mission.vehicles
    spare = relief if relief is not None else sysid in {sp.sysid for sp in v.spares}
    alt = float(v.altitude_m(sysid))
    return round(RELIEF_CLIMB_FRACTION * alt, 1) if spare else alt


def coordinated_bank_deg(airspeed_m_s: float, turn_rate_rad_s: float) -> float:
    """The bank (deg) of a coordinated turn at ``turn_rate_rad_s`` and ``airspeed_m_s``."""
    return math.degrees(math.atan(airspeed_m_s * turn_rate_rad_s / 9.80665))


def mission_params(mission: Mission, sysid: int) -> dict[str, float]:
    """The PX4 parameters of vehicle ``sysid`` of the mission (a spare's too), set at every
    start.

    The airframe's thrust raised (SIH_T_MAX) so that it cruises at the mission's airspeed;
    FW_AIRSPD_TRIM the mission's airspeed (MIN 0.6 and MAX 1.25 of it); FW_R_LIM the bank of
    the mission's turn-rate limit at that airspeed; MIS_TAKEOFF_ALT the vehicle's altitude
    (m above home); MAV_SYS_ID its system id; COM_OBL_RC_ACT 5 (hold: AUTO.LOITER when the
    companion's stream stops); NAV_DLL_ACT 0 (the fleet's ground-station link closes after the
    take-off); GF_PREDICT 0 (the geofence acts on a breach, not on a predicted one: the
    formation's convergence from the take-off loiter came within its prediction of the fence
    and PX4 held, then returned); MIS_TKO_LAND_REQ 0 (the perimeter is a loop, no landing: PX4
    otherwise rejects it as a mission, although it stores it); SDLOG_MODE -1 (no ULog).
    With a battery section, PX4's battery simulator drains it linearly over the flight time
    from full to empty (SIM_BAT_DRAIN = the battery's endurance, only while armed: it is full
    again whenever PX4 is disarmed), down to 0 % (SIM_BAT_MIN_PCT; the stock 50 % floor
    reached in 60 s would hold every battery at half), and PX4's low-battery failsafe only
    warns (COM_LOW_BAT_ACT 0: the companion brings it home, as on ArduPlane). A spare's
    MIS_TAKEOFF_ALT is its relief climb-out's (:func:`takeoff_alt_m`).
    """
    v = mission.vehicles
    airspeed = v.airspeed_m_s
    bank = coordinated_bank_deg(airspeed, v.max_turn_rate_rad_s)
    own = [sp.battery for sp in v.spares if sp.sysid == sysid and sp.battery is not None]
    b = own[0] if own else v.battery
    battery = {}
    if b is not None:
        battery = {
            "SIM_BAT_ENABLE": 1.0,
            "SIM_BAT_DRAIN": round(60.0 * b.endurance_min, 1),
            "SIM_BAT_MIN_PCT": 0.0,
            "COM_LOW_BAT_ACT": 0.0,
        }
    return battery | {
        "SIH_T_MAX": SIH_THRUST_N,
        "FW_AIRSPD_TRIM": airspeed,
        "FW_AIRSPD_MIN": round(0.6 * airspeed, 2),
        "FW_AIRSPD_MAX": round(1.25 * airspeed, 2),
        "FW_R_LIM": round(math.ceil(bank * 10.0) / 10.0, 1),
        "MIS_TAKEOFF_ALT": takeoff_alt_m(mission, sysid),
        "MAV_SYS_ID": float(sysid),
        "COM_OBL_RC_ACT": 5.0,
        "NAV_DLL_ACT": 0.0,
        "GF_PREDICT": 0.0,
        "MIS_TKO_LAND_REQ": 0.0,
        "SDLOG_MODE": -1.0,
    }
