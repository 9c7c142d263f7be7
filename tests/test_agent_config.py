"""The companion's options (companion.agent.config): each declared once with its bounds, each
value out of them refused with the field's name, the defaults and the edges accepted; the
command line's options are those declarations (same defaults, choices and bounds), and the
configurations of a run, a simulation and a fleet embed the one record."""

from __future__ import annotations

import math
from dataclasses import fields

import pytest

from companion.agent.config import AGENT_OPTIONS, AgentConfig
from companion.commands.main import build_parser
from companion.commands.options import agent_config, link_config
from companion.contracts.errors import UserError
from companion.contracts.options import OptionError, as_argv
from companion.link.config import LINK_OPTIONS, LinkConfig
from companion.link.setpoints import PROFILE_CHOICES
from companion.process.config import RunConfig
from companion.sim.fleet import FleetConfig
from companion.sim.inmemory import EngineConfig

# field -> (values just inside the bounds, values outside), read off the option's meaning
CASES = {
    "policy": (["next", "fastest"], ["nearest", ""]),
    "on_confirm": (["track", "chain"], ["follow"]),
    "rejoin": (["slot", "direct"], ["teleport"]),
    "member_timeout_s": ([0.5, 30.0, 600.0], [0.49, 600.5, 0.0, -1.0, math.inf, math.nan]),
    "replan_s": ([0.1, 5.0], [0.0, math.nan]),
    "max_prosecutors": ([1, 6], [0, -2]),
    "bid_window_s": ([0.0, 2.0], [-0.1, math.inf]),
    "alert_repeat_s": ([0.0, 1.0], [-1.0]),
    "lead_s": ([0.0, 1.0], [-0.01, 1.01, math.nan]),
    "hold_s": ([0.0, 2.0], [-0.01, 2.01]),
    "max_open_alerts": ([1, 64], [0]),
    "merge_hold_s": ([0.0, 10.0], [-1.0, math.inf]),
    "search_max_s": ([0.0, 600.0], [-1.0, 600.1]),
    "track_lost_s": ([0.1, 45.0], [0.0, -5.0]),
}


def test_every_option_declares_its_meaning_and_is_covered_here():
    names = [f.name for f in fields(AgentConfig)]
    assert sorted(names) == sorted(CASES)
    for f in fields(AgentConfig):
        assert f.metadata["doc"], f.name
        assert f.name.endswith("_s") == (f.metadata["unit"] == "s"), f.name


@pytest.mark.parametrize("name", list(CASES))
def test_values_within_the_bounds_are_kept_and_outside_refused_by_name(name):
    good, bad = CASES[name]
    for value in good:
        assert getattr(AgentConfig(**{name: value}), name) == value
    for value in bad:
        with pytest.raises(ValueError, match=f"^{name} must be") as err:
            AgentConfig(**{name: value})
        assert isinstance(err.value, OptionError) and err.value.field == name


def test_the_defaults_are_valid_and_frozen():
    cfg = AgentConfig()
    assert (cfg.policy, cfg.on_confirm, cfg.rejoin, cfg.max_prosecutors) == (
        "next",
        "track",
        "slot",
        1,
    )
    with pytest.raises(AttributeError):
        cfg.lead_s = 0.5  # type: ignore[misc]


def test_at_rate_leads_by_half_the_control_period_and_holds_for_one():
    cfg = AgentConfig(policy="fastest").at_rate(10.0)
    assert (cfg.lead_s, cfg.hold_s, cfg.policy) == (0.05, 0.1, "fastest")
    assert AgentConfig().at_rate(4.0).hold_s == 2.0 * (0.5 / 4.0)
    with pytest.raises(OptionError, match=r"^lead_s"):
        AgentConfig().at_rate(0.25)  # a 2 s lead is out of the option's bounds


# ---- the command line: built from the declarations ---------------------------------------
COMMANDS = {
    "run": ["run", "--connect", "udpout:127.0.0.1:9"],
    "simulate": ["simulate", "m.yaml", "--out", "x"],
    "fleet": ["fleet", "m.yaml"],
}


def parsed(command: str, *extra: str):
    argv = COMMANDS[command] + list(extra)
    return build_parser(command).parse_args(argv)


def actions(command: str) -> dict[str, object]:
    sub = build_parser(command)._subparsers._group_actions[0].choices[command]
    return {a.dest: a for a in sub._actions}


LINK = {"run": LINK_OPTIONS, "simulate": ("profile",), "fleet": ("profile",)}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_every_command_line_option_is_its_fields_declaration(command):
    opts = actions(command)
    for record, names in ((AgentConfig, AGENT_OPTIONS), (LinkConfig, LINK[command])):
        declared = {f.name: f for f in fields(record)}
        for name in names:
            f, a = declared[name], opts[name]
            assert a.option_strings == ["--" + name.replace("_", "-")]
            assert a.default == f.default, name
            assert a.choices == f.metadata["choices"], name
            assert f.metadata["doc"] in a.help, name
    assert agent_config(parsed(command)) == AgentConfig()  # the defaults are the record's
    assert link_config(parsed(command), LINK[command]) == LinkConfig()


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("name", [n for n in AGENT_OPTIONS if n in CASES])
def test_a_command_line_value_is_kept_or_refused_as_its_field_is(command, name):
    flag = "--" + name.replace("_", "-")
    good, bad = CASES[name]
    for value in good:
        assert getattr(agent_config(parsed(command, flag, str(value))), name) == value
    for value in bad:
        if isinstance(value, str):  # a choice argparse itself refuses (its usage, exit 2)
            with pytest.raises(SystemExit):
                parsed(command, flag, value)
            continue
        with pytest.raises(UserError, match=f"^{flag} must be"):
            agent_config(parsed(command, flag, str(value)))


def test_the_link_options_are_kept_or_refused_by_their_declaration():
    assert LinkConfig(profile="path", rate_hz=50.0).rate_hz == 50.0
    for profile in PROFILE_CHOICES:
        assert link_config(parsed("fleet", "--profile", profile), ("profile",)).profile == profile
    for rate in (0.5, 50.5, math.inf, math.nan):
        with pytest.raises(OptionError, match=r"^rate_hz must be between 1 and 50 Hz"):
            LinkConfig(rate_hz=rate)
        with pytest.raises(UserError, match=r"^--rate-hz must be between 1 and 50 Hz"):
            link_config(parsed("run", "--rate-hz", str(rate)))
    with pytest.raises(OptionError, match=r"^profile must be"):
        LinkConfig(profile="roll")  # type: ignore[arg-type]
    run = link_config(parsed("run", "--profile", "heading", "--rate-hz", "20"), adapt=False)
    assert run == LinkConfig(profile="heading", rate_hz=20.0, adapt=False)


def test_a_fleet_hands_its_options_to_each_companion_exactly():
    cfg = AgentConfig(policy="fastest", on_confirm="chain", max_prosecutors=2,
                      member_timeout_s=0.1 + 0.2 + 7.0)  # fmt: skip
    argv = as_argv(cfg, AGENT_OPTIONS)
    assert argv[:2] == ["--policy", "fastest"]
    assert agent_config(parsed("run", *argv)) == cfg


def test_the_run_the_simulation_and_the_fleet_embed_the_one_record_of_each():
    linked = {f.name for f in fields(LinkConfig)}
    for record in (RunConfig, EngineConfig, FleetConfig):
        kinds = {f.name: f.type for f in fields(record)}
        assert (kinds["agent"], kinds["link"]) == ("AgentConfig", "LinkConfig"), record
        assert not set(kinds) & (set(CASES) | linked), record  # no option declared twice
