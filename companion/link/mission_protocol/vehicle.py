"""One vehicle's perimeter and geofence, uploaded and verified (``companion upload``, and the
fleet's uploads, one thread per vehicle): open the link (signed or not), find the
autopilots, upload the perimeter waypoints (:mod:`~companion.link.mission_protocol.transfer`)
and the fence (:mod:`~companion.link.mission_protocol.fence`), each downloaded back and
compared.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from companion.contracts.errors import UserError
from companion.contracts.signing import FrameCheck
from companion.link.connection import link_signing, open_mavlink
from companion.link.mission_protocol.driver import drive
from companion.link.mission_protocol.fence import upload_fence
from companion.link.mission_protocol.listen import Listen
from companion.link.mission_protocol.transfer import upload_and_verify
from companion.mission import parse_mission
from companion.mission.load import read_text
from companion.mission.perimeter_files import PerimeterPoint, loop_points, parse_plan, parse_wpl


def perimeter_for(path: Path, points: int) -> tuple[Any, list[PerimeterPoint] | None]:
    """(mission or None, fixed points or None) from a perimeter source file.

    Read once, with the mission loader's size cap and UTF-8 check, before any link opens.
    """
    text = read_text(path)  # MissionError (a UserError) names the file and line
    if text.lstrip().startswith("QGC WPL"):
        return None, parse_wpl(text, str(path))
    if path.suffix == ".plan" or text.lstrip().startswith("{"):
        return None, parse_plan(text, str(path))
    if not 3 <= points <= 500:
        raise UserError("--points must be in [3, 500]")
    return parse_mission(text, str(path)), None


def link_check(link_key_file: str | None) -> FrameCheck | None:
    """The link signing check for ``link_key_file`` (None: unsigned links)."""
    if link_key_file is None:
        return None
    return link_signing(link_key_file, None, persist=False)


def open_link(url: str, check: FrameCheck | None, what: str) -> Any:
    """A MAVLink 2 connection to ``url`` as a ground station (system 255, component 190),
    its frames checked by ``check``; :class:`UserError` naming ``what`` if it cannot open.

    Opened as ``companion run`` opens its own (:func:`~companion.link.connection.open_mavlink`):
    a connection left to pymavlink's default starts in MAVLink 1 and replaces its encoder on
    the first MAVLink 2 frame heard, and the signing installed on the old one with it (a
    signed upload then sent unsigned frames and the autopilot answered none)."""
    try:
        conn = open_mavlink(url, 255, 190)
    except Exception as exc:  # pymavlink raises many types for a bad URL
        raise UserError(f"{what}: cannot open: {exc}") from None
    if check is not None:
        check.install(conn.mav)
    return conn


def upload_perimeter(
    conn: Any,
    sysid: int,
    autopilot: int | None,
    mission: Any,
    fixed: list[PerimeterPoint] | None,
    points: int,
    enable_fence: bool,
) -> tuple[bool, str]:
    """The perimeter (``fixed`` points, or ``points`` samples of the mission's loop at the
    vehicle's altitude) and then the mission's geofence to autopilot ``sysid`` on ``conn``,
    each verified by download; (ok, the vehicle's line)."""
    if fixed is not None:
        pts = fixed
    else:
        sysids = list(mission.vehicles.sysids)
        idx = sysids.index(sysid) if sysid in sysids else 0
        pts = loop_points(mission, points, mission.vehicles.altitudes_m[idx])
    ok, text = upload_and_verify(conn, sysid, pts, autopilot)
    if ok and mission is not None and mission.fence is not None:
        ok, fence_text = upload_fence(conn, sysid, mission, autopilot, enable=enable_fence)
        text += f"; {fence_text}"
    return ok, text


def upload_vehicle(
    url: str,
    sysid: int,
    mission_path: Path,
    *,
    enable_fence: bool = False,
    link_key_file: str | None = None,
    points: int = 16,
    listen_s: float = 2.0,
) -> tuple[bool, str]:
    """``companion upload MISSION --connect URL --sysid ID`` as a function, for a caller
    that uploads to several vehicles at once (the fleet, one thread per vehicle): (ok, the
    vehicle's line). Raises :class:`UserError` for a bad file or link."""
    mission, fixed = perimeter_for(Path(mission_path), points)
    check = link_check(link_key_file)
    conn = open_link(url, check, repr(url))
    try:
        kinds: dict[int, int] = {}
        found, _ = autopilots(conn, listen_s, sysid, check, kinds)
        if sysid not in found:
            return False, f"sysid {sysid}: no heartbeat on {url} within {listen_s:g} s"
        ok, text = upload_perimeter(
            conn, sysid, kinds.get(sysid), mission, fixed, points, enable_fence
        )
        return ok, f"sysid {sysid}: {text}"
    finally:
        conn.close()


def autopilots(
    conn: Any,
    listen_s: float,
    only: int | None,
    check: FrameCheck | None = None,
    kinds: dict[int, int] | None = None,
) -> tuple[list[int], bool]:
    """System ids of the autopilots (component 1) heard within ``listen_s`` (s), and
    whether their heartbeats were signed. Frames refused by ``check`` are counted there;
    ``kinds`` (if given) receives each system's HEARTBEAT ``autopilot`` (MAV_AUTOPILOT)."""
    heard = drive(conn, Listen(listen_s, only, check))
    if kinds is not None:
        kinds.update(heard.kinds)
    return heard.found, heard.signed
