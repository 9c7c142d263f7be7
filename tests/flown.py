"""What a real autopilot flew while a companion commanded it, read from the companion's
``autopilot.tlog`` (PX4 and ArduPlane SITL tests and ``bench/px4_profiles.py``): positions,
altitudes and airspeeds in the commanded mode, the setpoints sent, and their errors against
the mission's ellipse, airspeed and altitude."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from companion.link.connection import COMPANION_COMPID


@dataclass(frozen=True)
class Flown:
    """What the aircraft flew while the companion commanded, from the companion's tlog.

    Attributes:
        t_s: vehicle time of each GLOBAL_POSITION_INT (s from the first).
        pos_m: north + i east from the mission origin (m).
        alt_m: altitude above the mission origin (m).
        airspeed_m_s: VFR_HUD airspeed at each position (m/s, last heard).
        setpoints: setpoints sent while the autopilot last reported the commanded mode.
    """

    t_s: np.ndarray
    pos_m: np.ndarray
    alt_m: np.ndarray
    airspeed_m_s: np.ndarray
    setpoints: int


def flown_from_tlog(tlog: Path, origin: tuple[float, float, float], sysid: int, mode: int) -> Flown:
    """Positions, altitudes and airspeeds of autopilot ``sysid`` while its custom mode is
    ``mode`` (PX4's OFFBOARD, ArduPlane's GUIDED), in tlog order; ``origin``: the mission's
    (lat deg, lon deg, alt m)."""
    import pymap3d

    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    now = None
    airspeed = math.nan
    ts, pos, alt, air = [], [], [], []
    sent = 0
    while True:
        m = conn.recv_match()
        if m is None:
            break
        t = m.get_type()
        if m.get_srcComponent() == COMPANION_COMPID:
            sent += now == mode and t in ("SET_ATTITUDE_TARGET", "SET_POSITION_TARGET_GLOBAL_INT")
            continue
        if m.get_srcSystem() != sysid or m.get_srcComponent() != 1:
            continue
        if t == "HEARTBEAT":
            now = int(m.custom_mode)
        elif t == "VFR_HUD":
            airspeed = float(m.airspeed)
        elif t == "GLOBAL_POSITION_INT" and now == mode:
            n, e, d = pymap3d.geodetic2ned(m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3, *origin)
            ts.append(m.time_boot_ms * 1e-3)
            pos.append(complex(n, e))
            alt.append(-d)
            air.append(airspeed)
    conn.close()
    t = np.asarray(ts)
    return Flown(
        t - (t[0] if len(t) else 0.0), np.asarray(pos), np.asarray(alt), np.asarray(air), sent
    )


def ellipse_cross_track_m(pos_m: np.ndarray, mission) -> np.ndarray:
    """Distance (m) of each position (complex, local) from the mission's ellipse (a polyline
    of 20,000 vertices: under 1 cm of chord error)."""
    e = mission.perimeter.shape
    th = np.linspace(0.0, 2.0 * np.pi, 20_000, endpoint=False)
    rot = np.exp(1j * np.radians(e.major_axis_bearing_deg))
    centre = complex(e.centre_north_m, e.centre_east_m)
    loop = centre + rot * (e.semi_major_m * np.cos(th) + 1j * e.semi_minor_m * np.sin(th))
    out = np.empty(len(pos_m))
    for k in range(0, len(pos_m), 256):
        chunk = pos_m[k : k + 256]
        out[k : k + 256] = np.abs(chunk[:, None] - loop[None, :]).min(axis=1)
    return out


def summary(
    flown: Flown, mission, settle_s: float, until_s: float = math.inf, index: int = 0
) -> dict[str, float]:
    """Cross-track, airspeed and altitude errors of vehicle ``index`` of the mission (its
    altitude) from ``settle_s`` to ``until_s`` after it was first commanded (s)."""
    keep = (flown.t_s >= settle_s) & (flown.t_s <= until_s)
    xt = ellipse_cross_track_m(flown.pos_m[keep], mission)
    air = flown.airspeed_m_s[keep] - mission.vehicles.airspeed_m_s
    alt = flown.alt_m[keep] - mission.vehicles.altitudes_m[index]
    air = air[np.isfinite(air)]
    return {
        "window_s": float(min(flown.t_s[-1], until_s) - settle_s) if len(flown.t_s) else 0.0,
        "xt_median_m": float(np.median(xt)),
        "xt_p95_m": float(np.percentile(xt, 95)),
        "xt_max_m": float(xt.max()),
        "airspeed_err_mean_m_s": float(air.mean()),
        "airspeed_err_p95_abs_m_s": float(np.percentile(np.abs(air), 95)),
        "alt_err_mean_m": float(alt.mean()),
        "alt_err_p95_abs_m": float(np.percentile(np.abs(alt), 95)),
    }


def final_status(log: Path) -> dict[str, str]:
    """The fields (``name=value``) of the last status line in a companion's log."""
    lines = [ln for ln in log.read_text().splitlines() if "sysid=" in ln]
    return dict(f.split("=", 1) for f in lines[-1].split() if "=" in f) if lines else {}


def fleet_flights(
    out: Path, mission, mode: int, settle_s: float, tail_s: float
) -> dict[int, dict[str, float | str]]:
    """Per sysid of a ``companion fleet`` run folder ``out``: :func:`summary` of its flight in
    ``mode`` from ``settle_s`` after it was first commanded to ``tail_s`` before the tlog ends
    (s), its setpoints per vehicle second in ``mode``, and its companion's final ``gain``
    and ``health``."""
    o = mission.origin
    found: dict[int, dict[str, float | str]] = {}
    for i, sysid in enumerate(mission.vehicles.sysids):
        flown = flown_from_tlog(
            out / f"uav{sysid}" / "autopilot.tlog", (o.lat_deg, o.lon_deg, o.alt_m), sysid, mode
        )
        s: dict[str, float | str] = dict(
            summary(flown, mission, settle_s, flown.t_s[-1] - tail_s, index=i)
        )
        s["setpoints_per_s"] = flown.setpoints / flown.t_s[-1]
        status = final_status(out / f"uav{sysid}" / "companion.log")
        s["gain"], s["health"] = status.get("gain", "-"), status.get("health", "-")
        found[sysid] = s
    return found
