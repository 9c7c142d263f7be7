"""The autopilot's bank limit against the mission's turn-rate limit (issue 23's real day).

ArduPlane clips a bank setpoint to ROLL_LIMIT_DEG, and its plane turns at about 0.70 of
``g tan(phi) / V``: at the ideal coordinated bank of 18 deg/s at 20 m/s (32.6 deg) it turns
at 12.6 deg/s, and a loop that needs more (the ellipse's ends in 7.5 m/s of wind need 17.4
deg/s) is flown wide without a word. The companion reads the limit (PARAM_REQUEST_READ) and
says so once its bank gain is learnt (:class:`companion.link.supervision.BankLimitMonitor`).

Worked by hand: need = atan(20 x 0.314159 / (9.80665 x 0.70)) = atan(0.91526) = 42.47 deg;
at 32.6 deg the aircraft turns 0.70 x 9.80665 x tan(32.6 deg) / 20 = 0.2195 rad/s = 12.58
deg/s.
"""

from __future__ import annotations

import math

import pytest

from companion.link.supervision import (
    BANK_LIMIT_GRACE_S,
    BANK_LIMIT_HOLD_S,
    BANK_LIMIT_MIN_SAMPLES,
    BANK_LIMIT_WINDOW_S,
    BankLimitMonitor,
)
from companion.sim.inmemory import Engine, EngineConfig
from sitl_model.testing import REPO
from tests.relief_coverage import companion_events

MAX_TURN = math.radians(18.0)


def _commanding(mon: BankLimitMonitor, gain: float = 0.70) -> float:
    """Past the grace, with half a window of ``gain`` learnt, once a second; the time (s)."""
    mon.update(0.0, 20.0, gain, 500)  # commanding from here
    t = BANK_LIMIT_GRACE_S
    while t <= BANK_LIMIT_GRACE_S + BANK_LIMIT_WINDOW_S / 2:
        assert mon.update(t, 20.0, gain, 500) is None  # too few gains yet: not judged
        t += 1.0
    return t


def test_a_limit_below_the_needed_bank_is_said_with_the_figures_and_cleared_when_raised():
    mon = BankLimitMonitor(MAX_TURN)
    hold, g, w2 = BANK_LIMIT_HOLD_S, BANK_LIMIT_GRACE_S, BANK_LIMIT_WINDOW_S / 2
    assert mon.needed_deg(20.0, 0.70) == pytest.approx(42.47, abs=0.01)
    assert mon.update(0.0, 20.0, 0.70, 10_000) is None  # no limit read yet
    mon.limit_deg = 32.6
    assert mon.update(g - 1, 20.0, 0.70, 10_000) is None  # in the grace
    assert mon.update(g + 1, 20.0, 0.70, BANK_LIMIT_MIN_SAMPLES - 1) is None  # gain not learnt
    t0 = g + 2  # the first gain past the grace
    t = t0
    while t < t0 + w2:  # half a window of gains first
        assert mon.update(t, 20.0, 0.70, BANK_LIMIT_MIN_SAMPLES) is None
        t += 1.0
    while t < t0 + w2 + hold:  # low from here: not yet for long enough
        assert mon.update(t, 20.0, 0.70, 400) is None
        t += 1.0
    issue = mon.update(t, 20.0, 0.70, 400)
    assert issue is not None and issue.active and issue.name == "bank_limit_low"
    assert issue.text == "bank limit 32.6 deg turns 12.6 of 18.0 deg/s: raise it to 42.5"
    assert mon.update(t + 1, 20.0, 0.70, 500) is None  # said once
    mon.limit_deg = 45.0
    assert mon.update(t + 2, 20.0, 0.70, 500) is None  # fine from here
    cleared = mon.update(t + 2 + hold, 20.0, 0.70, 500)
    assert cleared is not None and not cleared.active
    mon.reset()  # not commanding: the grace again
    mon.limit_deg = 32.6
    assert mon.update(1000.0, 20.0, 0.70, 500) is None
    assert mon.update(1000.0 + hold + 1, 20.0, 0.70, 500) is None


def test_the_acquisitions_low_gains_count_for_nothing():
    """Gains of 0.5 in the grace (the formation acquiring) and 0.70 after: nothing said at a
    limit that is right for 0.70 (42.5 deg)."""
    mon = BankLimitMonitor(MAX_TURN)
    mon.limit_deg = 42.5
    said = [mon.update(float(t), 20.0, 0.50 if t < 120 else 0.70, 500) for t in range(400)]
    assert said == [None] * 400


def test_within_the_margin_or_with_an_ideal_aircraft_nothing_is_said():
    for limit, gain in ((32.6, 1.0), (37.6, 0.70)):  # 32.64 deg needed; 4.87 under 42.47
        mon = BankLimitMonitor(MAX_TURN)
        mon.limit_deg = limit
        t = _commanding(mon, gain)
        for k in range(200):
            assert mon.update(t + k, 20.0, gain, 500) is None
    mon = BankLimitMonitor(MAX_TURN)
    mon.limit_deg = 32.6
    t = _commanding(mon)
    assert mon.update(t, float("nan"), 0.70, 500) is None
    assert mon.update(t, 20.0, 0.0, 500) is None


def test_a_low_reading_that_does_not_last_is_not_said():
    mon = BankLimitMonitor(MAX_TURN)
    mon.limit_deg = 40.0  # 0.62 needs atan(6.28318 / 6.08012) = 45.94 deg > 40 + 5
    t = _commanding(mon)
    for k in range(0, 60):  # a minute at 0.62 after half a window of 0.70: the median holds
        assert mon.update(t + k, 20.0, 0.62, 500) is None


def test_a_gain_that_dips_in_turbulence_is_not_said_one_that_stays_low_is():
    """Judged at the median gain of the last two minutes (sampled once a second): 50 s at
    0.60 among 0.70s (a real day's turbulence) says nothing; 0.60 for more than half the
    window, then the hold, does (atan(6.28318 / (9.80665 x 0.60)) = 46.88 deg > 41 + 5)."""
    mon = BankLimitMonitor(MAX_TURN)
    mon.limit_deg = 41.0
    t = 0
    mon.update(0.0, 20.0, 0.70, 500)  # commanding from here
    gains = [0.70] * 180 + [0.60] * 50 + [0.70] * 120 + [0.60] * 200
    said = []
    for t, gain in enumerate(gains, start=1):
        issue = mon.update(float(t), 20.0, gain, 500)
        if issue is not None:
            said.append((t, issue))
    assert len(said) == 1 and said[0][1].active, said
    low_from = 180 + 50 + 120  # the last stretch at 0.60 starts here
    late = BANK_LIMIT_WINDOW_S / 2 + BANK_LIMIT_HOLD_S  # the median turns, then the hold
    assert low_from + late - 2 <= said[0][0] <= low_from + late + 2, said
    assert said[0][1].text.endswith("raise it to 46.9")


@pytest.mark.contract
@pytest.mark.parametrize(("limit_deg", "said"), [(30.0, True), (45.0, False)])
def test_companions_read_the_limit_and_say_it_is_too_low(tmp_path, limit_deg, said):
    """Six companions against autopilots that turn at 0.70 of g tan(phi)/V, with the bank
    limit at 30 deg (each says so once its gain is learnt) or at 45 deg (none does)."""
    params = {"SIM_TR_EFF": 0.70, "SIM_LAG": 0.5, "ROLL_LIMIT_DEG": limit_deg}
    eng = Engine(EngineConfig(REPO / "missions" / "ellipse_6uav.yaml", tmp_path, params=params))
    try:
        eng.run(300.0)
    finally:
        eng.close()
    raised = companion_events(eng, "bank_limit_low")
    if said:
        assert sorted(e["sysid"] for e in raised) == list(eng.sysids), raised
        assert all(e["text"].startswith(f"bank limit {limit_deg:.1f} deg") for e in raised)
        # the gain is learnt from the bank flown (the shaper clips at the limit it read), so
        # the bank asked for is the true one, 42.47 deg at 0.70 (it read 44-60 without that)
        asked = [float(e["text"].rsplit(" ", 1)[1]) for e in raised]
        assert all(abs(a - 42.5) <= 1.5 for a in asked), asked
    else:
        assert raised == []
