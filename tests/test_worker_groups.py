"""The unit tier's two workers keep each module on one worker (``--dist loadgroup`` and the
groups of ``tests/conftest.py``), so a module's fixtures (a 400-800 s in-memory run each) are
flown once, not once per worker.

This silently stopped holding twice: xdist's worker hook read the groups before the
conftest's hook had set them (the conftest's hook is now ``tryfirst``), and pytest 9.2's node
ids no longer take xdist's group suffix (pytest-dev/pytest-xdist#1386; the test extra pins
``pytest<9.2``). Nothing fails when it breaks, the tier only gets slower: this test runs two
small modules on two workers through the real conftest hook and reads where each test ran.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration  # starts a pytest with two worker processes

REPO = Path(__file__).resolve().parents[1]

MODULE = """
import pytest

@pytest.mark.parametrize("i", range(6))
def test_{name}(i):
    pass
"""


def test_each_module_runs_on_one_worker(tmp_path):
    for name in ("alpha", "beta"):
        (tmp_path / f"test_{name}.py").write_text(MODULE.format(name=name))
    (tmp_path / "conftest.py").write_text(
        "from tests.conftest import pytest_collection_modifyitems  # noqa: F401\n"
    )
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-n",
            "2",
            "--dist",
            "loadgroup",
            "-v",
            "-p",
            "no:cacheprovider",
            "-c",
            str(tmp_path / "pytest.ini"),
            str(tmp_path),
        ],
        cwd=tmp_path,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stdout + out.stderr
    workers: dict[str, set[str]] = defaultdict(set)
    for worker, module in re.findall(r"\[(gw\d)\] .*?PASSED .*?(test_\w+)\.py::", out.stdout):
        workers[module].add(worker)
    assert set(workers) == {"test_alpha", "test_beta"}, out.stdout
    assert all(len(w) == 1 for w in workers.values()), dict(workers)


TIMED = """
import os, time
import pytest
{mark}

@pytest.mark.parametrize("i", range({count}))
def test_{name}(i):
    start = time.monotonic()
    time.sleep(0.3)
    worker, nice = os.environ["PYTEST_XDIST_WORKER"], os.nice(0)
    with open(os.environ["TIMES_FILE"], "a") as f:
        f.write(f"{kind} {{worker}} {{nice}} {{start}} {{time.monotonic()}}\\n")
"""


@pytest.mark.alone  # reads its own niceness: a worker that is already niced could not tell
def test_alone_tests_go_first_to_the_first_two_workers_and_the_rest_run_niced_beside(tmp_path):
    """Three ``alone`` modules and three others on three workers, through the real conftest
    hooks: the alone tests run on gw0 and gw1 only, at the caller's priority; every other test
    runs niced, and some of them while alone tests still run."""
    from tests.alone_first import ALONE_WORKERS, NICE

    modules = {f"solo_{c}": "alone" for c in "abc"} | {f"many_{c}": "shared" for c in "abc"}
    for name, kind in modules.items():
        mark = "pytestmark = pytest.mark.alone" if kind == "alone" else ""
        text = TIMED.format(mark=mark, count=4, name=name, kind=kind)
        (tmp_path / f"test_{name}.py").write_text(text)
    (tmp_path / "conftest.py").write_text(
        "from tests.conftest import (  # noqa: F401\n"
        "    pytest_collection_modifyitems, pytest_runtest_setup, pytest_xdist_make_scheduler)\n"
    )
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    alone: free-running\n")
    times = tmp_path / "times.txt"
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "3", "--dist", "loadgroup", "-q",
         "-p", "no:cacheprovider", "-c", str(tmp_path / "pytest.ini"), str(tmp_path)],
        cwd=tmp_path,
        env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin", "TIMES_FILE": str(times)},
        capture_output=True,
        text=True,
        timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr
    rows = [line.split() for line in times.read_text().splitlines()]
    assert len(rows) == 4 * len(modules)
    base = os.nice(0)
    alone = [r for r in rows if r[0] == "alone"]
    shared = [r for r in rows if r[0] == "shared"]
    first = {f"gw{i}" for i in range(ALONE_WORKERS)}
    assert {r[1] for r in alone} <= first, alone
    assert all(int(r[2]) == base for r in alone), alone
    assert all(int(r[2]) == min(base + NICE, 19) for r in shared), shared
    last_alone_end = max(float(r[4]) for r in alone)
    assert min(float(r[3]) for r in shared) < last_alone_end  # beside them, not after
    for worker in first:  # a first worker took alone tests first, then only others
        kinds = [r[0] for r in sorted(rows, key=lambda r: float(r[3])) if r[1] == worker]
        assert kinds == sorted(kinds), (worker, kinds)  # "alone" < "shared"
