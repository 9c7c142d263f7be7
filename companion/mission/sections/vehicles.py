"""The mission's ``vehicles`` section: the fleet (ids, airspeed, turn-rate limit, altitudes,
initial poses), its battery and its spares, which must keep the patrol up
(:mod:`companion.mission.endurance`)."""

from __future__ import annotations

import numpy as np

from companion.core.loops import LoopShape
from companion.mission.endurance import LOOP_SAMPLES, fleet_rotation
from companion.mission.errors import MissionError
from companion.mission.model import Battery, Mission, Pose, Spare, SpareWait, Vehicles
from companion.mission.sections.origin import Frame
from companion.mission.sections.scenario import MAX_DURATION_S
from companion.mission.yamlnodes import MapReader, integer_at

MAX_VEHICLES = 250
OPENINGS = ("battery", "staggered")  # Vehicles.opening


def parse_vehicles(frame: Frame, m: MapReader, loop_shape: LoopShape) -> Vehicles:
    m.done(
        (
            "count",
            "sysids",
            "airspeed_m_s",
            "max_turn_rate_deg_s",
            "altitude_m",
            "altitude_step_m",
            "initial",
            "battery",
            "spares",
            "opening",
        )
    )
    n = m.integer("count", lo=1, hi=MAX_VEHICLES)
    if m.has("sysids"):
        ids = [
            integer_at(node, frame.file, f"{m.sub('sysids')}[{i}]", 1, 255)
            for i, node in enumerate(m.seq("sysids", MAX_VEHICLES))
        ]
        if len(ids) != n:
            raise m.error("sysids", f"expected {n} system ids (one per vehicle), got {len(ids)}")
        if len(set(ids)) != n:
            raise m.error("sysids", "system ids must be distinct")
    else:
        ids = list(range(1, n + 1))
    airspeed = m.number("airspeed_m_s", lo=1.0, hi=200.0, what="an airspeed (m/s)")
    rate = m.number(
        "max_turn_rate_deg_s", lo=0.0, hi=180.0, lo_open=True, what="a turn rate (deg/s)"
    )
    alt = m.number("altitude_m", 100.0, lo=0.0, hi=10_000.0, what="an altitude (m)")
    step = m.number("altitude_step_m", 0.0, lo=0.0, hi=1000.0, what="a height (m)")
    alts = tuple(alt + i * step for i in range(n))
    initial = parse_initial(frame, m, n, loop_shape)
    battery = parse_battery(frame, m.map("battery")) if m.has("battery") else None
    spares = parse_spares(frame, m, ids, battery) if m.has("spares") else ()
    opening = m.string("opening", "battery", OPENINGS)
    if opening != "battery" and not spares:
        raise m.error("opening", f"opening {opening!r} staggers reliefs: it needs spares")
    return Vehicles(n, tuple(ids), airspeed, rate, alts, initial, battery, spares, step, opening)


def parse_battery(frame: Frame, m: MapReader) -> Battery:
    """A battery: capacity, reserve, and the endurance or the cruise current."""
    m.done(("capacity_mah", "reserve_pct", "endurance_min", "cruise_current_a", "voltage_v"))
    cap = m.number("capacity_mah", lo=0.0, hi=1e7, lo_open=True, what="a capacity (mAh)")
    reserve = m.number("reserve_pct", 20.0, lo=0.0, hi=100.0, what="a reserve (%)")
    if reserve >= 100.0:
        raise m.error("reserve_pct", "must be below 100 % (expected the charge kept back)")
    volts = m.number("voltage_v", 12.6, lo=1.0, hi=100.0, what="a full pack's voltage (V)")
    if m.has("endurance_min") == m.has("cruise_current_a"):
        raise MissionError(
            frame.file, m.path, "give exactly one of 'endurance_min' or 'cruise_current_a'",
            m.line,
        )  # fmt: skip
    if m.has("endurance_min"):
        what = "a flight time (min)"
        endurance = m.number("endurance_min", lo=0.0, hi=100_000.0, lo_open=True, what=what)
        return Battery(cap, reserve, endurance, volts)
    amps = m.number("cruise_current_a", lo=0.0, hi=10_000.0, lo_open=True, what="a current (A)")
    return Battery(cap, reserve, cap / 1000.0 / amps * 60.0, volts, amps)


def parse_spares(
    frame: Frame, m: MapReader, patrol_ids: list[int], battery: Battery | None
) -> tuple[Spare, ...]:
    """The spares: distinct system ids, none of the patrol's; where each waits."""
    patrol = m.sub("sysids") + ("" if m.has("sysids") else ", 1..count by default")
    taken = dict.fromkeys(patrol_ids, "")
    out: list[Spare] = []
    for i, node in enumerate(m.seq("spares", MAX_VEHICLES)):
        s = MapReader.of(node, frame.file, f"{m.sub('spares')}[{i}]")
        s.done(("sysid", "ground", "holding", "turnaround_s", "battery"))
        sid = s.integer("sysid", lo=1, hi=255)
        if sid in taken:
            whose = f"repeats {taken[sid]}" if taken[sid] else f"is a patrol UAV's ({patrol})"
            raise s.error("sysid", f"system id {sid} {whose} (expected an id of its own)")
        taken[sid] = s.sub("sysid")
        heading = 0.0
        if s.has("ground") == s.has("holding"):
            raise MissionError(
                frame.file, s.path, "give exactly one of 'ground' or 'holding'", s.line
            )
        if s.has("ground"):
            w = s.map("ground")
            w.done(("north_m", "east_m", "lat_deg", "lon_deg", "heading_deg"))
            north, east = frame.point(w)[:2]
            alt = None
            if w.has("heading_deg"):  # its runway: it takes off this way
                heading = w.number("heading_deg", lo=-360.0, hi=360.0, what="a heading (deg)")
        else:
            w = s.map("holding")
            w.done(("north_m", "east_m", "lat_deg", "lon_deg", "alt_m"))
            north, east = frame.point(w)[:2]
            alt = w.number("alt_m", lo=0.0, hi=10_000.0, what="an altitude (m)")
        turnaround = s.number("turnaround_s", lo=0.0, hi=MAX_DURATION_S, what="a time (s)")
        own = parse_battery(frame, s.map("battery")) if s.has("battery") else None
        if own is not None and battery is None:
            raise s.error(
                "battery",
                f"a spare's battery needs the fleet's too ({m.sub('battery')}), so the "
                "relief rotation can be checked",
            )
        waits: SpareWait = "ground" if s.has("ground") else "holding"
        out.append(Spare(sid, waits, north, east, alt, turnaround, own, heading))
    return tuple(out)


def parse_initial(
    frame: Frame, m: MapReader, n: int, loop_shape: LoopShape
) -> tuple[Pose, ...]:
    if not m.has("initial"):
        raise m.error("initial", "missing required field (one of: line, poses)")
    init = m.map("initial")
    init.done(("line", "poses"))
    if init.has("line") == init.has("poses"):
        raise MissionError(
            frame.file, init.path, "give exactly one of 'line' or 'poses'", init.line
        )
    if init.has("poses"):
        nodes = init.seq("poses", MAX_VEHICLES)
        if len(nodes) != n:
            raise init.error("poses", f"expected {n} poses (one per vehicle), got {len(nodes)}")
        poses = []
        for i, node in enumerate(nodes):
            p = MapReader.of(node, frame.file, f"{init.sub('poses')}[{i}]")
            p.done(("north_m", "east_m", "lat_deg", "lon_deg", "heading_deg"))
            north, east = frame.point(p)[:2]
            poses.append(Pose(north, east, p.number("heading_deg", lo=-360.0, hi=360.0)))
        return tuple(poses)
    line = init.map("line")
    line.done(("from", "to", "heading_deg"))
    a = line.map("from")
    a.done(("north_m", "east_m", "lat_deg", "lon_deg"))
    b = line.map("to")
    b.done(("north_m", "east_m", "lat_deg", "lon_deg"))
    (an, ae), (bn, be) = frame.point(a)[:2], frame.point(b)[:2]
    heading = line.number("heading_deg", lo=-360.0, hi=360.0, what="a heading (deg)")
    f = np.linspace(0.0, 1.0, n) if n > 1 else np.array([0.5])
    return tuple(Pose(float(an + x * (bn - an)), float(ae + x * (be - ae)), heading) for x in f)


def check_rotation(m: MapReader, mission: Mission) -> None:
    """With a battery section, the spares must keep the patrol up indefinitely
    (:mod:`companion.mission.endurance`); without one nothing is checked."""
    v = mission.vehicles
    if v.battery is None:
        return
    loop = mission.patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, LOOP_SAMPLES, False))
    rot = fleet_rotation(v, loop, mission.wind.speed_m_s)
    if not rot.sustainable:
        key = "spares" if m.has("spares") else "battery"
        raise m.error(key, f"the patrol cannot be kept up: {rot.why()}")
