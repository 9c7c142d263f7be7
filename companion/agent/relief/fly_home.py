"""How a relieved UAV leaves the loop for home (pure; docs/energy.md, "Reliefs", home): it
drops back behind its relief, then leaves by a way out (straight out to its lane, its way on
to its base off the loop), or crosses the loop behind a member, or at its leave time flies
straight home. Its sensor so starts no member's pass early (the revisit is counted start to
start).

Functions over a :class:`~companion.agent.relief.records.GoingHome` record, one handler per
stage (:data:`WAY_HOME`: ``riding``, ``crossing``, ``out``); the stage changes along
:data:`~companion.agent.relief.states.HOME_TABLE`, the stage's record made as it is entered.
In ``straight`` the duty flies it to its base and lands it. Positions complex m, angles rad,
times s.
"""

from __future__ import annotations

from collections.abc import Callable

from companion.agent.fix import Fix
from companion.agent.neighbours import Neighbours
from companion.agent.relief.figures import Figures
from companion.agent.relief.fly_in import LANE_REACH_M
from companion.agent.relief.join import crossing, fly_to, loop_frame, slot_phase, way_out
from companion.agent.relief.records import (
    Crossing,
    GoingHome,
    OutToLane,
    Riding,
    StraightHome,
)
from companion.agent.relief.roster import LAND_MARGIN_S
from companion.agent.relief.states import DutyStep, HomeEvent, HomeStage
from companion.core.patrol import Patrol
from companion.core.wind import TWO_PI
from companion.group.messages import Mode
from companion.guidance.formation import splay_command
from companion.guidance.steering import Gains, slot_speed_offset, speed_holds_phase
from companion.guidance.virtual import phase_gap_rad

DROP_SENSORS = 1.5  # relieved, it drops this many sensor radii behind its relief to leave
DROP_REACH_M = 10.0  # ... and is that far back within this (m)
CROSS_MARGIN_S = 2.0  # crossing the loop home, its sensor is off it this long before the next
CROSS_EVERY_S = 1.0  # riding with no way out, it looks for a crossing this often (s)

StageStep = Callable[[GoingHome, Figures, Fix, Neighbours, Gains, complex], DutyStep | None]


def way_home(
    home: GoingHome, fig: Figures, fix: Fix, heard: Neighbours, gains: Gains, base_m: complex
) -> DutyStep | None:
    """Its step while it rides the loop, crosses it or flies out to its lane (a stage that
    ends hands on to the next within the step); None once it flies straight to ``base_m``
    (m)."""
    while home.stage.state is not HomeStage.STRAIGHT:
        step = WAY_HOME[home.stage.state](home, fig, fix, heard, gains, base_m)
        if step is not None:
            return step
    return None


def _riding(
    home: GoingHome, fig: Figures, fix: Fix, heard: Neighbours, gains: Gains, base_m: complex
) -> DutyStep | None:
    """On the loop (the steering law's path term), dropping back behind its relief; back
    there it leaves by a way out, else by a crossing (looked for every ``CROSS_EVERY_S``),
    and at its leave time by a crossing or straight home."""
    rec = home.stage.record
    assert isinstance(rec, Riding)
    t_s, pos_m, patrol = fix.t_s, fix.pos_m, fix.patrol
    v, back = _drop_back(rec, fig, fix, heard, gains)
    due = t_s >= rec.until_s
    radius_m = patrol.airspeed_m_s / fig.max_u
    out = not due and back and way_out(pos_m, base_m, patrol, fig.lane_m, fig.sensor_m,
                                       radius_m)  # fmt: skip
    cross_m = None
    if (due or back) and not out and t_s - rec.cross_t_s >= CROSS_EVERY_S:
        rec.cross_t_s = t_s  # no way out: home across the loop, behind a member?
        cross_m = _crossing(fig, fix, heard, base_m)
    if not due and not out and cross_m is None:
        u = splay_command(patrol, gains, pos_m, fix.heading_rad, fix.phase_rad, fix.centre_m,
                          [], fig.max_u)  # fmt: skip
        return DutyStep(True, u, v)
    if out:
        home.go(HomeEvent.WAY_OUT, OutToLane())
    elif cross_m is not None:
        home.go(HomeEvent.CROSS, Crossing(cross_m))
    else:
        home.go(HomeEvent.LEAVE, StraightHome())
    return None


def _crossing_stage(
    home: GoingHome, fig: Figures, fix: Fix, heard: Neighbours, gains: Gains, base_m: complex
) -> DutyStep | None:
    """To the loop point where it crosses; there, out across the loop."""
    rec = home.stage.record
    assert isinstance(rec, Crossing)
    if abs(rec.point_m - fix.pos_m) > LANE_REACH_M:
        u = fly_to(fix.pos_m, fix.heading_rad, rec.point_m, fix.patrol, fig.max_u)
        return DutyStep(True, u, fig.airspeed_m_s)
    home.go(HomeEvent.CROSSED, OutToLane())
    return None


def _out(
    home: GoingHome, fig: Figures, fix: Fix, heard: Neighbours, gains: Gains, base_m: complex
) -> DutyStep | None:
    """Straight out to its lane, its sensor off the loop beside it; there, on home."""
    pos_m = fix.pos_m
    near, _, n = loop_frame(pos_m, fix.patrol)
    if abs(pos_m - near) < fig.lane_m:
        u = fly_to(pos_m, fix.heading_rad, pos_m + 2.0 * fig.lane_m * n, fix.patrol, fig.max_u)
        return DutyStep(True, u, fig.airspeed_m_s)
    home.go(HomeEvent.CLEAR, StraightHome())
    return None


WAY_HOME: dict[HomeStage, StageStep] = {
    HomeStage.RIDING: _riding,
    HomeStage.CROSSING: _crossing_stage,
    HomeStage.OUT: _out,
}
"""The step of each stage but ``straight`` (the duty's: to the base, and land)."""


def _drop_back(
    rec: Riding, fig: Figures, fix: Fix, heard: Neighbours, gains: Gains
) -> tuple[float, bool]:
    """Relieved and riding the loop: its airspeed (m/s), the phase hold's for a slot
    ``DROP_SENSORS`` sensor radii (at most half the spacing L/N) behind its relief, and
    whether it is that far back (within ``DROP_REACH_M``). Its relief unheard, or its
    airspeed not holding the phase (the mean-centre form), it rides at the plan's airspeed
    and is back."""
    patrol = fix.patrol
    relief = heard.table.get(rec.behind)
    if relief is None or not speed_holds_phase(gains):
        return patrol.airspeed_m_s, True
    target = slot_phase(relief, fix.t_s, patrol) - TWO_PI * drop_m(fig, patrol) / patrol.length_m
    gap = phase_gap_rad(fix.loop_phase_rad, target)  # + ahead of it
    v = patrol.airspeed_m_s + slot_speed_offset(patrol, gains, gap)
    return v, gap * patrol.length_m / TWO_PI <= DROP_REACH_M


def drop_m(fig: Figures, patrol: Patrol) -> float:
    """How far behind its relief a relieved UAV drops back before it leaves (m):
    ``DROP_SENSORS`` sensor radii, at most half the spacing L/N."""
    return min(DROP_SENSORS * fig.sensor_m, 0.5 * patrol.length_m / fig.count)


def _crossing(fig: Figures, fix: Fix, heard: Neighbours, base_m: complex) -> complex | None:
    """Relieved with no way out (back behind its relief, or at its leave time): the loop
    point (m) where it crosses the loop home behind a member
    (:func:`~companion.agent.relief.join.crossing`: its drop-back distance after the last
    member, its sensor off the loop before the next one's reaches it), if that gets it home
    at most half the landing margin later than flying straight; else None."""
    patrol, pos_m = fix.patrol, fix.pos_m
    members = [slot_phase(n, fix.t_s, patrol) for n in heard.table.values()
               if n.state.mode is Mode.PATROL]  # fmt: skip
    slow_m_s = patrol.airspeed_m_s - abs(patrol.wind.vector)  # its slowest ground speed
    behind_s = drop_m(fig, patrol) / slow_m_s
    clear_s = 2.0 * fig.sensor_m / slow_m_s + CROSS_MARGIN_S
    found = crossing(pos_m, fix.heading_rad, base_m, members, patrol, behind_s, clear_s,
                     fig.lane_m, fig.sensor_m, fig.max_u)  # fmt: skip
    if found is None:
        return None
    point, flight = found
    straight_s = abs(base_m - pos_m) / slow_m_s
    home_s = flight + abs(base_m - point) / slow_m_s
    return point if home_s <= straight_s + 0.5 * LAND_MARGIN_S else None
