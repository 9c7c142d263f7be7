"""A mission when no file is given: the loop from the autopilot's stored waypoints.

Before the companion starts, it waits for its autopilot, downloads the stored mission
(MAVLink mission protocol) and reads HOME_POSITION, VFR_HUD and WIND. The perimeter is the
rounded convex hull of the NAV_WAYPOINT items (docs/design.md §3), without item 0 on
ArduPilot, which keeps home there (told by the HEARTBEAT's autopilot type,
:mod:`companion.link.mission_protocol.home_slot`),
with a corner radius flyable downwind (1.5 ``(s0 + beta)^2 / (s0 omega_max)``); the origin
is home (else the first waypoint); the airspeed is VFR_HUD's (else 20 m/s), the wind the
autopilot's estimate; the turn-rate limit (18 deg/s) and the sensor radius (50 m) are
defaults. The result is built through the mission loader, so it is checked like a file.
Wall-clock waits here are link plumbing before flight, not flight logic."""

from __future__ import annotations

import math
import sys
import time
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.contracts.errors import UserError
from companion.link.mission_protocol.home_slot import convention, loop_items
from companion.link.mission_protocol.transfer import download
from companion.mission import Mission, MissionError
from companion.mission.load import parse_mission

WAIT_S = 30.0
DEFAULT_AIRSPEED_M_S = 20.0
DEFAULT_TURN_RATE_DEG_S = 18.0
DEFAULT_SENSOR_M = 50.0


def mission_from_autopilot(link: Any, wait_s: float = WAIT_S) -> Mission:
    """The mission built from the autopilot's stored waypoints (UserError if impossible)."""
    deadline = time.monotonic() + wait_s
    while not link.up:
        if time.monotonic() > deadline:
            raise UserError(f"no autopilot heard on {link.url} within {wait_s:g} s")
        link.tick()
        link.receive()
        time.sleep(0.02)
    sysid = link.sysid
    for msg_id in (mav.MAVLINK_MSG_ID_HOME_POSITION, mav.MAVLINK_MSG_ID_VFR_HUD):
        link.command_long(mav.MAV_CMD_REQUEST_MESSAGE, msg_id)
    got: dict[str, Any] = {}
    until = time.monotonic() + 2.0
    while time.monotonic() < until and len(got) < 3:
        link.tick()
        for m in link.receive():
            if link.is_autopilot(m) and m.get_type() in ("HOME_POSITION", "VFR_HUD", "WIND"):
                got[m.get_type()] = m
        time.sleep(0.02)
    items = download(link.conn, sysid)
    if items is None:
        raise UserError(f"could not download the stored mission of system {sysid}")
    loop = loop_items(items, link.autopilot)
    wps = [(it.x * 1e-7, it.y * 1e-7) for it in loop]
    if len(wps) < 3:
        raise UserError(
            f"system {sysid} stores {len(wps)} waypoints ({convention(link.autopilot)}): give "
            "--mission FILE or upload a perimeter first (companion upload)"
        )
    seqs = [it.seq for it in loop]
    contiguous = seqs == list(range(seqs[0], seqs[-1] + 1))
    which = f"{seqs[0]}..{seqs[-1]}" if contiguous else ", ".join(map(str, seqs))
    print(
        f"companion: loop from the {len(wps)} waypoints in system {sysid}'s mission items "
        f"{which} ({convention(link.autopilot)})",
        file=sys.stderr,
        flush=True,
    )
    text = mission_yaml(sysid, wps, got)
    try:
        return parse_mission(text, f"<autopilot {sysid} mission>")
    except MissionError as exc:
        raise UserError(str(exc)) from None


def mission_yaml(sysid: int, wps: list[tuple[float, float]], got: dict[str, Any]) -> str:
    """Mission YAML text for one vehicle from its waypoints and telemetry."""
    home = got.get("HOME_POSITION")
    if home is not None and home.latitude != 0:
        lat0, lon0, alt0 = home.latitude * 1e-7, home.longitude * 1e-7, home.altitude * 1e-3
    else:
        lat0, lon0, alt0 = wps[0][0], wps[0][1], 0.0
    hud = got.get("VFR_HUD")
    s0 = float(hud.airspeed) if hud is not None and hud.airspeed > 5 else DEFAULT_AIRSPEED_M_S
    wind = got.get("WIND")
    beta = float(wind.speed) if wind is not None and 0 <= wind.speed < 0.8 * s0 else 0.0
    wind_from = float(wind.direction) % 360.0 if wind is not None else 0.0
    omega = math.radians(DEFAULT_TURN_RATE_DEG_S)
    corner = 1.5 * (s0 + beta) ** 2 / (s0 * omega)
    points = "\n".join(f"    - {{lat_deg: {a:.7f}, lon_deg: {b:.7f}}}" for a, b in wps)
    return f"""version: 1
name: autopilot-{sysid}
origin: {{lat_deg: {lat0:.7f}, lon_deg: {lon0:.7f}, alt_m: {alt0:.2f}}}
perimeter:
  sense: clockwise
  corner_radius_m: {corner:.1f}
  waypoints:
{points}
wind: {{speed_m_s: {beta:.2f}, from_deg: {wind_from:.1f}}}
vehicles:
  count: 1
  sysids: [{sysid}]
  airspeed_m_s: {s0:.2f}
  max_turn_rate_deg_s: {DEFAULT_TURN_RATE_DEG_S}
  initial:
    poses:
      - {{north_m: 0.0, east_m: 0.0, heading_deg: 0.0}}
sensor: {{footprint_radius_m: {DEFAULT_SENSOR_M}}}
"""
