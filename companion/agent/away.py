"""A UAV's working state while it is away from the loop (mutable): prosecuting an alert,
then flying back into its slot. Shared by :mod:`companion.agent.alerts.prosecution` and
:mod:`companion.agent.rejoin`.

Times are vehicle seconds, positions complex north + i east metres.
"""

from __future__ import annotations

from dataclasses import dataclass

from companion.guidance.virtual import VirtualParticle
from companion.planner import Plan


@dataclass
class Away:
    """A UAV's working state while away from the loop: prosecuting an alert, then flying
    back into its slot (whether it is still prosecuting or already rejoining is the Agent's
    own mode, :attr:`companion.agent.agent.Agent.mode`, not a field here)."""

    alert_id: str
    site_m: complex
    virtual: VirtualParticle
    plan: Plan | None = None
    plan_t0_s: float = 0.0
    last_plan_s: float = -1e9
    planned_time_s: float = 0.0
    covered: bool = False
    rejoin_t0_s: float = 0.0
    merge: Plan | None = None  # the path that meets the slot on time
    merge_t0_s: float = 0.0
    meet_t_s: float = 0.0  # when the path meets the slot (s)
    wait: Plan | None = None  # back over the site while the slot comes round
    wait_t0_s: float = 0.0
    last_check_s: float = -1e9
