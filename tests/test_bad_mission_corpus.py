"""Bad missions, unit tier: every file in ``tests/data/bad_missions/`` is refused by the mission
loader (and ``upload``'s perimeter reader) with the line, the field and the problem, and by
the commands that refuse a file before they open or start anything (``simulate``, ``fleet``)
with exit status 2 and one line. The commands that open links (``run``, ``upload``), real
processes and what reaches a vehicle are the integration tier (``test_bad_missions.py``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.link.mission_protocol.vehicle import perimeter_for
from companion.mission import load_mission
from tests.bad_missions import (
    CORPUS,
    EXPECTED,
    FILES,
    LOCAL_COMMANDS,
    UPLOAD_EXPECTED,
    check_one_line,
    expected_for,
    in_process,
)


def test_corpus_covers_every_file():
    assert len(FILES) >= 35
    assert {p.name for p in FILES} == set(EXPECTED)
    assert set(UPLOAD_EXPECTED) <= set(EXPECTED)


def test_each_file_says_what_it_tests():
    no_comments = {"empty.yaml", "binary_garbage.yaml", "non_convex.plan", "non_convex.waypoints"}
    for path in FILES:
        if path.name not in no_comments:
            assert path.read_bytes().startswith(b"# BAD MISSION: "), path.name


@pytest.mark.parametrize("reader", ["mission", "perimeter"])
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_the_reader_refuses_with_the_line_and_the_field(path: Path, reader: str):
    """``load_mission`` (and ``upload``'s reader, which also takes .plan and QGC WPL files)
    names FILE:LINE: FIELD: and the problem."""
    line, field, words = expected_for("upload" if reader == "perimeter" else "simulate", path)
    with pytest.raises(UserError) as info:  # MissionError, or the perimeter reader's own
        if reader == "perimeter":
            perimeter_for(path, 16)
        else:
            load_mission(path)
    text = str(info.value)
    assert text.startswith(f"{path}:{line}: " + (f"{field}: " if field else "")), text
    assert words in text


@pytest.mark.parametrize("command", LOCAL_COMMANDS)
@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_refused_with_one_line(tmp_path: Path, path: Path, command: str):
    outcome = in_process(command, path, ["udpout:127.0.0.1:9"], tmp_path / "out")
    check_one_line(outcome, command, path, expected_for(command, path))
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_the_corpus_is_where_the_table_says():
    assert CORPUS.is_dir() and all(p.parent == CORPUS for p in FILES)
