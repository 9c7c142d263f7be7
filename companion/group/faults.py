"""Network faults injected on send (pure, seeded): loss, delay jitter, duplication, reordering.

A :class:`FaultModel` decides, for each outgoing datagram, when (and how many times) it
leaves; :class:`companion.group.transport.Group` applies it in one place, so tests and
benchmarks can degrade the group without touching the network.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from companion.contracts.errors import UserError

__all__ = ["FaultModel"]


@dataclass
class FaultModel:
    """Per-datagram faults, drawn from one seeded ``numpy.random.Generator``.

    Attributes:
        loss: probability that a datagram is dropped (each copy independently).
        jitter_s: each copy is delayed by a uniform time in ``[0, jitter_s]`` (s).
        duplicate: probability that a datagram is sent twice.
        reorder: probability that a copy is held back an extra ``reorder_delay_s`` (s), so
            later datagrams overtake it (the receiver then drops it as ``replayed``:
            signed streams must be strictly increasing).
        reorder_delay_s: the hold-back of a reordered copy (s); a little over the 0.2 s
            state period by default.
        seed: seed of the generator (same seed, same faults).
    """

    loss: float = 0.0
    jitter_s: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    reorder_delay_s: float = 0.25
    seed: int | None = 0
    counts: dict[str, int] = field(
        default_factory=lambda: {"lost": 0, "duplicated": 0, "reordered": 0}
    )

    def __post_init__(self) -> None:
        """Check the probabilities and delays; build the generator."""
        for name in ("loss", "duplicate", "reorder"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1], got {p!r}")
        for name in ("jitter_s", "reorder_delay_s"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0 s, got {getattr(self, name)!r}")
        self._rng = np.random.default_rng(self.seed)

    def apply(self, datagram: bytes, now_s: float) -> list[tuple[float, bytes]]:
        """The copies of ``datagram`` to send, each with its due time (s, the sender's clock)."""
        copies = 1
        if self.duplicate and self._rng.random() < self.duplicate:
            copies = 2
            self.counts["duplicated"] += 1
        out: list[tuple[float, bytes]] = []
        for _ in range(copies):
            if self.loss and self._rng.random() < self.loss:
                self.counts["lost"] += 1
                continue
            due = now_s + (self._rng.uniform(0.0, self.jitter_s) if self.jitter_s else 0.0)
            if self.reorder and self._rng.random() < self.reorder:
                due += self.reorder_delay_s
                self.counts["reordered"] += 1
            out.append((due, datagram))
        return out


FAULT_KEYS = {
    "loss": "loss",
    "jitter": "jitter_s",
    "dup": "duplicate",
    "reorder": "reorder",
    "reorder_delay": "reorder_delay_s",
    "seed": "seed",
}


def parse_faults(spec: str) -> FaultModel:
    """``loss=0.1,jitter=0.2,dup=0.01,reorder=0.05,seed=1`` -> a FaultModel (UserError if bad)."""
    kwargs: dict[str, Any] = {}  # FaultModel's keywords: the seed an int, the rest floats
    for part in spec.split(","):
        key, sep, value = part.strip().partition("=")
        if not sep or key not in FAULT_KEYS:
            raise UserError(
                f"--faults {spec!r}: expected KEY=VALUE with KEY in {sorted(FAULT_KEYS)}"
            )
        try:
            kwargs[FAULT_KEYS[key]] = int(value) if key == "seed" else float(value)
        except ValueError:
            raise UserError(f"--faults {spec!r}: {key}={value!r} is not a number") from None
    try:
        return FaultModel(**kwargs)
    except ValueError as exc:
        raise UserError(f"--faults {spec!r}: {exc}") from None
