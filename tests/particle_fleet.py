"""A guidance-level test double of the fleet: exact particles and a perfect group.

This is not the product's simulation. ``companion simulate`` (:mod:`companion.sim.inmemory`)
flies the real companion stack (``Runner``, MAVLink links, the signed group) against the
simulator; use it for anything the product does. This harness keeps only the decisions:
every vehicle is the :mod:`companion.core.particle` model flying the commanded turn rate and
airspeed exactly (no autopilot, no estimator, no setpoint shaping), every companion is a bare
:class:`companion.agent.agent.Agent` whose states and alerts reach every other one at once and
without loss, and the intruders and their detection are the simulator's world
(:class:`sitl_model.world.World`). It serves the tests of the steering law and of alert
logic that need the idealised fleet (``tests/test_steering.py``, the rejoin comparison in
``tests/test_alert_simulation.py``). Time is simulated seconds from 0, this object's own
counter, never the wall clock. It lives in the test tree so that ``companion`` never imports
``sitl_model`` outside its composition roots (``tests/test_layers.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from companion.agent.agent import Agent
from companion.agent.config import AgentConfig
from companion.agent.fix import Fix
from companion.core.measures import centre_error_m, convergence_time_s, splay_error_deg
from companion.core.particle import ParticleParams, ParticleState, step
from companion.group.messages import MemberState
from companion.mission import Mission
from sitl_model.world import World

TruthRow = tuple[float, int, float, float, float, float, float, float, float, str, float, float]
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
        agent_options: options for every :class:`companion.agent.agent.Agent`
            (:class:`companion.agent.config.AgentConfig`'s fields).
    """

    def __init__(
        self,
        mission: Mission,
        seed: int = 0,
        dt_s: float = 0.1,
        agent_options: dict[str, object] | None = None,
    ) -> None:
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
        self.airspeed_m_s = np.full(v.count, v.airspeed_m_s)  # as commanded, flown at once
        self.series = Series()
        self.events: list[Event] = []
        options = {"lead_s": 0.5 * self.dt_s, **(agent_options or {})}  # half a step ahead
        config = AgentConfig(**options)  # type: ignore[arg-type]
        self.agents = [Agent(s, mission, config) for s in v.sysids]
        self._index = {s: k for k, s in enumerate(v.sysids)}
        self.world = World(mission.intruders)  # the simulator's world (sitl_model.world)
        self.sensor_m = mission.sensor.footprint_radius_m

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
            u, shared, events = self._control(t)
            for ev in events:
                self.events.append(ev)
                if on_event is not None:
                    on_event(ev)
            self._sample(t, u, shared, on_truth)
            if self.step_index >= steps:
                break
            self.state = step(
                self.state, u, self.params, self.wind_m_s, self.dt_s, self.rng, self.airspeed_m_s
            )
            self.step_index += 1
        return self.series

    def _control(self, t: float) -> tuple[np.ndarray, list[MemberState], list[Event]]:
        """One control step of every companion, with a perfect in-memory group."""
        st = self.state
        events: list[Event] = []
        sightings, world_events = self.world.update(t, st.pos_m, self.sensor_m)
        for e in world_events:
            if e.event == "intruder_appeared":
                where = e.pos_m
                events.append(_ev(t, e.event, None, intruder=e.intruder_id, north_m=where.real,
                                  east_m=where.imag))  # fmt: skip
            elif e.event == "intruder_vanished":
                events.append(_ev(t, e.event, None, intruder=e.intruder_id))
        for sighting in sightings:
            self.agents[sighting.index].detect(sighting.pos_m, t)
        outs = [
            a.update(Fix(t, complex(st.pos_m[k]), float(st.heading_rad[k]), a.patrol))
            for k, a in enumerate(self.agents)
        ]
        for k, out in enumerate(outs):
            events.extend(out.events)
            for j, other in enumerate(self.agents):
                if j == k:
                    continue
                other.receive_state(out.broadcast, t)
                for alert in out.alerts_out:
                    other.receive_alert(alert, t)
        self.modes = [o.mode for o in outs]
        self.airspeed_m_s = np.array([o.airspeed_m_s for o in outs])
        u = np.array([o.turn_rate_rad_s for o in outs])
        return u, [o.broadcast for o in outs], events

    # Heading and course carry 5 decimals (1.7e-7 rad): a loop centre recomputed from the log
    # moves by R0 d(course), which is 0.9 m per 0.001 deg on a 50 km edge.
    def _sample(
        self,
        t: float,
        u: np.ndarray,
        shared: list[MemberState],
        on_truth: Callable[[list[TruthRow]], None] | None,
    ) -> None:
        st = self.state
        centres = np.array([m.centre_m for m in shared])
        phases = np.array([m.phase_rad for m in shared])
        self.series.t_s.append(t)
        self.series.splay_deg.append(splay_error_deg(phases))
        self.series.centre_m.append(centre_error_m(centres, self.patrol.centre_m))
        if on_truth is None:
            return
        wind = self.wind_m_s + st.gust_m_s
        vel = self.airspeed_m_s * np.exp(1j * st.heading_rad) + wind
        u_ach = np.clip(u, -self.params.max_turn_rate_rad_s, self.params.max_turn_rate_rad_s)
        rows = list(
            zip(
                [round(t, 3)] * len(self.sysids),
                self.sysids.tolist(),
                np.round(st.pos_m.real, 3).tolist(),
                np.round(st.pos_m.imag, 3).tolist(),
                self.alt_m.tolist(),
                np.round(np.degrees(st.heading_rad) % 360.0, 5).tolist(),
                np.round(np.degrees(np.angle(vel)) % 360.0, 5).tolist(),
                np.round(np.abs(vel), 3).tolist(),
                np.round(np.degrees(u_ach), 4).tolist(),
                self.modes,
                np.round(wind.real, 3).tolist(),
                np.round(wind.imag, 3).tolist(),
                strict=True,
            )
        )
        on_truth(rows)


def _ev(t_s: float, event: str, sysid: int | None, **fields: object) -> Event:
    out: Event = {"t_s": round(float(t_s), 3), "event": event}
    if sysid is not None:
        out["sysid"] = int(sysid)
    out.update(fields)
    return out


__all__ = ["FleetSimulation", "Series"]
