"""The MAVLink mission protocol over a pymavlink connection: items up (MISSION_COUNT,
requests, MISSION_ACK; the count re-sent on silence) and down (MISSION_REQUEST_LIST,
MISSION_REQUEST_INT), for the mission (``mission_type`` 0) and the fence (1), and the perimeter
uploaded and verified by download. The protocol itself is the sans-IO client
(:mod:`~companion.link.mission_protocol.client`, the mirror of the simulator's
:mod:`sitl_model.mission_protocol`), run by :func:`~companion.link.mission_protocol.driver.drive`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.mission_protocol.client import Download, Upload
from companion.link.mission_protocol.driver import drive
from companion.link.mission_protocol.home_slot import convention, first_seq, home_in_item0
from companion.mission.perimeter_files import PerimeterPoint

FRAME = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


Item = tuple[int, float, float, float]  # (MAV_CMD, lat deg, lon deg, alt m above home)


def _item(sysid: int, seq: int, it: Item) -> Any:
    cmd, lat, lon, alt = it
    return mav.MAVLink_mission_item_int_message(
        sysid, 1, seq, FRAME, cmd, 0, 1, 0, 0, 0, 0,
        round(lat * 1e7), round(lon * 1e7), float(alt), 0,
    )  # fmt: skip


def upload_and_verify(
    conn: Any,
    sysid: int,
    pts: list[PerimeterPoint],
    autopilot: int | None = None,
    extra: list[Item] | tuple[Item, ...] = (),
) -> tuple[bool, str]:
    """Upload ``pts`` to ``sysid`` and download them back; (ok, description).

    ``autopilot`` is the HEARTBEAT's MAV_AUTOPILOT: for ArduPilot item 0 is a placeholder for
    home (the first point again, harmless if it were ever flown) and ``pts`` start at seq 1.
    ``extra`` items follow the perimeter (the fleet's landing sequences: (MAV_CMD, lat deg,
    lon deg, alt m above home)).
    """
    first = first_seq(autopilot)
    loop = [(int(mavutil.mavlink.MAV_CMD_NAV_WAYPOINT), p.lat_deg, p.lon_deg, p.alt_m) for p in pts]
    wire = loop[:1] * first + loop + list(extra)  # what is sent, by seq
    n = len(wire)
    failed = send_items(conn, sysid, n, lambda seq: _item(sysid, seq, wire[seq]))
    if failed is not None:
        return False, failed
    k = len(pts)
    back = download(conn, sysid)
    if back is None:
        return False, f"uploaded {k} waypoints, download failed"
    if len(back) != n:
        return False, f"uploaded {k} waypoints ({n} items), {len(back)} items came back"
    for i, (w, q) in enumerate(zip(wire[first:], back[first:], strict=True), start=first):
        cmd, lat, lon, alt = w
        if (
            q.command != cmd
            or q.x != round(lat * 1e7)
            or q.y != round(lon * 1e7)
            or abs(q.z - alt) > 0.01
        ):
            return False, f"uploaded {k} waypoints, item {i} differs on download"
    where = f"perimeter in items {first}..{first + k - 1}"
    if extra:
        where += f", {len(extra)} landing items after"
    if home_in_item0(autopilot):
        where = f"{convention(autopilot)} {_place(back[0])}; {where}"
    else:
        where = f"{convention(autopilot)}; {where}"
    return True, f"uploaded {k} waypoints, verified ({where})"


def send_items(
    conn: Any, sysid: int, n: int, item_at: Callable[[int], Any], mtype: int = 0
) -> str | None:
    """Upload ``n`` items (``item_at(seq)`` builds item ``seq``) of ``mission_type`` ``mtype``
    with the mission protocol; None when the autopilot accepted them, else what failed."""
    return drive(conn, Upload(sysid, n, item_at, mtype)).error


def _place(it: Any) -> str:
    """A downloaded item's position for a report (lat, lon deg; altitude m and its frame)."""
    alt = f"{it.z:.1f} m AMSL" if it.frame in (0, 5) else f"{it.z:.1f} m (frame {it.frame})"
    return f"at {it.x * 1e-7:.7f}, {it.y * 1e-7:.7f}, {alt}"


def download(conn: Any, sysid: int, mtype: int = 0) -> list[Any] | None:
    """The autopilot's stored items of ``mission_type`` ``mtype`` (0 = the mission, 1 = the
    fence), or None on a timeout."""
    return drive(conn, Download(sysid, mtype)).items
