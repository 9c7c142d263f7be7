"""The bad-mission corpus (issues 7 and 14): what each file in ``tests/data/bad_missions/`` must
be refused with, and how a refusal is judged. Shared by the unit tier
(``test_bad_mission_corpus.py``: the loader and the commands that refuse before opening
anything) and the integration tier (``test_bad_missions.py``: the commands with links to a
real simulator, real processes, nothing reaching a vehicle).
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

from companion.commands.main import main
from companion.contracts.errors import UserError
from companion.link.mission_protocol.vehicle import perimeter_for
from companion.mission import MissionError, load_mission

REPO = Path(__file__).resolve().parents[1]
CORPUS = REPO / "tests" / "data" / "bad_missions"
FILES = sorted(CORPUS.iterdir())
COMMANDS = ("simulate", "run", "upload", "fleet")
LOCAL_COMMANDS = ("simulate", "fleet")  # refuse the file before they open or start anything
MARKER = "pwned_by_bad_mission"  # what python_tag.yaml's payload would create in its cwd
SAMPLE = ("python_tag.yaml", "alias_bomb.yaml", "node_flood.yaml")  # also as real processes
RSS_LIMIT_MB = 300.0

# file -> (line, field or "" when the problem is the file or its YAML, words in the message)
EXPECTED: dict[str, tuple[int, str, str]] = {
    "absurd_count.yaml": (26, "vehicles.count", "whole number from 1 to 250"),
    "absurd_size.yaml": (19, "perimeter.ellipse.semi_major_m", "<= 100000"),
    "airspeed_string.yaml": (28, "vehicles.airspeed_m_s", "expected an airspeed"),
    "alias_bomb.yaml": (4, "description[0]", "aliases are not allowed"),
    "binary_garbage.yaml": (2, "", "not UTF-8"),
    "bool_turn_rate.yaml": (32, "vehicles.max_turn_rate_deg_s", "got bool"),
    "collinear_waypoints.yaml": (25, "perimeter.waypoints", "collinear"),
    "control_character.yaml": (5, "", "character 0x0 is not allowed"),
    "corner_radius_unflyable.yaml": (22, "perimeter.corner_radius_m", "corner radius of at least"),
    "deeply_nested.yaml": (4, "", "nested deeper than 20 levels"),
    "duplicate_key.yaml": (27, "vehicles.count", "duplicate key"),
    "duplicate_sysids.yaml": (27, "vehicles.sysids", "distinct"),
    "duplicate_waypoints.yaml": (29, "perimeter.waypoints[4]", "repeats perimeter.waypoints[0]"),
    "ellipse_and_waypoints.yaml": (21, "perimeter", "exactly one of 'ellipse' or 'waypoints'"),
    "ellipse_too_tight.yaml": (18, "perimeter.ellipse", "turn rates up to"),
    "fence_altitude_inverted.yaml": (57, "fence.max_alt_m", "must be above min_alt_m"),
    "fence_below_fleet.yaml": (57, "fence.max_alt_m", "outside the fence's 50 to 120 m"),
    "fence_inside_loop.yaml": (57, "fence.polygon", "loop passes 100 m outside the fence"),
    "fence_self_crossing.yaml": (60, "fence.polygon[3]", "crosses edge 1-2"),
    "fence_too_few_vertices.yaml": (57, "fence.polygon", "at least 3 vertices"),
    "fence_too_tight.yaml": (57, "fence.polygon", "at least 80 m of room"),
    "fence_unknown_key.yaml": (57, "fence.radius_m", "unknown field"),
    "fence_vertex_string.yaml": (58, "fence.polygon[1].north_m", "expected a distance"),
    "empty.yaml": (1, "", "empty"),
    "huge_file.yaml": (2, "", "larger than 1000000 bytes"),
    "huge_integer.yaml": (26, "vehicles.count", "a number written with 5000 characters"),
    "inf_axis.yaml": (20, "perimeter.ellipse.semi_minor_m", "finite"),
    "latitude_out_of_range.yaml": (12, "origin.lat_deg", "latitude"),
    "merge_key.yaml": (13, "origin.<<", "aliases are not allowed"),
    "missing_airspeed.yaml": (26, "vehicles.airspeed_m_s", "missing required field"),
    "nan_axis.yaml": (19, "perimeter.ellipse.semi_major_m", "finite"),
    "negative_count.yaml": (26, "vehicles.count", "got int -3"),
    "newline_in_key.yaml": (23, "wind", "is not a field name"),
    "node_flood.yaml": (27, "", "more than 20000 YAML nodes"),
    "non_convex.plan": (2, "fileType", "unknown field"),
    "non_convex.waypoints": (2, "", "YAML syntax error"),
    "non_convex_waypoints.yaml": (27, "perimeter.waypoints[2]", "1500 m inside the convex hull"),
    "path_empty.yaml": (54, "scenario.intruders[0].path", "an empty path"),
    "path_infinite_wait.yaml": (55, "scenario.intruders[0].path[0].wait_s", "finite"),
    "path_leg_unknown_key.yaml": (55, "scenario.intruders[0].path[0].sped_m_s", "unknown field"),
    "path_missing.yaml": (49, "scenario.intruders[0].path", "missing required field"),
    "path_missing_speed.yaml": (
        56,
        "scenario.intruders[0].path[1].speed_m_s",
        "missing required field",
    ),
    "path_nan_speed.yaml": (55, "scenario.intruders[0].path[0].speed_m_s", "finite"),
    "path_on_static.yaml": (55, "scenario.intruders[0].path", "only a 'path' intruder"),
    "path_too_fast.yaml": (56, "scenario.intruders[0].path[1].speed_m_s", "<= 60, got 61"),
    "path_zero_leg.yaml": (56, "scenario.intruders[0].path[1]", "zero length"),
    "python_tag.yaml": (3, "name", "python/object/apply:os.system' is not allowed"),
    "self_intersecting_waypoints.yaml": (26, "perimeter.waypoints[1]", "out of order"),
    "syntax_error.yaml": (4, "", "YAML syntax error"),
    "too_few_sysids.yaml": (27, "vehicles.sysids", "expected 6 system ids"),
    "top_level_list.yaml": (2, "(top level)", "expected a mapping"),
    "two_waypoints.yaml": (25, "perimeter.waypoints", "at least 3 waypoints"),
    "unknown_intruder_kind.yaml": (50, "scenario.intruders[0].kind", "static, moving, decoy"),
    "unknown_top_key.yaml": (6, "colour", "unknown field"),
    "unknown_wind_key.yaml": (24, "wind.gusty", "unknown field"),
    "very_long_line.yaml": (16, "perimeter.sense", "expected one of clockwise"),
    "wind_above_airspeed.yaml": (23, "wind", "below the airspeed"),
    "wind_equals_airspeed.yaml": (23, "wind", "below the airspeed"),
    "wind_negative.yaml": (23, "wind.speed_m_s", "wind speed (m/s) >= 0"),
    "wrong_version.yaml": (4, "version", "unsupported mission version 2"),
    "zero_vehicles.yaml": (26, "vehicles.count", "whole number from 1"),
}
# ``upload`` reads QGroundControl .plan and QGC WPL 110 files itself (as perimeters)
UPLOAD_EXPECTED: dict[str, tuple[int, str, str]] = {
    "non_convex.plan": (49, "mission.items[2]", "1499 m inside the convex hull"),
    "non_convex.waypoints": (5, "seq 3", "1499 m inside the convex hull"),
}


@dataclass
class Outcome:
    """What one command printed and returned (``status`` None: the file was accepted)."""

    status: int | None
    stdout: str
    stderr: str


def argv(command: str, path: Path, urls: list[str], out: Path) -> list[str]:
    """The command line of ``command`` on ``path``, links pointed at the simulator."""
    connects = [a for u in urls for a in ("--connect", u)]
    return {
        "simulate": ["simulate", str(path), "--out", str(out)],
        "run": ["run", "--connect", urls[0], "--mission", str(path), "--insecure"],
        "upload": ["upload", str(path), *connects, "--listen-s", "0.5"],
        "fleet": ["fleet", str(path), "--out", str(out), "--duration", "1", "--no-progress"],
    }[command]


def accepted(command: str, path: Path) -> bool:
    """Would the command get past its input (so running it could fly or hang)?"""
    try:
        if command == "upload":
            perimeter_for(path, 16)
        else:
            load_mission(path)
    except (MissionError, UserError):
        return False
    return True


def in_process(command: str, path: Path, urls: list[str], out: Path) -> Outcome:
    """``companion.commands.main`` with stdout/stderr captured."""
    if accepted(command, path):  # a regression: do not start a patrol from the test
        return Outcome(None, "", "")
    err, std = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        status = main(argv(command, path, urls, out))
    return Outcome(status, std.getvalue(), err.getvalue())


def expected_for(command: str, path: Path) -> tuple[int, str, str]:
    """What ``command`` must say of ``path``: (line, field, words)."""
    if command == "upload":
        return UPLOAD_EXPECTED.get(path.name, EXPECTED[path.name])
    return EXPECTED[path.name]


def check_one_line(outcome: Outcome, command: str, path: Path, expected: tuple[int, str, str]):
    """Exit 2, nothing on stdout, one short line on stderr: file, line, field, problem."""
    line, field, words = expected
    assert outcome.status is not None, f"{command} accepted {path.name}"
    assert outcome.status == 2, outcome.stderr
    assert outcome.stdout == ""
    assert "Traceback" not in outcome.stderr
    assert outcome.stderr.count("\n") == 1 and outcome.stderr.endswith("\n"), outcome.stderr
    where = f"companion {command}: error: {path}:{line}: " + (f"{field}: " if field else "")
    assert outcome.stderr.startswith(where), outcome.stderr
    assert words in outcome.stderr
    assert len(outcome.stderr) < 400  # a clear line, whatever the file holds
