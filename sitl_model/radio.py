"""A radio-like link, pure: one shared channel with a rate, a delay and random loss.

The simulated world's radio between the companions and their ground router (the group's
datagrams; the autopilot links are not on it). It stands in for Linux ``netem`` (``delay
50ms loss 10% rate 100kbit``), which this project's CI kernel does not have (no
``sch_netem``: docs/protocol.md, "A radio-like link"). Sans-IO, as h11: the edge
(:mod:`sitl_model.radio_relay`) feeds each datagram in with the time it arrived and gets
back when to deliver it, or that it is lost; time is passed in, randomness is one seeded
``numpy.random.Generator``.

The model, per datagram of ``n`` bytes offered at ``t`` (s):

* **Bytes on the air**: ``n + header_bytes`` (default 28: the IPv4 and UDP headers that
  the datagram carried; a real radio's own framing, preamble and FEC come on top, not
  modelled).
* **One shared channel** (a half-duplex radio: the UAVs' uplinks and the ground's downlinks
  take turns): datagrams are sent one at a time, first come first served, each occupying
  the channel ``wire / rate_bytes_s`` seconds (serialisation, as netem's ``rate``). It
  starts at ``max(t, the end of the previous one)``.
* **Counted**: the bytes offered per direction and whole second (the demand, bursts and
  all), the bytes on the air per whole second (each datagram's air time split across the
  seconds it spans: at most the rate), the longest wait per second.
* **Queue**: at most ``limit`` datagrams waiting or on the air (netem's ``limit``, 1000 by
  default); one more is dropped on arrival (``overflow``) and uses no air time.
* **Delay**: a fixed ``delay_s`` after the end of its serialisation (propagation and the
  radio's own latency; no jitter, so no reordering).
* **Loss**: each datagram independently with probability ``loss`` *after* it has used its
  air time (it was sent and not heard; netem drops before its rate, a radio cannot).

Not modelled: collisions and a MAC's retries, bit errors (a datagram is whole or lost),
bursty loss (Gilbert-Elliott), range and per-receiver loss, asymmetric links.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

__all__ = ["DIRECTIONS", "IPV4_UDP_HEADER_BYTES", "LinkSpec", "RadioLink", "Transit"]

IPV4_UDP_HEADER_BYTES = 28
DIRECTIONS = ("up", "down")  # up: a UAV to the ground; down: the ground to a UAV


@dataclass(frozen=True)
class LinkSpec:
    """The link's parameters (netem's names in brackets).

    Attributes:
        rate_bytes_s: the channel's rate, all directions together (bytes/s) [rate].
        delay_s: one-way delay after serialisation (s) [delay].
        loss: probability that a datagram is lost, independently (0..1) [loss].
        limit: datagrams queued or on the air at most [limit].
        header_bytes: bytes added to each datagram's payload on the air (IPv4 + UDP: 28).
    """

    rate_bytes_s: float = 12_500.0  # 100 kbit/s
    delay_s: float = 0.05
    loss: float = 0.10
    limit: int = 1000
    header_bytes: int = IPV4_UDP_HEADER_BYTES

    def __post_init__(self) -> None:
        """``ValueError`` naming the bad field."""
        if not (self.rate_bytes_s > 0 and math.isfinite(self.rate_bytes_s)):
            raise ValueError(f"rate_bytes_s must be finite and > 0, got {self.rate_bytes_s}")
        if not (self.delay_s >= 0 and math.isfinite(self.delay_s)):
            raise ValueError(f"delay_s must be finite and >= 0, got {self.delay_s}")
        if not 0.0 <= self.loss <= 1.0:
            raise ValueError(f"loss must be in [0, 1], got {self.loss}")
        if self.limit < 1 or self.header_bytes < 0:
            raise ValueError(f"need limit >= 1 and header_bytes >= 0, got {self}")


@dataclass(frozen=True)
class Transit:
    """What became of one datagram offered to the link.

    Attributes:
        deliver_s: when it arrives at the far end (s, the caller's clock), None if lost
            or dropped.
        wire_bytes: its bytes on the air (payload + header).
        outcome: ``"delivered"``, ``"lost"`` (sent, not heard) or ``"overflow"`` (queue full).
    """

    deliver_s: float | None
    wire_bytes: int
    outcome: str


@dataclass
class Counts:
    """Bytes offered to the link per direction and per whole second (s since ``t0_s``)."""

    t0_s: float | None = None
    offered: dict[str, dict[int, int]] = field(default_factory=lambda: {d: {} for d in DIRECTIONS})
    datagrams: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DIRECTIONS, 0))
    carried: dict[int, float] = field(default_factory=dict)  # second -> bytes on the air
    outcomes: dict[str, int] = field(
        default_factory=lambda: {"delivered": 0, "lost": 0, "overflow": 0}
    )
    max_backlog_s: float = 0.0
    backlog_s: dict[int, float] = field(default_factory=dict)  # second -> its largest (s)


class RadioLink:
    """The channel's state: when it is next free, what is queued, the counts."""

    def __init__(self, spec: LinkSpec, seed: int) -> None:
        """A quiet channel; ``seed`` seeds the loss draws (same seed, same losses)."""
        self.spec = spec
        self._rng = np.random.default_rng(seed)
        self._free_s = -math.inf  # when the channel ends its current datagram (s)
        self._ends: deque[float] = deque()  # serialisation ends of datagrams not yet sent
        self.counts = Counts()

    def offer(self, t_s: float, payload_bytes: int, direction: str) -> Transit:
        """One datagram of ``payload_bytes`` (bytes) offered at ``t_s`` (s) in ``direction``
        (``"up"`` or ``"down"``); offers must come in time order. Its fate (:class:`Transit`)."""
        if direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {DIRECTIONS}, got {direction!r}")
        c = self.counts
        if c.t0_s is None:
            c.t0_s = t_s
        wire = payload_bytes + self.spec.header_bytes
        second = math.floor(t_s - c.t0_s)
        per_s = c.offered[direction]
        per_s[second] = per_s.get(second, 0) + wire
        c.datagrams[direction] += 1
        while self._ends and self._ends[0] <= t_s:  # sent by now
            self._ends.popleft()
        if len(self._ends) >= self.spec.limit:
            c.outcomes["overflow"] += 1
            return Transit(None, wire, "overflow")
        start = max(t_s, self._free_s)
        self._free_s = start + wire / self.spec.rate_bytes_s
        self._carry(start - c.t0_s, self._free_s - c.t0_s)
        self._ends.append(self._free_s)
        backlog = self._free_s - t_s  # queued before it, and itself (s)
        c.max_backlog_s = max(c.max_backlog_s, backlog)
        c.backlog_s[second] = max(c.backlog_s.get(second, 0.0), backlog)
        if self.spec.loss > 0 and self._rng.random() < self.spec.loss:
            c.outcomes["lost"] += 1
            return Transit(None, wire, "lost")
        c.outcomes["delivered"] += 1
        return Transit(self._free_s + self.spec.delay_s, wire, "delivered")

    def _carry(self, start_s: float, end_s: float) -> None:
        """Air time [start_s, end_s) (s since the first offer) -> bytes per whole second."""
        carried, rate = self.counts.carried, self.spec.rate_bytes_s
        k = math.floor(start_s)
        while k < end_s:
            overlap = min(end_s, k + 1) - max(start_s, k)
            carried[k] = carried.get(k, 0.0) + overlap * rate
            k += 1

    def carried_per_second(self) -> list[float]:
        """Bytes on the air in each whole second since the first offer (bytes/s; at most the
        rate): what the link carried, lost datagrams included, the queue's wait included."""
        last = max(self.counts.carried, default=-1)
        return [round(self.counts.carried.get(k, 0.0), 1) for k in range(last + 1)]

    def per_second(self) -> dict[str, list[int]]:
        """Bytes offered in each whole second since the first datagram (bytes/s), by
        direction and ``"total"``; every second up to the last one seen, zeros included."""
        last = max((max(d) for d in self.counts.offered.values() if d), default=-1)
        out = {d: [self.counts.offered[d].get(k, 0) for k in range(last + 1)] for d in DIRECTIONS}
        out["total"] = [sum(v) for v in zip(*(out[d] for d in DIRECTIONS), strict=True)]
        return out

    def backlog_per_second(self) -> list[float]:
        """The longest wait (s) of a datagram offered in each whole second, serialisation
        included (0 for a quiet second): the queue, as :meth:`per_second` counts bytes."""
        last = max(self.counts.backlog_s, default=-1)
        return [round(self.counts.backlog_s.get(k, 0.0), 4) for k in range(last + 1)]
