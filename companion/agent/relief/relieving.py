"""A relieving spare's decisions besides its way in (pure; docs/energy.md, "Reliefs"): when
a committed spare goes, whether another has its member, when it holds the slot, and the
formation whose steering law settles it there. Its way in is
:mod:`companion.agent.relief.fly_in`; the duty (:mod:`companion.agent.relief.duty`) makes
the changes of state these lead to. Positions complex m, angles rad, times vehicle s.
"""

from __future__ import annotations

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbour, Neighbours
from companion.agent.relief.figures import Figures
from companion.agent.relief.fly_in import behind_rad, meet, meet_loop
from companion.agent.relief.join import inside, slot_phase
from companion.agent.relief.records import Flight, Relieving
from companion.agent.relief.states import DutyStep
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI, wrap_pi
from companion.group.messages import OUT_OF_FORMATION, Mode
from companion.guidance.formation import splay_airspeed, splay_command
from companion.guidance.steering import Gains, speed_holds_phase

IN_SLOT_M = 20.0  # along the loop from the member's slot, and off the loop (m)
IN_SLOT_S = 3.0  # held this long (s)
TAKEOVER_LIMIT_PERIODS = 4.0  # after this many T flying in, it takes the slot as it is
WAIT_PERIODS = 1.2  # a committed spare waits at most this many T for its slot to come round
LAUNCH_SLACK_S = 2.0  # ... and goes when it would meet the slot no more than this early (s)


def rival(rec: Relieving, heard: Neighbours, sysid: int) -> int | None:
    """Another UAV that has spare ``sysid``'s member: one flying in for it with a lower
    sysid (the tie-break every spare applies the same way), or one on station that says it
    took the slot; its sysid, or None."""
    for s, n in sorted(heard.table.items()):
        e = n.state.energy
        if s == sysid or e is None or e.relief_sysid != rec.member:
            continue
        if (e.role == "relieving" and s < sysid) or e.role == "on_station":
            return s
    return None


def when_to_go(
    fig: Figures, fix: Fix, member: Neighbour | None, since_t_s: float
) -> tuple[bool, complex | None]:
    """Committed since ``since_t_s`` (s): whether it goes now, and the lane point (m) it
    flies to then (None: none kept). It goes when its member's slot comes round (it would
    reach the lane point, or where no lane point fits the loop, no more than
    ``LAUNCH_SLACK_S`` early), at once if the slot is open (its ``member`` unheard, or not
    on patrol), or ``WAIT_PERIODS`` T after it was booked."""
    t_s, patrol = fix.t_s, fix.patrol
    found = None
    go = member is None or member.state.mode is not Mode.PATROL  # the slot is open now
    go = go or t_s - since_t_s > WAIT_PERIODS * patrol.period_s
    lane = not inside(fix.pos_m, patrol)  # from inside the loop no lane point fits
    if not go and member is not None:
        behind = behind_rad(fig, slot_phase(member, t_s, patrol), patrol)
        if lane:
            found = meet(fig, fix, behind)
        else:
            back = behind - TWO_PI * fig.sensor_m / patrol.length_m
            found = meet_loop(fig, fix, back, True)
        go = found is not None and found[1] <= LAUNCH_SLACK_S
    return go, (found[0] if found is not None and lane else None)


def along_m(member: Neighbour | None, fix: Fix) -> float | None:
    """How far along the loop (m, either way) ``fix`` is from ``member``'s slot; None if
    the member is not heard (or shares no position)."""
    if member is None or member.state.pos_m is None:
        return None
    patrol = fix.patrol
    slot = slot_phase(member, fix.t_s, patrol)
    return abs(float(wrap_pi(fix.loop_phase_rad - slot))) * patrol.length_m / TWO_PI


def in_slot_reason(
    flight: Flight, fix: Fix, member: Neighbour | None, took_s: float, along: float | None
) -> str | None:
    """Why a spare flying in is on station now: ``member_gone`` (an unplanned loss: the slot
    the formation leaves open), ``timeout`` (``TAKEOVER_LIMIT_PERIODS`` T after its launch,
    ``took_s`` s ago) or ``in_slot`` (held ``IN_SLOT_S`` within ``IN_SLOT_M`` of its
    member's slot, ``along`` m away, and of the loop; since when, kept in ``flight``); else
    None."""
    t_s = fix.t_s
    if member is None:
        return "member_gone"
    if took_s > TAKEOVER_LIMIT_PERIODS * fix.patrol.period_s:
        return "timeout"
    if along is None or fix.loop_offset_m >= IN_SLOT_M:
        return None
    if along >= IN_SLOT_M:
        flight.slot_since_t_s = None
        return None
    if flight.slot_since_t_s is None:
        flight.slot_since_t_s = t_s
    return "in_slot" if t_s - flight.slot_since_t_s >= IN_SLOT_S else None


def formation_less(
    heard: Neighbours, t_s: float, patrol: Patrol, member: int | None
) -> list[tuple[float, complex]]:
    """(phase rad, centre m) at ``t_s`` (s) of every heard member in the formation but
    ``member``, in sysid order: the splay a relief settles into, with the member's slot open."""
    out = []
    for s, n in sorted(heard.table.items()):
        if s == member or n.state.mode in OUT_OF_FORMATION:
            continue
        out.append((n.state.phase_at(n.state.t_s + (t_s - n.rx_t_s), patrol.period_s),
                    n.state.centre_m))  # fmt: skip
    return out


def steer_into_slot(
    fig: Figures, fix: Fix, gains: Gains, others: list[tuple[float, complex]]
) -> DutyStep:
    """The steering law and the phase-holding airspeed with the formation ``others`` (its
    member's slot open): it settles into that slot."""
    patrol = fix.patrol
    u = splay_command(patrol, gains, fix.pos_m, fix.heading_rad, fix.phase_rad, fix.centre_m,
                      others, fig.max_u)  # fmt: skip
    v = patrol.airspeed_m_s
    if speed_holds_phase(gains):
        v = splay_airspeed(patrol, gains, fix.loop_phase_rad, [ph for ph, _ in others])
    return DutyStep(True, u, v)
