"""A campaign spec expanded into its runs: missions x scenarios x seeds, each a :class:`RunPlan`.

A run's id is stable: its mission's name, scenario and seed, then the first 10 hex digits of
the SHA-256 of what decides the run (the mission's text, the scenario's name, parameters and
profile, the seed, the duration in s and the group faults), so the same spec expands to the
same ids on any machine and a changed mission file gets new ids. A plan carries everything
needed to fly it again alone: :meth:`RunPlan.simulate_argv` is its ``companion simulate``
command line (a generated mission is flown from its YAML written under ``OUT/missions``).
"""

from __future__ import annotations

import hashlib
import json
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

from companion.campaign.scenarios import BY_NAME
from companion.campaign.spec import CampaignSpec, ParamCheck
from companion.contracts.errors import UserError
from companion.mission.generate import generate

MAX_RUNS = 1_000_000
ID_HASH_CHARS = 10
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]")


@dataclass(frozen=True)
class RunPlan:
    """One run of a campaign (times in simulated s; ``sim_params`` as (NAME, value) pairs in
    ``sitl_model/params.py`` units; ``generator_*`` None for a mission file)."""

    run_id: str
    mission: str
    mission_path: str
    mission_sha256: str
    generator_seed: int | None
    generator_kind: str | None
    generator_max_loop_km: float | None
    scenario: str
    profile: str
    sim_params: tuple[tuple[str, float], ...]
    seed: int
    duration_s: float
    faults: str | None

    def simulate_argv(self, out: Path) -> list[str]:
        """The ``companion simulate`` command line that flies this run alone into
        ``out/runs/RUN_ID`` (absolute; the same measures: the engine is deterministic)."""
        argv = [
            "companion", "simulate", self.mission_path,
            "--out", str(out.resolve() / "runs" / self.run_id),
            "--duration", _num(self.duration_s), "--seed", str(self.seed),
            "--profile", self.profile,
        ]  # fmt: skip
        for name, value in self.sim_params:
            argv += ["--param", f"{name}={_num(value)}"]
        if self.faults:
            argv += ["--faults", self.faults]
        return argv

    def columns(self, out: Path) -> dict[str, object]:
        """The table columns that say what was run (``sim_params`` as a JSON object)."""
        return {
            "run_id": self.run_id,
            "mission": self.mission,
            "scenario": self.scenario,
            "seed": self.seed,
            "duration_s": self.duration_s,
            "profile": self.profile,
            "sim_params": json.dumps(dict(self.sim_params), sort_keys=True),
            "faults": self.faults,
            "mission_path": self.mission_path,
            "mission_sha256": self.mission_sha256,
            "generator_seed": self.generator_seed,
            "generator_kind": self.generator_kind,
            "generator_max_loop_km": self.generator_max_loop_km,
            "command": shlex.join(self.simulate_argv(out)),
        }


@dataclass(frozen=True)
class Grid:
    """The runs of a spec, in grid order, and the generated mission files to write before
    flying them (path -> YAML text)."""

    plans: tuple[RunPlan, ...]
    files: dict[Path, str]

    def find(self, run_id: str) -> RunPlan | None:
        """The plan with this id, or None."""
        return next((p for p in self.plans if p.run_id == run_id), None)


@dataclass(frozen=True)
class _Mission:
    name: str
    path: Path
    sha256: str
    wind_speed_m_s: float
    wind_from_deg: float
    duration_s: float
    generator: tuple[int, str | None, float] | None


def expand(spec: CampaignSpec, out: Path, check_params: ParamCheck) -> Grid:
    """The grid of ``spec``: missions (files, then generated) x scenarios x seeds.

    Args:
        spec: a validated spec (:func:`companion.campaign.spec.load_spec`).
        out: the campaign folder (generated missions are flown from ``out/missions``).
        check_params: validates each run's simulator parameters (raises ValueError).

    Raises:
        UserError: too many runs, a scenario's parameters refused for a mission, or two
            runs that would be the same run.
    """
    missions = [
        _Mission(m.mission.name, m.path, m.sha256, m.mission.wind.speed_m_s,
                 m.mission.wind.from_deg, m.mission.duration_s, None)
        for m in spec.missions
    ]  # fmt: skip
    files: dict[Path, str] = {}
    g = spec.generated
    count = (len(missions) + (len(g.seeds) if g else 0)) * len(spec.scenarios) * len(spec.seeds)
    if count > MAX_RUNS:
        raise UserError(f"{spec.file}: {count} runs in the grid (at most {MAX_RUNS})")
    if g is not None:
        for seed in g.seeds:
            gm = generate(seed, kind=g.kind, max_loop_km=g.max_loop_km)  # type: ignore[arg-type]
            path = (out / "missions" / f"{gm.name}.yaml").resolve()
            files[path] = gm.text
            sha = hashlib.sha256(gm.text.encode()).hexdigest()
            gen = (seed, g.kind, g.max_loop_km)
            missions.append(
                _Mission(gm.name, path, sha, gm.wind_speed_m_s, gm.wind_from_deg,
                         gm.duration_s, gen)
            )  # fmt: skip
    plans: list[RunPlan] = []
    seen: dict[str, str] = {}
    for m in missions:
        duration = spec.duration_s if spec.duration_s is not None else m.duration_s
        for sc in spec.scenarios:
            if sc.sim_params is None:
                params = BY_NAME[sc.name].params(m.wind_speed_m_s, m.wind_from_deg, duration)
                pairs = tuple(params.items())
            else:
                pairs = sc.sim_params
            try:
                check_params(dict(pairs))
            except ValueError as exc:
                raise UserError(f"{spec.file}: scenarios: {sc.name} on {m.name}: {exc}") from None
            for seed in spec.seeds:
                plan = _plan(m, sc.name, sc.profile, pairs, seed, duration, spec.faults)
                where = f"{m.name} {sc.name} seed {seed}"
                if plan.run_id in seen:
                    raise UserError(
                        f"{spec.file}: {where} is the same run as {seen[plan.run_id]} (a "
                        "mission listed twice?)"
                    )
                seen[plan.run_id] = where
                plans.append(plan)
    return Grid(tuple(plans), files)


def _plan(
    m: _Mission,
    scenario: str,
    profile: str,
    params: tuple[tuple[str, float], ...],
    seed: int,
    duration_s: float,
    faults: str | None,
) -> RunPlan:
    params = tuple((name, float(value)) for name, value in params)
    decided = {
        "mission_sha256": m.sha256,
        "scenario": scenario,
        "sim_params": [list(p) for p in params],
        "profile": profile,
        "seed": seed,
        "duration_s": float(duration_s),
        "faults": faults,
    }
    digest = hashlib.sha256(json.dumps(decided, sort_keys=True).encode()).hexdigest()
    run_id = f"{_UNSAFE.sub('_', m.name)}.{scenario}.s{seed}.{digest[:ID_HASH_CHARS]}"
    gen = m.generator
    return RunPlan(
        run_id=run_id,
        mission=m.name,
        mission_path=str(m.path),
        mission_sha256=m.sha256,
        generator_seed=None if gen is None else gen[0],
        generator_kind=None if gen is None else gen[1],
        generator_max_loop_km=None if gen is None else gen[2],
        scenario=scenario,
        profile=profile,
        sim_params=params,
        seed=seed,
        duration_s=float(duration_s),
        faults=faults,
    )


def _num(v: float) -> str:
    """``v`` as short as it reads back exactly."""
    short = f"{v:g}"
    return short if float(short) == v else repr(float(v))
