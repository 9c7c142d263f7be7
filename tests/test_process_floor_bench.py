"""``bench/process_floor.py``: the synthetic step timed alone and in a lockstep of processes.

Only its plumbing is checked here (a short run prints every arrangement's row with a CPU
figure, and every worker process is gone after it); its figures are for an idle machine
(docs/speed.md) and are never asserted.
"""

from __future__ import annotations

import importlib.util
import multiprocessing as mp
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("process_floor", ROOT / "bench" / "process_floor.py")
bench = importlib.util.module_from_spec(_spec)
sys.modules["process_floor"] = bench
_spec.loader.exec_module(bench)

pytestmark = [pytest.mark.integration]


def test_the_step_is_the_same_work_wherever_it_runs():
    pool = bench.pool_of(0.01)
    assert len({id(c) for c in pool}) == len(pool)  # a permutation: every cell once
    assert bench.step(pool, 50, 3) == bench.step(list(pool), 50, 3)
    assert bench.step(pool, 50, 3) != bench.step(pool, 50, 4)  # each tick reads elsewhere


def test_a_short_run_prints_every_arrangement_and_leaves_no_worker(capsys):
    argv = ["--ticks", "30", "--pool-mb", "0.05", "--workers", "1,2", "--rounds", "1"]
    assert bench.main(argv) == 0
    rows = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("| ")][1:]
    names = [r.split("|")[1].strip() for r in rows]
    assert names == ["alone", "lockstep 1", "lockstep 1, no step", "lockstep 2",
                     "lockstep 2, no step"]  # fmt: skip
    for r in rows:
        step_ms, tick_ms = float(r.split("|")[2]), float(r.split("|")[4])
        assert 0.0 <= step_ms <= tick_ms + 1e-3
    assert mp.active_children() == []


@pytest.mark.parametrize("argv", [["--workers", "0"], ["--workers", "two"], ["--ticks", "0"]])
def test_bad_options_are_refused_before_any_process_starts(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        bench.main(argv)
    assert exc.value.code == 2 and "--" in capsys.readouterr().err
    assert mp.active_children() == []
