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
import os

import yaml

from companion.guidance.steering import Gains
from companion.mission.errors import MissionError
from companion.mission.model import Mission, Sensor
from companion.mission.sections.fence import parse_fence
from companion.mission.sections.origin import Frame, parse_origin
from companion.mission.sections.perimeter import build_loop, check_flyable, parse_perimeter
from companion.mission.sections.scenario import parse_scenario
from companion.mission.sections.steering import parse_steering
from companion.mission.sections.vehicles import check_rotation, parse_vehicles
from companion.mission.sections.wind import parse_wind
from companion.mission.yamlnodes import MapReader, check_tree, compose

MAX_FILE_BYTES = 1_000_000
SECTIONS = (
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
        at = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MissionError(file, "", f"YAML syntax error: {problem}", at) from None
    if root is None:
        raise MissionError(file, "", "the file is empty (expected a mission mapping)", 1)
    check_tree(root, file)
    return _mission(file, MapReader.of(root, file, ""))


def _mission(file: str, top: MapReader) -> Mission:
    """The top-level mapping, section by section (:mod:`companion.mission.sections`)."""
    top.done(SECTIONS)
    version = top.integer("version", lo=1, hi=1_000_000)
    if version != 1:
        raise top.error("version", f"unsupported mission version {version} (expected 1)")
    name = top.string("name")
    description = top.string("description", "")
    frame = Frame(file, parse_origin(top.map("origin")))
    perimeter = parse_perimeter(frame, top.map("perimeter"))
    wind = parse_wind(top.map("wind"))
    vehicles_map = top.map("vehicles")
    airspeed = vehicles_map.number("airspeed_m_s", lo=1.0, hi=200.0, what="an airspeed (m/s)")
    if wind.speed_m_s >= airspeed:
        raise top.error(
            "wind",
            f"wind speed {wind.speed_m_s:g} m/s must be below the airspeed {airspeed:g} m/s",
        )
    gains = parse_steering(top.map("steering")) if top.has("steering") else Gains()
    sensor_map = top.map("sensor")
    sensor_map.done(("footprint_radius_m",))
    sensor = Sensor(sensor_map.number("footprint_radius_m", lo=0.0, hi=10_000.0, lo_open=True))
    scenario = top.map("scenario") if top.has("scenario") else None
    duration, intruders = parse_scenario(frame, scenario)
    loop_shape = build_loop(top, perimeter)
    vehicles = parse_vehicles(frame, vehicles_map, loop_shape)
    mission = Mission(
        path=file,
        name=name,
        description=description,
        origin=frame.origin,
        perimeter=perimeter,
        wind=wind,
        vehicles=vehicles,
        gains=gains,
        sensor=sensor,
        intruders=intruders,
        duration_s=duration,
    )
    check_flyable(top, mission)
    check_rotation(vehicles_map, mission)
    return dataclasses.replace(mission, fence=parse_fence(frame, top, mission))
