"""A member flooding the group beyond its share (pure): one token bucket per sender.

Under a bandwidth budget (:mod:`companion.group.budget`) every member sends its state at the
rate the budget gives (its share). :class:`FloodGate` lets each sender's states in at up to
``margin`` times that rate, with bursts of ``burst`` states, and refuses the rest. Only
accepted states take a token (:meth:`FloodGate.take`), so frames that fail the signature
check never spend a member's share: a sender without the key cannot silence a member. Time
is passed in (vehicle s); the decoder (:mod:`companion.group.codec`) asks
:meth:`FloodGate.full` before it decodes a state, so a refused one costs a header and a
signature check. docs/protocol.md, "Bandwidth budget".
"""

from __future__ import annotations

import math

__all__ = ["FLOOD_BURST", "FLOOD_MARGIN", "FloodGate"]

FLOOD_MARGIN = 2.0  # a sender's states are let in at up to this times its share
FLOOD_BURST = 10.0  # ... with bursts of this many (a state goes with each alert sent)


class FloodGate:
    """Per-sender token buckets refilled at ``margin * share_hz``, ``burst`` deep.

    Args:
        share_hz: each member's state rate under the budget (Hz); the Runner updates
            :attr:`share_hz` as the membership changes.
        margin: how many times the share a sender may send (>= 1).
        burst: bucket depth (states, >= 1).
    """

    def __init__(
        self, share_hz: float, margin: float = FLOOD_MARGIN, burst: float = FLOOD_BURST
    ) -> None:
        """Every sender starts with a full bucket."""
        if not (margin >= 1 and burst >= 1 and math.isfinite(margin) and math.isfinite(burst)):
            raise ValueError(f"need margin >= 1 and burst >= 1, got {margin}, {burst}")
        self.share_hz = share_hz
        self.margin = margin
        self.burst = burst
        self._buckets: dict[int, tuple[float, float]] = {}  # sysid -> (tokens, at t_s)

    def _tokens(self, sysid: int, t_s: float) -> float:
        tokens, at = self._buckets.get(sysid, (self.burst, t_s))
        refill = max(0.0, t_s - at) * self.margin * self.share_hz
        return min(self.burst, tokens + refill)

    def full(self, sysid: int, t_s: float) -> bool:
        """Whether a state from ``sysid`` at ``t_s`` (s) is beyond its share (refuse it)."""
        return self._tokens(sysid, t_s) < 1.0

    def take(self, sysid: int, t_s: float) -> None:
        """An accepted state from ``sysid`` at ``t_s`` (s) spends one token."""
        self._buckets[sysid] = (self._tokens(sysid, t_s) - 1.0, t_s)
