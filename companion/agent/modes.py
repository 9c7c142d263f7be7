"""A UAV's own mode as a table keyed by (mode, event) (pure; :mod:`companion.agent.machine`).

The stages of an alert's answer are modes of their own, so what the UAV is doing is one
value:

================= ==========================================================================
mode              what the UAV flies (what it shares on the group: :attr:`OwnMode.shared`)
================= ==========================================================================
patrol            the loop, steered by the time-splay law (its real state: ``patrol``)
prosecuting       the minimum-time intercept of the intruder's predicted track (its virtual
                  particle: ``prosecuting``)
searching         a pattern over the track's uncertainty, where the intruder was not under
                  the sensor at the intercept (``searching``)
tracking          over a persistent intruder, out of the formation (``tracking``: the others
                  splay without it)
rejoin_to_loop    the minimum-time path back onto the loop, ahead (``rejoining``: a virtual
                  particle in its slot)
rejoin_along_loop on the loop, its slot recovered by airspeed (``rejoining``)
================= ==========================================================================

================= ==================================================== ======================
event             what happened                                        from
================= ==================================================== ======================
tasked            this UAV took an alert                               patrol
path_flown        the intercept is flown and the intruder not seen     prosecuting
ended             seen and handed on (policy chain), cleared (the      prosecuting, searching
                  search done), or cleared by another
tracker           seen, and it stays over it (policy track)            prosecuting, searching
track_ended       the track lost, released by the operator, or the     tracking
                  intruder left the fence
on_loop           back on the loop                                     rejoin_to_loop
in_slot           back in its slot: it shares its real state again     either rejoin stage
timed_out         not back after ``REJOIN_TIMEOUT_PERIODS``: the same  either rejoin stage
handed_back       rejoin "direct": its real state at once              rejoin_to_loop
================= ==================================================== ======================
"""

from __future__ import annotations

from enum import StrEnum

from companion.agent.machine import advance
from companion.group.messages import Mode


class OwnMode(StrEnum):
    """What this UAV is doing (see the module's table)."""

    PATROL = "patrol"
    PROSECUTING = "prosecuting"
    SEARCHING = "searching"
    TRACKING = "tracking"
    REJOIN_TO_LOOP = "rejoin_to_loop"
    REJOIN_ALONG_LOOP = "rejoin_along_loop"

    @property
    def shared(self) -> Mode:
        """The mode as the group, the logs and the page name it."""
        return _SHARED[self]

    @property
    def rejoining(self) -> bool:
        """Whether this is a stage of the rejoin."""
        return _SHARED[self] is Mode.REJOINING

    @property
    def prosecuting(self) -> bool:
        """Whether it is on its way to an intruder (intercept or search)."""
        return _SHARED[self] in (Mode.PROSECUTING, Mode.SEARCHING)


class ModeEvent(StrEnum):
    """What changes a UAV's own mode (see the module's table)."""

    TASKED = "tasked"
    PATH_FLOWN = "path_flown"
    ENDED = "ended"
    TRACKER = "tracker"
    TRACK_ENDED = "track_ended"
    ON_LOOP = "on_loop"
    IN_SLOT = "in_slot"
    TIMED_OUT = "timed_out"
    HANDED_BACK = "handed_back"


_P, _X, _S, _K = OwnMode.PATROL, OwnMode.PROSECUTING, OwnMode.SEARCHING, OwnMode.TRACKING
_RL, _RA = OwnMode.REJOIN_TO_LOOP, OwnMode.REJOIN_ALONG_LOOP
_SHARED = {
    _P: Mode.PATROL,
    _X: Mode.PROSECUTING,
    _S: Mode.SEARCHING,
    _K: Mode.TRACKING,
    _RL: Mode.REJOINING,
    _RA: Mode.REJOINING,
}
_E = ModeEvent

MODE_TABLE: dict[tuple[OwnMode, ModeEvent], OwnMode] = {
    (_P, _E.TASKED): _X,
    (_X, _E.PATH_FLOWN): _S,
    (_X, _E.ENDED): _RL,
    (_S, _E.ENDED): _RL,
    (_X, _E.TRACKER): _K,
    (_S, _E.TRACKER): _K,
    (_K, _E.TRACK_ENDED): _RL,
    (_RL, _E.ON_LOOP): _RA,
    (_RL, _E.IN_SLOT): _P,
    (_RA, _E.IN_SLOT): _P,
    (_RL, _E.TIMED_OUT): _P,
    (_RA, _E.TIMED_OUT): _P,
    (_RL, _E.HANDED_BACK): _P,
}


def next_mode(mode: OwnMode, event: ModeEvent) -> OwnMode:
    """The mode after ``event`` (:data:`MODE_TABLE`); raises
    :class:`~companion.agent.machine.IllegalTransitionError` for a pair not in it."""
    return advance(MODE_TABLE, mode, event)
