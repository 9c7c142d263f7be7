"""A UAV's own mode as a table keyed by (mode, event) (pure; :mod:`companion.agent.machine`).

The rejoin's three stages are modes of their own, so what the UAV is doing is one value:

=============== ============================================================================
mode            what the UAV flies (what it shares on the group: :attr:`OwnMode.shared`)
=============== ============================================================================
patrol          the loop, steered by the time-splay law (its real state: ``patrol``)
prosecuting     the minimum-time path to an alert's site (its virtual particle: ``prosecuting``)
rejoin_seeking  back over the site while no path meets its slot on time yet (``rejoining``)
rejoin_merging  the path that meets its slot on time (``rejoining``)
rejoin_tracking the tracking law, on its slot, taking out the residual (``rejoining``)
=============== ============================================================================

=============== ====================================================== =====================
event           what happened                                          from
=============== ====================================================== =====================
tasked          this UAV took an alert                                 patrol
ended           the intruder seen again, the path flown, or the alert  prosecuting
                cleared by another (the prosecution's outcome)
meet_path_found a path that meets the slot on time                     rejoin_seeking
met_slot        that path is flown                                     rejoin_merging
in_slot         back in its slot: it shares its real state again       any rejoin stage
timed_out       not back after ``REJOIN_TIMEOUT_PERIODS``: the same    any rejoin stage
handed_back     rejoin "direct": the real state at once                rejoin_seeking
=============== ====================================================== =====================
"""

from __future__ import annotations

from enum import StrEnum

from companion.agent.machine import advance
from companion.group.messages import Mode


class OwnMode(StrEnum):
    """What this UAV is doing (see the module's table)."""

    PATROL = "patrol"
    PROSECUTING = "prosecuting"
    REJOIN_SEEKING = "rejoin_seeking"
    REJOIN_MERGING = "rejoin_merging"
    REJOIN_TRACKING = "rejoin_tracking"

    @property
    def shared(self) -> Mode:
        """The mode as the group, the logs and the page name it."""
        return _SHARED[self]

    @property
    def rejoining(self) -> bool:
        """Whether this is a stage of the rejoin."""
        return _SHARED[self] is Mode.REJOINING


class ModeEvent(StrEnum):
    """What changes a UAV's own mode (see the module's table)."""

    TASKED = "tasked"
    ENDED = "ended"
    MEET_PATH_FOUND = "meet_path_found"
    MET_SLOT = "met_slot"
    IN_SLOT = "in_slot"
    TIMED_OUT = "timed_out"
    HANDED_BACK = "handed_back"


_P, _X = OwnMode.PATROL, OwnMode.PROSECUTING
_S, _M, _K = OwnMode.REJOIN_SEEKING, OwnMode.REJOIN_MERGING, OwnMode.REJOIN_TRACKING
_SHARED = {
    _P: Mode.PATROL,
    _X: Mode.PROSECUTING,
    _S: Mode.REJOINING,
    _M: Mode.REJOINING,
    _K: Mode.REJOINING,
}
_E = ModeEvent

MODE_TABLE: dict[tuple[OwnMode, ModeEvent], OwnMode] = {
    (_P, _E.TASKED): _X,
    (_X, _E.ENDED): _S,
    (_S, _E.MEET_PATH_FOUND): _M,
    (_M, _E.MET_SLOT): _K,
    (_S, _E.IN_SLOT): _P,
    (_M, _E.IN_SLOT): _P,
    (_K, _E.IN_SLOT): _P,
    (_S, _E.TIMED_OUT): _P,
    (_M, _E.TIMED_OUT): _P,
    (_K, _E.TIMED_OUT): _P,
    (_S, _E.HANDED_BACK): _P,
}


def next_mode(mode: OwnMode, event: ModeEvent) -> OwnMode:
    """The mode after ``event`` (:data:`MODE_TABLE`); raises
    :class:`~companion.agent.machine.IllegalTransitionError` for a pair not in it."""
    return advance(MODE_TABLE, mode, event)
