"""``companion campaign``: the spec refused with one line, the grid's stable ids, and a tiny
campaign on Dask whose rows are the measures of the same runs flown alone.

Tiers: the spec and grid tests are unit tests (no flight). The campaign tests fly the
ellipse for 60 simulated s per run (about 3 s of CPU each) on an embedded LocalCluster
(worker processes, scheduler in this process): ``contract`` and ``slow``. The test that starts
``dask scheduler`` and ``dask worker`` as processes, and the one that stops a campaign with
SIGTERM, are ``integration``.
"""

from __future__ import annotations

import contextlib
import json
import os
import shlex
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from companion.campaign.grid import expand
from companion.campaign.measures import DIAGNOSTICS, alert_columns
from companion.campaign.spec import load_spec
from companion.campaign.table import TABLE, read_rows
from companion.commands.main import main
from sitl_model.params import Params

ROOT = Path(__file__).resolve().parents[1]
ELLIPSE = ROOT / "missions" / "ellipse_6uav.yaml"
TINY = f"""\
missions: [{ELLIPSE}]
scenarios: [nominal, gusts, {{name: windy, sim_params: {{SIM_WIND_SPD: 7}}, profile: bank}}]
seeds: [1]
duration_s: 60
"""
VARYING = ("wall_s", "command")  # the only columns that differ between two campaigns


def write_spec(folder: Path, text: str, name: str = "spec.yaml") -> Path:
    """A spec file ``name`` in ``folder`` with ``text``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


def refused(capsys: pytest.CaptureFixture[str], spec: Path) -> str:
    """Run ``companion campaign SPEC``; assert exit 2 and one line on stderr; that line."""
    assert main(["campaign", str(spec), "--out", str(spec.parent / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"companion campaign: error: {spec}:"), err
    return err


# ---- the spec --------------------------------------------------------------------------------
def test_a_missing_mission_is_named_with_the_spec_file_line_and_field(tmp_path, capsys):
    spec = write_spec(tmp_path, "missions:\n  - nowhere.yaml\nscenarios: [nominal]\nseeds: [0]\n")
    err = refused(capsys, spec)
    assert f"{spec}:2: missions[0]: no such mission file 'nowhere.yaml'" in err


def test_an_unknown_scenario_lists_the_matrix(tmp_path, capsys):
    spec = write_spec(tmp_path, f"missions: [{ELLIPSE}]\nscenarios: [nominal, gale]\nseeds: [0]\n")
    err = refused(capsys, spec)
    assert f"{spec}:2: scenarios[1]: unknown scenario 'gale'" in err
    assert "nominal, wind_off" in err


def test_an_unknown_simulator_parameter_is_refused_at_its_line(tmp_path, capsys):
    text = f"missions: [{ELLIPSE}]\nscenarios:\n  - name: x\n    sim_params:\n      SIM_WNID: 3\n"
    err = refused(capsys, write_spec(tmp_path, text + "seeds: [0]\n"))
    assert ":5: scenarios[0].sim_params.SIM_WNID: unknown parameter 'SIM_WNID'" in err


@pytest.mark.parametrize(
    ("body", "where"),
    [
        ("seeds: [0, one]", ":3: seeds[1]: expected a whole number"),
        ("seeds: {start: 0, count: 0}", ":3: seeds.count: expected a whole number from 1"),
        ("seeds: [0]\nduration_s: -5", ":4: duration_s: expected a number > 0"),
        ("seeds: [0]\nduration_s: long", ":4: duration_s: expected a number"),
        ("seeds: [0]\nfaults: loss=lots", ":4: faults: 'loss=lots': loss='lots' is not a number"),
        ("seeds: [0]\nseed: 3", ":4: seed: unknown field (expected one of: missions,"),
        ("seeds: 7", ":3: seeds: expected a list of seeds or {start: S, count: N}"),
    ],
)
def test_bad_types_name_the_field(tmp_path, capsys, body, where):
    spec = write_spec(tmp_path, f"missions: [{ELLIPSE}]\nscenarios: [nominal]\n{body}\n")
    assert where in refused(capsys, spec)


def test_a_bad_mission_file_is_named_inside_the_spec_error(tmp_path, capsys):
    write_spec(tmp_path / "m", "version: 1\nname: broken\n", "broken.yaml")
    spec = write_spec(tmp_path, "missions: [m/broken.yaml]\nscenarios: [nominal]\nseeds: [0]\n")
    err = refused(capsys, spec)
    assert f"{spec}:1: missions[0]: bad mission: {tmp_path / 'm' / 'broken.yaml'}" in err


# ---- the grid --------------------------------------------------------------------------------
def test_the_grid_is_missions_x_scenarios_x_seeds_with_ids_stable_and_tied_to_the_mission(
    tmp_path,
):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "e.yaml").write_bytes(ELLIPSE.read_bytes())
    text = "missions: [m/e.yaml]\nscenarios: [nominal, wind_step]\nseeds: {start: 4, count: 3}\n"
    spec = write_spec(tmp_path, text)
    grid = expand(load_spec(spec, Params), tmp_path / "out", Params)
    assert [(p.scenario, p.seed) for p in grid.plans] == [
        (s, k) for s in ("nominal", "wind_step") for k in (4, 5, 6)
    ]
    again = expand(load_spec(spec, Params), tmp_path / "elsewhere", Params)
    assert [p.run_id for p in again.plans] == [p.run_id for p in grid.plans]
    assert len({p.run_id for p in grid.plans}) == 6
    step = grid.plans[3]  # the mission's own 900 s: the wind step at 450 s (bench/robustness.py)
    assert step.run_id.startswith("ellipse_6uav.wind_step.s4.")
    assert dict(step.sim_params) == {"SIM_WSTEP_T": 450.0, "SIM_WSTEP_SPD": 3.0}
    assert step.duration_s == 900.0 and step.profile == "auto"
    (tmp_path / "m" / "e.yaml").write_text(ELLIPSE.read_text() + "# edited\n")
    edited = expand(load_spec(spec, Params), tmp_path / "out", Params)
    assert not {p.run_id for p in edited.plans} & {p.run_id for p in grid.plans}


def test_the_bench_spec_is_the_robustness_matrix_on_the_ellipse():
    """bench/campaign_ellipse.yaml flies what ``bench/robustness.py --engine memory`` flies."""
    from companion.campaign.scenarios import SCENARIOS

    grid = expand(load_spec(ROOT / "bench" / "campaign_ellipse.yaml", Params), ROOT, Params)
    assert [p.scenario for p in grid.plans] == [s.name for s in SCENARIOS]
    for plan, sc in zip(grid.plans, SCENARIOS, strict=True):
        assert dict(plan.sim_params) == sc.params(5.0, 180.0, 900.0)
        assert (plan.profile, plan.seed, plan.duration_s) == (sc.profile, 0, 900.0)
        assert plan.mission_path == str(ELLIPSE)


def test_generated_missions_are_written_under_out_and_flown_from_there(tmp_path):
    spec = write_spec(
        tmp_path,
        "generated: {seeds: [3, 8], kind: decoy, max_loop_km: 3}\nscenarios: [gusts]\nseeds: [0]\n",
    )
    grid = expand(load_spec(spec, Params), tmp_path / "out", Params)
    assert [p.generator_seed for p in grid.plans] == [3, 8]
    assert {p.generator_kind for p in grid.plans} == {"decoy"}
    for p in grid.plans:
        assert Path(p.mission_path) in grid.files
        assert Path(p.mission_path).parent == (tmp_path / "out" / "missions").resolve()


def test_show_prints_the_simulate_command_line_of_a_run(tmp_path, capsys):
    spec = write_spec(tmp_path, TINY)
    grid = expand(load_spec(spec, Params), tmp_path / "out", Params)
    windy = grid.plans[2]
    out = tmp_path / "out"
    assert main(["campaign", str(spec), "--out", str(out), "--show", windy.run_id]) == 0
    argv = shlex.split(capsys.readouterr().out)
    assert argv == [
        "companion", "simulate", str(ELLIPSE), "--out", str(out / "runs" / windy.run_id),
        "--duration", "60", "--seed", "1", "--profile", "bank", "--param", "SIM_WIND_SPD=7",
    ]  # fmt: skip
    assert main(["campaign", str(spec), "--show", "nope"]) == 2
    assert "no run 'nope' in the grid" in capsys.readouterr().err


# ---- a tiny campaign on the embedded cluster ------------------------------------------------
@pytest.fixture(scope="module")
def tiny_campaign(tmp_path_factory) -> tuple[Path, Path, str]:
    """The TINY spec (3 runs of 60 s) run on a LocalCluster of 2 workers: (spec, OUT, what
    it printed)."""
    import io
    from contextlib import redirect_stdout

    folder = tmp_path_factory.mktemp("campaign")
    spec = write_spec(folder, TINY)
    out = folder / "out"
    buf = io.StringIO()
    with redirect_stdout(buf):
        code = main(["campaign", str(spec), "--out", str(out), "--no-progress"])
    assert code == 0, buf.getvalue()
    return spec, out, buf.getvalue()


@pytest.mark.contract
@pytest.mark.slow
def test_a_campaigns_rows_are_the_measures_of_the_same_runs_flown_alone(tiny_campaign):
    from companion.report.episodes import episode_measures
    from companion.report.rundata import load_run

    _, out, printed = tiny_campaign
    assert "3 runs in the grid: 0 already in" in printed and ", 3 to run" in printed
    assert "scenario windy: 1 run" in printed and (out / "summary.png").stat().st_size > 10_000
    rows = read_rows(out / TABLE)
    assert [(r["scenario"], r["seed"], r["error"]) for r in rows] == [
        ("gusts", 1, None), ("nominal", 1, None), ("windy", 1, None),
    ]  # fmt: skip
    for row in rows:  # each row's own command line, flown alone with companion simulate
        argv = shlex.split(row["command"])
        assert argv[:2] == ["companion", "simulate"]
        assert main(argv[1:]) == 0
        folder = Path(argv[argv.index("--out") + 1])
        metrics = json.loads((folder / "metrics.json").read_text())
        compared = 0
        for key, value in metrics.items():
            column = "metrics_duration_s" if key == "duration_s" else key
            if key == "mission":
                assert row["mission"] == value  # the run's own column
            elif key in DIAGNOSTICS or isinstance(value, str | list | dict):
                assert column not in row, key
            else:
                assert row[column] == value, (row["run_id"], key)  # exactly
                compared += 1
        assert compared >= 30 and row["cross_track_p95_m"] is not None
        alerts = alert_columns(episode_measures(load_run(folder)), metrics["alerts"])
        assert {k: row[k] for k in alerts} == alerts
        assert row["intruders"] == 1 and row["intruders_detected"] == 0  # the decoy: at 600 s


@pytest.mark.contract
@pytest.mark.slow
def test_a_rerun_skips_the_runs_already_in_the_table(tiny_campaign, capsys):
    spec, out, _ = tiny_campaign
    before = {r["run_id"]: r for r in read_rows(out / TABLE)}
    assert main(["campaign", str(spec), "--out", str(out), "--no-progress"]) == 0
    assert "3 runs in the grid: 3 already in" in capsys.readouterr().out  # nothing started
    more = spec.with_name("more.yaml")
    more.write_text(TINY.replace("scenarios: [nominal, gusts,", "scenarios: [nominal, wind_off,"))
    args = ["campaign", str(more), "--out", str(out), "--no-progress", "--workers", "1"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert f"3 runs in the grid: 2 already in {out / TABLE} (skipped), 1 to run" in printed
    after = {r["run_id"]: r for r in read_rows(out / TABLE)}
    assert len(after) == 4 and set(before) < set(after)
    assert all(after[k] == before[k] for k in before)  # the finished rows are untouched
    (new,) = set(after) - set(before)
    assert after[new]["scenario"] == "wind_off" and after[new]["error"] is None


def fail_or_die(plan, out: str, keep_runs: bool) -> dict:
    """A task for the failure test: counts its attempts in ``out``; the nominal run raises,
    the gusts run kills its worker process, the others are flown."""
    from companion.campaign.execute import run_one

    with open(Path(out) / f"attempts-{plan.scenario}", "a") as fh:
        fh.write("1\n")
    if plan.scenario == "nominal":
        raise RuntimeError("the engine broke")
    if plan.scenario == "gusts":
        os._exit(3)  # the worker dies under the run
    return run_one(plan, out, keep_runs)


@pytest.mark.contract
@pytest.mark.slow
def test_a_run_that_fails_twice_is_a_row_with_its_error_and_the_table_stays_whole(tmp_path):
    from companion.campaign.execute import run_campaign

    spec = write_spec(tmp_path, TINY.replace("duration_s: 60", "duration_s: 30"))
    out = tmp_path / "out"
    grid = expand(load_spec(spec, Params), out, Params)
    done = run_campaign(grid, out, workers=1, progress=False, task=fail_or_die, log=sys.stderr)
    assert (done.ran, done.failed, done.skipped, done.not_run) == (3, 2, 0, 0)
    by = {r["scenario"]: r for r in read_rows(out / TABLE)}
    assert by["nominal"]["error"].startswith("RuntimeError: the engine broke (test_campaign.py:")
    assert by["gusts"]["error"].startswith("KilledWorker: ")
    assert by["windy"]["error"] is None and by["windy"]["cross_track_p95_m"] > 0
    assert by["nominal"]["cross_track_p95_m"] is None and by["nominal"]["command"]
    for scenario in ("nominal", "gusts"):  # retried once, no more
        assert (out / f"attempts-{scenario}").read_text() == "1\n1\n", scenario


# ---- real processes --------------------------------------------------------------------------
def free_tcp_port() -> int:
    """A TCP port free on 127.0.0.1 just now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop(procs: list[subprocess.Popen]) -> None:
    """End ``procs`` (and what they started) by pid: SIGTERM, then SIGKILL after 20 s."""
    import psutil

    for p in reversed(procs):
        kids = []
        with contextlib.suppress(psutil.NoSuchProcess):
            kids = psutil.Process(p.pid).children(recursive=True)
        if p.poll() is None:
            p.terminate()
        try:
            p.wait(20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
        _, alive = psutil.wait_procs(kids, timeout=10)
        for k in alive:
            k.kill()


@pytest.mark.integration
@pytest.mark.slow
def test_a_running_scheduler_and_worker_give_the_same_table(tiny_campaign, tmp_path):
    spec, local_out, _ = tiny_campaign
    dask = str(Path(sys.executable).with_name("dask"))
    port = free_tcp_port()
    address = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    try:
        procs.append(subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT,
        ))  # fmt: skip
        procs.append(subprocess.Popen(
            [dask, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard",
             "--host", "127.0.0.1"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT,
        ))  # fmt: skip
        out = tmp_path / "remote"
        args = ["campaign", str(spec), "--out", str(out), "--scheduler", address, "--no-progress"]
        assert main(args) == 0
    finally:
        stop(procs)
    assert all(p.poll() is not None for p in procs)

    def same(rows: list[dict]) -> list[dict]:
        return [{k: v for k, v in r.items() if k not in VARYING} for r in rows]

    remote = read_rows(out / TABLE)
    ids = {r["run_id"] for r in remote}
    local = [r for r in read_rows(local_out / TABLE) if r["run_id"] in ids]  # + the rerun's
    assert len(remote) == len(local) == 3
    assert same(remote) == same(local)


@pytest.mark.integration
@pytest.mark.slow
def test_sigterm_keeps_the_finished_rows_and_leaves_no_process(tmp_path):
    more = TINY.replace("seeds: [1]", "seeds: [1, 2, 3]")
    spec = write_spec(tmp_path, more.replace("duration_s: 60", "duration_s: 45"))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "companion", "campaign", str(spec), "--out", str(out),
           "--workers", "2", "--batch", "1", "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 240
        while not (out / TABLE).exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.2)
        assert (out / TABLE).exists(), "no run finished"
        proc.send_signal(signal.SIGTERM)
        text, _ = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, text
    assert "interrupted: " in text and "Traceback" not in text, text
    rows = read_rows(out / TABLE)
    assert 1 <= len(rows) < 9 and all(r["error"] is None for r in rows)
    deadline = time.monotonic() + 10  # the resource tracker ends when it sees its parent gone
    while (left := _alive_in_session(proc.pid)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, left


def _alive_in_session(sid: int) -> list:
    """The processes of session ``sid`` still running (a zombie has ended; this container's
    init may be slow to reap the campaign's resource tracker)."""
    import psutil

    out = []
    for p in psutil.process_iter(["status"]):
        with contextlib.suppress(OSError, psutil.Error):
            if os.getsid(p.pid) == sid and p.info["status"] != psutil.STATUS_ZOMBIE:
                out.append(p)
    return out
