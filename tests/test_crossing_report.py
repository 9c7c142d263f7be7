"""Each intruder's crossings of the sensor band in the run's report, judged against the
promise (companion/report/episodes.py ``crossings``; companion/core/guarantee.py).

The hand-built circle of ``test_episode_measures``: radius 300 m at 20 m/s in calm air, two
UAVs, sensor 40 m, truth every second. Its period is T = 2 pi 300 / 20 = 94.25 s, T/N =
47.12 s, so the promise is 80 m / 47.12 s = 1.698 m/s with both UAVs on the loop; with one
away the gap is 1.5 T / 1 + 80 m / 20 m/s = 145.4 s and the promise 0.550 m/s. The band is
north 260-340 m on the line east = 0. Every figure below is worked out by hand from the
intruders' legs; none comes from the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from companion.agent.events import AlertTasked, Rejoined
from companion.report.episodes import episode_measures, format_episode
from tests.test_episode_measures import FAR, TIMES, by_id, run_of

T_S = 2 * math.pi * 300.0 / 20.0
PROMISE = 80.0 / (T_S / 2)
PROMISE_ONE_AWAY = 80.0 / (1.5 * T_S + 80.0 / 20.0)

INTRUDERS = (
    # outward at 1.5 m/s from north 240: in the band 14-66 s (north 261-339 m)
    "    - {id: slow, kind: path, appear_t_s: 0, north_m: 240, east_m: 0,"
    " path: [{north_m: 450, east_m: 0, speed_m_s: 1.5}]}\n"
    # inward at 8 m/s from north 421 at 100 s: in the band 111-120 s (north 333-261 m)
    "    - {id: fast, kind: path, appear_t_s: 100, north_m: 421, east_m: 0,"
    " path: [{north_m: 100, east_m: 0, speed_m_s: 8}], vanish_t_s: 150}\n"
    # into the band to north 320 and back out the way it came
    "    - {id: back, kind: path, appear_t_s: 0, north_m: 420, east_m: 0,"
    " path: [{north_m: 320, east_m: 0, speed_m_s: 5}, {north_m: 420, east_m: 0,"
    " speed_m_s: 5}]}\n"
)


def test_a_crossing_is_judged_against_the_promise_and_seen_from_the_truth():
    pos1 = np.full(TIMES.size, FAR)
    pos1[TIMES == 40] = 300 + 0j  # over "slow" at 40 s (north 240 + 1.5 x 40 = 300)
    # UAV 2 leaves at 45 s (for "slow", seen by then: not away for its crossing) to the end
    events = [
        AlertTasked(t_s=45.0, sysid=2, alert_id="1-1", prosecutor_sysid=2, policy="next"),
        Rejoined(t_s=199.0, sysid=2, alert_id="1-1", in_slot=True, rejoin_s=1.0),
    ]
    recs = by_id(episode_measures(run_of(INTRUDERS, pos1, np.full(TIMES.size, FAR), events)))
    (slow,) = recs["slow"]["crossings"]
    assert (slow["t0_s"], slow["t1_s"], slow["inward"]) == (14.0, 66.0, False)
    assert slow["speed_m_s"] == 1.5 and slow["away"] == 0
    assert slow["promised_m_s"] == pytest.approx(PROMISE, abs=1e-3)
    assert slow["promised"] and slow["seen"]
    assert recs["slow"]["promised_crossings"] == 1
    assert recs["slow"]["promised_crossings_missed"] == 0
    (fast,) = recs["fast"]["crossings"]
    assert (fast["t0_s"], fast["t1_s"], fast["inward"]) == (111.0, 120.0, True)
    assert fast["speed_m_s"] == 8.0 and not fast["promised"] and not fast["seen"]
    assert fast["away"] == 1  # UAV 2 was away all through it
    assert fast["promised_m_s"] == pytest.approx(PROMISE_ONE_AWAY, abs=1e-3)
    assert recs["fast"]["promised_crossings_missed"] == 0  # nothing was promised
    assert recs["back"]["crossings"] == []  # it left the band on the side it came from
    assert "crossed the band 1x, seen 1; 1 no faster than the promise, seen 1" in (
        format_episode(recs["slow"])
    )


def test_with_a_uav_away_the_promise_is_the_smaller_one_and_a_miss_is_counted():
    # outward at 0.5 m/s from north 255.25: in the band 10-169 s (north 260.25-339.75 m);
    # UAV 2 is away from 5 s to the end of the log, nobody comes near
    intruders = (
        "    - {id: creep, kind: path, appear_t_s: 0, north_m: 255.25, east_m: 0,"
        " path: [{north_m: 355, east_m: 0, speed_m_s: 0.5}]}\n"
    )
    events = [
        AlertTasked(t_s=5.0, sysid=2, alert_id="9-1", prosecutor_sysid=2, policy="next"),
        Rejoined(t_s=199.0, sysid=2, alert_id="9-1", in_slot=True, rejoin_s=1.0),
    ]
    far = np.full(TIMES.size, FAR)
    (rec,) = episode_measures(run_of(intruders, far, far, events))
    (c,) = rec["crossings"]
    assert (c["t0_s"], c["t1_s"], c["away"]) == (10.0, 169.0, 1)
    assert c["promised_m_s"] == pytest.approx(PROMISE_ONE_AWAY, abs=1e-3)
    assert c["promised"] and not c["seen"]  # 0.5 <= 0.550 m/s, and nobody passed
    assert rec["promised_crossings_missed"] == 1
