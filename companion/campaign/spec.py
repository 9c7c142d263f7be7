"""A campaign spec (YAML) -> a frozen :class:`CampaignSpec`; every problem one error line.

The format (``docs/campaigns.md``)::

    missions: [../missions/ellipse_6uav.yaml]   # mission YAMLs, relative to this file
    generated:                                  # and/or seeded random missions
      seeds: {start: 0, count: 20}              # or a list: [0, 4, 7]
      kind: decoy                               # optional (static, decoy, walker, ...)
      max_loop_km: 3                            # optional (km, default 25)
    scenarios:                                  # names of the robustness matrix, or explicit
      - nominal
      - gusts
      - {name: strong_gusts, sim_params: {SIM_WIND_TURB: 3.0}, profile: bank}
    seeds: {start: 0, count: 3}                 # simulator seeds (or a list)
    duration_s: 900                             # optional: each mission's own by default
    faults: loss=0.1,seed=1                     # optional: group faults of every companion

The grid is missions x scenarios x seeds (:mod:`companion.campaign.grid`). Bad input
raises :class:`~companion.contracts.errors.UserError` reading ``SPEC:LINE: FIELD: problem``
(the mission loader's line-aware YAML reader, :mod:`companion.mission.yamlnodes`). Parameter
names and ranges belong to the simulator, so the caller passes ``check_params`` (a
composition root hands in ``sitl_model.params.Params``); this module imports no simulator.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import yaml

from companion.campaign.scenarios import BY_NAME
from companion.contracts.errors import UserError
from companion.group.faults import parse_faults
from companion.link.setpoints import PROFILE_CHOICES
from companion.mission import Mission, MissionError, load_mission
from companion.mission.generate import MAX_LOOP_KM, MIN_LOOP_KM, SCENARIO_KINDS
from companion.mission.load import read_text
from companion.mission.yamlnodes import MapReader, check_tree, compose, integer_at

MAX_SEED = 2**31 - 1
MAX_SEEDS = 100_000  # seeds in one list or range
MAX_ENTRIES = 1_000  # missions or scenarios listed
MAX_DURATION_S = 7 * 24 * 3600.0  # as companion simulate --duration
TOP_FIELDS = ("missions", "generated", "scenarios", "seeds", "duration_s", "faults")

ParamCheck = Callable[[dict[str, float]], object]
"""Validates simulator parameters (NAME -> value); raises ValueError naming the bad one."""


@dataclass(frozen=True)
class MissionFile:
    """A mission YAML of the grid: its path as written in the spec and resolved, the mission,
    and the SHA-256 of its text (hex; part of every run id)."""

    given: str
    path: Path
    mission: Mission
    sha256: str


@dataclass(frozen=True)
class Generated:
    """Seeded random missions (:func:`companion.mission.generate.generate`): its seeds, the
    scenario family (None: drawn per seed) and the longest loop (km)."""

    seeds: tuple[int, ...]
    kind: str | None
    max_loop_km: float


@dataclass(frozen=True)
class ScenarioChoice:
    """A scenario of the grid: a name of the robustness matrix (``sim_params`` None: the
    matrix computes them per mission and duration) or explicit parameters (NAME, value)."""

    name: str
    sim_params: tuple[tuple[str, float], ...] | None
    profile: str


@dataclass(frozen=True)
class CampaignSpec:
    """A campaign: missions (files, generated) x scenarios x simulator seeds; the duration
    of each run (s; None: each mission's own) and the group faults (``--faults`` text)."""

    file: str
    missions: tuple[MissionFile, ...]
    generated: Generated | None
    scenarios: tuple[ScenarioChoice, ...]
    seeds: tuple[int, ...]
    duration_s: float | None
    faults: str | None


def load_spec(path: str | os.PathLike[str], check_params: ParamCheck) -> CampaignSpec:
    """Read and validate the campaign spec at ``path``.

    Args:
        path: the spec YAML; mission paths in it are relative to its folder.
        check_params: validates an explicit scenario's simulator parameters (raises
            ValueError).

    Raises:
        UserError: unreadable, malformed or invalid (``SPEC:LINE: FIELD: problem``).
    """
    file = os.fspath(path)
    try:
        return _Parser(file, check_params).spec(read_text(file))
    except MissionError as exc:  # the line-aware reader's type; here it names the spec
        raise UserError(str(exc)) from None


class _Parser:
    def __init__(self, file: str, check_params: ParamCheck) -> None:
        self.file = file
        self.folder = Path(file).resolve().parent
        self.check_params = check_params

    def spec(self, text: str) -> CampaignSpec:
        try:
            root = compose(text, self.file)
        except yaml.YAMLError as exc:
            mark = getattr(exc, "problem_mark", None)
            problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
            line = mark.line + 1 if mark is not None else None
            raise MissionError(self.file, "", f"YAML syntax error: {problem}", line) from None
        if root is None:
            raise MissionError(self.file, "", "the file is empty (expected a campaign)", 1)
        check_tree(root, self.file)
        top = MapReader.of(root, self.file, "")
        top.done(TOP_FIELDS)
        missions = self.missions(top) if top.has("missions") else ()
        generated = self.generated(top.map("generated")) if top.has("generated") else None
        if not missions and generated is None:
            raise top.error("missions", "no mission: give missions, generated or both")
        duration = None
        if top.has("duration_s"):
            duration = top.number("duration_s", lo=0.0, hi=MAX_DURATION_S, lo_open=True)
        faults = top.string("faults") if top.has("faults") else None
        if faults is not None:
            try:
                parse_faults(faults)
            except UserError as exc:
                raise top.error("faults", str(exc).removeprefix("--faults ")) from None
        return CampaignSpec(
            file=self.file,
            missions=missions,
            generated=generated,
            scenarios=self.scenarios(top),
            seeds=self.seeds(top, "seeds"),
            duration_s=duration,
            faults=faults,
        )

    def missions(self, top: MapReader) -> tuple[MissionFile, ...]:
        out = []
        for i, node in enumerate(top.seq("missions", MAX_ENTRIES)):
            field = f"missions[{i}]"
            line = node.start_mark.line + 1
            given = _scalar_str(node)
            if given is None:
                raise MissionError(self.file, field, "expected a mission file path", line)
            path = (self.folder / given).resolve()
            if not path.is_file():
                raise MissionError(self.file, field, f"no such mission file {given!r}", line)
            try:
                mission = load_mission(path)
            except MissionError as exc:
                raise MissionError(self.file, field, f"bad mission: {exc}", line) from None
            sha = hashlib.sha256(path.read_bytes()).hexdigest()
            out.append(MissionFile(given, path, mission, sha))
        if not out:
            raise top.error("missions", "expected at least one mission file")
        return tuple(out)

    def generated(self, m: MapReader) -> Generated:
        m.done(("seeds", "kind", "max_loop_km"))
        kind = m.string("kind", choices=SCENARIO_KINDS) if m.has("kind") else None
        km = m.number("max_loop_km", MAX_LOOP_KM, lo=MIN_LOOP_KM, hi=MAX_LOOP_KM)
        return Generated(self.seeds(m, "seeds"), kind, km)

    def seeds(self, m: MapReader, key: str) -> tuple[int, ...]:
        node = m.node_of(key)
        field = m.sub(key)
        if isinstance(node, yaml.MappingNode):
            r = MapReader.of(node, self.file, field)
            r.done(("start", "count"))
            start = r.integer("start", lo=0, hi=MAX_SEED)
            count = r.integer("count", lo=1, hi=MAX_SEEDS)
            if start + count - 1 > MAX_SEED:
                raise r.error("count", f"the last seed passes {MAX_SEED}")
            return tuple(range(start, start + count))
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            raise m.error(key, "expected a list of seeds or {start: S, count: N}")
        nodes = m.seq(key, MAX_SEEDS)
        out = tuple(
            integer_at(n, self.file, f"{field}[{i}]", 0, MAX_SEED) for i, n in enumerate(nodes)
        )
        if len(set(out)) != len(out):
            raise m.error(key, "a seed is listed twice")
        return out

    def scenarios(self, top: MapReader) -> tuple[ScenarioChoice, ...]:
        out: list[ScenarioChoice] = []
        for i, node in enumerate(top.seq("scenarios", MAX_ENTRIES)):
            field = f"scenarios[{i}]"
            line = node.start_mark.line + 1
            name = _scalar_str(node)
            if name is not None:
                if name not in BY_NAME:
                    raise MissionError(
                        self.file,
                        field,
                        f"unknown scenario {name!r} (expected one of: {', '.join(BY_NAME)}, "
                        "or {name: ..., sim_params: {...}})",
                        line,
                    )
                choice = ScenarioChoice(name, None, BY_NAME[name].profile)
            else:
                choice = self.explicit(MapReader.of(node, self.file, field))
            if any(c.name == choice.name for c in out):
                raise MissionError(self.file, field, f"scenario {choice.name!r} twice", line)
            out.append(choice)
        if not out:
            raise top.error("scenarios", "expected at least one scenario")
        return tuple(out)

    def explicit(self, m: MapReader) -> ScenarioChoice:
        m.done(("name", "sim_params", "profile"))
        name = m.string("name")
        if name in BY_NAME:
            raise m.error("name", f"{name!r} is a scenario of the matrix: choose another name")
        if not name or not name.replace("_", "").replace("-", "").isalnum() or len(name) > 60:
            raise m.error("name", "expected a short name of letters, digits, - and _")
        params: dict[str, float] = {}
        if m.has("sim_params"):
            p = m.map("sim_params")
            for key in p.items:
                params[key] = p.number(key, what="a parameter value")
                try:
                    self.check_params({key: params[key]})
                except ValueError as exc:
                    raise p.error(key, str(exc)) from None
        profile = m.string("profile", "auto", choices=PROFILE_CHOICES)
        return ScenarioChoice(name, tuple(sorted(params.items())), profile)


def _scalar_str(node: yaml.Node) -> str | None:
    """The plain string of a scalar node, else None."""
    if isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:str":
        return node.value or None
    return None
