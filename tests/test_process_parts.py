"""The companion process's parts one by one (no sockets): its typed events give exactly the
records it has always logged, the GUIDED targets return what they send and log instead of
sending it, the one sender puts each effect where it belongs in order, messages are routed
by (source, type), and the Runner is a composition of small parts, not a stack of mixins."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.group.messages import Alert
from companion.link.events import AirspeedDenied, GuidedTargetsSent, TargetUnsupported
from companion.link.outbox import CommandLong, Statustext
from companion.link.targets import GuidedTargets
from companion.process import events as ev
from companion.process.events import parse_process_event
from companion.process.messages import message_key
from companion.process.runner import Runner
from companion.process.sender import Sender
from tests.test_house import attributes_per_class

REPO = Path(__file__).resolve().parents[1]


# ---- events: the records as logged ---------------------------------------------------------
@pytest.mark.parametrize(
    ("event", "record"),
    [
        (
            ev.TakeControl(t_s=12.34567, sysid=2, action="guided"),
            {"t_s": 12.346, "event": "take_control", "sysid": 2, "action": "guided"},
        ),
        (
            ev.TakeControl(t_s=12.0, sysid=2, action="offboard", attempt=3),
            {"t_s": 12.0, "event": "take_control", "sysid": 2, "action": "offboard", "attempt": 3},
        ),
        (
            ev.AuthorityChanged(
                t_s=None, sysid=None, before="commanding", after="no_link", autopilot_mode=None
            ),
            {
                "t_s": None,
                "event": "authority",
                "sysid": None,
                "before": "commanding",
                "after": "no_link",
                "autopilot_mode": None,
            },
        ),
        (
            ev.GroupSchedule(
                t_s=5.0,
                sysid=4,
                members=6,
                rate_hz=0.25,
                member_timeout_s=16.0,
                budget_bytes_s=142.5,
            ),
            {
                "t_s": 5.0,
                "event": "group_schedule",
                "sysid": 4,
                "members": 6,
                "rate_hz": 0.25,
                "member_timeout_s": 16.0,
                "budget_bytes_s": 142.5,
            },
        ),
        (
            ev.IssueRaised(t_s=7.0, sysid=1, issue="airspeed_off", text="airspeed 12.0"),
            {"t_s": 7.0, "event": "airspeed_off", "sysid": 1, "text": "airspeed 12.0"},
        ),
        (
            ev.IssueCleared(t_s=8.0, sysid=1, issue="airspeed_off", text="airspeed ok"),
            {"t_s": 8.0, "event": "airspeed_off_cleared", "sysid": 1, "text": "airspeed ok"},
        ),
        (ev.Disarmed(t_s=9.0, sysid=1), {"t_s": 9.0, "event": "disarmed", "sysid": 1}),
        (
            GuidedTargetsSent(t_s=1.0, sysid=3, airspeed_m_s=20.0, alt_amsl_m=350.0),
            {
                "t_s": 1.0,
                "event": "guided_targets",
                "sysid": 3,
                "airspeed_m_s": 20.0,
                "alt_amsl_m": 350.0,
            },
        ),
    ],
)
def test_a_process_event_is_the_record_it_always_was_and_reads_back(event, record):
    """Same keys in the same order (``t_s``, ``event``, ``sysid``, the fields), ``t_s`` to
    the millisecond or None, an optional field left out when None; read back equal."""
    got = event.to_record()
    assert json.dumps(got) == json.dumps(record)  # the order of the keys too
    assert parse_process_event(got, issues=frozenset({"airspeed_off"})) == event


def test_a_record_missing_a_field_is_refused():
    with pytest.raises(ValueError, match="reconnects"):
        parse_process_event({"t_s": 1.0, "event": "link_restored", "sysid": 1})
    assert parse_process_event({"t_s": 1.0, "event": "member_lost", "sysid": 1}) is None


# ---- the GUIDED targets: returned, not sent ------------------------------------------------
class Peer:
    sysid: int | None = 2


def test_guided_targets_return_what_they_send_and_log_in_order():
    targets = GuidedTargets(Peer(), 20.0, lambda: 350.0)
    r = targets.take_over(100.0)
    speed, alt, logged = r.out
    assert (speed.get_type(), speed.command, speed.param2) == ("COMMAND_INT", 43000, 20.0)
    assert (alt.get_type(), alt.command, alt.z) == ("COMMAND_INT", 43001, 350.0)
    assert logged == GuidedTargetsSent(t_s=100.0, sysid=2, airspeed_m_s=20.0, alt_amsl_m=350.0)
    assert r.airspeed_m_s == 20.0 and not r.denied
    assert targets.take_over(None).out == ()  # no vehicle time yet: with the first step

    r = targets.command_speed(23.456, 101.0)
    assert [m.param2 for m in r.out] == [pytest.approx(23.46)] and r.airspeed_m_s == 23.46
    assert targets.command_speed(25.0, 101.5).out == ()  # at most every second

    r = targets.on_ack(43000, mav.MAV_RESULT_DENIED, True, 102.0)
    denied, text, back = r.out
    assert denied == AirspeedDenied(
        t_s=102.0, sysid=2, airspeed_m_s=23.46, mission_airspeed_m_s=20.0
    )
    assert text == Statustext(
        "companion 2: airspeed 23.5 m/s refused; holding 20.0, phase kept by steering only", 4
    )
    assert (back.command, back.param2) == (43000, 20.0)
    assert r.denied and r.airspeed_m_s == 20.0 and not targets.free

    r = targets.on_ack(43000, mav.MAV_RESULT_UNSUPPORTED, True, 103.0)
    unsupported, older = r.out
    assert unsupported == TargetUnsupported(t_s=103.0, sysid=2, command=43000)
    assert (older.get_type(), older.command, older.param2) == ("COMMAND_LONG", 178, 20.0)
    assert targets.on_ack(43000, mav.MAV_RESULT_UNSUPPORTED, True, 104.0).out == ()  # once


# ---- the one sender ------------------------------------------------------------------------
class Recorder:
    """A link, a group and an event log writing into one list."""

    def __init__(self) -> None:
        self.seen: list[tuple[str, object]] = []

    def send(self, msg) -> None:
        self.seen.append(("link", msg.get_type()))

    def statustext(self, text: str, severity: int = 5) -> None:
        self.seen.append(("statustext", (text, severity)))

    def command_long(self, command: int, *params: float) -> None:
        self.seen.append(("command_long", (command, *params)))

    def send_state(self, state) -> None:
        self.seen.append(("group_state", state))

    def send_alert(self, alert) -> None:
        self.seen.append(("group_alert", alert.alert_id))

    def write(self, record: dict) -> None:
        self.seen.append(("event", record["event"]))


def test_the_sender_puts_each_effect_where_it_belongs_in_order():
    rec = Recorder()
    sender = Sender(rec, rec)  # type: ignore[arg-type]
    alert = Alert("a1", 10 + 20j, 3, 1.0, "new")
    with pytest.raises(RuntimeError):  # nothing goes to a group not yet opened
        sender.send([alert])
    sender.group = rec
    sender.send(
        [
            ev.Resumed(t_s=1.0, sysid=2),
            Statustext("hello", 4),
            alert,
            CommandLong.of(176, 1, 15),
            mav.MAVLink_param_request_read_message(2, 1, b"ROLL_LIMIT_DEG", -1),
        ]
    )
    assert rec.seen == [
        ("event", "resumed"),
        ("statustext", ("hello", 4)),
        ("group_alert", "a1"),
        ("command_long", (176, 1, 15)),
        ("link", "PARAM_REQUEST_READ"),
    ]


# ---- routing ------------------------------------------------------------------------------
class Routed:
    sysid: int | None = 2

    def is_autopilot(self, m) -> bool:
        return m.get_srcSystem() == 2 and m.get_srcComponent() == 1


def wire(msg, src_system: int, src_component: int):
    enc = mav.MAVLink(None, srcSystem=src_system, srcComponent=src_component)
    (out,) = mav.MAVLink(None).parse_buffer(msg.pack(enc))
    return out


def test_messages_are_routed_by_source_and_type():
    hb = mav.MAVLink_heartbeat_message(1, 3, 0, 15, 4, 3)
    cam = mav.MAVLink_camera_tracking_geo_status_message(1, *[0] * 12)
    assert message_key(Routed(), wire(hb, 2, 1)) == (False, "HEARTBEAT")
    assert message_key(Routed(), wire(cam, 2, 100)) == (True, "CAMERA_TRACKING_GEO_STATUS")
    assert message_key(Routed(), wire(hb, 3, 1)) is None  # another vehicle
    assert message_key(Routed(), wire(hb, 2, 190)) is None  # a ground station on its system
    nobody = Routed()
    nobody.sysid = None
    assert message_key(nobody, wire(hb, 2, 1)) is None  # no autopilot heard yet


# ---- the shape -----------------------------------------------------------------------------
def test_the_runner_is_a_composition_of_small_parts_not_mixins():
    assert Runner.__mro__ == (Runner, object)
    counts = {
        f"{p.name}:{name}": len(names)
        for p in sorted((REPO / "companion" / "process").glob("*.py"))
        for name, names in attributes_per_class(p).items()
    }
    assert counts["runner.py:Runner"] > 10  # the check sees the Runner's parts
    assert {k: n for k, n in counts.items() if n > 20} == {}
