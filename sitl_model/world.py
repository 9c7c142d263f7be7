"""The simulated world apart from the vehicles: intruders and the downward sensors (pure).

Intruders are :class:`companion.mission.Intruder` (static, constant velocity, decoys that
vanish a while after their first detection, or paths: straight legs with turns and waits),
from the mission scenario or added while running. Where an intruder is and how fast it moves
at a time are its own (``Intruder.position_m``, ``Intruder.velocity_at_m_s``: exact,
piecewise linear for a path, zero velocity while it waits); when it is there is
``Intruder.present``. Each vehicle's sensor sees an intruder when the horizontal distance is
within the footprint radius (m). Positions are complex ``north + i east`` (m); times are
simulated s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from companion.mission import Intruder


@dataclass(frozen=True)
class Sighting:
    """Vehicle ``index`` sees intruder ``intruder_id`` at ``pos_m`` moving at ``vel_m_s``."""

    index: int
    intruder_id: str
    pos_m: complex
    vel_m_s: complex
    distance_m: float


@dataclass(frozen=True)
class WorldEvent:
    """``event`` in {intruder_appeared, intruder_vanished, detection, detection_lost}."""

    t_s: float
    event: str
    intruder_id: str
    index: int | None = None  # vehicle index for detections
    pos_m: complex = 0j


class World:
    """Intruders and their detection by the vehicles' sensors."""

    def __init__(self, intruders: tuple[Intruder, ...] = ()) -> None:
        """A world with the scheduled ``intruders``."""
        self._intruders: dict[str, Intruder] = {}
        self._first_detected: dict[str, float] = {}
        self._present: set[str] = set()
        self._seen: set[tuple[int, str]] = set()
        for it in intruders:
            self.add(it)

    def add(self, intruder: Intruder) -> None:
        """Add an intruder; raises ``ValueError`` if its id is taken."""
        if intruder.id in self._intruders:
            raise ValueError(f"intruder id {intruder.id!r} already exists")
        self._intruders[intruder.id] = intruder

    @property
    def intruders(self) -> tuple[Intruder, ...]:
        """All intruders ever added."""
        return tuple(self._intruders.values())

    def update(
        self, t_s: float, vehicle_pos_m: np.ndarray, radius_m: float
    ) -> tuple[list[Sighting], list[WorldEvent]]:
        """Who sees what at ``t_s``: current sightings and the events since the last call."""
        events: list[WorldEvent] = []
        present: list[Intruder] = []
        for it in self._intruders.values():
            was = it.id in self._present
            now = it.present(t_s, self._first_detected.get(it.id))
            if now and not was:
                self._present.add(it.id)
                events.append(WorldEvent(t_s, "intruder_appeared", it.id, pos_m=it.position_m(t_s)))
            elif was and not now:
                self._present.discard(it.id)
                events.append(WorldEvent(t_s, "intruder_vanished", it.id, pos_m=it.position_m(t_s)))
            if now:
                present.append(it)
        sightings: list[Sighting] = []
        seen_now: set[tuple[int, str]] = set()
        if present and radius_m > 0:
            ipos = np.array([it.position_m(t_s) for it in present])
            dist = np.abs(np.asarray(vehicle_pos_m)[:, None] - ipos[None, :])
            for k, j in zip(*np.nonzero(dist <= radius_m), strict=True):
                it = present[j]
                key = (int(k), it.id)
                seen_now.add(key)
                sightings.append(
                    Sighting(
                        int(k),
                        it.id,
                        complex(ipos[j]),
                        it.velocity_at_m_s(t_s),
                        float(dist[k, j]),
                    )
                )
                if key not in self._seen:
                    self._first_detected.setdefault(it.id, t_s)
                    events.append(WorldEvent(t_s, "detection", it.id, int(k), complex(ipos[j])))
        for k, iid in sorted(self._seen - seen_now):
            pos = self._intruders[iid].position_m(t_s)
            events.append(WorldEvent(t_s, "detection_lost", iid, k, pos))
        self._seen = seen_now
        return sightings, events
