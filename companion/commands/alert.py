"""``companion alert``: an operator injects an intruder alert into the patrol group.

The alert is a PATROL_ALERT (state "new") from the operator's reserved system id 255
(component 190, a ground station), signed with the fleet key, sent ``--repeat`` times
``--interval-s`` apart with the same id and time so a lossy network still delivers it (the
members merge repeats by id).

Time: the operator does not have the vehicles' clock. Before sending, the command listens to
the group for up to ``--listen-s`` seconds; the first member state it hears gives the
vehicle time (the state's time plus the age since its receipt) and also brings the operator's
signing timestamp up to the group's. If nothing is heard, the alert carries time 0, which
receivers read as "now, on receipt" (their own vehicle time). See ``docs/protocol.md``.

Position: ``--at NORTH,EAST`` in metres from the mission origin (``--at -40,120`` and
``--at=-40,120`` both work), or ``--lat/--lon`` in degrees with ``--mission FILE`` for the
origin. With ``--mission`` an alert the mission's geofence rules out (the check every
companion makes, :func:`companion.agent.alerts.paths.fence_refusal`) is refused here, exit 2.
Prints one JSON line describing what was sent; exit 0, or 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import time

import pymap3d

from companion.agent.alerts.paths import fence_refusal
from companion.commands.options import add_group_options
from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import parse_group
from companion.group.codec import ALERT_ID_MAX, COMPID_OPERATOR, OPERATOR_SYSID
from companion.group.keys import signing_from_key_file
from companion.group.messages import Alert
from companion.group.operator import (
    MAX_DISTANCE_M,
    default_alert_id,
    listen_for_alert,
    listen_for_vehicle_time,
    send_copies,
)
from companion.group.transport import open_group
from companion.mission import load_mission


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``alert`` sub-command."""
    p = sub.add_parser(
        "alert",
        help="inject an intruder alert into the patrol group (operator)",
        description="Send a signed intruder alert (state new, detector sysid 255) to the "
        "patrol group, repeated so a lossy network still delivers it.",
    )
    where = p.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--at", metavar="NORTH,EAST", help="site in metres from the mission origin (--at -40,5)"
    )
    where.add_argument("--lat", type=float, metavar="DEG", help="site latitude (needs --lon)")
    where.add_argument(
        "--clear",
        metavar="ID",
        help="clear alert ID instead: its prosecutor flies back, its tracker is released "
        "(the site is taken from the group's repeats of it, heard within --listen-s)",
    )
    p.add_argument("--lon", type=float, metavar="DEG", help="site longitude (with --lat)")
    p.add_argument(
        "--mission",
        metavar="FILE",
        help="mission YAML: its origin (--lat/--lon) and its fence (an alert outside is refused)",
    )
    add_group_options(p)
    auth = p.add_mutually_exclusive_group(required=True)
    auth.add_argument("--key-file", metavar="FILE", help="fleet signing key (32 bytes, mode 600)")
    auth.add_argument("--insecure", action="store_true", help="send unsigned (test groups only)")
    p.add_argument(
        "--state-dir",
        metavar="DIR",
        help="where to keep the signing-timestamp state (default: next to the key file)",
    )
    p.add_argument("--alert-id", metavar="ID", help=f"alert id (at most {ALERT_ID_MAX} chars)")
    p.add_argument("--repeat", type=int, default=3, metavar="N", help="copies (default 3)")
    p.add_argument(
        "--interval-s", type=float, default=0.2, metavar="S", help="between copies (default 0.2)"
    )
    p.add_argument(
        "--listen-s",
        type=float,
        default=1.0,
        metavar="S",
        help="listen this long for a member's time first (default 1; 0 = send at once)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build, sign and send the alert; print what was sent as one JSON line."""
    site = site_from_args(args) if args.clear is None else 0j
    where = parse_group(args.group)
    if args.repeat < 1 or not 0 <= args.interval_s <= 10:
        raise UserError("--repeat must be >= 1 and --interval-s in [0, 10] s")
    if not 0 <= args.listen_s <= 60:
        raise UserError("--listen-s must be in [0, 60] s")
    signing: Signing | None = None
    if not args.insecure:
        signing = signing_from_key_file(args.key_file, OPERATOR_SYSID, state_dir=args.state_dir)
    alert_id = args.alert_id if args.alert_id is not None else default_alert_id(time.time())
    if not alert_id or len(alert_id) > ALERT_ID_MAX or not alert_id.isascii():
        raise UserError(f"--alert-id {alert_id!r}: 1 to {ALERT_ID_MAX} ASCII characters")
    with open_group(
        where, OPERATOR_SYSID, signing, iface=args.group_iface, compid=COMPID_OPERATOR
    ) as group:
        t_s, heard = listen_for_vehicle_time(group, args.listen_s)
        if args.clear is not None:
            known = listen_for_alert(group, args.clear, max(args.listen_s, 1.0))
            if known is None:
                raise UserError(f"--clear {args.clear}: no member repeated that alert")
            alert_id, site = args.clear, known.site_m
        alert = Alert(
            alert_id, site, OPERATOR_SYSID, t_s, "new" if args.clear is None else "cleared"
        )
        sent = send_copies(group, alert, args.repeat, args.interval_s)
    print(
        json.dumps(
            {
                "alert_id": alert.alert_id,
                "state": alert.state,
                "north_m": round(site.real, 3),
                "east_m": round(site.imag, 3),
                "detector_sysid": OPERATOR_SYSID,
                "time_usec": round(t_s * 1e6),
                "time_from": f"sysid {heard}" if heard is not None else "receipt",
                "sent": sent,
                "group": str(where),
                "signed": signing is not None,
            }
        )
    )
    return 0


def site_from_args(args: argparse.Namespace) -> complex:
    """The alert site (north + i east, m from the mission origin) from the flags."""
    mission = load_mission(args.mission) if args.mission is not None else None  # MissionError
    if args.at is not None:
        if args.lon is not None:
            raise UserError("--at takes no --lon")
        parts = args.at.split(",")
        try:
            north, east = (float(x) for x in parts)
        except ValueError:
            raise UserError(f"--at {args.at!r}: expected NORTH,EAST in metres") from None
    else:
        if args.lon is None or mission is None:
            raise UserError("--lat needs --lon and --mission FILE (for the origin)")
        if not (-90 <= args.lat <= 90 and -180 <= args.lon <= 180):
            raise UserError(f"--lat {args.lat} --lon {args.lon}: not a position")
        o = mission.origin
        n, e, _ = pymap3d.geodetic2ned(args.lat, args.lon, o.alt_m, o.lat_deg, o.lon_deg, o.alt_m)
        north, east = float(n), float(e)
    if not (math.isfinite(north) and math.isfinite(east)):
        raise UserError("the alert site must be finite")
    if max(abs(north), abs(east)) > MAX_DISTANCE_M:
        raise UserError(f"the alert site is more than {MAX_DISTANCE_M:g} m from the origin")
    site = complex(north, east)
    if mission is not None and mission.fence is not None:
        why = fence_refusal(
            mission.patrol, mission.fence.fence, site, mission.vehicles.max_turn_rate_rad_s
        )
        if why is not None:
            raise UserError(
                f"alert at north {north:g}, east {east:g} m refused by the fence of "
                f"{args.mission}: {why} (the companions would refuse it too)"
            )
    return site
