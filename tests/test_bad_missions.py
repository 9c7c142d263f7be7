"""Bad missions, integration tier (issues 7 and 14): with links open to a real simulator,
``run`` and ``upload`` refuse every file in ``tests/data/bad_missions/`` with exit status 2 and
one line; a sample runs as real ``python -m companion`` processes (all four commands) whose
peak RSS stays bounded; no file runs code; nothing reaches a vehicle. The loader and the
commands that refuse before opening anything are the unit tier (``test_bad_mission_corpus.py``;
the table of what each file must be refused with: ``tests/bad_missions.py``).

One module fixture starts a real simulator (two vehicles), points every ``run --connect``
and ``upload --connect`` at it, runs those in process (``companion.commands.main``) and the
sample as real processes under a small parent that measures their peak RSS; the tests then
check what was recorded and what the simulator saw.
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
from sitl_model.codec import dialect
from sitl_model.testing import REPO, MavClient, SitlProcess
from tests.bad_missions import (
    COMMANDS,
    CORPUS,
    EXPECTED,
    FILES,
    MARKER,
    RSS_LIMIT_MB,
    SAMPLE,
    Outcome,
    argv,
    check_one_line,
    expected_for,
    in_process,
)

LINK_COMMANDS = ("run", "upload")  # the commands that open links to the autopilots

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

GUIDED = 15


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
                           env=env, capture_output=True, text=True, timeout=180)
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
                for command in LINK_COMMANDS:
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


@pytest.mark.parametrize("command", LINK_COMMANDS)
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_refused_with_one_line_with_links_open(corpus, path, command):
    """The commands that talk to autopilots refuse the file before a message leaves."""
    outcome = corpus.in_process[path.name, command]
    check_one_line(outcome, command, path, expected_for(command, path))


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("name", SAMPLE)
def test_real_process_exits_2_with_one_line(corpus, name, command):
    path = CORPUS / name
    check_one_line(corpus.processes[name, command], command, path, EXPECTED[name])


def test_no_mission_runs_code(corpus, tmp_path):
    assert not (corpus.workdir / MARKER).exists()  # neither in process nor in the processes
    # the payload is live: an unsafe YAML load would have run it
    unsafe = "import sys, yaml; yaml.unsafe_load(open(sys.argv[1]).read())"
    control = subprocess.run(
        [sys.executable, "-c", unsafe, str(CORPUS / "python_tag.yaml")],
        cwd=tmp_path,
        capture_output=True,
        timeout=120,
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
            argv = ["upload", str(good), "--connect", corpus.urls[1], "--sysid", "2"]
            status = main([*argv, "--points", "8", "--listen-s", "10"])
        assert status == 0
        assert stored_mission_count(clients[1], 2) == 9  # home (ArduPilot's item 0) + 8
        assert stored_mission_count(clients[0], 1) == 0
        assert counter(corpus.sitl.control("status"), "peers") > 0
    finally:
        for c in clients:
            c.close()
