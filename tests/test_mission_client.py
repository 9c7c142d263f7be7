"""The mission-protocol client, sans-IO, wired to the simulator's side of the same protocol
(:class:`sitl_model.mission_protocol.MissionProtocol`) in memory: two protocol objects, the
messages packed to bytes and parsed back between them, time passed in, no sockets, no
clock. A lost message is recovered, a refused item ends the upload with the autopilot's
answer, silence gives up after the tries; the parameter exchange and the heartbeat listen the
same way against hand-written peers."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.mission_protocol.client import RETRIES, STEP_TIMEOUT_S, Download, Upload
from companion.link.mission_protocol.driver import drive
from companion.link.mission_protocol.listen import Listen
from companion.link.mission_protocol.params import ParamExchange
from sitl_model.mission_protocol import MissionProtocol, home_item

GCS, AUTOPILOT = (255, 190), (1, 1)
FENCE = mav.MAV_MISSION_TYPE_FENCE
DT_S = 0.05  # the time one exchange of messages takes in the wire below (s)


def wire(msg: Any, src: tuple[int, int]) -> Any:
    """``msg`` packed as MAVLink 2 by system and component ``src`` and parsed back."""
    enc = mav.MAVLink(None, srcSystem=src[0], srcComponent=src[1])
    (out,) = mav.MAVLink(None).parse_buffer(msg.pack(enc))
    return out


def waypoint(seq: int, lat_e7: int = 398_000_000, mtype: int = 0) -> Any:
    """A MISSION_ITEM_INT NAV_WAYPOINT for system 1 at ``lat_e7`` (degE7), lon -84 deg."""
    return mav.MAVLink_mission_item_int_message(
        1, 1, seq, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 16, 0, 1, 0, 0, 0, 0,
        lat_e7 + 1000 * seq, -840_000_000, 100.0, mtype,
    )  # fmt: skip


class Wire:
    """The client and the simulator's protocol, in memory. ``lose(msg)`` drops a message
    on its way (either way); :attr:`lost` counts the drops."""

    def __init__(self, ap: MissionProtocol, lose: Callable[[Any], bool] = lambda m: False):
        self.ap, self.lose = ap, lose
        self.t_s = 0.0
        self.to_client: list[Any] = []
        self.lost = 0
        self.sent: list[str] = []  # what the client sent, by type

    def _to_ap(self, msgs: list[Any]) -> None:
        for msg in msgs:
            self.sent.append(msg.get_type())
            if self.lose(msg):
                self.lost += 1
                continue
            self._answers(self.ap.handle(wire(msg, GCS), "gcs", self.t_s))

    def _answers(self, outs: list[tuple[Any, Any]]) -> None:
        for out, _peer in outs:
            if self.lose(out):
                self.lost += 1
            else:
                self.to_client.append(wire(out, AUTOPILOT))

    def run(self, client: Any) -> Any:
        """Both sides until the client is done; time moves on only while nothing is in
        flight (each side's tick then)."""
        self._to_ap(client.start(self.t_s))
        while not client.done:
            if self.to_client:
                self._to_ap(client.handle(self.to_client.pop(0), self.t_s))
                continue
            self.t_s += DT_S
            self._answers(self.ap.tick(self.t_s))
            self._to_ap(client.tick(self.t_s))
            assert self.t_s < 60.0, "the exchange never ends"
        return client


def items_for(n: int, lat_e7: int = 398_000_000, mtype: int = 0) -> Callable[[int], Any]:
    return lambda seq: waypoint(seq, lat_e7, mtype)


def test_an_upload_then_a_download_in_memory_store_and_return_the_items():
    ap = MissionProtocol()
    up = Wire(ap).run(Upload(1, 4, items_for(4)))
    assert up.error is None and up.counts_sent == 1
    assert [(it.seq, it.x) for it in ap.items] == [(k, 398_000_000 + 1000 * k) for k in range(4)]
    down = Wire(ap).run(Download(1))
    assert [(it.seq, it.x, it.z) for it in down.items] == [(it.seq, it.x, it.z) for it in ap.items]


def test_ardupilots_home_comes_back_in_item_0():
    ap = MissionProtocol(home=home_item(-35.0, 149.0, 584.0))
    assert Wire(ap).run(Upload(1, 3, items_for(3))).error is None
    down = Wire(ap).run(Download(1))
    assert [it.seq for it in down.items] == [0, 1, 2]
    assert (down.items[0].x, down.items[0].z) == (-350_000_000, 584.0)  # home, not our item


def test_a_lost_ack_is_recovered_by_counting_again():
    """The MISSION_ACK is lost: the client hears nothing for STEP_TIMEOUT_S and sends the
    count again; the autopilot takes the whole upload again and answers."""
    acks = []

    def lose_first_ack(m: Any) -> bool:
        if m.get_type() == "MISSION_ACK" and not acks:
            acks.append(m)
            return True
        return False

    w = Wire(MissionProtocol(), lose_first_ack)
    up = w.run(Upload(1, 3, items_for(3)))
    assert up.error is None and up.counts_sent == 2 and w.lost == 1
    assert w.t_s == pytest.approx(STEP_TIMEOUT_S, abs=2 * DT_S)  # one silence, not more
    assert w.sent.count("MISSION_ITEM_INT") == 6  # the upload, twice
    assert len(w.ap.items) == 3


def test_a_lost_item_is_asked_for_again_by_the_autopilot():
    """Item 1 is lost on its way: the simulator re-requests it after its RETRY_S; the client
    answers the request again without counting again."""
    lost = []

    def lose_item_1(m: Any) -> bool:
        if m.get_type() == "MISSION_ITEM_INT" and m.seq == 1 and not lost:
            lost.append(m)
            return True
        return False

    w = Wire(MissionProtocol(), lose_item_1)
    up = w.run(Upload(1, 3, items_for(3)))
    assert up.error is None and up.counts_sent == 1 and w.lost == 1
    assert w.sent.count("MISSION_ITEM_INT") == 4


def test_a_download_asks_again_for_a_lost_item():
    ap = MissionProtocol()
    assert Wire(ap).run(Upload(1, 3, items_for(3))).error is None
    lost = []

    def lose_item_2(m: Any) -> bool:
        if m.get_type() == "MISSION_ITEM_INT" and m.seq == 2 and not lost:
            lost.append(m)
            return True
        return False

    w = Wire(ap, lose_item_2)
    down = w.run(Download(1))
    assert [it.seq for it in down.items] == [0, 1, 2]
    assert w.sent.count("MISSION_REQUEST_INT") == 4 and w.sent[-1] == "MISSION_ACK"


def test_a_refused_item_ends_the_upload_with_the_autopilots_answer():
    """Item 1's latitude is out of range: the simulator refuses it (MAV_MISSION_INVALID) and
    keeps the mission it had; the client stops at once with that answer."""
    ap = MissionProtocol()
    assert Wire(ap).run(Upload(1, 2, items_for(2))).error is None
    before = ap.items

    def item(seq: int) -> Any:
        return waypoint(seq, 1_000_000_000 if seq == 1 else 398_000_000)

    w = Wire(ap)
    up = w.run(Upload(1, 3, item))
    assert up.error == f"upload refused (MISSION_ACK type {mav.MAV_MISSION_INVALID})"
    assert ap.items == before and w.t_s == 0.0  # answered at once, not timed out


def test_a_malformed_fence_is_refused():
    """Three vertices that say their polygon has four: refused, no fence stored."""
    ap = MissionProtocol()

    def vertex(seq: int) -> Any:
        return mav.MAVLink_mission_item_int_message(
            1, 1, seq, mav.MAV_FRAME_GLOBAL, 5001, 0, 1, 4.0, 0, 0, 0,
            398_000_000 + 1000 * seq, -840_000_000, 0.0, FENCE,
        )  # fmt: skip

    up = Wire(ap).run(Upload(1, 3, vertex, FENCE))
    assert up.error == f"upload refused (MISSION_ACK type {mav.MAV_MISSION_INVALID})"
    assert ap.fence == ()


def test_silence_gives_up_after_the_tries():
    """Nothing gets through: the count sent RETRIES times, STEP_TIMEOUT_S apart, then the
    error the operator has always read; a download gives up the same way."""
    w = Wire(MissionProtocol(), lambda m: True)
    up = w.run(Upload(1, 3, items_for(3)))
    assert up.error == f"no answer to MISSION_COUNT after {RETRIES} tries"
    assert w.sent == ["MISSION_COUNT"] * RETRIES
    assert w.t_s == pytest.approx(RETRIES * STEP_TIMEOUT_S, abs=RETRIES * DT_S)  # a tick late each
    down = Wire(MissionProtocol(), lambda m: True).run(Download(1))
    assert down.done and down.items is None


def test_an_answer_from_another_vehicle_is_not_ours():
    """A request from system 2 is ignored (but shows the link is alive); ours is answered."""
    up = Upload(1, 2, items_for(2))
    up.start(0.0)
    other = wire(mav.MAVLink_mission_request_int_message(255, 190, 0, 0), (2, 1))
    assert up.handle(other, 1.0) == [] and up.deadline_s == 1.0 + STEP_TIMEOUT_S
    ours = wire(mav.MAVLink_mission_request_int_message(255, 190, 1, 0), (1, 1))
    (item,) = up.handle(ours, 1.1)
    assert item.seq == 1


# ---- parameters and heartbeats --------------------------------------------------------------
def param_value(name: str, value: float, ptype: int, src: int = 1) -> Any:
    msg = mav.MAVLink_param_value_message(name.encode(), value, ptype, 100, 3)
    return wire(msg, (src, 1))


def test_a_parameter_set_is_read_back_and_asked_again_when_unanswered():
    x = ParamExchange(1, "FENCE_ALT_MAX", 200.0)
    (first,) = x.start(0.0)
    assert (first.get_type(), first.param_value) == ("PARAM_SET", 200.0)
    assert x.handle(param_value("FENCE_ALT_MIN", 50.0, 9), 0.5) == []  # another one's
    assert x.tick(0.9) == [] and x.deadline_s == 1.0  # others do not move the deadline
    (again,) = x.tick(1.0)
    assert again.get_type() == "PARAM_SET" and x.asked == 2
    x.handle(param_value("FENCE_ALT_MAX", 200.0, 9), 1.2)
    assert x.done and x.result == (200.0, 9)
    never = ParamExchange(1, "NO_SUCH")
    never.start(0.0)
    sent = [never.tick(t) for t in (1.0, 2.0, 3.0)]
    assert [len(s) for s in sent] == [1, 1, 0] and never.done and never.result is None


def test_listening_stops_at_the_autopilot_asked_for():
    x = Listen(2.0, only=3)
    (hb,) = x.start(10.0)
    assert (hb.type, hb.autopilot) == (mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID)
    gcs = wire(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS, 8, 0, 0, 0, 3), (3, 1))
    assert len(x.handle(gcs, 10.1)) == 1 and x.kinds == {}  # a ground station: not counted
    plane = mav.MAVLink_heartbeat_message(1, mav.MAV_AUTOPILOT_PX4, 0, 0, 4, 3)
    assert len(x.handle(wire(plane, (2, 1)), 10.2)) == 1  # another autopilot: noted
    assert x.handle(wire(plane, (3, 1)), 10.3) == [] and x.done
    assert x.found == [3] and x.kinds == {2: 12, 3: 12} and not x.signed
    late = Listen(1.0)
    late.start(0.0)
    assert [len(late.tick(t)) for t in (0.3, 0.6, 0.9, 1.2)] == [1, 1, 1, 0] and late.done


class PeerConnection:
    """A pymavlink-like connection (``mav.send``, ``recv_match``) whose far end is the
    simulator's protocol, on a fake clock that a receive with nothing waiting moves to its
    time-out: the driver end to end, no sockets."""

    def __init__(self, ap: MissionProtocol) -> None:
        self.ap, self.mav, self.t_s = ap, self, 0.0
        self.inbox: list[Any] = []

    def clock(self) -> float:
        return self.t_s

    def send(self, msg: Any) -> None:
        for out, _peer in self.ap.handle(wire(msg, GCS), "gcs", self.t_s):
            self.inbox.append(wire(out, AUTOPILOT))

    def recv_match(self, type: list[str], blocking: bool, timeout: float) -> Any:
        while self.inbox:
            m = self.inbox.pop(0)
            if m.get_type() in type:
                return m
        self.t_s += timeout
        return None


def test_the_driver_runs_a_transfer_over_a_connection():
    conn = PeerConnection(MissionProtocol())
    up = drive(conn, Upload(1, 5, items_for(5)), clock=conn.clock)
    assert up.error is None and len(conn.ap.items) == 5 and conn.t_s == 0.0
    down = drive(conn, Download(1), clock=conn.clock)
    assert [it.seq for it in down.items] == [0, 1, 2, 3, 4]
    silent = PeerConnection(MissionProtocol())
    silent.send = lambda msg: None  # type: ignore[method-assign]
    up = drive(silent, Upload(1, 2, items_for(2)), clock=silent.clock)
    assert up.error == f"no answer to MISSION_COUNT after {RETRIES} tries"
    assert silent.t_s == pytest.approx(RETRIES * STEP_TIMEOUT_S)
