"""``autopilot_messages``: only the autopilot's own messages, until none is waiting, the link
fails, or the limit of messages read."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.sim.firmware.links import autopilot_messages


class _Msg:
    def __init__(self, sysid: int, compid: int, name: str) -> None:
        self.sysid, self.compid, self.name = sysid, compid, name

    def get_srcSystem(self) -> int:
        return self.sysid

    def get_srcComponent(self) -> int:
        return self.compid


class _Conn:
    def __init__(self, items: list) -> None:
        self.items, self.reads = list(items), 0

    def recv_msg(self):
        self.reads += 1
        item = self.items.pop(0) if self.items else None
        if isinstance(item, Exception):
            raise item
        return item


def test_only_the_autopilots_own_until_none_waits() -> None:
    conn = _Conn([_Msg(1, 1, "a"), _Msg(2, 1, "other uav"), _Msg(1, 191, "companion"),
                  _Msg(1, 1, "b"), None, _Msg(1, 1, "after the gap")])  # fmt: skip
    assert [m.name for m in autopilot_messages(conn, 1)] == ["a", "b"]
    assert conn.reads == 5


def test_a_link_error_ends_the_reading() -> None:
    for error in (OSError("gone"), mav.MAVError("bad")):
        conn = _Conn([_Msg(1, 1, "a"), error, _Msg(1, 1, "never")])
        assert [m.name for m in autopilot_messages(conn, 1)] == ["a"]


def test_the_limit_counts_every_message_read() -> None:
    conn = _Conn([_Msg(2, 1, "x"), _Msg(1, 1, "a"), _Msg(1, 1, "b"), _Msg(1, 1, "c")])
    assert [m.name for m in autopilot_messages(conn, 1, limit=3)] == ["a", "b"]
    assert conn.reads == 3
