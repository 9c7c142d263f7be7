"""The mission's ``scenario`` section: how long it runs and its intruders (static, moving,
decoys, and paths: straight legs in turn, each at its own speed, with waits).

A path intruder (``kind: path``) appears at ``north_m``/``east_m`` (or ``lat_deg``/``lon_deg``)
at ``appear_t_s`` and flies its ``path``: each leg a point (``north_m``/``east_m`` or
``lat_deg``/``lon_deg``), the ``speed_m_s`` it goes there at (> 0, at most 60 m/s) and an
optional ``wait_s`` it stays there; after the last leg it stays at the last point until its
``vanish_t_s``, if any. A leg of zero length is only a wait (it needs ``wait_s`` > 0).
"""

from __future__ import annotations

from companion.mission.errors import MissionError
from companion.mission.model import (
    INTRUDER_KINDS,
    MAX_INTRUDER_SPEED_M_S,
    ZERO_LEG_M,
    Intruder,
    Leg,
)
from companion.mission.sections.origin import Frame
from companion.mission.yamlnodes import MapReader

MAX_INTRUDERS = 1000
MAX_LEGS = 1000  # legs of one path intruder
MAX_DURATION_S = 7 * 24 * 3600.0
DEFAULT_DURATION_S = 900.0
INTRUDER_FIELDS = (
    "id",
    "kind",
    "appear_t_s",
    "north_m",
    "east_m",
    "lat_deg",
    "lon_deg",
    "velocity_north_m_s",
    "velocity_east_m_s",
    "vanish_t_s",
    "vanish_after_detection_s",
    "path",
)
LEG_FIELDS = ("north_m", "east_m", "lat_deg", "lon_deg", "speed_m_s", "wait_s")


def parse_scenario(frame: Frame, scenario: MapReader | None) -> tuple[float, tuple[Intruder, ...]]:
    """The run's duration (s; 900 without a scenario) and its intruders."""
    duration = DEFAULT_DURATION_S
    intruders: tuple[Intruder, ...] = ()
    if scenario is not None:
        scenario.done(("duration_s", "intruders"))
        duration = scenario.number(
            "duration_s", DEFAULT_DURATION_S, lo=0.0, hi=MAX_DURATION_S, lo_open=True
        )
        if scenario.has("intruders"):
            intruders = parse_intruders(frame, scenario)
    return duration, intruders


def parse_intruders(frame: Frame, scenario: MapReader) -> tuple[Intruder, ...]:
    """Every intruder of the ``intruders`` list, each checked (ids distinct)."""
    out: list[Intruder] = []
    seen: set[str] = set()
    for i, node in enumerate(scenario.seq("intruders", MAX_INTRUDERS)):
        m = MapReader.of(node, frame.file, f"{scenario.sub('intruders')}[{i}]")
        m.done(INTRUDER_FIELDS)
        ident = m.string("id", f"intruder-{i + 1}")
        if ident in seen:
            raise m.error("id", f"duplicate intruder id {ident!r}")
        seen.add(ident)
        kind = m.string("kind", "static", INTRUDER_KINDS)
        appear = m.number("appear_t_s", lo=0.0, hi=MAX_DURATION_S, what="a time (s)")
        north, east = frame.point(m)[:2]
        moving = kind == "moving"
        for key in ("velocity_north_m_s", "velocity_east_m_s"):
            if m.has(key) and not moving:
                raise m.error(key, "only a 'moving' intruder has a velocity")
        vn = m.number("velocity_north_m_s", 0.0, lo=-100.0, hi=100.0, what="a speed (m/s)")
        ve = m.number("velocity_east_m_s", 0.0, lo=-100.0, hi=100.0, what="a speed (m/s)")
        vanish = (
            m.number("vanish_t_s", lo=0.0, hi=MAX_DURATION_S, what="a time (s)")
            if m.has("vanish_t_s")
            else None
        )
        if vanish is not None and vanish <= appear:
            raise m.error("vanish_t_s", f"must be after appear_t_s ({appear:g} s)")
        after = None
        if kind == "decoy":
            after = m.number(
                "vanish_after_detection_s", 5.0, lo=0.0, hi=MAX_DURATION_S, what="a time (s)"
            )
        elif m.has("vanish_after_detection_s"):
            raise m.error("vanish_after_detection_s", "only a 'decoy' vanishes once detected")
        legs: tuple[Leg, ...] = ()
        if kind == "path":
            legs = parse_path(frame, m, complex(north, east))
        elif m.has("path"):
            raise m.error("path", "only a 'path' intruder has a path")
        out.append(Intruder(ident, kind, appear, north, east, vn, ve, vanish, after, legs))
    return tuple(out)


def parse_path(frame: Frame, m: MapReader, start_m: complex) -> tuple[Leg, ...]:
    """The legs of a path intruder's ``path`` (at least one), from ``start_m`` (complex m,
    where it appears): each a point, a speed (m/s) in (0, 60] and a wait (s, >= 0); a leg
    of zero length must wait."""
    nodes = m.seq("path", MAX_LEGS)
    if not nodes:
        raise m.error("path", "an empty path (expected at least one leg)")
    legs: list[Leg] = []
    here = start_m
    for j, node in enumerate(nodes):
        leg = MapReader.of(node, frame.file, f"{m.sub('path')}[{j}]")
        leg.done(LEG_FIELDS)
        north, east = frame.point(leg)[:2]
        speed = leg.number(
            "speed_m_s", lo=0.0, lo_open=True, hi=MAX_INTRUDER_SPEED_M_S, what="a speed (m/s)"
        )
        wait = leg.number("wait_s", 0.0, lo=0.0, hi=MAX_DURATION_S, what="a time (s)")
        there = complex(north, east)
        if abs(there - here) < ZERO_LEG_M and wait == 0.0:
            raise MissionError(
                frame.file,
                leg.path,
                "a leg of zero length (its point is where the one before ends) and no wait_s",
                leg.line,
            )
        legs.append(Leg(north, east, speed, wait))
        if abs(there - here) >= ZERO_LEG_M:  # as Intruder.knots: a shorter leg does not move
            here = there
    return tuple(legs)
