"""The events of the companion's side of its autopilot link, as typed records (pure).

Every event carries the latest vehicle time ``t_s`` (s, rounded to the millisecond as logged;
None before the first position) and the autopilot's ``sysid`` (None before its first
heartbeat); the class attribute :attr:`LinkEvent.name` is the ``event`` string written to
``events.jsonl``. :meth:`LinkEvent.to_record` gives exactly the dict the companion has always
logged: ``t_s``, ``event``, ``sysid``, then the fields in declaration order; a field whose
default is None is optional and left out when None. :func:`parse_link_event` reads a record
back (``parse_link_event(ev.to_record()) == ev``).

This module holds the base class and the events of the GUIDED targets
(:mod:`companion.link.targets`); the process's own events (``start``, ``authority``,
``take_control`` ...) subclass it in :mod:`companion.process.events`. The Agent's events are
:mod:`companion.agent.events` (same record shape, vehicle time never None).
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, fields
from typing import Any, ClassVar, TypeVar, dataclass_transform


class LinkEventRecordError(ValueError):
    """A record of a known event kind that does not carry that kind's fields."""


@dataclass(frozen=True, kw_only=True)
class LinkEvent:
    """What every link and process event carries: the latest vehicle time ``t_s`` (s,
    rounded to 1 ms, or None) and the autopilot's ``sysid`` (or None); subclasses add their
    fields and ``name``."""

    name: ClassVar[str] = ""
    t_s: float | None
    sysid: int | None

    def __post_init__(self) -> None:
        """Round the time to the millisecond, as the log always has (idempotent)."""
        if self.t_s is not None:
            object.__setattr__(self, "t_s", round(self.t_s, 3))

    @property
    def event(self) -> str:
        """The ``event`` string of the record (the class's :attr:`name`)."""
        return self.name

    def to_record(self) -> dict[str, Any]:
        """The JSON-ready dict logged to ``events.jsonl``: ``t_s``, ``event``, ``sysid``,
        then the fields in declaration order (optional ones left out when None)."""
        rec: dict[str, Any] = {"t_s": self.t_s, "event": self.event, "sysid": self.sysid}
        for f in fields(self)[2:]:
            value = getattr(self, f.name)
            if value is None and f.default is None:
                continue
            rec[f.name] = value
        return rec


E = TypeVar("E", bound=type[LinkEvent])

LINK_EVENT_TYPES: dict[str, type[LinkEvent]] = {}
"""Every typed link or process event kind with a fixed name, by its ``event`` name."""


@dataclass_transform(frozen_default=True, kw_only_default=True)
def link_event(cls: E) -> E:
    """An event kind: a frozen keyword-only dataclass, added to :data:`LINK_EVENT_TYPES`
    (a name used twice raises ``ValueError``)."""
    dataclass(frozen=True, kw_only=True)(cls)  # in place: no slots
    if not cls.name or cls.name in LINK_EVENT_TYPES:
        raise ValueError(f"event name {cls.name!r} of {cls.__name__} is empty or taken")
    LINK_EVENT_TYPES[cls.name] = cls
    return cls


def parse_link_event(
    record: dict[str, Any], types: dict[str, type[LinkEvent]] | None = None
) -> LinkEvent | None:
    """The typed event of a logged record (looked up in ``types``, default
    :data:`LINK_EVENT_TYPES`), or None for a kind not typed there.

    Raises:
        LinkEventRecordError: a known kind with a field missing or an unexpected key.
    """
    cls = (types if types is not None else LINK_EVENT_TYPES).get(record.get("event", ""))
    if cls is None:
        return None
    known = {f.name: f for f in fields(cls)}
    given = set(record) - {"event", "source"}
    missing = [n for n, f in known.items() if n not in given and f.default is MISSING]
    unexpected = sorted(given - set(known))
    if missing or unexpected:
        raise LinkEventRecordError(
            f"{cls.name} event at t_s={record.get('t_s')!r}: missing {missing}, "
            f"unexpected {unexpected}"
        )
    return cls(**{k: record[k] for k in given})


# ---- the GUIDED targets (companion/link/targets.py) ---------------------------------------
@link_event
class GuidedTargetsSent(LinkEvent):
    """The airspeed (m/s) and altitude (m above mean sea level, to 1 cm) asked of GUIDED."""

    name: ClassVar[str] = "guided_targets"
    airspeed_m_s: float
    alt_amsl_m: float


@link_event
class TargetUnsupported(LinkEvent):
    """The autopilot does not know a target command (MAV_CMD): the older one from now on."""

    name: ClassVar[str] = "target_unsupported"
    command: int


@link_event
class AirspeedDenied(LinkEvent):
    """The autopilot refused an airspeed (m/s): the mission's is held from now on."""

    name: ClassVar[str] = "airspeed_denied"
    airspeed_m_s: float
    mission_airspeed_m_s: float
