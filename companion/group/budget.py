"""The group's bandwidth budget: each member's state rate falls as the group grows (pure).

With ``N`` members each sending a PATROL_STATE of ``b`` bytes ``r`` times a second, the
group carries ``N r b`` bytes/s of states: on one multicast LAN that is what the medium
carries; over Zenoh every receiver gets ``(N - 1) r b`` and a router forwarding to all of
them sends ``N (N - 1) r b``. :func:`state_rate_hz` holds the first within a budget: the
rate is the largest at most ``max_rate_hz`` with ``N r b <= budget``, but never below
``min_rate_hz`` (a member must still be heard several times per member timeout), where
the budget is then exceeded and :func:`group_state_bytes_s` says by how much.

Not wired into the Runner yet (issue 24, later part).
"""

from __future__ import annotations

import math

__all__ = [
    "DEFAULT_MAX_RATE_HZ",
    "STATE_DATAGRAM_BYTES",
    "group_state_bytes_s",
    "min_rate_for_timeout_hz",
    "state_rate_hz",
]

# The largest signed PATROL_STATE datagram (version 2, every field set): MAVLink 2 header
# 10, payload 70, CRC 2, signature 13 (tests/test_group_budget.py encodes one).
STATE_DATAGRAM_BYTES = 95
DEFAULT_MAX_RATE_HZ = 5.0  # the Runner's state period, 0.2 s


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
