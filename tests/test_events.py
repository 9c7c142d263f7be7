"""The Agent's typed events (companion/agent/events.py): records as logged, and read back."""

from __future__ import annotations

import dataclasses
import json

import pytest

from companion.agent.events import (
    EVENT_TYPES,
    AgentEvent,
    AlertCleared,
    AlertNew,
    EventRecordError,
    ProsecutionEnd,
    Rejoined,
    parse_event,
)

SAMPLE = {  # a value per field annotation (annotations are strings: postponed evaluation)
    "float": 12.345,
    "int": 7,
    "str": "2-1",
    "bool": True,
    "str | None": "1-4",
    "int | None": 255,
    "float | None": 3.25,
}


def example(cls: type[AgentEvent], **given: object) -> AgentEvent:
    """An instance of ``cls`` with every field set to a sample of its type."""
    values = {f.name: SAMPLE[f.type] for f in dataclasses.fields(cls)}
    return cls(**(values | given))


@pytest.mark.parametrize("name", sorted(EVENT_TYPES))
def test_every_kind_round_trips_through_its_record_and_json(name):
    cls = EVENT_TYPES[name]
    ev = example(cls, t_s=101.5, sysid=3)
    rec = ev.to_record()
    assert list(rec)[:3] == ["t_s", "event", "sysid"] and rec["event"] == name == cls.name
    assert parse_event(rec) == ev
    assert parse_event(json.loads(json.dumps(rec))) == ev
    assert parse_event(rec | {"source": "companion"}) == ev  # the merged log's extra key


def test_names_are_unique_and_each_maps_to_its_class():
    names = [cls.name for cls in EVENT_TYPES.values()]
    assert len(names) == len(set(names)) == len(EVENT_TYPES)
    assert all(EVENT_TYPES[cls.name] is cls for cls in EVENT_TYPES.values())
    with pytest.raises(ValueError, match="taken"):

        @dataclasses.dataclass(frozen=True, kw_only=True)
        class Twin(AgentEvent):
            name = "plan"

        from companion.agent.events import _register

        _register(Twin)


def test_records_are_todays_dicts_key_for_key():
    new = AlertNew(
        t_s=12.3456, sysid=2, alert_id="2-1", detector_sysid=2, north_m=1.5, east_m=-2.25, own=True
    )
    assert json.dumps(new.to_record(), separators=(",", ":")) == (
        '{"t_s":12.346,"event":"alert_new","sysid":2,"alert_id":"2-1","detector_sysid":2,'
        '"north_m":1.5,"east_m":-2.25,"own":true}'
    )
    cleared = dict(t_s=5.0, sysid=1, alert_id="3-1", detector_sysid=4)
    assert "via" not in AlertCleared(**cleared).to_record()
    assert AlertCleared(**cleared, via="3-2").to_record()["via"] == "3-2"


def test_optional_fields_keep_their_place_and_are_left_out_when_none():
    head = dict(t_s=10.0, sysid=4, alert_id="1-1", planned_time_s=20.5)
    cancelled = ProsecutionEnd(**head, outcome="cancelled", by_sysid=255)
    confirmed = ProsecutionEnd(**head, outcome="confirmed", response_time_s=30.25)
    assert list(cancelled.to_record())[3:] == ["alert_id", "outcome", "by_sysid", "planned_time_s"]
    assert list(confirmed.to_record())[3:] == [
        "alert_id",
        "outcome",
        "planned_time_s",
        "response_time_s",
    ]
    direct = Rejoined(t_s=1.0, sysid=1, alert_id="a", in_slot=False, rejoin_s=0.0)
    assert "tol_m" not in direct.to_record()
    for ev in (cancelled, confirmed, direct):
        assert parse_event(ev.to_record()) == ev


def test_a_record_with_a_field_missing_or_unexpected_is_refused():
    rec = example(ProsecutionEnd, t_s=1.0, sysid=2).to_record()
    del rec["planned_time_s"]
    with pytest.raises(EventRecordError, match=r"prosecution_end event at t_s=1.0: missing "):
        parse_event(rec)
    with pytest.raises(EventRecordError, match="unexpected colour"):
        parse_event(example(Rejoined, t_s=1.0, sysid=2).to_record() | {"colour": "red"})
    assert issubclass(EventRecordError, ValueError)


def test_kinds_not_typed_here_stay_dicts():
    assert parse_event({"t_s": 1.0, "event": "link_up", "sysid": 1}) is None  # the Runner's
    assert parse_event({"t_s": 1.0, "event": "detection", "intruder": 1}) is None  # the sim's
    assert parse_event({"t_s": 1.0}) is None


def test_time_is_rounded_to_the_millisecond_as_logged():
    ev = Rejoined(t_s=7.00049, sysid=1, alert_id="a", in_slot=True, rejoin_s=3.0)
    assert ev.t_s == 7.0 and dataclasses.replace(ev).t_s == 7.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        ev.t_s = 8.0  # type: ignore[misc]
