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
others get the perimeter from seq 0 (:mod:`companion.link.mission_protocol.home_slot`). One line
per vehicle:
``sysid N: uploaded K waypoints, verified (CONVENTION ...)`` or what failed; exit 0 only if
all verified.
A mission YAML's geofence follows (:mod:`companion.link.mission_protocol.fence`): its inclusion
polygon as FENCE items (mission_type 1), downloaded back and compared, then the autopilot's
fence parameters (ArduPilot: FENCE_ALT_MIN/MAX, FENCE_TYPE, FENCE_ACTION; PX4:
GF_MAX_VER_DIST, GF_ACTION), each read back; ``--enable-fence`` also sets FENCE_ENABLE=1.
With ``--link-key-file`` every frame is signed (MAVLink 2 signing, as ``companion run``) and
unsigned or badly signed frames from the links are refused.
Wall-clock timeouts here are link plumbing (an operator command, not flight logic).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from companion.contracts.errors import UserError
from companion.contracts.signing import REJECT_REASONS, FrameCheck
from companion.link.mission_protocol.vehicle import (
    autopilots,
    link_check,
    open_link,
    perimeter_for,
    upload_perimeter,
)


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


def refusals(check: FrameCheck | None) -> str:
    """Why no autopilot was heard, as far as link signing tells: "" when it refused nothing;
    all refused frames unsigned: the autopilot does not sign (set its key, or upload without
    one); otherwise: a wrong key."""
    if check is None or not check.rejects():
        return ""
    counts = ", ".join(f"{r} {check.counts[r]}" for r in REJECT_REASONS if check.counts[r])
    refused = f" ({check.rejects()} frames refused by link signing: {counts}; "
    if all(check.counts[r] == 0 for r in REJECT_REASONS if r != "unsigned"):
        return refused + (
            "the autopilot does not sign its frames: set its key with SETUP_SIGNING "
            "(see docs/companion.md) or upload without --link-key-file)"
        )
    return refused + "wrong key?)"


def run(args: argparse.Namespace) -> int:
    """Upload to every autopilot heard; print one line per vehicle."""
    mission, fixed = perimeter_for(Path(args.mission), args.points)
    check = link_check(args.link_key_file)
    ok_all = True
    seen = 0
    signed_heard = False
    for url in args.connect:
        conn = open_link(url, check, f"--connect {url!r}")
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
        raise UserError("no autopilot heard on " + ", ".join(args.connect) + refusals(check))
    return 0 if ok_all else 1
