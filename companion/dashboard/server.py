"""The live patrol page's web server (aiohttp): the page, its JSON API and the group edge.

One process: an asyncio loop that

* listens to the signed group as a passive member (a non-blocking :class:`Group` in the
  loop's reader; it never sends a state) and feeds a :class:`FleetView`;
* serves ``/`` (one static HTML page with vanilla JS, shipped as package data),
  ``/api/mission`` (the fixed geometry), ``/api/state`` (a snapshot), ``/api/stream``
  (server-sent events, a snapshot every ``STREAM_PERIOD_S``), and ``POST /api/alert`` /
  ``POST /api/cancel``, which sign and send an operator alert (state new) or clear one
  (state cleared, detector 255) exactly as ``companion alert`` does
  (:func:`companion.group.operator.send_copies`), from a second group socket in a worker
  thread so the loop never blocks.

Security (see ``docs/dashboard.md``): with a token every request must carry it (header
``X-Dashboard-Token`` or query ``token``), else 403 and nothing is sent; a POST must be JSON
(a cross-site form cannot be) and, when the browser names an ``Origin``, come from the page's
own host; a server bound to loopback answers only requests addressed to a loopback host name
(no DNS rebinding). Input is checked: finite numbers within ``MAX_DISTANCE_M`` of the origin.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import json
import math
import time
from concurrent.futures import ThreadPoolExecutor
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

import pymap3d
from aiohttp import web

from companion.dashboard.geometry import Geometry
from companion.dashboard.model import FleetView
from companion.group.codec import ALERT_ID_MAX, OPERATOR_SYSID
from companion.group.messages import Alert
from companion.group.operator import MAX_DISTANCE_M, default_alert_id, send_copies
from companion.group.transport import Group
from companion.mission import Mission

__all__ = ["STREAM_PERIOD_S", "Dashboard", "is_loopback"]

STREAM_PERIOD_S = 0.2  # server-sent snapshots: 5 a second
REPEAT = 3  # copies of each operator alert, as ``companion alert`` sends by default
INTERVAL_S = 0.2  # between copies (s)
TOKEN_HEADER = "X-Dashboard-Token"
MAX_BODY = 4096  # bytes of a POST body


def is_loopback(host: str) -> bool:
    """Whether a bind address or host name is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class Dashboard:
    """The web application around one :class:`FleetView`.

    Args:
        view: the model fed from the group.
        mission: the mission (geometry, origin for lat/lon), or None.
        listener: the passive group socket (its decoder hears every sender).
        sender: the operator's group socket (system id 255, component 190), used only to
            send the alerts and cancels the operator asks for.
        token: required on every request when not None.
        loopback_only_hosts: refuse requests whose Host is not a loopback name (set when
            the server is bound to loopback).
    """

    def __init__(
        self,
        view: FleetView,
        mission: Mission | None,
        listener: Group,
        sender: Group,
        *,
        token: str | None = None,
        loopback_only_hosts: bool = True,
    ) -> None:
        """Build the aiohttp application (nothing listens until it is run)."""
        self.view = view
        self.mission = mission
        self.geometry = Geometry.of(mission).to_json() if mission is not None else None
        self.listener = listener
        self.sender = sender
        self.token = token
        self.loopback_only_hosts = loopback_only_hosts
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="operator-send")
        self._page = (
            resources.files("companion.dashboard").joinpath("static/index.html").read_bytes()
        )
        self.app = web.Application(middlewares=[self._guard], client_max_size=MAX_BODY)
        self.app.add_routes(
            [
                web.get("/", self._index),
                web.get("/api/mission", self._mission),
                web.get("/api/state", self._state),
                web.get("/api/stream", self._stream),
                web.post("/api/alert", self._alert),
                web.post("/api/cancel", self._cancel),
            ]
        )
        self.app.on_startup.append(self._on_startup)
        self.app.on_shutdown.append(self._on_shutdown)
        self.app.on_cleanup.append(self._on_cleanup)
        self._closing: asyncio.Event | None = None

    # ---- group ----------------------------------------------------------------------------
    async def _on_startup(self, _app: web.Application) -> None:
        self._closing = asyncio.Event()
        asyncio.get_running_loop().add_reader(self.listener.fileno(), self._read_group)

    async def _on_shutdown(self, _app: web.Application) -> None:
        if self._closing is not None:
            self._closing.set()  # end the open event streams, so shutdown is prompt

    async def _on_cleanup(self, _app: web.Application) -> None:
        asyncio.get_running_loop().remove_reader(self.listener.fileno())
        self._pool.shutdown(wait=True)

    def _read_group(self) -> None:
        now = time.monotonic()
        for msg in self.listener.receive(self.view.vehicle_time_at(now)):
            self.view.feed(msg, now)

    def snapshot(self, events: int = 60) -> dict[str, Any]:
        """The view's snapshot now, with the group's counters."""
        snap = self.view.snapshot(time.monotonic(), events=events)
        snap["group"] = dict(self.listener.stats)
        return snap

    # ---- security -------------------------------------------------------------------------
    @web.middleware
    async def _guard(self, request: web.Request, handler: Any) -> web.StreamResponse:
        if self.loopback_only_hosts and not is_loopback(_host_name(request.host)):
            return _error(403, "this dashboard answers only on a loopback address")
        if self.token is not None:
            given = request.headers.get(TOKEN_HEADER) or request.query.get("token", "")
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return _error(403, "a valid token is required (X-Dashboard-Token or ?token=)")
        if request.method == "POST":
            if request.content_type != "application/json":
                return _error(415, "send application/json")
            origin = request.headers.get("Origin")
            if origin is not None and urlsplit(origin).netloc != request.host:
                return _error(403, f"cross-origin request from {origin} refused")
        return await handler(request)

    # ---- pages ----------------------------------------------------------------------------
    async def _index(self, _request: web.Request) -> web.Response:
        return web.Response(
            body=self._page,
            content_type="text/html",
            headers={
                "Cache-Control": "no-store",
                "Content-Security-Policy": "default-src 'self'; script-src 'unsafe-inline'; "
                "style-src 'unsafe-inline'; img-src 'self' data:; frame-ancestors 'none'",
                "X-Frame-Options": "DENY",
            },
        )

    async def _mission(self, _request: web.Request) -> web.Response:
        return web.json_response({"mission": self.geometry})

    async def _state(self, request: web.Request) -> web.Response:
        try:
            n = max(0, min(500, int(request.query.get("events", "60"))))
        except ValueError:
            return _error(400, "events must be an integer")
        return web.json_response(self.snapshot(events=n))

    async def _stream(self, request: web.Request) -> web.StreamResponse:
        resp = web.StreamResponse(
            headers={"Content-Type": "text/event-stream", "Cache-Control": "no-store"}
        )
        await resp.prepare(request)
        closing = self._closing or asyncio.Event()
        try:
            while not closing.is_set():
                data = json.dumps(self.snapshot(), separators=(",", ":"), allow_nan=False)
                await resp.write(f"event: state\ndata: {data}\n\n".encode())
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(closing.wait(), STREAM_PERIOD_S)
        except ConnectionResetError:
            pass  # the page went away
        return resp

    # ---- operator actions -----------------------------------------------------------------
    async def _alert(self, request: web.Request) -> web.Response:
        body = await _json_body(request)
        if isinstance(body, web.Response):
            return body
        try:
            site = self._site(body)
        except ValueError as exc:
            return _error(400, str(exc))
        alert_id = body.get("alert_id")
        if alert_id is None:
            alert_id = default_alert_id(time.time())
        if (
            not isinstance(alert_id, str)
            or not 1 <= len(alert_id) <= ALERT_ID_MAX
            or not alert_id.isascii()
            or not alert_id.isprintable()
        ):
            return _error(400, f"alert_id: 1 to {ALERT_ID_MAX} printable ASCII characters")
        if alert_id in self.view.alerts:
            return _error(409, f"alert {alert_id} exists already")
        t_s = self.view.vehicle_time_at(time.monotonic())
        alert = Alert(alert_id, site, OPERATOR_SYSID, t_s, "new")
        sent = await self._send(alert)
        self.view.note(
            "operator_alert",
            f"operator raised alert {alert_id} at ({site.real:.0f}, {site.imag:.0f}) m",
            alert_id=alert_id,
        )
        return web.json_response(_sent_json(alert, sent))

    async def _cancel(self, request: web.Request) -> web.Response:
        body = await _json_body(request)
        if isinstance(body, web.Response):
            return body
        alert_id = body.get("alert_id")
        rec = self.view.alerts.get(alert_id) if isinstance(alert_id, str) else None
        if rec is None:
            return _error(404, f"no alert {alert_id!r} known")
        if rec.state in ("cleared", "lost"):
            return _error(409, f"alert {alert_id} is already {rec.state}")
        t_s = self.view.vehicle_time_at(time.monotonic())
        alert = Alert(rec.alert_id, rec.site_m, OPERATOR_SYSID, t_s, "cleared")
        sent = await self._send(alert)
        self.view.note("operator_cancel", f"operator cleared alert {alert_id}", alert_id=alert_id)
        return web.json_response(_sent_json(alert, sent))

    async def _send(self, alert: Alert) -> int:
        """Send ``alert`` (signed, ``REPEAT`` copies) from the worker thread; datagrams sent."""
        return await asyncio.get_running_loop().run_in_executor(self._pool, self._send_now, alert)

    def _send_now(self, alert: Alert) -> int:
        """In the one worker thread, so the sender's signing state is touched by one thread."""
        if self.sender.signing is not None and self.listener.signing is not None:
            # never sign below a timestamp heard on the group (MAVLink's rule)
            self.sender.signing.observe(self.listener.signing.last)
        return send_copies(self.sender, alert, REPEAT, INTERVAL_S)

    def _site(self, body: dict[str, Any]) -> complex:
        """The site (north + i east, m) of a request: ``north_m``/``east_m`` or, with a
        mission, ``lat_deg``/``lon_deg``; ValueError when it is not a sane point."""
        if "north_m" in body or "east_m" in body:
            north, east = _number(body, "north_m"), _number(body, "east_m")
        elif "lat_deg" in body or "lon_deg" in body:
            if self.mission is None:
                raise ValueError("lat_deg/lon_deg need the dashboard's --mission (origin)")
            lat, lon = _number(body, "lat_deg"), _number(body, "lon_deg")
            if not (-90 <= lat <= 90 and -180 <= lon <= 180):
                raise ValueError("lat_deg/lon_deg: not a position")
            o = self.mission.origin
            n, e, _ = pymap3d.geodetic2ned(lat, lon, o.alt_m, o.lat_deg, o.lon_deg, o.alt_m)
            north, east = float(n), float(e)
        else:
            raise ValueError("give north_m and east_m (or lat_deg and lon_deg)")
        if max(abs(north), abs(east)) > MAX_DISTANCE_M:
            raise ValueError(f"the site is more than {MAX_DISTANCE_M:g} m from the origin")
        return complex(north, east)


def _number(body: dict[str, Any], key: str) -> float:
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{key}: expected a finite number")
    return float(v)


async def _json_body(request: web.Request) -> dict[str, Any] | web.Response:
    try:
        body = await request.json()
    except (ValueError, UnicodeDecodeError):
        return _error(400, "the body is not JSON")
    except web.HTTPRequestEntityTooLarge:
        return _error(413, "the body is too large")
    if not isinstance(body, dict):
        return _error(400, "the body must be a JSON object")
    return body


def _sent_json(alert: Alert, sent: int) -> dict[str, Any]:
    return {
        "alert_id": alert.alert_id,
        "state": alert.state,
        "north_m": round(alert.site_m.real, 3),
        "east_m": round(alert.site_m.imag, 3),
        "detector_sysid": alert.detector_sysid,
        "time_usec": round(alert.t_s * 1e6),
        "sent": sent,
    }


def _host_name(host: str) -> str:
    """The name part of a Host header (``[::1]:8080`` -> ``::1``, ``a:80`` -> ``a``)."""
    if host.startswith("["):
        return host[1 : host.find("]")] if "]" in host else host
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


def _error(status: int, message: str) -> web.Response:
    return web.json_response({"error": message}, status=status)
