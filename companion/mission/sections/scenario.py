"""The mission's ``scenario`` section: how long it runs and its intruders (static, moving,
decoys)."""

from __future__ import annotations

from companion.mission.model import INTRUDER_KINDS, Intruder
from companion.mission.sections.origin import Frame
from companion.mission.yamlnodes import MapReader

MAX_INTRUDERS = 1000
MAX_DURATION_S = 7 * 24 * 3600.0
DEFAULT_DURATION_S = 900.0


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
    out: list[Intruder] = []
    seen: set[str] = set()
    for i, node in enumerate(scenario.seq("intruders", MAX_INTRUDERS)):
        m = MapReader.of(node, frame.file, f"{scenario.sub('intruders')}[{i}]")
        m.done(
            (
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
            )
        )
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
        out.append(Intruder(ident, kind, appear, north, east, vn, ve, vanish, after))
    return tuple(out)
