"""What a companion tells the ground stations on its autopilot link (pure; no sockets).

A ground station (QGroundControl, MAVProxy, Mission Planner) on the autopilot's link, or on
a router / the simulator's ``--gcs-out`` that forwards the companion's messages, sees:

* STATUSTEXT, at most 50 characters, ``"PP <sysid>: ..."``, made from the Agent's own events
  (:attr:`companion.agent.output.AgentOutput.events`; no decision is re-made here). Each
  companion reports what it did itself (its detection, its tasking, its confirmation or
  clear, its rejoin); what the whole fleet decides alike (a refusal by the fence, a member
  lost or joined, an alert re-queued, an operator's cancel) is reported by the member with
  the lowest system id only, so the operator reads it once. Severity by kind
  (:data:`TEXTS`); at most :data:`MAX_TEXTS_PER_S` per second of vehicle time, the rest
  counted in :attr:`GcsReport.suppressed`.
* NAMED_VALUE_FLOAT / NAMED_VALUE_INT every :data:`VALUE_PERIOD_S` of vehicle time (2 Hz),
  for graphs: ``pp_phs_err`` (deg), ``pp_xtrk`` (m), ``pp_mode`` (:data:`PP_MODE`) and
  ``pp_members``; with reliefs (a mission with a battery and spares) also ``pp_role``
  (:data:`PP_ROLE`), ``pp_batt`` (%, when known), ``pp_leave_s`` (s until it must leave,
  on station) and ``pp_rlf_s`` (s until its relief holds its slot, by the fleet's plan;
  ``inf``: no spare for it). ``time_boot_ms`` is the autopilot's (from the position report).

The names, units and texts are documented in ``docs/protocol.md`` ("What a ground station
sees"); keep the two in step.
"""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.core.wind import TWO_PI
from companion.group.messages import RELIEF_ROLES, Mode

VALUE_PERIOD_S = 0.5  # NAMED_VALUE_* period (vehicle s)
MAX_TEXTS_PER_S = 5  # STATUSTEXT budget per second of vehicle time
TEXT_MAX_CHARS = 50  # STATUSTEXT.text
PP_MODE = {mode: k for k, mode in enumerate(Mode)}  # pp_mode values: PATROL_MODE's
PP_ROLE = {role: k + 1 for k, role in enumerate(RELIEF_ROLES)}  # pp_role: PATROL_STATE's

ALERT, WARNING, NOTICE, INFO = (
    mav.MAV_SEVERITY_ALERT,
    mav.MAV_SEVERITY_WARNING,
    mav.MAV_SEVERITY_NOTICE,
    mav.MAV_SEVERITY_INFO,
)

# event -> (severity, who reports it: "own" = the UAV that did it, "fleet" = the lowest sysid)
TEXTS: dict[str, tuple[int, str]] = {
    "alert_new": (ALERT, "own"),
    "alert_tasked": (NOTICE, "own"),
    "prosecution_end": (WARNING, "own"),  # INFO when cleared (nothing seen)
    "rejoined": (INFO, "own"),
    "search_started": (NOTICE, "own"),
    "tracker_ended": (WARNING, "own"),
    "alert_lost": (WARNING, "fleet"),
    "plan_failed": (WARNING, "own"),
    "alert_refused": (WARNING, "fleet"),
    "alert_requeued": (NOTICE, "fleet"),
    "alert_cleared": (INFO, "fleet"),  # only an operator's cancel (detector 255)
    "member_lost": (WARNING, "fleet"),
    "member_joined": (INFO, "fleet"),
    "loop_infeasible": (WARNING, "fleet"),
    "loop_flyable": (INFO, "fleet"),
    "relief_late": (WARNING, "own"),  # announced before it is late
    "spare_no_launch": (WARNING, "own"),
    "spare_uncharged": (WARNING, "own"),
    "relief_refused": (WARNING, "fleet"),
    "relief_launched": (NOTICE, "own"),
    "relief_in_slot": (NOTICE, "own"),  # WARNING when it did not take off
    "relief_stood_down": (NOTICE, "own"),
    "relieved": (NOTICE, "own"),  # WARNING when nobody came
    "relief_landed": (INFO, "own"),
}


def _at(site: complex | None) -> str:
    return "" if site is None else f" at {site.real:.0f},{site.imag:.0f}"


def event_text(ev: dict[str, Any], sysid: int, site: complex | None) -> tuple[int, str] | None:
    """The (severity, text) a ground station gets for one Agent event, or None.

    ``site`` is the alert's site (m) when known. Whether this UAV is the one to report it
    is decided by :meth:`GcsReport.texts`.
    """
    name = ev.get("event")
    if name not in TEXTS:
        return None
    sev = TEXTS[name][0]
    aid = ev.get("alert_id", "")
    head = f"PP {sysid}: "
    if name == "alert_new":
        if not ev.get("own"):
            return None
        text = f"intruder {aid}{_at(site)}"
    elif name == "alert_tasked":
        if ev.get("prosecutor_sysid") != sysid:
            return None
        text = f"alert {aid}{_at(site)} -> UAV {sysid}"
    elif name == "prosecution_end":
        outcome = ev.get("outcome")
        sev = WARNING if outcome in ("confirmed", "tracking", "lost") else INFO
        text = {
            "confirmed": f"confirmed {aid}{_at(site)}",
            "tracking": f"tracking {aid}{_at(site)}",
            "cleared": f"cleared {aid}: nothing seen",
            "lost": f"lost {aid}: not found",
        }.get(str(outcome), f"{aid} {outcome}, flying back")
    elif name == "search_started":
        text = f"searching {aid}: {ev.get('sigma_m', 0):.0f} m sigma"
    elif name == "tracker_ended":
        text = f"track {aid} {ev.get('reason', '')} after {ev.get('tracked_s', 0):.0f} s"
    elif name == "alert_lost":
        text = f"track {aid} lost by UAV {ev.get('detector_sysid')}"
    elif name == "rejoined":
        text = f"back in slot after {aid}"
    elif name == "plan_failed":
        text = f"no path to {aid}"
    elif name == "alert_refused":
        text = f"refused {aid}{_at(site)}: {ev.get('reason', '')}"
    elif name == "alert_requeued":
        text = f"alert {aid} requeued"
    elif name == "alert_cleared":
        if ev.get("detector_sysid") != 255:
            return None
        text = f"alert {aid} cancelled by operator"
    elif name == "member_lost":
        text = f"lost UAV {ev.get('member_sysid')}, {ev.get('members')} on patrol"
    elif name == "loop_infeasible":
        text = (
            f"wind {ev.get('wind_speed_m_s', 0):.0f} m/s: loop needs "
            f"{ev.get('need_deg_s', 0):.0f} > {ev.get('limit_deg_s', 0):.0f} deg/s"
        )
    elif name == "loop_flyable":
        text = f"wind {ev.get('wind_speed_m_s', 0):.0f} m/s: loop flyable again"
    elif name.startswith("relie") or name in _SPARE_EVENTS:
        sev, text = _relief_text(name, ev, sev)
    else:  # member_joined
        text = f"UAV {ev.get('member_sysid')} joined, {ev.get('members')} on patrol"
    return sev, (head + text)[:TEXT_MAX_CHARS]


_SPARE_EVENTS = ("spare_no_launch", "spare_uncharged", "relief_refused")


def _relief_text(name: str, ev: dict[str, Any], sev: int) -> tuple[int, str]:
    """(severity, text without the head) of a relief event (docs/energy.md)."""
    if name == "relief_late":
        late = ev.get("late_s")
        if late is None:
            return sev, f"no spare: must leave at {ev.get('leave_t_s', 0):.0f} s"
        return sev, f"relief {late:.0f} s late (spare {ev.get('spare_sysid')})"
    if name == "spare_no_launch":
        return sev, f"spare {ev.get('spare_sysid')} did not launch"
    if name == "spare_uncharged":
        pct, need = ev.get("battery_pct", 0), ev.get("need_pct", 0)
        return sev, f"spare at {pct:.0f} %, needs {need:.0f}: unavailable"
    if name == "relief_refused":
        return sev, f"refused UAV {ev.get('member_sysid')} as {ev.get('role')}: not in mission"
    if name == "relief_launched":
        return sev, f"launched to relieve UAV {ev.get('member_sysid')}"
    if name == "relief_in_slot":
        if ev.get("reason") == "no_takeoff":
            return WARNING, "did not take off: unavailable"
        return sev, f"in UAV {ev.get('member_sysid')}'s slot ({ev.get('reason')})"
    if name == "relief_stood_down":
        how = "turning back" if ev.get("airborne") else "a spare again"
        return sev, f"UAV {ev.get('rival_sysid')} relieves UAV {ev.get('member_sysid')}: {how}"
    if name == "relieved":
        if ev.get("spare_sysid"):
            return sev, f"relieved by UAV {ev.get('spare_sysid')}, going home"
        return WARNING, "leave time: going home unrelieved"
    return sev, f"landed, ready at {ev.get('ready_t_s', 0):.0f} s"  # relief_landed


def phase_error_deg(own_phase_rad: float, others_rad: list[float]) -> float:
    """Gap to the member ahead in time-phase minus the ideal ``360 / N`` (deg).

    Positive: this UAV is further behind the member ahead than its share of the loop. 0 when
    it is alone.
    """
    if not others_rad:
        return 0.0
    ahead = min((p - own_phase_rad) % TWO_PI for p in others_rad)
    return math.degrees(ahead - TWO_PI / (len(others_rad) + 1))


class GcsReport:
    """Builds the STATUSTEXT and NAMED_VALUE_* messages of one companion."""

    def __init__(self, period_s: float = VALUE_PERIOD_S) -> None:
        """Nothing sent yet; values every ``period_s`` of vehicle time."""
        self.period_s = period_s
        self._last_values_s = -math.inf
        self._budget_t_s = -math.inf
        self._budget = MAX_TEXTS_PER_S
        self.suppressed = 0

    def messages(
        self,
        t_s: float,
        time_boot_ms: int,
        agent: Any,
        out: Any,
        pos_m: complex,
        course_rad: float | None = None,
    ) -> list[Any]:
        """The messages due after one Agent update at vehicle time ``t_s`` (s).

        Args:
            t_s: vehicle time (s).
            time_boot_ms: the autopilot's boot time of the state (ms), for NAMED_VALUE_*.
            agent: the :class:`companion.agent.agent.Agent` (its formation table and alerts).
            out: the :class:`companion.agent.output.AgentOutput` of that update.
            pos_m: own position (world, complex m).
            course_rad: own ground course (rad, compass), where the search for the nearest
                loop point starts (None: a global search, some 40 us).
        """
        msgs = [
            mav.MAVLink_statustext_message(sev, text.encode())
            for sev, text in self.texts(t_s, agent, out.events)
        ]
        if t_s - self._last_values_s >= self.period_s - 1e-9:
            self._last_values_s = t_s
            msgs += self.values(time_boot_ms, t_s, agent, out, pos_m, course_rad)
        return msgs

    def texts(self, t_s: float, agent: Any, events: Any) -> list[tuple[int, str]]:
        """(severity, text) for the events this UAV reports, within the text budget."""
        lowest = agent.sysid < min(agent.neighbours, default=256)
        out = []
        for ev in events:
            rule = TEXTS.get(ev.get("event"))
            if rule is None or (rule[1] == "fleet" and not lowest):
                continue
            rec = agent.alerts.get(ev.get("alert_id", ""))
            site = rec.alert.site_m if rec is not None else None
            if site is None and "north_m" in ev:
                site = complex(ev["north_m"], ev["east_m"])
            got = event_text(ev, agent.sysid, site)
            if got is None:
                continue
            if t_s - self._budget_t_s >= 1.0:
                self._budget_t_s, self._budget = t_s, MAX_TEXTS_PER_S
            if self._budget <= 0:
                self.suppressed += 1
                continue
            self._budget -= 1
            out.append(got)
        return out

    def values(
        self,
        time_boot_ms: int,
        t_s: float,
        agent: Any,
        out: Any,
        pos_m: complex,
        course_rad: float | None = None,
    ) -> list:
        """NAMED_VALUE_FLOAT pp_phs_err (deg), pp_xtrk (m); NAMED_VALUE_INT pp_mode,
        pp_members; with reliefs also pp_role, pp_batt (%), pp_leave_s (s), pp_rlf_s (s).
        ``pos_m`` (complex m) and ``course_rad`` (rad, compass) as :meth:`messages`'."""
        period = agent.patrol.period_s
        others = [
            n.state.phase_at(n.state.t_s + (t_s - n.rx_t_s), period)
            for n in agent.neighbours.values()
        ]
        err = phase_error_deg(out.broadcast.phase_rad, others)
        patrol = agent.patrol
        if course_rad is None:
            xtrk = patrol.phase_and_offset_of_point(pos_m)[1]
        else:  # Newton from the tangent parallel to the course, as a Fix's
            xtrk = abs(patrol.loop_point_on_course(pos_m, course_rad).offset_m)
        ms = int(time_boot_ms) & 0xFFFFFFFF
        return [
            mav.MAVLink_named_value_float_message(ms, b"pp_phs_err", float(err)),
            mav.MAVLink_named_value_float_message(ms, b"pp_xtrk", float(xtrk)),
            mav.MAVLink_named_value_int_message(ms, b"pp_mode", PP_MODE.get(out.mode, 255)),
            mav.MAVLink_named_value_int_message(ms, b"pp_members", len(others) + 1),
            *relief_values(ms, t_s, getattr(agent, "duty", None)),
        ]


def relief_values(ms: int, t_s: float, duty: Any) -> list:
    """The reliefs' NAMED_VALUE_* of one UAV at vehicle time ``t_s`` (s) from its
    :class:`companion.agent.relief.duty.Duty` (none when the reliefs are off): pp_role,
    pp_batt (% left, when known), pp_leave_s (s until it must leave; on station, when
    known), pp_rlf_s (s until its relief holds its slot by the plan; inf: no spare)."""
    e = duty.energy() if duty is not None else None
    if e is None:
        return []
    out = [mav.MAVLink_named_value_int_message(ms, b"pp_role", PP_ROLE.get(e.role, 0))]
    if e.battery_pct is not None:
        out.append(mav.MAVLink_named_value_float_message(ms, b"pp_batt", float(e.battery_pct)))
    if e.role == "on_station" and e.t_s is not None:
        out.append(mav.MAVLink_named_value_float_message(ms, b"pp_leave_s", float(e.t_s - t_s)))
        mine = duty.plan.of_member(duty.sysid) if duty.plan is not None else None
        if mine is not None and not mine.under_way:
            rlf = mine.on_station_t_s - t_s
            out.append(mav.MAVLink_named_value_float_message(ms, b"pp_rlf_s", float(rlf)))
    return out
