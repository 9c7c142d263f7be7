"""The group's bandwidth budget: each member's state rate falls as the group grows (pure).

With ``N`` members each sending a PATROL_STATE of ``b`` bytes ``r`` times a second, the
group carries ``N r b`` bytes/s of states: on one multicast LAN that is what the medium
carries; over Zenoh every receiver gets ``(N - 1) r b`` and a router forwarding to all of
them sends ``N (N - 1) r b``. :func:`state_rate_hz` holds the first within a budget: the
rate is the largest at most ``max_rate_hz`` with ``N r b <= budget``, but never below
``min_rate_hz`` (a member must still be heard several times per member timeout), where
the budget is then exceeded and :func:`group_state_bytes_s` says by how much.

:class:`Budget` is what the Runner uses (``companion run --group-budget``): for the members
it hears it gives the state period and the member time-out (:meth:`Budget.schedule`); the
time-out is a function of the rate alone (:func:`member_timeout_for_rate_s`), so members that
agree on the rate agree on the time-out. docs/protocol.md, "Bandwidth budget".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "DEFAULT_MAX_RATE_HZ",
    "ENERGY_STATE_DATAGRAM_BYTES",
    "HEARD_PER_TIMEOUT",
    "MAX_MEMBER_TIMEOUT_S",
    "STATE_DATAGRAM_BYTES",
    "Budget",
    "Schedule",
    "group_state_bytes_s",
    "member_timeout_for_rate_s",
    "min_rate_for_timeout_hz",
    "state_rate_hz",
]

# The largest signed PATROL_STATE datagram (version 2, every field set): MAVLink 2 header
# 10, payload 70, CRC 2, signature 13 (tests/test_group_budget.py encodes one).
STATE_DATAGRAM_BYTES = 95
# ... and version 3 (battery and relief fields, a mission with a battery and spares): 112
ENERGY_STATE_DATAGRAM_BYTES = 112
DEFAULT_MAX_RATE_HZ = 5.0  # the Runner's state period, 0.2 s
HEARD_PER_TIMEOUT = 4.0  # states a member sends within one member time-out, at least
MAX_MEMBER_TIMEOUT_S = 30.0  # the rate never falls below HEARD_PER_TIMEOUT / this (Hz)


def min_rate_for_timeout_hz(member_timeout_s: float, heard_per_timeout: float = 4.0) -> float:
    """The lowest state rate (Hz) at which a member is heard ``heard_per_timeout`` times
    within ``member_timeout_s`` (s): below it, a few lost datagrams drop a live member."""
    if not (member_timeout_s > 0 and heard_per_timeout > 0):
        raise ValueError("member_timeout_s and heard_per_timeout must be > 0")
    return heard_per_timeout / member_timeout_s


def state_rate_hz(
    members: int,
    budget_bytes_s: float,
    *,
    datagram_bytes: int = STATE_DATAGRAM_BYTES,
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ,
    min_rate_hz: float = 0.0,
) -> float:
    """Each member's state rate (Hz) for ``members`` members within ``budget_bytes_s``
    (bytes/s of states on the group, all members together).

    ``min(max_rate_hz, budget / (members * datagram_bytes))``, raised to ``min_rate_hz``.
    Non-increasing in ``members``; ``members * rate * datagram_bytes <= budget`` whenever the
    result is above ``min_rate_hz``. ``ValueError`` for a bad argument.
    """
    if members < 1:
        raise ValueError(f"members must be >= 1, got {members}")
    if not (budget_bytes_s > 0 and math.isfinite(budget_bytes_s)):
        raise ValueError(f"budget_bytes_s must be finite and > 0, got {budget_bytes_s}")
    if datagram_bytes < 1:
        raise ValueError(f"datagram_bytes must be >= 1, got {datagram_bytes}")
    if not 0 <= min_rate_hz <= max_rate_hz or not math.isfinite(max_rate_hz):
        raise ValueError(f"need 0 <= min_rate_hz <= max_rate_hz, got {min_rate_hz}, {max_rate_hz}")
    return max(min_rate_hz, min(max_rate_hz, budget_bytes_s / (members * datagram_bytes)))


def group_state_bytes_s(
    members: int, rate_hz: float, datagram_bytes: int = STATE_DATAGRAM_BYTES
) -> float:
    """Bytes/s of states the group carries: ``members * rate_hz * datagram_bytes``."""
    return members * rate_hz * datagram_bytes


def member_timeout_for_rate_s(
    rate_hz: float, floor_s: float, heard_per_timeout: float = HEARD_PER_TIMEOUT
) -> float:
    """The member time-out (s) for members sending at ``rate_hz`` (Hz): long enough to hear
    each ``heard_per_timeout`` times, never shorter than ``floor_s`` (s, ``--member-timeout``).

    ``max(floor_s, heard_per_timeout / rate_hz)``: a function of the rate alone, so two
    members at the same rate use the same time-out. A sender whose view of the group is
    larger by ``d`` members than the receiver's (``n`` heard) sends at ``n / (n + d)`` of the
    receiver's rate and is still heard ``heard_per_timeout * n / (n + d)`` times per time-out:
    twice for views that differ by up to ``n`` members."""
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise ValueError(f"rate_hz must be finite and > 0, got {rate_hz}")
    if not (floor_s > 0 and heard_per_timeout > 0):
        raise ValueError("floor_s and heard_per_timeout must be > 0")
    return max(floor_s, heard_per_timeout / rate_hz)


@dataclass(frozen=True)
class Schedule:
    """What a budget gives for one group size.

    Attributes:
        rate_hz: each member's state rate (Hz).
        period_s: its state period, ``1 / rate_hz`` (s).
        member_timeout_s: silence after which a member leaves the formation (s).
    """

    rate_hz: float
    period_s: float
    member_timeout_s: float


@dataclass(frozen=True)
class Budget:
    """The group's state budget (``--group-budget``): every member must use the same.

    Attributes:
        bytes_s: bytes/s of states on the group, all members together.
        timeout_floor_s: the shortest member time-out (s): ``--member-timeout``.
        datagram_bytes: the size a state is counted at (bytes): the largest signed state.
        max_rate_hz: the rate when the budget does not bind (Hz): 5, as without a budget.
        min_rate_hz: the lowest rate (Hz), where the budget is exceeded rather than the
            time-out made longer than ``MAX_MEMBER_TIMEOUT_S``.
    """

    bytes_s: float
    timeout_floor_s: float = 3.0
    datagram_bytes: int = STATE_DATAGRAM_BYTES
    max_rate_hz: float = DEFAULT_MAX_RATE_HZ
    min_rate_hz: float = HEARD_PER_TIMEOUT / MAX_MEMBER_TIMEOUT_S

    def __post_init__(self) -> None:
        """Validate through :func:`state_rate_hz` and :func:`member_timeout_for_rate_s`."""
        self.schedule(1)
        if not self.min_rate_hz > 0:
            raise ValueError(f"min_rate_hz must be > 0, got {self.min_rate_hz}")

    def schedule(self, members: int) -> Schedule:
        """Rate, period and member time-out for ``members`` members (the ones this member
        hears, plus itself)."""
        rate = state_rate_hz(
            members,
            self.bytes_s,
            datagram_bytes=self.datagram_bytes,
            max_rate_hz=self.max_rate_hz,
            min_rate_hz=self.min_rate_hz,
        )
        return Schedule(rate, 1.0 / rate, member_timeout_for_rate_s(rate, self.timeout_floor_s))
