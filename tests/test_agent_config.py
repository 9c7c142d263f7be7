"""The companion's options (companion.agent.config): each declared once with its bounds, each
value out of them refused with the field's name, the defaults and the edges accepted."""

from __future__ import annotations

import math
from dataclasses import fields

import pytest

from companion.agent.config import AgentConfig

# field -> (values just inside the bounds, values outside), read off the option's meaning
CASES = {
    "policy": (["next", "fastest"], ["nearest", ""]),
    "on_confirm": (["track", "chain"], ["follow"]),
    "rejoin": (["slot", "direct"], ["teleport"]),
    "member_timeout_s": ([1e-3, 30.0], [0.0, -1.0, math.inf, math.nan]),
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
        with pytest.raises(ValueError, match=f"^{name} must be"):
            AgentConfig(**{name: value})


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
