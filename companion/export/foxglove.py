"""Foxglove's well-known message schemas, as JSON Schema, and the messages in them (pure).

Foxglove (and Lichtblick) recognise a channel whose schema is named ``foxglove.<Name>`` and
draw it without configuration: :data:`LOCATION_FIX` on the Map panel, :data:`GEOJSON` on the
Map panel as shapes, :data:`POSE_IN_FRAME` and :data:`FRAME_TRANSFORM` in the 3D panel,
:data:`LOG` in the Log panel. Their JSON Schemas below follow the ones Foxglove publishes
(the fields we write; ``timestamp`` is ``{"sec", "nsec"}`` in the JSON encoding). Scalars
(velocity, battery, setpoint, mode) go out as plain JSON objects under a schema of our own,
:func:`plain_schema`, so that a Plot panel plots any numeric field
(``/uav1/battery.remaining_pct``) and a State Transitions panel any string.

Frames: ``local`` is the mission's local tangent plane as Foxglove's 3D panel wants a world
frame, ENU (x east, y north, z up, metres from the mission origin); each UAV's body frame
``uavN`` has x forward, y left, z up (a yaw about z from east, counter-clockwise). Our own
data are north/east/down and headings clockwise from north: :func:`enu_yaw_rad` converts.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = [
    "FRAME_TRANSFORM",
    "GEOJSON",
    "LOCAL_FRAME",
    "LOCATION_FIX",
    "LOG",
    "LOG_LEVELS",
    "POSE_IN_FRAME",
    "enu_yaw_rad",
    "frame_transform",
    "geojson",
    "location_fix",
    "log",
    "plain_schema",
    "pose_in_frame",
    "stamp",
    "time_ns",
    "yaw_quaternion",
]

LOCAL_FRAME = "local"
LOG_LEVELS = {"debug": 1, "info": 2, "warning": 3, "error": 4, "fatal": 5}

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}
_VECTOR3 = {
    "title": "foxglove.Vector3",
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z")},
}
_QUATERNION = {
    "title": "foxglove.Quaternion",
    "type": "object",
    "properties": {k: {"type": "number"} for k in ("x", "y", "z", "w")},
}


def _schema(name: str, description: str, properties: dict[str, Any]) -> dict[str, Any]:
    return {"title": name, "description": description, "type": "object", "properties": properties}


LOCATION_FIX = _schema(
    "foxglove.LocationFix",
    "A navigation satellite fix for any Global Navigation Satellite System",
    {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "latitude": {"type": "number", "description": "Latitude in degrees"},
        "longitude": {"type": "number", "description": "Longitude in degrees"},
        "altitude": {"type": "number", "description": "Altitude in meters"},
        "position_covariance": {
            "type": "array",
            "items": {"type": "number"},
            "minItems": 9,
            "maxItems": 9,
        },
        "position_covariance_type": {
            "title": "foxglove.PositionCovarianceType",
            "oneOf": [
                {"title": t, "const": i}
                for i, t in enumerate(("UNKNOWN", "APPROXIMATED", "DIAGONAL_KNOWN", "KNOWN"))
            ],
        },
    },
)
GEOJSON = _schema(
    "foxglove.GeoJSON",
    "GeoJSON data for annotating maps",
    {"geojson": {"type": "string", "description": "GeoJSON data encoded as a UTF-8 string"}},
)
POSE_IN_FRAME = _schema(
    "foxglove.PoseInFrame",
    "A timestamped pose for an object or reference frame in 3D space",
    {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "pose": {
            "title": "foxglove.Pose",
            "type": "object",
            "properties": {"position": _VECTOR3, "orientation": _QUATERNION},
        },
    },
)
FRAME_TRANSFORM = _schema(
    "foxglove.FrameTransform",
    "A transform between two reference frames in 3D space",
    {
        "timestamp": _TIME,
        "parent_frame_id": {"type": "string"},
        "child_frame_id": {"type": "string"},
        "translation": _VECTOR3,
        "rotation": _QUATERNION,
    },
)
LOG = _schema(
    "foxglove.Log",
    "A log message",
    {
        "timestamp": _TIME,
        "level": {
            "title": "foxglove.LogLevel",
            "oneOf": [
                {"title": t.upper(), "const": i} for t, i in [("unknown", 0), *LOG_LEVELS.items()]
            ],
        },
        "message": {"type": "string"},
        "name": {"type": "string"},
        "file": {"type": "string"},
        "line": {"type": "integer", "minimum": 0},
    },
)


def plain_schema(name: str, fields: dict[str, str]) -> dict[str, Any]:
    """A plain JSON object's schema ``name`` with ``fields`` (field -> JSON type: "number",
    "string", "integer", "boolean"); every field optional (absent: not known)."""
    return {
        "title": name,
        "type": "object",
        "properties": {k: {"type": t} for k, t in fields.items()},
    }


def stamp(t_unix_s: float) -> dict[str, int]:
    """A time (s since the Unix epoch) as Foxglove's JSON ``time``: ``{"sec", "nsec"}``, to
    the microsecond (:func:`time_ns`)."""
    ns = time_ns(t_unix_s)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def time_ns(t_unix_s: float) -> int:
    """A time (s since the Unix epoch) in ns, rounded to the microsecond: our logs carry
    microseconds at most (tlog stamps), and a float of today's Unix time holds them exactly
    (its step is 0.24 us) where ``round(t * 1e9)`` would be off by up to 120 ns."""
    return round(t_unix_s * 1e6) * 1000


def enu_yaw_rad(heading_deg: float) -> float:
    """The yaw about the local ENU frame's z axis (rad, counter-clockwise from east) of a
    heading (deg, clockwise from north)."""
    return math.radians(90.0 - heading_deg)


def yaw_quaternion(yaw_rad: float) -> dict[str, float]:
    """The quaternion ``{x, y, z, w}`` of a rotation by ``yaw_rad`` (rad) about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2.0), "w": math.cos(yaw_rad / 2.0)}


def location_fix(
    t_unix_s: float, frame_id: str, lat_deg: float, lon_deg: float, alt_m: float
) -> dict[str, Any]:
    """A ``foxglove.LocationFix`` at time ``t_unix_s`` (s): latitude and longitude (deg, WGS-84)
    and altitude (m above mean sea level); no covariance (type UNKNOWN)."""
    return {
        "timestamp": stamp(t_unix_s),
        "frame_id": frame_id,
        "latitude": lat_deg,
        "longitude": lon_deg,
        "altitude": alt_m,
        "position_covariance": [0.0] * 9,
        "position_covariance_type": 0,
    }


def pose_in_frame(
    t_unix_s: float, east_m: float, north_m: float, up_m: float, heading_deg: float
) -> dict[str, Any]:
    """A ``foxglove.PoseInFrame`` in :data:`LOCAL_FRAME` (ENU, m from the origin) with the
    yaw of ``heading_deg`` (deg, clockwise from north)."""
    return {
        "timestamp": stamp(t_unix_s),
        "frame_id": LOCAL_FRAME,
        "pose": {
            "position": {"x": east_m, "y": north_m, "z": up_m},
            "orientation": yaw_quaternion(enu_yaw_rad(heading_deg)),
        },
    }


def frame_transform(
    t_unix_s: float, child: str, east_m: float, north_m: float, up_m: float, heading_deg: float
) -> dict[str, Any]:
    """A ``foxglove.FrameTransform`` from :data:`LOCAL_FRAME` to the body frame ``child``."""
    return {
        "timestamp": stamp(t_unix_s),
        "parent_frame_id": LOCAL_FRAME,
        "child_frame_id": child,
        "translation": {"x": east_m, "y": north_m, "z": up_m},
        "rotation": yaw_quaternion(enu_yaw_rad(heading_deg)),
    }


def geojson(features: list[dict[str, Any]]) -> dict[str, Any]:
    """A ``foxglove.GeoJSON`` message holding a FeatureCollection of ``features``."""
    fc = {"type": "FeatureCollection", "features": features}
    return {"geojson": json.dumps(fc, separators=(",", ":"))}


def log(t_unix_s: float, level: str, message: str, name: str) -> dict[str, Any]:
    """A ``foxglove.Log`` line at ``t_unix_s`` (s); ``level`` a key of :data:`LOG_LEVELS`."""
    return {
        "timestamp": stamp(t_unix_s),
        "level": LOG_LEVELS[level],
        "message": message,
        "name": name,
        "file": "",
        "line": 0,
    }
