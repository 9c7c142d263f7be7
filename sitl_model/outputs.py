"""What the simulator emits after each physics step, whatever carries it (pure).

:func:`after_step` turns one :meth:`Simulation.step` into outputs for a transport: the
event records for ``events.jsonl``, the messages each vehicle sends (STATUSTEXT for events
with a text, MISSION_ITEM_REACHED, due telemetry, camera detections from component 100)
and the truth rows due at this step. The UDP server and the in-memory engine
(:mod:`companion.sim.inmemory`) both send exactly these, so the two transports see one world.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from sitl_model.codec import dialect
from sitl_model.link import VehicleLink
from sitl_model.sim import SENSOR_EVERY, TRUTH_EVERY, Simulation

CAMERA_EVERY = SENSOR_EVERY * 2  # detection reports at 5 Hz simulated


@dataclass
class StepOutput:
    """Outputs of one step.

    Attributes:
        events: event records (``t_s`` s rounded to ms, ``event``, ``sysid`` if any, fields).
        sends: (vehicle index, message, sent by the camera component) to every peer, in order.
        truth: CSV rows of the truth log due at this step (empty when none is due).
    """

    events: list[dict[str, Any]] = field(default_factory=list)
    sends: list[tuple[int, Any, bool]] = field(default_factory=list)
    truth: list[str] = field(default_factory=list)


def event_record(t_s: float, event: str, sysid: int | None, data: dict) -> dict[str, Any]:
    """One ``events.jsonl`` record of the simulator: time (s), name, vehicle, fields."""
    rec: dict[str, Any] = {"t_s": round(t_s, 3), "event": event}
    if sysid is not None:
        rec["sysid"] = sysid
    rec.update(data)
    return rec


def after_step(sim: Simulation, links: list[VehicleLink]) -> StepOutput:
    """Everything the simulator emits after the step it just took (advances the streams)."""
    out = StepOutput()
    for e in sim.drain_events():
        out.events.append(
            event_record(e.t_s, e.event, e.sysid, e.data | ({"text": e.text} if e.text else {}))
        )
        if e.sysid is None:
            continue
        i = sim.index_of[e.sysid]
        if e.text:
            out.sends.append((i, links[i].statustext(e.text, e.severity), False))
        if e.event == "waypoint_reached":
            msg = dialect.MAVLink_mission_item_reached_message(e.data["seq"])
            out.sends.append((i, msg, False))
    for i, link in enumerate(links):
        for m in link.due_telemetry():
            out.sends.append((i, m, False))
    if sim.steps % CAMERA_EVERY == 0 and sim.sightings:
        for s in sim.sightings:
            tm = links[s.index].tm
            msg = tm.camera_tracking(s.index, s.pos_m, s.vel_m_s, s.distance_m)
            out.sends.append((s.index, msg, True))
    if sim.steps % TRUTH_EVERY == 0:
        out.truth = sim.truth_rows()
    return out
