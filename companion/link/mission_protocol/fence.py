"""Upload a mission's geofence to an autopilot and verify it (``companion upload``).

* The inclusion polygon goes with the MAVLink mission protocol, ``mission_type`` FENCE (1):
  one ``MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`` (5001) item per vertex, ``param1`` =
  the vertex count, frame GLOBAL, lat/lon in degE7; ArduPilot and PX4 both store fences this
  way. It is downloaded back and compared item by item.
* The altitude band and the action are parameters, set with PARAM_SET and read back
  (PARAM_VALUE), only where the autopilot has them (a PARAM_REQUEST_READ answered first):
  ArduPilot ``FENCE_ALT_MIN``, ``FENCE_ALT_MAX`` (m above home), ``FENCE_TYPE`` = 13 (max
  altitude, polygon, min altitude), ``FENCE_ACTION`` = 1 (RTL), and ``FENCE_ENABLE`` = 1 with
  ``enable``; PX4 ``GF_MAX_VER_DIST`` (the ceiling; PX4 has no floor) and ``GF_ACTION`` = 3
  (Return); PX4 enables its geofence through ``GF_ACTION`` itself.
* PX4 carries an integer parameter's bits in PARAM_VALUE's and PARAM_SET's float field
  (converted in :mod:`~companion.link.mission_protocol.params`).

The exchanges are the sans-IO ones (:mod:`~companion.link.mission_protocol.client`,
:mod:`~companion.link.mission_protocol.params`) run over the connection by
:func:`~companion.link.mission_protocol.driver.drive`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pymap3d
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.mission_protocol.driver import drive
from companion.link.mission_protocol.home_slot import MAV_AUTOPILOT_PX4
from companion.link.mission_protocol.params import ParamExchange
from companion.link.mission_protocol.transfer import download, send_items
from companion.mission import Mission

FENCE = mav.MAV_MISSION_TYPE_FENCE
VERTEX_INCLUSION = mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION  # 5001
FRAME_GLOBAL = mav.MAV_FRAME_GLOBAL
ARDUPILOT_FENCE_TYPE = 13.0  # 1 max altitude + 4 polygon + 8 min altitude
ARDUPILOT_ACTION_RTL = 1.0
PX4_ACTION_RETURN = 3.0


def fence_vertices_e7(mission: Mission) -> list[tuple[int, int]]:
    """The fence polygon's vertices as (lat, lon) in degE7 (given lat/lon kept as given)."""
    o = mission.origin
    out = []
    for v in mission.fence.vertices:
        if v.lat_deg is not None and v.lon_deg is not None:
            lat, lon = v.lat_deg, v.lon_deg
        else:
            lat, lon, _ = pymap3d.ned2geodetic(
                v.north_m, v.east_m, 0.0, o.lat_deg, o.lon_deg, o.alt_m
            )
        out.append((round(float(lat) * 1e7), round(float(lon) * 1e7)))
    return out


def fence_params(mission: Mission, autopilot: int | None, enable: bool) -> list[tuple[str, float]]:
    """The fence parameters to set on this autopilot type, in order."""
    f = mission.fence
    if autopilot == MAV_AUTOPILOT_PX4:
        return [("GF_MAX_VER_DIST", f.max_alt_m), ("GF_ACTION", PX4_ACTION_RETURN)]
    out = [
        ("FENCE_ALT_MIN", f.min_alt_m),
        ("FENCE_ALT_MAX", f.max_alt_m),
        ("FENCE_TYPE", ARDUPILOT_FENCE_TYPE),
        ("FENCE_ACTION", ARDUPILOT_ACTION_RTL),
    ]
    return [*out, ("FENCE_ENABLE", 1.0)] if enable else out


def _vertex(sysid: int, seq: int, n: int, lat_lon: tuple[int, int]) -> Any:
    return mav.MAVLink_mission_item_int_message(
        sysid, 1, seq, FRAME_GLOBAL, VERTEX_INCLUSION, 0, 1, float(n), 0, 0, 0,
        lat_lon[0], lat_lon[1], 0.0, FENCE,
    )  # fmt: skip


def upload_fence(
    conn: Any, sysid: int, mission: Mission, autopilot: int | None, enable: bool = False
) -> tuple[bool, str]:
    """Upload, download and compare the fence, then set its parameters; (ok, description)."""
    verts = fence_vertices_e7(mission)
    n = len(verts)
    failed = send_items(conn, sysid, n, lambda seq: _vertex(sysid, seq, n, verts[seq]), FENCE)
    if failed is not None:
        return False, f"fence: {failed}"
    back = download(conn, sysid, FENCE)
    if back is None:
        return False, f"fence: uploaded {n} vertices, download failed"
    if len(back) != n:
        return False, f"fence: uploaded {n} vertices, {len(back)} items came back"
    for i, (ll, q) in enumerate(zip(verts, back, strict=True)):
        if q.command != VERTEX_INCLUSION or int(q.param1) != n or (q.x, q.y) != ll:
            return False, f"fence: uploaded {n} vertices, item {i} differs on download"
    done, missing = [], []
    bytewise = autopilot == MAV_AUTOPILOT_PX4
    for name, value in fence_params(mission, autopilot, enable):
        read = _param(conn, sysid, name, None, bytewise)
        if read is None:
            missing.append(name)
            continue
        set_ = _param(conn, sysid, name, value, bytewise, read[1])
        got = None if set_ is None else set_[0]
        if got is None or not np.isclose(got, value, rtol=1e-6, atol=1e-3):
            return False, f"fence: {n} vertices verified; {name}={value:g} not accepted"
        done.append(f"{name}={value:g}")
    text = f"fence: {n} vertices verified"
    if done:
        text += ", " + " ".join(done)
    if missing:
        text += " (the autopilot has no " + ", ".join(missing) + ")"
    if not enable:
        text += "; FENCE_ENABLE left as it is"
    return True, text


def _param(
    conn: Any,
    sysid: int,
    name: str,
    value: float | None,
    bytewise: bool = False,
    param_type: int = mav.MAV_PARAM_TYPE_REAL32,
) -> tuple[float, int] | None:
    """Read (``value`` None) or set a parameter of ``param_type``; (its value as the autopilot
    reports it, its type), or None when it never answers (no such parameter, or the link is
    down). ``bytewise``: PX4's encoding of integers
    (:func:`~companion.link.mission_protocol.params.encode_param`)."""
    return drive(conn, ParamExchange(sysid, name, value, bytewise, param_type)).result
