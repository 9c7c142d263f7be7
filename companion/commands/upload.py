"""``companion upload``: upload the perimeter waypoints to the autopilots and verify them.

``companion upload MISSION --connect URL [--connect URL ...] [--sysid ID] [--points N]``

MISSION is a mission YAML (its patrol loop sampled equally in time, e.g. an ellipse as N
points, at each vehicle's altitude), a QGroundControl ``.plan`` file or a ``QGC WPL 110``
waypoint file. For every autopilot heard on each link (or only ``--sysid``) the points are
uploaded as MAV_CMD_NAV_WAYPOINT items (MISSION_ITEM_INT, frame GLOBAL_RELATIVE_ALT_INT)
with the MAVLink mission protocol (MISSION_COUNT, requests, MISSION_ACK; the count is
re-sent on silence), then downloaded back and compared item by item. The autopilot type
comes from its HEARTBEAT (``autopilot``): ArduPilot keeps home in item 0 and overwrites
whatever is sent there, so it gets a placeholder at seq 0 (the first perimeter point) and
the perimeter from seq 1, and on download item 0 is reported (home), not compared; PX4 and
others get the perimeter from seq 0 (:mod:`companion.link.home_slot`). One line per vehicle:
``sysid N: uploaded K waypoints, verified (CONVENTION ...)`` or what failed; exit 0 only if
all verified.
A mission YAML's geofence follows (:mod:`companion.link.fence_upload`): its inclusion
polygon as FENCE items (mission_type 1), downloaded back and compared, then the autopilot's
fence parameters (ArduPilot: FENCE_ALT_MIN/MAX, FENCE_TYPE, FENCE_ACTION; PX4:
GF_MAX_VER_DIST, GF_ACTION), each read back; ``--enable-fence`` also sets FENCE_ENABLE=1.
With ``--link-key-file`` every frame is signed (MAVLink 2 signing, as ``companion run``) and
unsigned or badly signed frames from the links are refused.
Wall-clock timeouts here are link plumbing (an operator command, not flight logic).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.core.signing import REJECT_REASONS, FrameCheck
from companion.errors import UserError
from companion.link.connection import link_signing
from companion.link.fence_upload import upload_fence
from companion.link.home_slot import convention, first_seq, home_in_item0
from companion.mission import parse_mission
from companion.mission.load import read_text
from companion.perimeter_files import PerimeterPoint, loop_points, parse_plan, parse_wpl

FRAME = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
RETRIES = 5
STEP_TIMEOUT_S = 1.5


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``upload`` sub-command."""
    p = sub.add_parser(
        "upload",
        help="upload the perimeter waypoints to the autopilots and verify them",
        description="Upload the perimeter (mission YAML loop, .plan or QGC WPL 110) as "
        "waypoints over the MAVLink mission protocol; verify by downloading them back.",
    )
    p.add_argument("mission", metavar="MISSION", help="mission YAML, .plan or .waypoints file")
    p.add_argument(
        "--connect", action="append", required=True, metavar="URL", help="link (repeatable)"
    )
    p.add_argument("--sysid", type=int, metavar="ID", help="only this autopilot")
    p.add_argument("--points", type=int, default=16, metavar="N", help="loop samples (YAML)")
    p.add_argument("--listen-s", type=float, default=2.0, metavar="S", help="heartbeat wait")
    p.add_argument(
        "--enable-fence",
        action="store_true",
        help="also switch the uploaded geofence on (FENCE_ENABLE=1; default: left as it is)",
    )
    p.add_argument(
        "--link-key-file",
        metavar="FILE",
        help="sign the links (MAVLink 2 signing) with this key (32 bytes, mode 600)",
    )
    p.set_defaults(func=run)


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


def _link_check(link_key_file: str | None) -> FrameCheck | None:
    """The link signing check for ``link_key_file`` (None: unsigned links)."""
    if link_key_file is None:
        return None
    os.environ["MAVLINK20"] = "1"  # signing is MAVLink 2 only (pymavlink's switch)
    return link_signing(link_key_file, None, persist=False)


def _open_link(url: str, check: FrameCheck | None, what: str) -> Any:
    """A pymavlink connection to ``url`` as a ground station (system 255, component 190),
    its frames checked by ``check``; :class:`UserError` naming ``what`` if it cannot open."""
    try:
        conn = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    except Exception as exc:  # pymavlink raises many types for a bad URL
        raise UserError(f"{what}: cannot open: {exc}") from None
    if check is not None:
        check.install(conn.mav)
    return conn


def run(args: argparse.Namespace) -> int:
    """Upload to every autopilot heard; print one line per vehicle."""
    mission, fixed = perimeter_for(Path(args.mission), args.points)
    check = _link_check(args.link_key_file)
    ok_all = True
    seen = 0
    signed_heard = False
    for url in args.connect:
        conn = _open_link(url, check, f"--connect {url!r}")
        try:
            kinds: dict[int, int] = {}
            found, signed = autopilots(conn, args.listen_s, args.sysid, check, kinds)
            signed_heard |= signed
            for sysid in found:
                seen += 1
                ok, text = upload_perimeter(
                    conn, sysid, kinds.get(sysid), mission, fixed, args.points, args.enable_fence
                )
                if not ok and signed and check is None:
                    text += " (the autopilot signs its frames: give --link-key-file FILE)"
                ok_all &= ok
                print(f"sysid {sysid}: {text}")
        finally:
            conn.close()
    if not seen:
        why = ""
        if check is not None and check.rejects():
            counts = ", ".join(f"{r} {check.counts[r]}" for r in REJECT_REASONS if check.counts[r])
            why = f" ({check.rejects()} frames refused by link signing: {counts}; wrong key?)"
        raise UserError("no autopilot heard on " + ", ".join(args.connect) + why)
    return 0 if ok_all else 1


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
    check = _link_check(link_key_file)
    conn = _open_link(url, check, repr(url))
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
    found: set[int] = set()
    signed = False
    deadline = time.monotonic() + listen_s
    while time.monotonic() < deadline:
        conn.mav.heartbeat_send(mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        m = conn.recv_match(type=["HEARTBEAT", "BAD_DATA"], blocking=True, timeout=0.3)
        if m is not None and m.get_type() == "BAD_DATA":
            if check is not None and getattr(m, "reason", "") == "Invalid signature":
                check.rejected(m.data)
            continue
        if m is not None and m.get_srcComponent() == 1 and m.type != mav.MAV_TYPE_GCS:
            found.add(m.get_srcSystem())
            if kinds is not None:
                kinds[m.get_srcSystem()] = int(m.autopilot)
            signed |= bool(m.get_header().incompat_flags & 1)
            if only is not None and only in found:
                return [only], signed
    return sorted(s for s in found if only is None or s == only), signed


def _item(sysid: int, seq: int, p: PerimeterPoint) -> Any:
    return mav.MAVLink_mission_item_int_message(
        sysid, 1, seq, FRAME, mavutil.mavlink.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0,
        round(p.lat_deg * 1e7), round(p.lon_deg * 1e7), float(p.alt_m), 0,
    )  # fmt: skip


def upload_and_verify(
    conn: Any, sysid: int, pts: list[PerimeterPoint], autopilot: int | None = None
) -> tuple[bool, str]:
    """Upload ``pts`` to ``sysid`` and download them back; (ok, description).

    ``autopilot`` is the HEARTBEAT's MAV_AUTOPILOT: for ArduPilot item 0 is a placeholder for
    home (the first point again, harmless if it were ever flown) and ``pts`` start at seq 1.
    """
    first = first_seq(autopilot)
    wire = pts[:1] * first + pts  # what is sent, by seq
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
    for i, (p, q) in enumerate(zip(pts, back[first:], strict=True), start=first):
        if (
            q.command != mavutil.mavlink.MAV_CMD_NAV_WAYPOINT
            or q.x != round(p.lat_deg * 1e7)
            or q.y != round(p.lon_deg * 1e7)
            or abs(q.z - p.alt_m) > 0.01
        ):
            return False, f"uploaded {k} waypoints, item {i} differs on download"
    where = f"perimeter in items {first}..{n - 1}"
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
    sent_count = 0
    for _ in range(RETRIES):
        conn.mav.send(mav.MAVLink_mission_count_message(sysid, 1, n, mtype))
        sent_count += 1
        while True:
            m = conn.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                blocking=True,
                timeout=STEP_TIMEOUT_S,
            )
            if m is None:
                break
            if m.get_srcSystem() != sysid or getattr(m, "mission_type", 0) != mtype:
                continue
            if m.get_type() == "MISSION_ACK":
                if m.type != mav.MAV_MISSION_ACCEPTED:
                    return f"upload refused (MISSION_ACK type {m.type})"
                return None
            if 0 <= m.seq < n:
                conn.mav.send(item_at(m.seq))
    return f"no answer to MISSION_COUNT after {sent_count} tries"


def _place(it: Any) -> str:
    """A downloaded item's position for a report (lat, lon deg; altitude m and its frame)."""
    alt = f"{it.z:.1f} m AMSL" if it.frame in (0, 5) else f"{it.z:.1f} m (frame {it.frame})"
    return f"at {it.x * 1e-7:.7f}, {it.y * 1e-7:.7f}, {alt}"


def download(conn: Any, sysid: int, mtype: int = 0) -> list[Any] | None:
    """The autopilot's stored items of ``mission_type`` ``mtype`` (0 = the mission, 1 = the
    fence), or None on a timeout."""
    for _ in range(RETRIES):
        conn.mav.send(mav.MAVLink_mission_request_list_message(sysid, 1, mtype))
        m = conn.recv_match(type="MISSION_COUNT", blocking=True, timeout=STEP_TIMEOUT_S)
        if m is not None and m.get_srcSystem() == sysid and m.mission_type == mtype:
            break
    else:
        return None
    items = []
    for seq in range(m.count):
        for _ in range(RETRIES):
            conn.mav.send(mav.MAVLink_mission_request_int_message(sysid, 1, seq, mtype))
            it = conn.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=STEP_TIMEOUT_S)
            if it is not None and it.get_srcSystem() == sysid and it.seq == seq:
                items.append(it)
                break
        else:
            return None
    conn.mav.send(mav.MAVLink_mission_ack_message(sysid, 1, mav.MAV_MISSION_ACCEPTED, mtype))
    return items
