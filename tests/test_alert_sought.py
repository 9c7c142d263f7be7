"""The prosecutor's own sighting of a vehicle that turned is its intruder, not a new alert
(issue 47; :meth:`companion.agent.alerts.book.AlertBook.sought`).

The case measured in generated missions 28 and 32 (``bench/alerts.py``, ``docs/alerts.md``): a
vehicle turned at a junction just before a pass ended (or 20 s before the prosecutor came),
so its track predicted it straight on; the prosecutor flew over it 19-34 m (five sigma) or
164 m (1.7 sigma of a 22 s old track) off the prediction, outside every alert's twin gate.
It raised a new alert, flew on to the old prediction, searched, and ended "lost"; the new
alert was tasked to another UAV 30-190 s later, after the vehicle was gone.

Here the duty is fed the alert of a vehicle driving east at 15 m/s and then one sighting of
its own where the vehicle is after a 60 deg turn to the north: the duty this UAV is away for
takes it (its contact is ``seen``, no alert raised); without being away for it, or from a
still track, or beyond the sought region, it is a new alert as before. A vehicle that
turned right after its last sighting and is seen well after is within where it can have
driven since (generated mission 28 on loops up to 25 km: 17 s, 207 m off the prediction).
"""

from __future__ import annotations

import cmath
import math

from companion.agent.alert_duty import AlertDuty
from companion.agent.config import AgentConfig
from companion.group.messages import Alert, Track

SENSOR_M = 40.0
T0 = 100.0  # the track's time (s)
T1 = 101.3  # the prosecutor's first sighting (s)
SPEED = 15.0  # m/s, east


def duty_with(vel: complex) -> AlertDuty:
    """A duty that heard alert 7-1: a track at the origin at ``T0`` moving at ``vel``."""
    duty = AlertDuty(6, SENSOR_M, AgentConfig())
    # the filter's manoeuvre acceleration of a straight track (0.3-0.4 m/s^2: motion.py)
    track = Track(T0, 0j, vel, 1.7, 0.5, 37, manoeuvre_m_s2=0.4)
    (renamed, _events) = duty.receive(Alert("7-1", 0j, 7, T0, "new", track=track), T0)
    assert renamed is None and duty.get("7-1") is not None
    return duty


def turned(off_m: float) -> complex:
    """Where the vehicle is seen at ``T1``: ``off_m`` north of its straight-on prediction."""
    return complex(off_m, SPEED * (T1 - T0))


def raised(duty: AlertDuty) -> list[str]:
    return [a.alert_id for a in duty.take_outbox() if a.state == "new"]


def test_the_straight_prediction_misses_the_turned_vehicle_by_five_sigma():
    """The premise: the twin gate alone does not hold the sighting (so before the fix the
    prosecutor raised a new alert over its own intruder)."""
    duty = duty_with(SPEED * 1j)
    rec = duty.get("7-1")
    assert rec is not None
    one = Track(T1, turned(34.0))
    assert duty.book.twin(turned(34.0), T1, one) is None
    assert abs(rec.predict(T1) - turned(34.0)) > 4.0 * rec.sigma_m(T1)


def test_the_prosecutor_takes_its_turned_vehicle_as_its_intruder():
    duty = duty_with(SPEED * 1j)
    duty.detect(turned(34.0), T1)
    found = duty.sightings(T1, "7-1")
    assert found.seen is not None and found.seen.alert_id == "7-1"
    assert raised(duty) == []
    # its own fit, not the old straight track's: the next sighting is the same contact
    duty.detect(turned(34.0) + 0.2 * SPEED * (0.5 + 0.866j), T1 + 0.2)
    again = duty.sightings(T1 + 0.2, "7-1")
    assert again.seen is found.seen and raised(duty) == []


def test_an_old_track_is_sought_over_its_grown_prediction():
    """164 m off a 22 s old straight track (three sigma of its grown prediction)."""
    duty = duty_with(SPEED * 1j)
    t = T0 + 22.0
    rec = duty.get("7-1")
    assert rec is not None
    site = rec.predict(t) + 164.0  # north of it
    off = 164.0
    assert 3.0 * rec.sigma_m(t) >= off > 3.0 * SENSOR_M
    duty.detect(site, t)
    assert duty.sightings(t, "7-1").seen is not None and raised(duty) == []


def test_a_uav_not_away_for_it_raises_a_new_alert():
    duty = duty_with(SPEED * 1j)
    duty.detect(turned(34.0), T1)
    found = duty.sightings(T1, None)
    assert found.seen is None and raised(duty) == ["6-1"]


def test_beyond_the_sought_region_it_is_another_intruder():
    duty = duty_with(SPEED * 1j)
    duty.detect(turned(3.0 * SENSOR_M + 10.0), T1)
    found = duty.sightings(T1, "7-1")
    assert found.seen is None and raised(duty) == ["6-1"]


def test_a_still_track_keeps_its_narrow_gate():
    """A still intruder (a walker stopped, a parked car) does not take a passer-by 34 m off."""
    duty = duty_with(0j)
    duty.detect(complex(34.0, 0.0), T1)
    found = duty.sightings(T1, "7-1")
    assert found.seen is None and raised(duty) == ["6-1"]


def after_a_turn(turn_deg: float, age_s: float) -> complex:
    """Where the vehicle is ``age_s`` after the track's time, having turned ``turn_deg``
    to the north at once and driven on at its speed (east, then north-east)."""
    return SPEED * age_s * 1j * cmath.exp(-1j * math.radians(turn_deg))


def test_a_vehicle_that_turned_long_ago_is_sought_where_it_can_have_driven():
    """Mission 28's case: a 60 deg turn just after the last sighting, seen 17 s later
    outside three sigma of the straight prediction, inside its reachable disc."""
    duty = duty_with(SPEED * 1j)
    rec = duty.get("7-1")
    assert rec is not None
    t = T0 + 17.0
    site = after_a_turn(60.0, 17.0)
    off = abs(site - rec.predict(t))
    assert off > 3.0 * rec.sigma_m(t) and off > 3.0 * SENSOR_M  # beyond the sought region
    assert abs(site) <= duty.book.reachable_m(rec.track, t)
    duty.detect(site, t)
    assert duty.sightings(t, "7-1").seen is not None and raised(duty) == []


def test_faster_than_it_can_drive_is_another_intruder():
    """Twice as far from the last sighting as the track's speed can take it."""
    duty = duty_with(SPEED * 1j)
    t = T0 + 17.0
    duty.detect(2.0 * after_a_turn(60.0, 17.0), t)
    assert duty.sightings(t, "7-1").seen is None and raised(duty) == ["6-1"]
