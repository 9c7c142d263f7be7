"""In-process fleet simulation: particles + the companion's guidance, no MAVLink.

Every vehicle is the ``sitl_model`` particle; every companion's decisions come from the same
pure modules the real companion uses, exchanging states through a perfect in-memory group.
Used by ``companion simulate`` to tune gains and check a mission before flying. Time is
simulated seconds from 0; the clock is this object's own counter, never the wall clock.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from companion.core.measures import centre_error_m, convergence_time_s, splay_error_deg
from companion.core.wind import TWO_PI
from companion.mission import Mission
from sitl_model.particle import ParticleParams, ParticleState, step

TRUTH_COLUMNS = (
    "t_s",
    "sysid",
    "north_m",
    "east_m",
    "alt_m",
    "heading_deg",
    "course_deg",
    "groundspeed_m_s",
    "turn_rate_deg_s",
    "mode",
)

TruthRow = tuple[float, int, float, float, float, float, float, float, float, str]
Event = dict[str, object]


@dataclass
class Series:
    """Formation measures sampled over the run (one entry per sample time)."""

    t_s: list[float] = field(default_factory=list)
    splay_deg: list[float] = field(default_factory=list)
    centre_m: list[float] = field(default_factory=list)

    def convergence_time_s(self) -> float | None:
        """First time after which splay < 2 deg and centre < 5 m hold (s), or None."""
        return convergence_time_s(self.t_s, self.splay_deg, self.centre_m)


class FleetSimulation:
    """N particles steered by the companion guidance, stepped at a fixed ``dt_s``.

    Args:
        mission: the mission (loop, wind, vehicles, gains, sensor, scenario).
        seed: seed of the one random generator (gusts).
        dt_s: control and physics step (s); the physics is exact for the held turn rate.
    """

    def __init__(self, mission: Mission, seed: int = 0, dt_s: float = 0.1) -> None:
        """Place the vehicles at the mission's initial poses at t = 0."""
        self.mission = mission
        self.patrol = mission.patrol
        self.dt_s = float(dt_s)
        self.rng = np.random.default_rng(seed)
        v = mission.vehicles
        self.sysids = np.array(v.sysids)
        self.alt_m = np.array(v.altitudes_m)
        self.params = ParticleParams(
            v.airspeed_m_s, v.max_turn_rate_rad_s, gust_std_m_s=mission.wind.gust_std_m_s
        )
        self.wind_m_s = mission.wind.wind().vector
        self.state = ParticleState.at(
            [p.north_m for p in v.initial],
            [p.east_m for p in v.initial],
            np.radians([p.heading_deg for p in v.initial]),
        )
        self.step_index = 0
        self.modes = ["patrol"] * v.count
        self.series = Series()
        self.events: list[Event] = []
        self._controller = PatrolController(mission)

    @property
    def t_s(self) -> float:
        """Simulated time (s)."""
        return self.step_index * self.dt_s

    def run(
        self,
        duration_s: float,
        on_truth: Callable[[list[TruthRow]], None] | None = None,
        on_event: Callable[[Event], None] | None = None,
    ) -> Series:
        """Fly until ``duration_s`` (s); sample every step; return the measures."""
        steps = round(duration_s / self.dt_s)
        for _ in range(steps + 1):
            t = self.t_s
            u, modes, events = self._controller.commands(t, self.state, self.modes)
            self.modes = modes
            for ev in events:
                self.events.append(ev)
                if on_event is not None:
                    on_event(ev)
            self._sample(t, u, on_truth)
            if self.step_index >= steps:
                break
            self.state = step(self.state, u, self.params, self.wind_m_s, self.dt_s, self.rng)
            self.step_index += 1
        return self.series

    def _sample(
        self, t: float, u: np.ndarray, on_truth: Callable[[list[TruthRow]], None] | None
    ) -> None:
        st = self.state
        centres, phases = self._controller.shared_centres_phases(t, st, self.modes)
        self.series.t_s.append(t)
        self.series.splay_deg.append(splay_error_deg(phases))
        self.series.centre_m.append(centre_error_m(centres, self.patrol.centre_m))
        if on_truth is None:
            return
        vel = self.params.airspeed_m_s * np.exp(1j * st.heading_rad) + self.wind_m_s + st.gust_m_s
        u_ach = np.clip(u, -self.params.max_turn_rate_rad_s, self.params.max_turn_rate_rad_s)
        rows = list(
            zip(
                [round(t, 3)] * len(self.sysids),
                self.sysids.tolist(),
                np.round(st.pos_m.real, 3).tolist(),
                np.round(st.pos_m.imag, 3).tolist(),
                self.alt_m.tolist(),
                np.round(np.degrees(st.heading_rad) % 360.0, 3).tolist(),
                np.round(np.degrees(np.angle(vel)) % 360.0, 3).tolist(),
                np.round(np.abs(vel), 3).tolist(),
                np.round(np.degrees(u_ach), 4).tolist(),
                self.modes,
                strict=True,
            )
        )
        on_truth(rows)


class PatrolController:
    """The companions' patrol decisions for the whole fleet (all members in patrol mode)."""

    def __init__(self, mission: Mission) -> None:
        """Bind the mission's loop, gains and limits."""
        from companion.core.steering import phase_gains_m2_s

        self.mission = mission
        self.patrol = mission.patrol
        self.gains = mission.gains
        self.max_u = mission.vehicles.max_turn_rate_rad_s
        self.k_m = phase_gains_m2_s(self.patrol, self.gains, mission.vehicles.count)

    def shared_centres_phases(
        self, t_s: float, state: ParticleState, modes: list[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Centres (m) and phases (rad) the members share at ``t_s``."""
        return self.patrol.centre_and_phase(state.pos_m, state.heading_rad)

    def commands(
        self, t_s: float, state: ParticleState, modes: list[str]
    ) -> tuple[np.ndarray, list[str], list[Event]]:
        """Turn-rate commands (rad/s), the new modes and any events at ``t_s``."""
        from companion.core.steering import reference_centre, splay_gradient, steering_turn_rate

        centres, phases = self.shared_centres_phases(t_s, state, modes)
        grad = splay_gradient(phases, phases, self.k_m)
        c_ref = reference_centre(self.patrol, self.gains, centres)
        u = steering_turn_rate(
            self.patrol, self.gains, state.pos_m, state.heading_rad, grad, c_ref, self.max_u
        )
        return u, modes, []


__all__ = ["TRUTH_COLUMNS", "TWO_PI", "FleetSimulation", "Series"]
