"""Each UAV's topics (pure): ``/uavN/fix``, ``pose``, ``tf``, ``velocity``, ``mode``,
``battery`` from its ground truth (``truth.csv``) or, without one, from its tlog's autopilot
messages; ``setpoint`` from the setpoints its companion sent (the tlog); ``targets`` from its
``guided_targets`` events. See :mod:`companion.export.topics` for the table."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

from companion.export import foxglove as fg
from companion.export.model import Message, Origin, RunFolder, Tlog, Truth
from companion.link.battery import BatteryMonitor
from companion.link.setpoints import describe

__all__ = ["vehicle_messages"]


def vehicle_messages(run: RunFolder, origin: Origin | None) -> Iterator[Message]:
    """Every UAV's messages, UAV by UAV, each topic in time order (none of the position
    topics without an ``origin``)."""
    for sysid in run.sysids:
        tr, tl = run.truth.get(sysid), run.tlogs.get(sysid)
        if tr is not None and origin is not None:
            yield from _truth_messages(tr, origin)
        elif tl is not None and origin is not None:
            yield from _tlog_vehicle_messages(tl, origin)
        if tl is not None:
            yield from _setpoints(tl)
    yield from _targets(run.events)


def _vehicle(
    sysid: int,
    t: float,
    n: float,
    e: float,
    up: float,
    lat: float,
    lon: float,
    alt: float,
    heading_deg: float,
) -> Iterator[Message]:
    """fix, pose and tf of one sample."""
    uav = f"uav{sysid}"
    yield Message(f"/{uav}/fix", t, fg.location_fix(t, uav, lat, lon, alt))
    yield Message(f"/{uav}/pose", t, fg.pose_in_frame(t, e, n, up, heading_deg))
    yield Message(f"/{uav}/tf", t, fg.frame_transform(t, uav, e, n, up, heading_deg))


def _truth_messages(tr: Truth, origin: Origin) -> Iterator[Message]:
    """fix, pose, tf, velocity, mode and battery from ``truth.csv`` rows."""
    c = tr.columns
    n, e, up = c["north_m"], c["east_m"], c["alt_m"]
    lat, lon, alt = origin.to_geodetic(n, e, up)
    course = np.radians(c["course_deg"])
    vn, ve = c["groundspeed_m_s"] * np.cos(course), c["groundspeed_m_s"] * np.sin(course)
    battery = [
        k
        for k in ("remaining_pct", "consumed_mah", "energy_wh", "voltage_v")
        if f"battery_{k}" in c
    ]
    uav = f"/uav{tr.sysid}"
    mode = None
    for k, t in enumerate(tr.t_unix_s.tolist()):
        yield from _vehicle(
            tr.sysid,
            t,
            float(n[k]),
            float(e[k]),
            float(up[k]),
            float(lat[k]),
            float(lon[k]),
            float(alt[k]),
            float(c["heading_deg"][k]),
        )
        yield Message(
            f"{uav}/velocity",
            t,
            {
                "north_m_s": float(vn[k]),
                "east_m_s": float(ve[k]),
                "groundspeed_m_s": float(c["groundspeed_m_s"][k]),
                "course_deg": float(c["course_deg"][k]),
                "heading_deg": float(c["heading_deg"][k]),
                "turn_rate_deg_s": float(c["turn_rate_deg_s"][k]),
            },
        )
        if tr.mode[k] != mode:
            mode = str(tr.mode[k])
            yield Message(f"{uav}/mode", t, {"mode": mode})
        if battery:
            yield Message(f"{uav}/battery", t, {b: float(c[f"battery_{b}"][k]) for b in battery})


def _tlog_vehicle_messages(tl: Tlog, origin: Origin) -> Iterator[Message]:
    """fix, pose, tf, velocity, mode and battery from a tlog's autopilot messages."""
    from pymavlink import mavutil

    uav = f"/uav{tl.sysid}"
    mode: tuple[str, bool] | None = None
    battery = BatteryMonitor()
    for m in tl.messages:
        t, kind = float(m._timestamp), m.get_type()
        if m.get_srcSystem() != tl.sysid or m.get_srcComponent() != 1:
            continue  # not the autopilot's
        if kind == "GLOBAL_POSITION_INT":
            lat, lon, alt = m.lat * 1e-7, m.lon * 1e-7, m.alt / 1000.0
            n, e, up = (float(x) for x in origin.to_local(lat, lon, alt))
            heading = m.hdg / 100.0 if m.hdg != 65535 else math.degrees(math.atan2(m.vy, m.vx))
            yield from _vehicle(tl.sysid, t, n, e, up, lat, lon, alt, heading)
            vn, ve, vd = m.vx / 100.0, m.vy / 100.0, m.vz / 100.0
            yield Message(
                f"{uav}/velocity",
                t,
                {
                    "north_m_s": vn,
                    "east_m_s": ve,
                    "down_m_s": vd,
                    "groundspeed_m_s": math.hypot(vn, ve),
                    "course_deg": math.degrees(math.atan2(ve, vn)) % 360.0,
                    "heading_deg": heading,
                },
            )
        elif kind == "HEARTBEAT":
            now = (mavutil.mode_string_v10(m), bool(m.base_mode & 128))  # MAV_MODE_FLAG_SAFETY
            if now != mode:
                mode = now
                yield Message(f"{uav}/mode", t, {"mode": now[0], "armed": now[1]})
        elif kind in ("SYS_STATUS", "BATTERY_STATUS"):
            if kind == "SYS_STATUS":
                got = battery.on_sys_status(
                    t, m.voltage_battery, m.current_battery, m.battery_remaining
                )
            else:
                got = battery.on_battery_status(
                    t, m.id, m.voltages, m.current_battery, m.current_consumed, m.battery_remaining
                )
            if got is not None and got.t_s == t:
                yield Message(
                    f"{uav}/battery",
                    t,
                    {
                        k: v
                        for k, v in (
                            ("remaining_pct", got.remaining_pct),
                            ("consumed_mah", got.consumed_mah),
                            ("voltage_v", got.voltage_v),
                            ("current_a", got.current_a),
                        )
                        if v is not None
                    },
                )


def _setpoints(tl: Tlog) -> Iterator[Message]:
    """Every setpoint the companion sent in the tlog (not the autopilot's own messages)."""
    for m in tl.messages:
        if (
            m.get_type()
            not in (
                "SET_ATTITUDE_TARGET",
                "SET_POSITION_TARGET_GLOBAL_INT",
                "COMMAND_INT",
                "COMMAND_LONG",
            )
            or m.get_srcComponent() == 1
        ):
            continue
        try:
            sp = describe(m)
        except ValueError:
            continue  # a command, not a setpoint
        yield Message(f"/uav{tl.sysid}/setpoint", float(m._timestamp), sp)


def _targets(events: list[dict[str, Any]]) -> Iterator[Message]:
    for ev in events:
        if ev.get("event") == "guided_targets" and isinstance(ev.get("sysid"), int):
            data = {k: float(ev[k]) for k in ("airspeed_m_s", "alt_amsl_m") if k in ev}
            yield Message(f"/uav{ev['sysid']}/targets", ev["t_unix_s"], data)
