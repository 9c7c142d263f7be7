"""Bad missions (issues 7 and 14): every file in ``tests/data/bad_missions/`` is refused by every
command that reads a mission (``simulate``, ``run``, ``upload``, ``fleet``) with exit status 2
and one line on stderr naming the file, the line and the field; no file runs code or
exhausts memory; and nothing reaches a vehicle.

One module fixture starts a real simulator (two vehicles), points every ``run --connect``
and ``upload --connect`` at it, runs all files x commands in process (``companion.commands.main``)
and a sample as real ``python -m companion`` processes under a small parent that measures
their peak RSS; the tests then check what was recorded and what the simulator saw.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

from companion.commands.main import main
from companion.contracts.errors import UserError
from companion.link.mission_protocol.vehicle import perimeter_for
from companion.mission import MissionError, load_mission
from sitl_model.codec import dialect
from sitl_model.testing import REPO, MavClient, SitlProcess

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

CORPUS = REPO / "tests" / "data" / "bad_missions"
FILES = sorted(CORPUS.iterdir())
COMMANDS = ("simulate", "run", "upload", "fleet")
MARKER = "pwned_by_bad_mission"  # what python_tag.yaml's payload would create in its cwd
SAMPLE = ("python_tag.yaml", "alias_bomb.yaml", "node_flood.yaml")  # also as real processes
RSS_LIMIT_MB = 300.0
GUIDED = 15

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


# A small parent for the real processes: runs each command line in turn and reports its
# status, output and the peak RSS of its children (RUSAGE_CHILDREN: only these commands).
PARENT = textwrap.dedent(
    """
    import json, os, resource, subprocess, sys
    jobs = json.loads(sys.stdin.read())
    env = dict(os.environ, PYTHONPATH=jobs["repo"])
    out = []
    for args in jobs["argv"]:
        p = subprocess.run([sys.executable, "-m", "companion", *args], cwd=jobs["cwd"],
                           env=env, capture_output=True, text=True, timeout=60)
        out.append([p.returncode, p.stdout, p.stderr])
    rss_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    print(json.dumps({"results": out, "max_rss_mb": rss_kb / 1024}))
    """
)


@dataclass
class Corpus:
    """Everything the module fixture recorded."""

    in_process: dict[tuple[str, str], Outcome]
    processes: dict[tuple[str, str], Outcome]
    max_rss_mb: float
    status_after: str  # the simulator's status line after all bad commands
    workdir: Path
    sitl: SitlProcess
    urls: list[str]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bad_missions")
    workdir = tmp / "cwd"  # the current directory of every command (the payload's target)
    workdir.mkdir()
    with SitlProcess(vehicles=2) as sitl:
        urls = [f"udpout:127.0.0.1:{sitl.port(i)}" for i in range(2)]
        inproc = {}
        with contextlib.chdir(workdir):
            for path in FILES:
                for command in COMMANDS:
                    out = tmp / "out" / f"{path.name}-{command}"
                    inproc[path.name, command] = in_process(command, path, urls, out)
        jobs = [(name, c) for name in SAMPLE for c in COMMANDS]
        cmd_lines = [argv(c, CORPUS / name, urls, tmp / "proc" / f"{name}-{c}") for name, c in jobs]
        parent = subprocess.run(
            [sys.executable, "-c", PARENT],
            input=json.dumps({"argv": cmd_lines, "cwd": str(workdir), "repo": str(REPO)}),
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert parent.returncode == 0, parent.stderr
        report = json.loads(parent.stdout)
        procs = {job: Outcome(*r) for job, r in zip(jobs, report["results"], strict=True)}
        yield Corpus(
            inproc, procs, report["max_rss_mb"], sitl.control("status"), workdir, sitl, urls
        )


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


def test_corpus_covers_every_file():
    assert len(FILES) >= 35
    assert {p.name for p in FILES} == set(EXPECTED)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_refused_with_one_line(corpus, path, command):
    expected = EXPECTED[path.name]
    if command == "upload":
        expected = UPLOAD_EXPECTED.get(path.name, expected)
    check_one_line(corpus.in_process[path.name, command], command, path, expected)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("name", SAMPLE)
def test_real_process_exits_2_with_one_line(corpus, name, command):
    path = CORPUS / name
    check_one_line(corpus.processes[name, command], command, path, EXPECTED[name])


def test_each_file_says_what_it_tests():
    no_comments = {"empty.yaml", "binary_garbage.yaml", "non_convex.plan", "non_convex.waypoints"}
    for path in FILES:
        if path.name not in no_comments:
            assert path.read_bytes().startswith(b"# BAD MISSION: "), path.name


def test_no_mission_runs_code(corpus, tmp_path):
    assert not (corpus.workdir / MARKER).exists()  # neither in process nor in the processes
    # the payload is live: an unsafe YAML load would have run it
    unsafe = "import sys, yaml; yaml.unsafe_load(open(sys.argv[1]).read())"
    control = subprocess.run(
        [sys.executable, "-c", unsafe, str(CORPUS / "python_tag.yaml")],
        cwd=tmp_path,
        capture_output=True,
        timeout=30,
    )
    assert control.returncode == 0, control.stderr
    assert (tmp_path / MARKER).exists()


def test_memory_stays_bounded(corpus):
    # alias bomb and a 20,000-node flood, through all four commands: peak RSS of any of them
    print(f"peak RSS of the bad-mission processes: {corpus.max_rss_mb:.0f} MB")
    assert 0 < corpus.max_rss_mb < RSS_LIMIT_MB


def counter(status: str, name: str) -> int:
    m = re.search(rf"\b{name}=(\d+)", status)
    assert m is not None, status
    return int(m.group(1))


def stored_mission_count(client: MavClient, sysid: int) -> int:
    client.send(dialect.MAVLink_mission_request_list_message(sysid, 1, 0))
    return client.match("MISSION_COUNT", cond=lambda m: m.get_srcSystem() == sysid).count


def test_nothing_reaches_the_vehicles(corpus):
    # not one MAVLink message (valid or not) arrived from any run or upload
    for name in ("rx", "bad", "peers"):
        assert counter(corpus.status_after, name) == 0, corpus.status_after
    clients = [MavClient(corpus.sitl.port(i)) for i in range(2)]
    try:
        for sysid, client in enumerate(clients, start=1):
            assert stored_mission_count(client, sysid) == 0
            hb = client.match("HEARTBEAT", cond=lambda m, s=sysid: m.get_srcSystem() == s)
            assert hb.custom_mode == GUIDED and hb.base_mode & 128  # as started: armed, GUIDED
        # the probes can see an upload: a good one to vehicle 2 only
        good = REPO / "missions" / "ellipse_6uav.yaml"
        with contextlib.redirect_stdout(io.StringIO()):
            status = main(
                ["upload", str(good), "--connect", corpus.urls[1], "--sysid", "2", "--points", "8"]
            )
        assert status == 0
        assert stored_mission_count(clients[1], 2) == 9  # home (ArduPilot's item 0) + 8
        assert stored_mission_count(clients[0], 1) == 0
        assert counter(corpus.sitl.control("status"), "peers") > 0
    finally:
        for c in clients:
            c.close()
