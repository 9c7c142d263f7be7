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
