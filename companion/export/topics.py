"""What a run becomes in MCAP: topics, their schemas, and the messages (pure).

:func:`messages` turns a :class:`~companion.export.model.RunFolder` into
:class:`Message` records (topic, vehicle time, a JSON-ready dict), and :data:`SCHEMAS` says
which schema each topic's messages follow (:mod:`companion.export.foxglove`). Per UAV ``N``:

========================  ======================  ==========================================
topic                     schema                  from
========================  ======================  ==========================================
``/uavN/fix``             foxglove.LocationFix    truth.csv, else the tlog's
                                                  GLOBAL_POSITION_INT (lat, lon, m AMSL)
``/uavN/pose``            foxglove.PoseInFrame    the same, in frame ``local`` (ENU m)
``/uavN/tf``              foxglove.FrameTransform ``local`` -> ``uavN``
``/uavN/velocity``        patrol.Velocity         truth (ground speed, course, turn rate)
                                                  or GLOBAL_POSITION_INT (vx, vy, vz)
``/uavN/setpoint``        patrol.Setpoint         the tlog: every setpoint the companion sent
                                                  (:func:`companion.link.setpoints.describe`)
``/uavN/targets``         patrol.Targets          the ``guided_targets`` events (airspeed,
                                                  altitude asked of the autopilot)
``/uavN/mode``            patrol.Mode             truth's mode column, or the autopilot's
                                                  HEARTBEAT; one message per change
``/uavN/battery``         patrol.Battery          truth's battery columns, or SYS_STATUS and
                                                  BATTERY_STATUS
========================  ======================  ==========================================

and for the run: ``/mission/loop`` and ``/mission/fence`` (foxglove.GeoJSON, once at the
start), ``/alerts`` (foxglove.GeoJSON: every alert so far with its state, at each change)
with ``/alerts/changes`` (patrol.Alert, one per change: the first report of an alert id in
each state, whoever logged it), ``/tracks`` (foxglove.GeoJSON: each alert's newest track)
with ``/tracks/sightings`` (patrol.Sighting, one per ``sighted`` event), and ``/events``
(foxglove.Log: every event, and the autopilots' STATUSTEXT).

Positions: truth is already local (north, east, alt above the origin); a tlog's fixes are put
in the local frame at the mission's origin (pymap3d, WGS-84), or, without a mission, at the
first fix's home (lat, lon and ``alt - relative_alt``). Times are vehicle time, unix s.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from companion.export import foxglove as fg
from companion.export.model import Message, Origin, RunFolder
from companion.export.vehicles import vehicle_messages

__all__ = ["SCHEMAS", "messages", "origin_of", "topic_schema"]

NUMBER, STRING, INTEGER, BOOLEAN = "number", "string", "integer", "boolean"
SCHEMAS: dict[str, dict[str, Any]] = {
    s["title"]: s
    for s in (
        fg.LOCATION_FIX,
        fg.POSE_IN_FRAME,
        fg.FRAME_TRANSFORM,
        fg.GEOJSON,
        fg.LOG,
        fg.plain_schema(
            "patrol.Velocity",
            {
                "north_m_s": NUMBER,
                "east_m_s": NUMBER,
                "down_m_s": NUMBER,
                "groundspeed_m_s": NUMBER,
                "course_deg": NUMBER,
                "heading_deg": NUMBER,
                "turn_rate_deg_s": NUMBER,
            },
        ),
        fg.plain_schema(
            "patrol.Setpoint",
            {
                "kind": STRING,
                "turn_rate_rad_s": NUMBER,
                "roll_rad": NUMBER,
                "pitch_rad": NUMBER,
                "thrust": NUMBER,
                "course_rad": NUMBER,
                "accel_m_s2": NUMBER,
                "lat_deg": NUMBER,
                "lon_deg": NUMBER,
                "alt_amsl_m": NUMBER,
                "vn_m_s": NUMBER,
                "ve_m_s": NUMBER,
                "an_m_s2": NUMBER,
                "ae_m_s2": NUMBER,
            },
        ),
        fg.plain_schema("patrol.Targets", {"airspeed_m_s": NUMBER, "alt_amsl_m": NUMBER}),
        fg.plain_schema("patrol.Mode", {"mode": STRING, "armed": BOOLEAN}),
        fg.plain_schema(
            "patrol.Battery",
            {
                "remaining_pct": NUMBER,
                "consumed_mah": NUMBER,
                "energy_wh": NUMBER,
                "voltage_v": NUMBER,
                "current_a": NUMBER,
            },
        ),
        fg.plain_schema(
            "patrol.Alert",
            {
                "alert_id": STRING,
                "state": STRING,
                "north_m": NUMBER,
                "east_m": NUMBER,
                "detector_sysid": INTEGER,
                "logged_by": INTEGER,
            },
        ),
        fg.plain_schema(
            "patrol.Sighting",
            {
                "alert_id": STRING,
                "sysid": INTEGER,
                "north_m": NUMBER,
                "east_m": NUMBER,
                "speed_m_s": NUMBER,
                "sigma_m": NUMBER,
                "sightings": INTEGER,
            },
        ),
    )
}
UAV_TOPICS = {  # topic under /uavN -> schema
    "fix": "foxglove.LocationFix",
    "pose": "foxglove.PoseInFrame",
    "tf": "foxglove.FrameTransform",
    "velocity": "patrol.Velocity",
    "setpoint": "patrol.Setpoint",
    "targets": "patrol.Targets",
    "mode": "patrol.Mode",
    "battery": "patrol.Battery",
}
RUN_TOPICS = {
    "/mission/loop": "foxglove.GeoJSON",
    "/mission/fence": "foxglove.GeoJSON",
    "/alerts": "foxglove.GeoJSON",
    "/alerts/changes": "patrol.Alert",
    "/tracks": "foxglove.GeoJSON",
    "/tracks/sightings": "patrol.Sighting",
    "/events": "foxglove.Log",
}
ALERT_STATES = {  # alert event -> the state it reports
    "alert_new": "new",
    "alert_received": "new",
    "alert_confirmed": "confirmed",
    "alert_cleared": "cleared",
    "alert_lost": "lost",
    "alert_refused": "refused",
}
WARNING_EVENTS = ("lost", "refused", "late", "timeout", "override", "overflow", "failed")
LOOP_POINTS = 360  # points of the loop's line on the map


def topic_schema(topic: str) -> str:
    """The schema name of ``topic`` (KeyError for a topic not made here)."""
    if topic in RUN_TOPICS:
        return RUN_TOPICS[topic]
    head, _, tail = topic.strip("/").partition("/")
    if head.startswith("uav") and head[3:].isdigit():
        return UAV_TOPICS[tail]
    raise KeyError(topic)


def origin_of(run: RunFolder) -> Origin | None:
    """The mission's origin, else the first tlog fix's home; None when there is neither."""
    if run.mission is not None:
        o = run.mission.origin
        return Origin(o.lat_deg, o.lon_deg, o.alt_m, "mission")
    for tl in run.tlogs.values():
        for m in tl.messages:
            if m.get_type() == "GLOBAL_POSITION_INT" and (m.lat or m.lon):
                home_m = (m.alt - m.relative_alt) / 1000.0
                return Origin(m.lat * 1e-7, m.lon * 1e-7, home_m, "first fix")
    return None


def messages(run: RunFolder) -> Iterator[Message]:
    """Every message of the run's export (see the module doc), per topic in time order."""
    origin = origin_of(run)
    yield from vehicle_messages(run, origin)
    if run.mission is not None and origin is not None:
        yield from _mission_shapes(run, origin, _first_time(run))
    yield from _alerts(run.events, origin)
    yield from _tracks(run.events, origin)
    yield from _log(run)


def _first_time(run: RunFolder) -> float:
    times = [float(tr.t_unix_s[0]) for tr in run.truth.values() if len(tr.t_unix_s)]
    times += [tl.messages[0]._timestamp for tl in run.tlogs.values() if tl.messages]
    times += [run.events[0]["t_unix_s"]] if run.events else []
    return min(times) if times else 0.0


# ---- the mission, alerts and tracks --------------------------------------------------------
def _lonlat(origin: Origin, pts_m: np.ndarray) -> list[list[float]]:
    """GeoJSON positions ``[lon, lat]`` of local points (complex north + i east, m)."""
    pts = np.asarray(pts_m, dtype=complex)
    lat, lon, _ = origin.to_geodetic(pts.real, pts.imag, np.zeros(pts.shape))
    return [[round(float(a), 8), round(float(b), 8)] for a, b in zip(lon, lat, strict=True)]


def _mission_shapes(run: RunFolder, origin: Origin, t0: float) -> Iterator[Message]:
    mission = run.mission
    assert mission is not None
    loop = np.asarray(mission.patrol.sample_by_time(LOOP_POINTS), dtype=complex)
    ring = _lonlat(origin, np.append(loop, loop[0]))
    features = [
        {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": ring},
            "properties": {"name": "patrol loop", "period_s": mission.patrol.period_s},
        }
    ]
    for sp in mission.vehicles.spares:
        features.append(
            {
                "type": "Feature",
                "properties": {"name": f"base of spare {sp.sysid}"},
                "geometry": {"type": "Point", "coordinates": _lonlat(origin, [sp.base_m])[0]},
            }
        )
    yield Message("/mission/loop", t0, fg.geojson(features))
    if mission.fence is not None:
        f = mission.fence
        poly = [complex(v.north_m, v.east_m) for v in f.vertices]
        shape = {"type": "Polygon", "coordinates": [_lonlat(origin, [*poly, poly[0]])]}
        props = {"name": "geofence", "min_alt_m": f.min_alt_m, "max_alt_m": f.max_alt_m}
        yield Message(
            "/mission/fence",
            t0,
            fg.geojson([{"type": "Feature", "geometry": shape, "properties": props}]),
        )


def _alerts(events: list[dict[str, Any]], origin: Origin | None) -> Iterator[Message]:
    """One change per alert id and state (the first report, whoever logged it)."""
    known: dict[str, dict[str, Any]] = {}
    said: set[tuple[str, str]] = set()
    for ev in events:
        state = ALERT_STATES.get(ev.get("event", ""))
        alert_id = ev.get("alert_id")
        if state is None or not isinstance(alert_id, str) or (alert_id, state) in said:
            continue
        if state == "new" and alert_id in known:
            continue  # a later first report of one already known (heard in a later state)
        said.add((alert_id, state))
        rec = known.setdefault(alert_id, {"alert_id": alert_id})
        rec["state"] = state
        for k in ("north_m", "east_m"):
            if isinstance(ev.get(k), int | float) and k not in rec:
                rec[k] = float(ev[k])
        if isinstance(ev.get("detector_sysid"), int):
            rec["detector_sysid"] = ev["detector_sysid"]
        t = ev["t_unix_s"]
        yield Message("/alerts/changes", t, dict(rec, logged_by=ev.get("sysid")))
        if origin is not None:
            yield Message(
                "/alerts",
                t,
                fg.geojson(
                    [
                        _point(origin, r["north_m"], r["east_m"], dict(r))
                        for r in known.values()
                        if "north_m" in r
                    ]
                ),
            )


def _tracks(events: list[dict[str, Any]], origin: Origin | None) -> Iterator[Message]:
    """Each ``sighted`` event, and the newest track of every alert after it."""
    newest: dict[str, dict[str, Any]] = {}
    for ev in events:
        if ev.get("event") != "sighted" or not isinstance(ev.get("alert_id"), str):
            continue
        s = {
            "alert_id": ev["alert_id"],
            "sysid": ev.get("sysid"),
            "north_m": float(ev["north_m"]),
            "east_m": float(ev["east_m"]),
            "speed_m_s": float(ev["speed_m_s"]),
            "sigma_m": float(ev["sigma_m"]),
            "sightings": int(ev["sightings"]),
        }
        t = ev["t_unix_s"]
        yield Message("/tracks/sightings", t, s)
        newest[s["alert_id"]] = s
        if origin is not None:
            yield Message(
                "/tracks",
                t,
                fg.geojson([_point(origin, r["north_m"], r["east_m"], r) for r in newest.values()]),
            )


def _point(origin: Origin, north_m: float, east_m: float, props: dict) -> dict[str, Any]:
    coords = _lonlat(origin, [complex(north_m, east_m)])[0]
    return {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": coords},
        "properties": props,
    }


def _log(run: RunFolder) -> Iterator[Message]:
    """Every event as a log line, then the autopilots' STATUSTEXT."""
    for ev in run.events:
        kind = str(ev.get("event", ""))
        rest = {
            k: v for k, v in ev.items() if k not in ("event", "t_s", "t_unix_s", "source", "sysid")
        }
        text = kind + "".join(f" {k}={v}" for k, v in sorted(rest.items()))
        who = f"uav{ev['sysid']}" if isinstance(ev.get("sysid"), int) else "sim"
        if ev.get("source") == "sim" and who != "sim":
            who = f"sim/{who}"
        level = "warning" if any(w in kind for w in WARNING_EVENTS) else "info"
        yield Message("/events", ev["t_unix_s"], fg.log(ev["t_unix_s"], level, text, who))
    for tl in run.tlogs.values():
        for m in tl.messages:
            if m.get_type() == "STATUSTEXT":
                sev = int(m.severity)
                level = (
                    "fatal"
                    if sev <= 2
                    else "error"
                    if sev == 3
                    else ("warning" if sev == 4 else "info" if sev <= 6 else "debug")
                )
                name = f"uav{tl.sysid}/{m.get_srcComponent()}"
                t = float(m._timestamp)
                yield Message("/events", t, fg.log(t, level, str(m.text), name))
