"""Who took the aircraft away and whether its companion takes it back (companion/link/failsafe.py),
and what a silent companion's aircraft flies (companion/link/fallback.py): pure, on fake times."""

from __future__ import annotations

import math
import struct
from itertools import pairwise

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.core.wind import TWO_PI
from companion.link.failsafe import (
    HEALTHY_WALL_S,
    RETAKE_MAX,
    RETAKE_RETRY_WALL_S,
    SILENT_S,
    Loss,
    Retake,
    Silence,
    StepHealth,
)
from companion.link.fallback import (
    CHORD_OFF_M,
    LEAD_MAX_S,
    REFRESH_S,
    GuidedFallback,
    ParamsAtTakeOver,
    lead_point,
    loiter_radius_m,
    px4_loss_params,
    reposition_command,
)
from companion.mission import load_mission
from tests.test_companion_link import REPO

MISSION = load_mission(REPO / "tests" / "data" / "ellipse_3uav.yaml")  # 400 x 200 m, clockwise
PATROL = MISSION.patrol


# ---- silences and causes -------------------------------------------------------------------
def _stream(silence: Silence, t0: float, t1: float, dt: float = 0.1) -> None:
    for k in range(round((t1 - t0) / dt) + 1):
        silence.setpoint(t0 + k * dt)


def test_a_mode_change_while_setpoints_flow_is_a_pilots():
    s = Silence()
    _stream(s, 0.0, 10.0)
    assert s.cause(10.05, link_was_lost=False) == ("pilot", pytest.approx(0.05))


def test_a_silence_that_ended_just_before_the_change_was_heard_is_the_companions():
    """PX4 heartbeats at 1 Hz: its failsafe is heard up to a second after it, and by then the
    companion may stream again; a silence within RECENT_S still counts."""
    s = Silence()
    _stream(s, 0.0, 10.0)
    _stream(s, 11.5, 12.5)  # 1.5 s without a setpoint, then streaming again
    assert s.cause(12.55, link_was_lost=False) == ("own_silence", pytest.approx(1.5))
    assert s.cause(20.0, link_was_lost=False)[0] == "own_silence"  # still silent since 12.5
    _stream(s, 20.0, 20.5)
    assert s.cause(20.55, link_was_lost=False)[0] == "own_silence"  # the 7.5 s gap is recent
    _stream(s, 20.6, 30.0)
    assert s.cause(30.05, link_was_lost=False)[0] == "pilot"  # long ago
    assert s.cause(30.05, link_was_lost=True)[0] == "own_silence"  # a lost link is its own


def test_a_gap_just_under_the_threshold_is_no_silence():
    s = Silence()
    _stream(s, 0.0, 5.0)
    s.setpoint(5.0 + SILENT_S * 0.9)
    assert s.cause(5.0 + SILENT_S, link_was_lost=False)[0] == "pilot"


# ---- the steps' health ---------------------------------------------------------------------
def test_steady_positions_are_healthy_and_a_pause_or_a_hole_is_not():
    h = StepHealth(rate_hz=10.0)
    wall, t = 100.0, 1000.0
    for _ in range(40):  # 4 s at 10 Hz, at 1x
        wall, t = wall + 0.1, t + 0.1
        h.position(wall, t)
    assert h.healthy(wall)
    assert not h.healthy(wall + 0.6)  # nothing for 0.6 s of wall time
    h.position(wall + 0.6, t + 0.6)  # a hole of 0.6 s in the positions' own times
    assert not h.healthy(wall + 0.6)


def test_a_backlog_after_a_stall_is_not_healthy_until_the_stream_is_steady_again():
    """SIGSTOP for 5 s: on SIGCONT 50 positions arrive at once; the window still holds the
    5 s pause, so not healthy until HEALTHY_WALL_S of steady positions have passed."""
    h = StepHealth(rate_hz=10.0)
    wall, t = 0.0, 0.0
    for _ in range(30):
        wall, t = wall + 0.1, t + 0.1
        h.position(wall, t)
    wall += 5.0
    for _ in range(50):  # the backlog, all at once
        t += 0.1
        h.position(wall, t)
    assert not h.healthy(wall)
    steady_since = wall
    while wall - steady_since < HEALTHY_WALL_S + 0.2:
        wall, t = wall + 0.1, t + 0.1
        h.position(wall, t)
        if wall - steady_since < HEALTHY_WALL_S - 0.2:
            assert not h.healthy(wall)
    assert h.healthy(wall)


def test_a_starved_stream_at_half_the_asked_rate_is_not_healthy():
    h = StepHealth(rate_hz=10.0)
    wall, t = 0.0, 0.0
    for _ in range(20):  # 4 Hz of positions for 10 Hz asked, each 0.25 s apart
        wall, t = wall + 0.25, t + 0.25
        h.position(wall, t)
    assert not h.healthy(wall)


# ---- retakes -------------------------------------------------------------------------------
SILENT = Loss("own_silence", "AUTO.LOITER", 5.0)
PILOT = Loss("pilot", "MANUAL", 0.1)


def test_a_loss_to_its_own_silence_is_taken_back_only_with_consent_and_when_healthy():
    r = Retake(consent=True)
    r.taken(SILENT)
    assert r.state == "lost"
    assert not r.due(0.0, link_up=True, healthy=False)
    assert not r.due(0.0, link_up=False, healthy=True)
    assert r.due(0.0, link_up=True, healthy=True) and r.state == "retaking"
    assert not r.due(RETAKE_RETRY_WALL_S - 0.1, True, True)  # paced
    assert r.due(RETAKE_RETRY_WALL_S, True, True) and r.tries == 2
    r.back()
    assert r.state == "in_command" and r.loss is None
    no = Retake(consent=False)
    no.taken(SILENT)
    assert not any(no.due(w, True, True) for w in range(0, 100, 5))


def test_a_pilots_mode_change_is_never_taken_back():
    r = Retake(consent=True)
    r.taken(PILOT)
    assert r.state == "held_off"
    assert not any(r.due(w, True, True) for w in range(0, 100, 5))
    r.taken(SILENT)  # after the pilot's mode, a silence... (the pilot chose; it stays his)
    assert r.state == "lost"  # a new loss of its own: its own to take back
    r.taken(PILOT)  # the pilot again while it was about to retake
    assert r.state == "held_off" and not r.due(1e3, True, True)


def test_retakes_give_up_after_the_most_asks_in_a_window():
    r = Retake(consent=True)
    r.taken(SILENT)
    asks = [w for w in range(0, 1000, 10) if r.due(float(w), True, True)]
    assert len(asks) == RETAKE_MAX and r.state == "held_off"


def test_an_illegal_retake_event_raises():
    r = Retake(consent=True)
    with pytest.raises(ValueError, match="illegal retake event 'asked'"):
        r._step("asked")


# ---- ArduPlane's GUIDED target on the loop ahead -----------------------------------------------
def _loop_offset_m(p: complex) -> float:
    return PATROL.phase_and_offset_of_point(p)[1]


@pytest.mark.parametrize("phase_deg", range(0, 360, 15))
def test_the_point_ahead_is_on_the_loop_ahead_and_its_chord_stays_near_the_loop(phase_deg):
    phase = math.radians(phase_deg)
    here = complex(PATROL.point_at_phase(phase))
    point, lead = lead_point(PATROL, here + 20.0)  # a little off the loop
    assert _loop_offset_m(point) < 0.5
    ahead = (PATROL.phase_of_point(point) - PATROL.phase_of_point(here + 20.0)) % TWO_PI
    assert ahead * PATROL.period_s / TWO_PI == pytest.approx(lead, abs=0.3)
    start = complex(PATROL.point_at_phase(PATROL.phase_of_point(here + 20.0)))
    worst = max(_loop_offset_m(start + (point - start) * k / 50) for k in range(51))
    assert worst <= CHORD_OFF_M + 3.0  # sampled at 8 points: a little between them


def test_the_lead_is_long_on_the_sides_and_short_round_the_tight_ends():
    leads = {d: lead_point(PATROL, complex(PATROL.point_at_phase(math.radians(d))))[1]
             for d in range(0, 360, 5)}  # fmt: skip
    assert max(leads.values()) == LEAD_MAX_S  # along a side (16 s = 320 m)
    assert min(leads.values()) <= 9.0  # round an end of 100 m radius (b^2 / a)


def test_the_reposition_asks_arduplane_to_circle_the_point_in_the_loops_sense():
    m = reposition_command(MISSION.origin, complex(300.0, -50.0), 350.0, 80.0, True, 2)
    assert (m.command, m.frame, m.target_system) == (mav.MAV_CMD_DO_REPOSITION, 0, 2)
    assert (m.param1, m.param2, m.param3, m.param4) == (-1.0, 0.0, 80.0, 0.0)  # clockwise
    assert m.z == 350.0 and m.x > 39.80 * 1e7 and m.y < -84.0 * 1e7
    ccw = reposition_command(MISSION.origin, complex(300.0, -50.0), 350.0, 80.0, False, 2)
    assert ccw.param4 == 1.0  # ArduPlane: param4 non-zero circles counter-clockwise


def test_the_loiter_radius_is_within_reach_of_the_aircraft():
    v = MISSION.vehicles
    r = loiter_radius_m(v.airspeed_m_s, v.max_turn_rate_rad_s)
    assert r == 80.0  # 1.25 x 20 m/s / 18 deg/s = 79.6 m: under the goal's 100 m


def test_the_guided_target_is_refreshed_every_few_seconds_of_vehicle_time():
    g = GuidedFallback(MISSION.origin, 80.0)
    here = complex(PATROL.point_at_phase(0.3))
    sent = [t / 10 for t in range(0, 101) if g.refresh_if_due(t / 10, PATROL, here, 350.0, 1)]
    assert sent[0] == 0.0
    assert all(b - a == pytest.approx(REFRESH_S) for a, b in pairwise(sent))
    g.forget()
    assert g.refresh_if_due(10.05, PATROL, here, 350.0, 1) is not None  # at once on take-over
    g.on_ack(mav.MAV_CMD_DO_REPOSITION, mav.MAV_RESULT_UNSUPPORTED)  # e.g. our simulator
    g.forget()
    assert g.refresh_if_due(20.0, PATROL, here, 350.0, 1) is None  # never again


# ---- PX4's offboard-loss action ----------------------------------------------------------------
def _int_bits(v: int) -> float:
    return struct.unpack("<f", struct.pack("<i", v))[0]


def test_px4_loss_params_are_sent_bytewise_until_read_back():
    p = ParamsAtTakeOver(px4_loss_params(80.0))
    sent = p.due(0.0, 1)
    by = {m.param_id: m for m in sent}
    act = by["COM_OBL_RC_ACT"]
    assert act.param_type == mav.MAV_PARAM_TYPE_INT32 and act.param_value == _int_bits(5)
    assert by["NAV_LOITER_RAD"].param_value == 80.0
    assert p.due(0.5, 1) == []  # paced
    assert p.on_param_value("COM_OBL_RC_ACT", _int_bits(5), mav.MAV_PARAM_TYPE_INT32)
    assert not p.on_param_value("NAV_LOITER_RAD", 50.0, mav.MAV_PARAM_TYPE_REAL32)  # not ours yet
    assert [m.param_id for m in p.due(1.0, 1)] == ["NAV_LOITER_RAD"]
    assert p.on_param_value("NAV_LOITER_RAD", 80.0, mav.MAV_PARAM_TYPE_REAL32)
    assert (
        p.done
        and p.refused == []
        and p.confirmed == {"COM_OBL_RC_ACT": 5.0, "NAV_LOITER_RAD": 80.0}
    )


def test_a_parameter_never_read_back_is_given_up():
    p = ParamsAtTakeOver(px4_loss_params(80.0))
    p.on_param_value("NAV_LOITER_RAD", 80.0, mav.MAV_PARAM_TYPE_REAL32)
    for k in range(20):
        p.due(float(k), 1)
    assert p.done and p.refused == ["COM_OBL_RC_ACT"]
