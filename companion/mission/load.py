"""Read a mission YAML file (version 1) into :class:`companion.mission.model.Mission`.

Safety: the file is read with a size cap, composed (never constructed) with PyYAML's safe
loader under a depth and node-count limit, and walked node by node: anchors/aliases,
non-standard tags, odd keys, overlong numbers, duplicate keys and unknown keys are refused,
so no file can run code, overflow the stack or expand into a huge object. Waypoints must be
the corners of a convex outline, each once, in order (the loop is their rounded hull). A fleet
with a battery section must be able to keep the patrol up indefinitely with its spares
(:mod:`companion.mission.endurance`). Every error is one :class:`MissionError` naming the
file, the field, its line and what was expected.
"""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np
import pymap3d
import yaml

from companion.core.fence import polygon_fault, signed_distance_m, support_polygon
from companion.core.loops import DEFAULT_EDGE_RADIUS_M, LoopError
from companion.core.outline import OUTLINE_TOL_M, OutlineFault, outline_fault
from companion.guidance.steering import Gains
from companion.mission.endurance import LOOP_SAMPLES, fleet_rotation
from companion.mission.errors import MissionError
from companion.mission.model import (
    CENTRE_FORMS,
    INTRUDER_KINDS,
    Battery,
    EllipsePerimeter,
    FenceSpec,
    Intruder,
    Mission,
    Origin,
    Perimeter,
    Pose,
    Sensor,
    Spare,
    Vehicles,
    Waypoint,
    WaypointPerimeter,
    WindSpec,
)
from companion.mission.yamlnodes import MapReader, check_tree, compose, integer_at

MAX_FILE_BYTES = 1_000_000
MAX_VEHICLES = 250
MAX_WAYPOINTS = 500
MAX_INTRUDERS = 1000
MAX_DISTANCE_M = 200_000.0
MAX_DURATION_S = 7 * 24 * 3600.0
FLYABLE_MARGIN = 0.8  # the loop may use at most this fraction of the turn-rate limit
MAX_FENCE_VERTICES = 100
DEFAULT_FENCE_MARGIN_M = 150.0  # how far outside the loop alerts can still be served
FENCE_ALT_MARGIN_M = 50.0  # default band: the fleet's altitudes -/+ this
FENCE_LOOP_SAMPLES = 720  # loop points checked against the fence


def load_mission(path: str | os.PathLike[str]) -> Mission:
    """Read and validate the mission file at ``path``.

    Raises:
        MissionError: unreadable, too large, malformed or invalid; the message names the
            file, field and line.
    """
    file = os.fspath(path)
    return parse_mission(read_text(file), file)


def read_text(path: str | os.PathLike[str]) -> str:
    """The UTF-8 text of a file of at most :data:`MAX_FILE_BYTES` (only that much is read).

    Raises:
        MissionError: unreadable, too large (at the line where the limit is crossed) or not
            UTF-8 (at the line of the first bad byte).
    """
    file = os.fspath(path)
    try:
        with open(file, "rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise MissionError(file, "", f"cannot read the file ({exc.strerror or exc})") from None
    if len(data) > MAX_FILE_BYTES:
        line = data.count(b"\n", 0, MAX_FILE_BYTES) + 1
        raise MissionError(file, "", f"file is larger than {MAX_FILE_BYTES} bytes", line)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MissionError(file, "", f"not UTF-8 text (byte {exc.start})", line) from None


def parse_mission(text: str, file: str = "<mission>") -> Mission:
    """Parse mission YAML ``text``; ``file`` is used in error messages."""
    try:
        root = compose(text, file)
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        raise MissionError(
            file, "", f"character {exc.character:#x} is not allowed in YAML text", line
        ) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MissionError(file, "", f"YAML syntax error: {problem}", line) from None
    if root is None:
        raise MissionError(file, "", "the file is empty (expected a mission mapping)", 1)
    check_tree(root, file)
    return _Parser(file).mission(MapReader.of(root, file, ""))


class _Parser:
    """Walks the top-level mapping section by section."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.origin: Origin | None = None

    def mission(self, top: MapReader) -> Mission:
        top.done(
            (
                "version",
                "name",
                "description",
                "origin",
                "perimeter",
                "wind",
                "vehicles",
                "steering",
                "sensor",
                "scenario",
                "fence",
            )
        )
        version = top.integer("version", lo=1, hi=1_000_000)
        if version != 1:
            raise top.error("version", f"unsupported mission version {version} (expected 1)")
        name = top.string("name")
        description = top.string("description", "")
        self.origin = self.parse_origin(top.map("origin"))
        perimeter = self.parse_perimeter(top.map("perimeter"))
        wind = self.parse_wind(top.map("wind"))
        vehicles_map = top.map("vehicles")
        airspeed = vehicles_map.number("airspeed_m_s", lo=1.0, hi=200.0, what="an airspeed (m/s)")
        if wind.speed_m_s >= airspeed:
            raise top.error(
                "wind",
                f"wind speed {wind.speed_m_s:g} m/s must be below the airspeed {airspeed:g} m/s",
            )
        gains = self.parse_steering(top.map("steering")) if top.has("steering") else Gains()
        sensor_map = top.map("sensor")
        sensor_map.done(("footprint_radius_m",))
        sensor = Sensor(sensor_map.number("footprint_radius_m", lo=0.0, hi=10_000.0, lo_open=True))
        scenario = top.map("scenario") if top.has("scenario") else None
        duration = 900.0
        intruders: tuple[Intruder, ...] = ()
        if scenario is not None:
            scenario.done(("duration_s", "intruders"))
            duration = scenario.number("duration_s", 900.0, lo=0.0, hi=MAX_DURATION_S, lo_open=True)
            if scenario.has("intruders"):
                intruders = self.parse_intruders(scenario)
        loop_shape = self.build_loop(top, perimeter)
        vehicles = self.parse_vehicles(vehicles_map, loop_shape)
        mission = Mission(
            path=self.file,
            name=name,
            description=description,
            origin=self.origin,
            perimeter=perimeter,
            wind=wind,
            vehicles=vehicles,
            gains=gains,
            sensor=sensor,
            intruders=intruders,
            duration_s=duration,
        )
        self.check_flyable(top, mission)
        self.check_rotation(vehicles_map, mission)
        return dataclasses.replace(mission, fence=self.parse_fence(top, mission))

    # ---- sections ------------------------------------------------------------------------
    def parse_origin(self, m: MapReader) -> Origin:
        m.done(("lat_deg", "lon_deg", "alt_m"))
        return Origin(
            m.number("lat_deg", lo=-89.0, hi=89.0, what="a latitude (deg)"),
            m.number("lon_deg", lo=-180.0, hi=180.0, what="a longitude (deg)"),
            m.number("alt_m", 0.0, lo=-500.0, hi=9000.0, what="an altitude (m)"),
        )

    def point(self, m: MapReader) -> tuple[float, float, float | None, float | None]:
        """north, east (m) of a point given as north_m/east_m or lat_deg/lon_deg."""
        local = m.has("north_m") or m.has("east_m")
        geo = m.has("lat_deg") or m.has("lon_deg")
        if local and geo:
            raise MissionError(
                self.file, m.path, "give either north_m/east_m or lat_deg/lon_deg, not both", m.line
            )
        if geo:
            lat = m.number("lat_deg", lo=-89.0, hi=89.0, what="a latitude (deg)")
            lon = m.number("lon_deg", lo=-180.0, hi=180.0, what="a longitude (deg)")
            o = self.origin
            n, e, _ = pymap3d.geodetic2ned(lat, lon, o.alt_m, o.lat_deg, o.lon_deg, o.alt_m)
            if max(abs(n), abs(e)) > MAX_DISTANCE_M:
                raise MissionError(
                    self.file,
                    m.path,
                    f"point is more than {MAX_DISTANCE_M:g} m from the origin",
                    m.line,
                )
            return float(n), float(e), lat, lon
        d = MAX_DISTANCE_M
        return (
            m.number("north_m", lo=-d, hi=d, what="a distance (m)"),
            m.number("east_m", lo=-d, hi=d, what="a distance (m)"),
            None,
            None,
        )

    def parse_perimeter(self, m: MapReader) -> Perimeter:
        m.done(
            ("sense", "ellipse", "waypoints", "corner_radius_m", "edge_radius_m", "smoothing_deg")
        )
        sense = m.string("sense", "clockwise", ("clockwise", "counterclockwise"))
        if m.has("ellipse") == m.has("waypoints"):
            raise MissionError(
                self.file, m.path, "give exactly one of 'ellipse' or 'waypoints'", m.line
            )
        if m.has("ellipse"):
            for key in ("corner_radius_m", "edge_radius_m", "smoothing_deg"):
                if m.has(key):
                    raise m.error(key, "only applies to a waypoint perimeter")
            e = m.map("ellipse")
            e.done(("centre", "semi_major_m", "semi_minor_m", "major_axis_bearing_deg"))
            c = e.map("centre") if e.has("centre") else None
            if c is not None:
                c.done(("north_m", "east_m", "lat_deg", "lon_deg"))
            cn, ce = self.point(c)[:2] if c is not None else (0.0, 0.0)
            shape: EllipsePerimeter | WaypointPerimeter = EllipsePerimeter(
                cn,
                ce,
                e.number("semi_major_m", lo=1.0, hi=100_000.0, what="a length (m)"),
                e.number("semi_minor_m", lo=1.0, hi=100_000.0, what="a length (m)"),
                e.number(
                    "major_axis_bearing_deg", 0.0, lo=-360.0, hi=360.0, what="a bearing (deg)"
                ),
            )
        else:
            nodes = m.seq("waypoints", MAX_WAYPOINTS)
            pts = []
            for i, node in enumerate(nodes):
                w = MapReader.of(node, self.file, f"{m.sub('waypoints')}[{i}]")
                w.done(("name", "north_m", "east_m", "lat_deg", "lon_deg"))
                n, e_, lat, lon = self.point(w)
                pts.append(Waypoint(w.string("name", f"WP{i + 1}"), n, e_, lat, lon))
            if len(pts) < 3:
                raise m.error("waypoints", f"expected at least 3 waypoints, got {len(pts)}")
            fault = outline_fault([complex(p.north_m, p.east_m) for p in pts])
            if fault is not None:
                raise self.outline_error(m.sub("waypoints"), nodes, fault)
            shape = WaypointPerimeter(
                tuple(pts),
                m.number("corner_radius_m", lo=0.0, hi=50_000.0, lo_open=True, what="a radius (m)"),
                m.number(
                    "edge_radius_m",
                    DEFAULT_EDGE_RADIUS_M,
                    lo=0.0,
                    hi=1e7,
                    lo_open=True,
                    what="a radius (m)",
                ),
                m.number("smoothing_deg", 1.0, lo=0.0, hi=10.0, what="an angle (deg)"),
            )
        return Perimeter(shape, clockwise=(sense == "clockwise"))

    def outline_error(self, path: str, nodes: list[yaml.Node], fault: OutlineFault) -> MissionError:
        """The error naming the waypoint that keeps the list from being a convex outline."""
        line = nodes[fault.index].start_mark.line + 1
        if fault.kind == "repeat":
            other = nodes[fault.other].start_mark.line + 1
            problem = (
                f"repeats {path}[{fault.other}] (line {other}, within {OUTLINE_TOL_M:g} m): "
                "list each corner once, the loop closes by itself"
            )
        elif fault.kind == "dent":
            problem = (
                f"lies {fault.depth_m:.0f} m inside the convex hull of the other waypoints, "
                "so the patrol loop (their rounded hull) would not pass it (expected the "
                "corners of a convex outline: remove it or move it outward)"
            )
        else:
            problem = (
                "is out of order round the outline, so the outline as listed crosses itself "
                "(expected the corners in order round the perimeter, either way)"
            )
        return MissionError(self.file, f"{path}[{fault.index}]", problem, line)

    def build_loop(self, top: MapReader, perimeter: Perimeter):
        pm = top.map("perimeter")
        try:
            return perimeter.loop()
        except LoopError as exc:
            key = "waypoints" if pm.has("waypoints") else "ellipse"
            if "edge radius" in str(exc):
                key = "edge_radius_m"
            elif "corner radius" in str(exc):
                key = "corner_radius_m"
            raise pm.error(key, str(exc)) from None

    def parse_wind(self, m: MapReader) -> WindSpec:
        m.done(("speed_m_s", "from_deg", "gust_std_m_s"))
        return WindSpec(
            m.number("speed_m_s", lo=0.0, hi=100.0, what="a wind speed (m/s)"),
            m.number("from_deg", 0.0, lo=-360.0, hi=360.0, what="a direction (deg)"),
            m.number("gust_std_m_s", 0.0, lo=0.0, hi=20.0, what="a gust strength (m/s rms)"),
        )

    def parse_steering(self, m: MapReader) -> Gains:
        m.done(
            (
                "centre_gain",
                "phase_gain",
                "centre_form",
                "track_gain",
                "speed_authority_m_s",
                "speed_tau_s",
                "xtrack_bw_rad_s",
                "xtrack_damping",
            )
        )
        d = Gains()
        return Gains(
            centre_gain=m.number("centre_gain", d.centre_gain, lo=0.0, hi=1e3, lo_open=True),
            phase_gain=m.number("phase_gain", d.phase_gain, lo=0.0, hi=1e3, lo_open=True),
            centre_form=m.string("centre_form", d.centre_form, CENTRE_FORMS),
            track_gain=m.number("track_gain", d.track_gain, lo=0.0, hi=1e3, lo_open=True),
            speed_authority_m_s=m.number(
                "speed_authority_m_s",
                d.speed_authority_m_s,
                lo=0.0,
                hi=10.0,
                what="an airspeed authority (m/s)",
            ),
            speed_tau_s=m.number(
                "speed_tau_s", d.speed_tau_s, lo=1.0, hi=600.0, what="a time constant (s)"
            ),
            xtrack_bw_rad_s=m.number(
                "xtrack_bw_rad_s", d.xtrack_bw_rad_s, lo=0.0, hi=2.0, what="a bandwidth (rad/s)"
            ),
            xtrack_damping=m.number(
                "xtrack_damping", d.xtrack_damping, lo=0.0, hi=10.0, lo_open=True
            ),
        )

    def parse_vehicles(self, m: MapReader, loop_shape) -> Vehicles:
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
            )
        )
        n = m.integer("count", lo=1, hi=MAX_VEHICLES)
        if m.has("sysids"):
            ids = [
                integer_at(node, self.file, f"{m.sub('sysids')}[{i}]", 1, 255)
                for i, node in enumerate(m.seq("sysids", MAX_VEHICLES))
            ]
            if len(ids) != n:
                raise m.error(
                    "sysids", f"expected {n} system ids (one per vehicle), got {len(ids)}"
                )
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
        initial = self.parse_initial(m, n, loop_shape)
        battery = self.parse_battery(m.map("battery")) if m.has("battery") else None
        spares = self.parse_spares(m, ids, battery) if m.has("spares") else ()
        return Vehicles(n, tuple(ids), airspeed, rate, alts, initial, battery, spares, step)

    def parse_battery(self, m: MapReader) -> Battery:
        """A battery: capacity, reserve, and the endurance or the cruise current."""
        m.done(("capacity_mah", "reserve_pct", "endurance_min", "cruise_current_a", "voltage_v"))
        cap = m.number("capacity_mah", lo=0.0, hi=1e7, lo_open=True, what="a capacity (mAh)")
        reserve = m.number("reserve_pct", 20.0, lo=0.0, hi=100.0, what="a reserve (%)")
        if reserve >= 100.0:
            raise m.error("reserve_pct", "must be below 100 % (expected the charge kept back)")
        volts = m.number("voltage_v", 12.6, lo=1.0, hi=100.0, what="a full pack's voltage (V)")
        if m.has("endurance_min") == m.has("cruise_current_a"):
            raise MissionError(
                self.file, m.path, "give exactly one of 'endurance_min' or 'cruise_current_a'",
                m.line,
            )  # fmt: skip
        if m.has("endurance_min"):
            what = "a flight time (min)"
            endurance = m.number("endurance_min", lo=0.0, hi=100_000.0, lo_open=True, what=what)
            return Battery(cap, reserve, endurance, volts)
        amps = m.number("cruise_current_a", lo=0.0, hi=10_000.0, lo_open=True, what="a current (A)")
        return Battery(cap, reserve, cap / 1000.0 / amps * 60.0, volts, amps)

    def parse_spares(
        self, m: MapReader, patrol_ids: list[int], battery: Battery | None
    ) -> tuple[Spare, ...]:
        """The spares: distinct system ids, none of the patrol's; where each waits."""
        patrol = m.sub("sysids") + ("" if m.has("sysids") else ", 1..count by default")
        taken = dict.fromkeys(patrol_ids, "")
        out: list[Spare] = []
        for i, node in enumerate(m.seq("spares", MAX_VEHICLES)):
            s = MapReader.of(node, self.file, f"{m.sub('spares')}[{i}]")
            s.done(("sysid", "ground", "holding", "turnaround_s", "battery"))
            sid = s.integer("sysid", lo=1, hi=255)
            if sid in taken:
                whose = f"repeats {taken[sid]}" if taken[sid] else f"is a patrol UAV's ({patrol})"
                raise s.error("sysid", f"system id {sid} {whose} (expected an id of its own)")
            taken[sid] = s.sub("sysid")
            if s.has("ground") == s.has("holding"):
                raise MissionError(
                    self.file, s.path, "give exactly one of 'ground' or 'holding'", s.line
                )
            if s.has("ground"):
                w = s.map("ground")
                w.done(("north_m", "east_m", "lat_deg", "lon_deg"))
                north, east = self.point(w)[:2]
                alt = None
            else:
                w = s.map("holding")
                w.done(("north_m", "east_m", "lat_deg", "lon_deg", "alt_m"))
                north, east = self.point(w)[:2]
                alt = w.number("alt_m", lo=0.0, hi=10_000.0, what="an altitude (m)")
            turnaround = s.number("turnaround_s", lo=0.0, hi=MAX_DURATION_S, what="a time (s)")
            own = self.parse_battery(s.map("battery")) if s.has("battery") else None
            if own is not None and battery is None:
                raise s.error(
                    "battery",
                    f"a spare's battery needs the fleet's too ({m.sub('battery')}), so the "
                    "relief rotation can be checked",
                )
            waits = "ground" if s.has("ground") else "holding"
            out.append(Spare(sid, waits, north, east, alt, turnaround, own))
        return tuple(out)

    def parse_initial(self, m: MapReader, n: int, loop_shape) -> tuple[Pose, ...]:
        if not m.has("initial"):
            raise m.error("initial", "missing required field (one of: line, poses)")
        init = m.map("initial")
        init.done(("line", "poses"))
        if init.has("line") == init.has("poses"):
            raise MissionError(
                self.file, init.path, "give exactly one of 'line' or 'poses'", init.line
            )
        if init.has("poses"):
            nodes = init.seq("poses", MAX_VEHICLES)
            if len(nodes) != n:
                raise init.error("poses", f"expected {n} poses (one per vehicle), got {len(nodes)}")
            poses = []
            for i, node in enumerate(nodes):
                p = MapReader.of(node, self.file, f"{init.sub('poses')}[{i}]")
                p.done(("north_m", "east_m", "lat_deg", "lon_deg", "heading_deg"))
                north, east = self.point(p)[:2]
                poses.append(Pose(north, east, p.number("heading_deg", lo=-360.0, hi=360.0)))
            return tuple(poses)
        line = init.map("line")
        line.done(("from", "to", "heading_deg"))
        a = line.map("from")
        a.done(("north_m", "east_m", "lat_deg", "lon_deg"))
        b = line.map("to")
        b.done(("north_m", "east_m", "lat_deg", "lon_deg"))
        (an, ae), (bn, be) = self.point(a)[:2], self.point(b)[:2]
        heading = line.number("heading_deg", lo=-360.0, hi=360.0, what="a heading (deg)")
        f = np.linspace(0.0, 1.0, n) if n > 1 else np.array([0.5])
        return tuple(Pose(float(an + x * (bn - an)), float(ae + x * (be - ae)), heading) for x in f)

    def parse_intruders(self, scenario: MapReader) -> tuple[Intruder, ...]:
        out: list[Intruder] = []
        seen: set[str] = set()
        for i, node in enumerate(scenario.seq("intruders", MAX_INTRUDERS)):
            m = MapReader.of(node, self.file, f"{scenario.sub('intruders')}[{i}]")
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
            north, east = self.point(m)[:2]
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

    def check_flyable(self, top: MapReader, mission: Mission) -> None:
        """The loop must need at most FLYABLE_MARGIN of the turn-rate limit."""
        pm = top.map("perimeter")
        patrol = mission.patrol
        need = patrol.max_required_turn_rate_rad_s()
        limit = mission.vehicles.max_turn_rate_rad_s
        if need > FLYABLE_MARGIN * limit:
            key = "corner_radius_m" if pm.has("waypoints") else "ellipse"
            hint = ""
            if pm.has("waypoints"):
                s0, b = mission.vehicles.airspeed_m_s, mission.wind.speed_m_s
                r_min = (s0 + b) ** 2 / (s0 * FLYABLE_MARGIN * limit)
                hint = f"; use a corner radius of at least {math.ceil(r_min)} m"
            raise pm.error(
                key,
                f"the loop needs turn rates up to {math.degrees(need):.1f} deg/s in this wind, "
                f"more than {FLYABLE_MARGIN:.0%} of the {math.degrees(limit):g} deg/s limit "
                f"(vehicles.max_turn_rate_deg_s){hint}",
            )

    def check_rotation(self, m: MapReader, mission: Mission) -> None:
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

    def parse_fence(self, top: MapReader, mission: Mission) -> FenceSpec:
        """The geofence: the ``fence`` section, or the default derived from the loop.

        Default polygon: the loop and the initial positions, grown by
        ``max(2 r, r_s) + margin_m`` where ``r = (s0 + wind) / omega_max`` is the turn radius
        at the fastest ground speed and ``r_s`` the sensor radius. A polygon given in the file
        must be simple and keep every loop point at least ``r`` inside, with every initial
        position inside. Default altitude band: the fleet's altitudes (spares included) -/+
        :data:`FENCE_ALT_MARGIN_M` (never below 0).
        """
        m = top.map("fence") if top.has("fence") else None
        if m is not None:
            m.done(("polygon", "margin_m", "min_alt_m", "max_alt_m"))
        margin = DEFAULT_FENCE_MARGIN_M
        if m is not None:
            margin = m.number("margin_m", margin, lo=0.0, hi=100_000.0, what="a distance (m)")
        alts = mission.vehicles.all_altitudes_m()
        lo_alt, hi_alt = max(0.0, min(alts) - FENCE_ALT_MARGIN_M), max(alts) + FENCE_ALT_MARGIN_M
        if m is not None:
            what = "an altitude (m above the origin)"
            lo_alt = m.number("min_alt_m", lo_alt, lo=-500.0, hi=20_000.0, what=what)
            hi_alt = m.number("max_alt_m", hi_alt, lo=-500.0, hi=20_000.0, what=what)
            if hi_alt <= lo_alt:
                raise m.error("max_alt_m", f"must be above min_alt_m ({lo_alt:g} m)")
            if min(alts) < lo_alt or max(alts) > hi_alt:
                key = "min_alt_m" if min(alts) < lo_alt else "max_alt_m"
                raise m.error(
                    key,
                    f"the vehicles fly at {min(alts):g} to {max(alts):g} m, outside the "
                    f"fence's {lo_alt:g} to {hi_alt:g} m (expected a band around them)",
                )
        v, patrol = mission.vehicles, mission.patrol
        turn_r = (v.airspeed_m_s + mission.wind.speed_m_s) / v.max_turn_rate_rad_s
        loop = patrol.point_at_phase(np.linspace(0.0, 2 * np.pi, FENCE_LOOP_SAMPLES, False))
        starts = np.array([complex(p.north_m, p.east_m) for p in v.initial])
        if m is None or not m.has("polygon"):
            offset = max(2.0 * turn_r, mission.sensor.footprint_radius_m) + margin
            poly = support_polygon(np.concatenate([loop, starts]), offset)
            verts = tuple(
                Waypoint(f"F{i + 1}", float(z.real), float(z.imag)) for i, z in enumerate(poly)
            )
            return FenceSpec(verts, lo_alt, hi_alt, margin, explicit=False)
        nodes = m.seq("polygon", MAX_FENCE_VERTICES)
        verts_l = []
        for i, node in enumerate(nodes):
            w = MapReader.of(node, self.file, f"{m.sub('polygon')}[{i}]")
            w.done(("name", "north_m", "east_m", "lat_deg", "lon_deg"))
            n, e_, lat, lon = self.point(w)
            verts_l.append(Waypoint(w.string("name", f"F{i + 1}"), n, e_, lat, lon))
        poly = np.array([complex(w.north_m, w.east_m) for w in verts_l])
        fault = polygon_fault(poly)
        if fault is not None:
            index, problem = fault
            if len(nodes) < 3:
                raise m.error("polygon", problem)
            line = nodes[index].start_mark.line + 1
            raise MissionError(self.file, f"{m.sub('polygon')}[{index}]", problem, line)
        room = signed_distance_m(loop, poly)
        k = int(np.argmin(room))
        if room[k] < turn_r:
            where = "inside" if room[k] >= 0 else "outside"
            raise m.error(
                "polygon",
                f"the patrol loop passes {abs(room[k]):.0f} m {where} the fence at north "
                f"{loop[k].real:.0f}, east {loop[k].imag:.0f} m (expected a polygon around the "
                f"loop with at least {math.ceil(turn_r)} m of room: one turn radius, "
                "(airspeed + wind) / max turn rate)",
            )
        inside = signed_distance_m(starts, poly) > 0
        if not inside.all():
            j = int(np.flatnonzero(~inside)[0])
            raise m.error(
                "polygon",
                f"vehicle {j + 1} starts outside the fence, at north {starts[j].real:.0f}, "
                f"east {starts[j].imag:.0f} m (vehicles.initial)",
            )
        return FenceSpec(tuple(verts_l), lo_alt, hi_alt, margin, explicit=True)
