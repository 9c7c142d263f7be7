"""The MAVLink mission protocol (mission_type MISSION and FENCE), as a pure state machine.

Feed it decoded messages with the peer they came from and the current time (s, any
monotonic clock); it returns the messages to send, each addressed to one peer. Upload
(MISSION_COUNT -> MISSION_REQUEST_INT* -> MISSION_ITEM_INT* -> MISSION_ACK) replaces the
stored mission only when the last item has arrived; a stalled upload is re-requested
``RETRIES`` times ``RETRY_S`` apart and then cancelled, keeping the old mission. Download
answers MISSION_REQUEST_LIST, MISSION_REQUEST_INT (and legacy MISSION_REQUEST with
MISSION_ITEM); a legacy MISSION_ITEM upload is accepted too. MISSION_CLEAR_ALL clears.
FENCE items (mission_type 1) are stored separately, with the same transfers; a FENCE upload
whose polygons are malformed (:func:`sitl_model.fence.fence_fault`) is refused with
MAV_MISSION_INVALID and the old fence kept. Rally points are reported empty and uploads of
them are refused with MAV_MISSION_UNSUPPORTED.

States: IDLE, RECEIVING (one peer's upload). A second peer's MISSION_COUNT while receiving
is refused with MAV_MISSION_DENIED.

ArduPilot's convention (given a ``home`` item): item 0 of a stored mission is home, never a
waypoint. Whatever item 0 an upload sends is replaced by home once the upload completes, so
a download returns home at seq 0 (a NAV_WAYPOINT at the home location, frame GLOBAL, AMSL
altitude) and the uploaded items from seq 1. Without ``home`` items are stored verbatim
(PX4's convention).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from sitl_model.codec import dialect as d
from sitl_model.fence import FENCE_COMMANDS, fence_fault

RETRY_S = 0.5
RETRIES = 4
MAX_ITEMS = 1000
FRAME_GLOBAL = 0  # MAV_FRAME_GLOBAL: AMSL altitude, the frame ArduPilot reports home in
NAV_WAYPOINT = 16
NAV_COMMANDS = frozenset({16, 17, 18, 19, 31})  # WAYPOINT, LOITER_UNLIM/TURNS/TIME, TO_ALT
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})  # GLOBAL(_INT), RELATIVE_ALT(_INT), TERRAIN
MISSION, FENCE = d.MAV_MISSION_TYPE_MISSION, d.MAV_MISSION_TYPE_FENCE
STORED_TYPES = frozenset({MISSION, FENCE})


@dataclass(frozen=True)
class MissionItem:
    """One stored MISSION_ITEM_INT, verbatim (x, y = lat, lon in degE7 for global frames)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int = MISSION

    def message(self, target_system: int, target_component: int) -> Any:
        """As a MISSION_ITEM_INT addressed to a peer."""
        return d.MAVLink_mission_item_int_message(
            target_system, target_component, self.seq, self.frame, self.command, self.current,
            self.autocontinue, self.param1, self.param2, self.param3, self.param4,
            self.x, self.y, self.z, self.mission_type,
        )  # fmt: skip

    def message_float(self, target_system: int, target_component: int) -> Any:
        """As a legacy MISSION_ITEM (float lat/lon in deg for global frames)."""
        scale = 1e-7 if self.frame in GLOBAL_FRAMES else 1.0
        return d.MAVLink_mission_item_message(
            target_system, target_component, self.seq, self.frame, self.command, self.current,
            self.autocontinue, self.param1, self.param2, self.param3, self.param4,
            self.x * scale, self.y * scale, self.z, self.mission_type,
        )  # fmt: skip

    @property
    def is_nav(self) -> bool:
        """A navigation item with a global position that AUTO flies to."""
        return self.command in NAV_COMMANDS and self.frame in GLOBAL_FRAMES


def home_item(lat_deg: float, lon_deg: float, alt_amsl_m: float) -> MissionItem:
    """Mission item 0 as ArduPilot reports it: a NAV_WAYPOINT at home (deg, deg, m AMSL) in
    frame GLOBAL."""
    return MissionItem(
        0, FRAME_GLOBAL, NAV_WAYPOINT, 0, 1, 0.0, 0.0, 0.0, 0.0,
        round(lat_deg * 1e7), round(lon_deg * 1e7), float(alt_amsl_m),
    )  # fmt: skip


def item_from_message(m: Any) -> MissionItem:
    """A :class:`MissionItem` from a MISSION_ITEM_INT (or a legacy float MISSION_ITEM, whose
    global lat/lon in deg are stored as degE7); ``ValueError`` if a field is invalid."""
    x, y = m.x, m.y
    if m.get_type() == "MISSION_ITEM":
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError("x/y not finite")
        scale = 1e7 if int(m.frame) in GLOBAL_FRAMES else 1.0
        x, y = round(x * scale), round(y * scale)
    item = MissionItem(
        int(m.seq), int(m.frame), int(m.command), int(m.current), int(m.autocontinue),
        float(m.param1), float(m.param2), float(m.param3), float(m.param4),
        int(x), int(y), float(m.z), int(getattr(m, "mission_type", MISSION)),
    )  # fmt: skip
    if not math.isfinite(item.z) or not math.isfinite(item.param1):
        raise ValueError("z not finite")
    lat_ok = -900_000_000 <= item.x <= 900_000_000
    lon_ok = -1_800_000_000 <= item.y <= 1_800_000_000
    if (item.is_nav or item.command in FENCE_COMMANDS) and not (lat_ok and lon_ok):
        raise ValueError("latitude/longitude out of range")
    return item


Out = tuple[Any, Any]  # (message, peer)


@dataclass
class _Upload:
    peer: Any
    sysid: int
    compid: int
    count: int
    items: list[MissionItem]
    last_t: float
    retries: int = 0
    mtype: int = MISSION


class MissionProtocol:
    """Stored mission plus the transfer state machine for one vehicle."""

    def __init__(
        self,
        items: tuple[MissionItem, ...] = (),
        home: MissionItem | None = None,
        fence: tuple[MissionItem, ...] = (),
    ) -> None:
        """Start IDLE with ``items`` and ``fence`` stored; with ``home``, item 0 is always home
        (ArduPilot)."""
        self.home = home
        self.items: tuple[MissionItem, ...] = self._with_home(items)
        self.version = 0  # bumps whenever ``items`` is replaced
        self.fence: tuple[MissionItem, ...] = tuple(fence)
        self.fence_version = 0  # bumps whenever ``fence`` is replaced
        self.refused = 0  # refused or cancelled transfers and bad items
        self.events: list[tuple[str, dict]] = []
        self._up: _Upload | None = None

    @property
    def total(self) -> int:
        """MISSION_CURRENT's ``total``: the stored items, home excluded (MAVLink's rule)."""
        n = len(self.items)
        return n - 1 if self.home is not None and n else n

    @property
    def state(self) -> str:
        """``"IDLE"`` or ``"RECEIVING"``."""
        return "IDLE" if self._up is None else "RECEIVING"

    def _ack(self, peer: Any, sysid: int, compid: int, result: int, mtype: int = 0) -> Out:
        return (d.MAVLink_mission_ack_message(sysid, compid, result, mtype), peer)

    def _request(self, up: _Upload) -> Out:
        seq = len(up.items)
        msg = d.MAVLink_mission_request_int_message(up.sysid, up.compid, seq, up.mtype)
        return (msg, up.peer)

    def stored(self, mtype: int) -> tuple[MissionItem, ...]:
        """The stored items of ``mtype`` (MISSION or FENCE; nothing else is kept)."""
        return self.fence if mtype == FENCE else self.items if mtype == MISSION else ()

    def handle(self, m: Any, peer: Any, now_s: float) -> list[Out]:
        """Process one mission-protocol message from ``peer``; returns what to send."""
        t = m.get_type()
        src, comp = m.get_srcSystem(), m.get_srcComponent()
        mtype = int(getattr(m, "mission_type", 0))
        if t == "MISSION_COUNT":
            return self._count(m, peer, src, comp, mtype, now_s)
        if t in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._item(m, peer, src, comp, mtype, now_s)
        if t == "MISSION_REQUEST_LIST":
            n = len(self.stored(mtype))
            return [(d.MAVLink_mission_count_message(src, comp, n, mtype), peer)]
        if t in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            seq = int(m.seq)
            items = self.stored(mtype)
            if not 0 <= seq < len(items):
                self.refused += 1
                return [self._ack(peer, src, comp, d.MAV_MISSION_INVALID_SEQUENCE, mtype)]
            it = items[seq]
            if t == "MISSION_REQUEST_INT":
                return [(it.message(src, comp), peer)]
            return [(it.message_float(src, comp), peer)]
        if t == "MISSION_CLEAR_ALL":
            if mtype not in STORED_TYPES:
                return [self._ack(peer, src, comp, d.MAV_MISSION_ACCEPTED, mtype)]
            if self._up is not None:
                self.refused += 1
                return [self._ack(peer, src, comp, d.MAV_MISSION_DENIED, mtype)]
            self._store(mtype, ())
            self.events.append(("fence_cleared" if mtype == FENCE else "mission_cleared", {}))
            return [self._ack(peer, src, comp, d.MAV_MISSION_ACCEPTED, mtype)]
        return []  # MISSION_ACK from a downloader: nothing to do

    def _count(self, m: Any, peer: Any, src: int, comp: int, mtype: int, now: float) -> list[Out]:
        if mtype not in STORED_TYPES:
            self.refused += 1
            return [self._ack(peer, src, comp, d.MAV_MISSION_UNSUPPORTED, mtype)]
        if self._up is not None and self._up.peer != peer:
            self.refused += 1
            return [self._ack(peer, src, comp, d.MAV_MISSION_DENIED, mtype)]
        count = int(m.count)
        if count > MAX_ITEMS:
            self._up = None
            self.refused += 1
            return [self._ack(peer, src, comp, d.MAV_MISSION_NO_SPACE, mtype)]
        if count == 0:
            self._up = None
            self._store(mtype, ())
            return [self._ack(peer, src, comp, d.MAV_MISSION_ACCEPTED, mtype)]
        self._up = _Upload(peer, src, comp, count, [], now, mtype=mtype)
        return [self._request(self._up)]

    def _item(self, m: Any, peer: Any, src: int, comp: int, mtype: int, now: float) -> list[Out]:
        up = self._up
        if up is None or up.peer != peer or mtype != up.mtype:
            self.refused += 1
            return []  # not ours: ArduPilot ignores stray items
        seq = int(m.seq)
        if seq != len(up.items):
            return [self._request(up)] if seq > len(up.items) else []
        try:
            item = item_from_message(m)
        except ValueError:
            self._up = None
            self.refused += 1
            self.events.append(("mission_upload_refused", {"seq": seq}))
            return [self._ack(peer, src, comp, d.MAV_MISSION_INVALID, mtype)]
        up.items.append(item)
        up.last_t = now
        up.retries = 0
        if len(up.items) < up.count:
            return [self._request(up)]
        self._up = None
        if mtype == FENCE and (fault := fence_fault(up.items)) is not None:
            self.refused += 1
            self.events.append(("fence_upload_refused", {"reason": fault}))
            return [self._ack(peer, src, comp, d.MAV_MISSION_INVALID, mtype)]
        self._store(mtype, tuple(up.items))
        name = "fence_uploaded" if mtype == FENCE else "mission_uploaded"
        self.events.append((name, {"count": up.count}))
        return [self._ack(peer, src, comp, d.MAV_MISSION_ACCEPTED, mtype)]

    def tick(self, now_s: float) -> list[Out]:
        """Re-request or cancel a stalled upload."""
        up = self._up
        if up is None or now_s - up.last_t < RETRY_S:
            return []
        if up.retries >= RETRIES:
            self._up = None
            self.refused += 1
            self.events.append(("mission_upload_timeout", {"received": len(up.items)}))
            cancelled = d.MAV_MISSION_OPERATION_CANCELLED
            return [self._ack(up.peer, up.sysid, up.compid, cancelled, up.mtype)]
        up.retries += 1
        up.last_t = now_s
        return [self._request(up)]

    def _with_home(self, items: tuple[MissionItem, ...]) -> tuple[MissionItem, ...]:
        """``items`` with item 0 replaced by home (ArduPilot), or as they are."""
        if self.home is None or not items:
            return items
        return (replace(self.home, seq=0), *items[1:])

    def _replace(self, items: tuple[MissionItem, ...]) -> None:
        self.items = self._with_home(items)
        self.version += 1

    def _store(self, mtype: int, items: tuple[MissionItem, ...]) -> None:
        """Replace the stored items of ``mtype`` (MISSION or FENCE)."""
        if mtype == FENCE:
            self.fence = items
            self.fence_version += 1
        else:
            self._replace(items)
