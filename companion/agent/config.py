"""The options of one companion's decisions (frozen): each declared once, with its unit and
bounds, and checked when made.

An :class:`AgentConfig` is what :class:`companion.agent.agent.Agent` is told beyond the mission:
the tasking policy, what a prosecutor does on seeing its intruder, the periods of its re-plans
and re-sends, its limits. Each field names its unit (``_s``: vehicle seconds) and carries its
bounds in its metadata (:func:`spec`), so a reader, a command-line parser or a check finds
them in one place; ``__post_init__`` checks every field against them and raises ``ValueError``
naming the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Literal

from companion.agent.alerts.book import MAX_OPEN_ALERTS
from companion.agent.alerts.search import SEARCH_MAX_S
from companion.agent.alerts.tasking import Policy
from companion.agent.alerts.tracker import TRACK_LOST_S

OnConfirm = Literal["track", "chain"]
Rejoin = Literal["slot", "direct"]


def spec(
    doc: str,
    *,
    unit: str = "",
    choices: tuple[str, ...] | None = None,
    above: float | None = None,
    at_least: float | None = None,
    at_most: float | None = None,
) -> dict[str, Any]:
    """One option's metadata: what it means (``doc``), its ``unit`` and its bounds: one of
    ``choices``, or a finite number greater than ``above``, at least ``at_least`` and at
    most ``at_most`` (each None: no such bound)."""
    bounds = {"choices": choices, "above": above, "at_least": at_least, "at_most": at_most}
    return {"doc": doc, "unit": unit, **bounds}


def bound_error(name: str, value: Any, meta: dict[str, Any]) -> str | None:
    """Why ``value`` breaks the bounds in ``meta`` (a :func:`spec`) of the
    option ``name``, or None when it keeps them."""
    unit = f" {meta['unit']}" if meta["unit"] else ""
    if meta["choices"] is not None:
        if value in meta["choices"]:
            return None
        return f"{name} must be {' or '.join(repr(c) for c in meta['choices'])}, got {value!r}"
    low, above, high = meta["at_least"], meta["above"], meta["at_most"]
    ok = isinstance(value, int | float) and math.isfinite(value)
    ok = ok and (above is None or value > above) and (low is None or value >= low)
    if ok and (high is None or value <= high):
        return None
    if low is not None and high is not None:
        return f"{name} must be between {low:g} and {high:g}{unit}, got {value!r}"
    if above is not None:
        return f"{name} must be > {above:g}{unit}, got {value!r}"
    return f"{name} must be at least {low:g}{unit}, got {value!r}"


@dataclass(frozen=True)
class AgentConfig:
    """How one companion decides, beyond its mission (every member of a fleet uses the same).

    Attributes:
        policy: tasking policy, "next" (the paper's) or "fastest".
        on_confirm: "track" (the prosecutor that sees the intruder stays over it) or "chain"
            (the paper's: it confirms and the next UAV takes the alert).
        rejoin: "slot" keeps sharing the virtual particle until the UAV has flown back into
            its slot (the others never react); "direct" hands back the real state as soon
            as the prosecution ends (the paper's behaviour: the formation reshuffles).
        member_timeout_s: silence after which a member leaves the formation (s; a group
            budget changes it in flight: :meth:`Agent.set_member_timeout`).
        replan_s: re-planning period while away (s).
        max_prosecutors: most UAVs away at once.
        bid_window_s: how long bids are collected under the "fastest" policy (s).
        alert_repeat_s: active alerts are re-sent this often, against packet loss (s).
        lead_s: predict the state this far ahead (s) with the command in force before
            deciding; half the control period removes the zero-order-hold bias.
        hold_s: how long each command is held (s, the control period): a planned path's
            turn rate is averaged over it (:func:`companion.agent.alerts.paths.turn_rate_at`);
            0: the rate at the decision instant.
        max_open_alerts: most alerts open at once (queued or under way); more are dropped.
        merge_hold_s: a finished alert is kept this long to absorb late reports (s).
        search_max_s: the longest search of a track's uncertainty (s); never longer than
            ``pilot.SEARCH_REVISITS`` ideal revisit times T/N.
        track_lost_s: a tracked intruder not seen for this long is lost (s).
    """

    policy: Policy = field(
        default="next", metadata=spec("tasking policy", choices=("next", "fastest"))
    )
    on_confirm: OnConfirm = field(
        default="track",
        metadata=spec("what a prosecutor that sees its intruder does", choices=("track", "chain")),
    )
    rejoin: Rejoin = field(
        default="slot", metadata=spec("how a prosecutor hands back", choices=("slot", "direct"))
    )
    member_timeout_s: float = field(
        default=3.0, metadata=spec("a silent member leaves", unit="s", above=0.0)
    )
    replan_s: float = field(
        default=1.0, metadata=spec("re-planning period while away", unit="s", above=0.0)
    )
    max_prosecutors: int = field(default=1, metadata=spec("most UAVs away at once", at_least=1))
    bid_window_s: float = field(
        default=1.0, metadata=spec("bids collected (fastest)", unit="s", at_least=0.0)
    )
    alert_repeat_s: float = field(
        default=1.0, metadata=spec("alerts re-sent this often", unit="s", at_least=0.0)
    )
    lead_s: float = field(
        default=0.0, metadata=spec("decide this far ahead", unit="s", at_least=0.0, at_most=1.0)
    )
    hold_s: float = field(
        default=0.0, metadata=spec("each command held", unit="s", at_least=0.0, at_most=2.0)
    )
    max_open_alerts: int = field(
        default=MAX_OPEN_ALERTS, metadata=spec("most alerts open at once", at_least=1)
    )
    merge_hold_s: float = field(
        default=10.0, metadata=spec("a finished alert kept", unit="s", at_least=0.0)
    )
    search_max_s: float = field(
        default=SEARCH_MAX_S,
        metadata=spec("longest search", unit="s", at_least=0.0, at_most=600.0),
    )
    track_lost_s: float = field(
        default=TRACK_LOST_S, metadata=spec("a tracked intruder lost", unit="s", above=0.0)
    )

    def __post_init__(self) -> None:
        """Check every option against its bounds.

        Raises:
            ValueError: naming the first option out of its bounds.
        """
        for f in fields(self):
            why = bound_error(f.name, getattr(self, f.name), dict(f.metadata))
            if why is not None:
                raise ValueError(why)
