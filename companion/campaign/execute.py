"""A campaign's runs, each through the in-memory engine in a Dask task; the table kept whole.

Each run (:func:`run_one`) flies one :class:`~companion.campaign.grid.RunPlan` as
``companion simulate`` does (:class:`companion.sim.inmemory.Engine`: the simulator and one
real companion per UAV, lockstepped, deterministic), in a temporary folder (``OUT/runs/ID``
with ``keep_runs``), and returns its row: what was run, the model-free ``metrics.json``
scalars and the per-run alert summary (:mod:`companion.campaign.measures`).

:func:`run_campaign` submits the runs not yet in ``OUT/runs.parquet`` to an embedded
``distributed.LocalCluster`` (worker processes, one thread each) or to a running scheduler,
with ``retries=1``: a run that raises is run once more. A worker that dies under a run gets
the run rescheduled once (the embedded scheduler's ``allowed-failures`` is 1; a running
scheduler keeps its own setting), then the run is a failure. A failed run is a row too, its
``error`` set and its measures empty. The table is rewritten (atomically) after every batch
of finished runs, so an interruption (Ctrl-C, SIGTERM) loses none of them; the cluster is
then shut down (its processes ended, its ports closed) before the interrupt goes on.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from companion.campaign.grid import Grid, RunPlan
from companion.campaign.measures import Scalar, run_columns
from companion.campaign.table import TABLE, read_rows, write_rows
from companion.contracts.errors import UserError

Task = Callable[[RunPlan, str, bool], dict]
"""Flies one plan: (plan, campaign folder, keep the run folder) -> its row."""


def run_one(plan: RunPlan, out: str, keep_runs: bool = False) -> dict[str, Scalar]:
    """Fly ``plan`` in the in-memory engine and measure it: its table row.

    Args:
        plan: the run.
        out: the campaign folder (its row's command line names ``out/runs/RUN_ID``).
        keep_runs: keep the run folder (truth, events, metrics.json) in ``out/runs/RUN_ID``.

    Raises:
        Exception: whatever the engine or the measures raise (Dask retries the run once).
    """
    from companion.group.faults import parse_faults
    from companion.link.config import LinkConfig
    from companion.report.episodes import episode_measures
    from companion.report.metrics import compute_metrics
    from companion.report.rundata import load_run
    from companion.sim.inmemory import Engine, EngineConfig

    wall0 = time.perf_counter()
    folder = Path(out) / "runs" / plan.run_id if keep_runs else None
    tmp = None
    if folder is None:
        tmp = tempfile.mkdtemp(prefix=f"campaign-{plan.run_id}-")
        folder = Path(tmp)
    try:
        cfg = EngineConfig(
            Path(plan.mission_path),
            folder,
            seed=plan.seed,
            params=dict(plan.sim_params),
            link=LinkConfig(profile=plan.profile),
            faults=parse_faults(plan.faults) if plan.faults else None,
        )
        with Engine(cfg) as engine:
            engine.run(plan.duration_s)
            engine.close()
        data = load_run(folder)
        metrics = compute_metrics(data)
        episodes = episode_measures(data)
        if keep_runs:
            (folder / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    head = plan.columns(Path(out))
    wall_s = round(time.perf_counter() - wall0, 3)
    return head | run_columns(metrics, episodes, head) | {"error": None, "wall_s": wall_s}


def error_row(plan: RunPlan, out: Path, exc: BaseException) -> dict[str, Scalar]:
    """The row of a run that failed twice: what was run and why it failed (one line)."""
    where = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    at = f" ({Path(where[0].filename).name}:{where[0].lineno})" if where else ""
    text = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
    return plan.columns(out) | {"error": text + at, "wall_s": None}


@dataclass(frozen=True)
class Outcome:
    """What a campaign did: the whole table after it, and how many runs of the grid were
    skipped (already in the table), run, failed, and not run (interrupted)."""

    rows: list[dict]
    skipped: int
    ran: int
    failed: int
    not_run: int


def run_campaign(
    grid: Grid,
    out: Path,
    *,
    workers: int = 2,
    scheduler: str | None = None,
    batch: int | None = None,
    retry_failed: bool = False,
    keep_runs: bool = False,
    progress: bool = True,
    task: Task = run_one,
    log: TextIO | None = None,
) -> Outcome:
    """Run the grid's runs that ``out/runs.parquet`` lacks; the table rewritten after every
    ``batch`` finished runs (default: the number of workers) and at the end.

    Args:
        grid: the runs (:func:`companion.campaign.grid.expand`).
        out: the campaign folder (created).
        workers: worker processes of the embedded cluster (one thread each).
        scheduler: a running scheduler's address (``tcp://HOST:PORT``) instead.
        batch: finished runs between two writes of the table.
        retry_failed: run again the runs whose row records an error.
        keep_runs: keep each run folder in ``out/runs/RUN_ID``.
        progress: show a progress bar (stderr).
        task: flies one plan (:func:`run_one`; tests pass another).
        log: where the counts are printed (default stdout).

    Raises:
        KeyboardInterrupt: on Ctrl-C or SIGTERM, after the finished rows are written and the
            cluster is shut down.
        UserError: the table is unreadable, the scheduler unreachable.
    """
    from tqdm import tqdm

    log = log or sys.stdout
    out.mkdir(parents=True, exist_ok=True)
    path = out / TABLE
    table = {r["run_id"]: r for r in read_rows(path)}
    todo = [
        p
        for p in grid.plans
        if p.run_id not in table or (retry_failed and table[p.run_id].get("error"))
    ]
    skipped = len(grid.plans) - len(todo)
    print(
        f"{len(grid.plans)} run{'s' * (len(grid.plans) != 1)} in the grid: {skipped} already "
        f"in {path} (skipped), "
        f"{len(todo)} to run",
        file=log,
        flush=True,
    )
    needed = {p.mission_path for p in todo}
    for file, text in grid.files.items():  # generated missions, flown from these files
        if str(file) in needed and (not file.exists() or file.read_text() != text):
            file.parent.mkdir(parents=True, exist_ok=True)
            file.write_text(text)
    ran = failed = 0
    if todo:
        batch = batch or workers
        pending: list[dict] = []

        def flush() -> None:
            for row in pending:
                table[row["run_id"]] = row
            pending.clear()
            write_rows(path, list(table.values()))

        with sigterm_as_interrupt(), cluster_client(workers, scheduler) as client:
            bar = tqdm(total=len(todo), unit="run", desc="campaign", disable=not progress)
            try:
                for row, error in _finished(client, todo, task, out, keep_runs):
                    ran += 1
                    failed += error
                    pending.append(row)
                    bar.update()
                    if len(pending) >= batch:
                        flush()
            finally:
                bar.close()
                if pending:
                    flush()
                if ran < len(todo):
                    print(
                        f"interrupted: {ran} of {len(todo)} runs finished and kept in {path}; "
                        "run the same command again to go on",
                        file=log,
                        flush=True,
                    )
    rows = [table[p.run_id] for p in grid.plans if p.run_id in table]
    return Outcome(rows, skipped, ran, failed, len(todo) - ran)


def _finished(
    client: Any, plans: list[RunPlan], task: Task, out: Path, keep_runs: bool
) -> Iterator[tuple[dict, bool]]:
    """(row, failed) of each run as it finishes. At most as many runs are in flight as the
    cluster has threads, so a worker that dies takes only its own run with it (Dask counts a
    death against every run the worker held). The runs in flight are cancelled when the
    caller stops early (an interrupt)."""
    from distributed import as_completed

    queue = list(reversed(plans))
    running: dict[Any, RunPlan] = {}
    done = as_completed()

    def refill() -> None:
        room = max(1, sum(client.nthreads().values())) - len(running)
        while queue and room > 0:
            p = queue.pop()
            key = f"campaign-{p.run_id}"
            fut = client.submit(task, p, str(out), keep_runs, key=key, retries=1, pure=False)
            running[fut] = p
            done.add(fut)
            room -= 1

    try:
        refill()
        for fut in done:
            plan = running.pop(fut)
            try:
                row, failed = fut.result(), False
            except Exception as exc:  # raised twice, or its worker died twice
                row, failed = error_row(plan, out, exc), True
            refill()
            yield row, failed
    finally:
        if running:
            client.cancel(list(running))


@contextlib.contextmanager
def cluster_client(workers: int, scheduler: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` on a running ``scheduler`` or on an embedded LocalCluster of
    ``workers`` processes (one thread each, no dashboard, ports chosen free on 127.0.0.1),
    closed on the way out (the embedded cluster's processes ended)."""
    import logging

    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="20s")
        except OSError as exc:
            raise UserError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            scheduler_port=0,
            dashboard_address=None,
            silence_logs=logging.ERROR,
            preload=[__name__],  # dask_setup below, in each worker process
        )
    try:
        client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        cluster.close()


def dask_setup(worker: object) -> None:
    """Dask's preload hook, run in each embedded worker process as it starts: ignore SIGINT
    there (Ctrl-C in a terminal reaches the whole process group; the campaign then shuts
    its cluster down itself, and the workers stop without a traceback each)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Within it, SIGTERM raises KeyboardInterrupt as Ctrl-C does (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)
