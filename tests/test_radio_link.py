"""The radio-like link: its pure core against hand calculations, and twelve UAVs over it.

Unit (milliseconds): :class:`sitl_model.radio.RadioLink`'s serialisation at the rate, the
fixed delay, the seeded loss, the queue limit and the per-second counts.

Integration (``extended``: 400 s of flight at 1x, about 7 minutes; ``bench/radio_link.py``
prints the same figures): 12 UAVs on the paper's ellipse, Zenoh clients reaching one
router through the link (100 kbit/s shared, 50 ms, 10 % loss) under ``--group-budget``,
against issue 24's goals. Kernel ``netem`` would be the usual tool; this kernel has no
``sch_netem`` (``tc qdisc add dev lo root netem delay 50ms loss 10% rate 100kbit``:
"Error: Specified qdisc kind is unknown.", and no /lib/modules to load it from), so the
link is emulated in user space (docs/protocol.md, "A radio-like link").
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from sitl_model.radio import LinkSpec, RadioLink

QUIET = LinkSpec(rate_bytes_s=12_500.0, delay_s=0.05, loss=0.0)


# ---- the pure core ----------------------------------------------------------------------
def test_one_datagram_arrives_after_its_serialisation_and_the_delay() -> None:
    """97 bytes + 28 of headers = 125 bytes at 12,500 bytes/s: 10 ms, then 50 ms."""
    got = RadioLink(QUIET, seed=1).offer(1.0, 97, "up")
    assert got.outcome == "delivered" and got.wire_bytes == 125
    assert got.deliver_s == pytest.approx(1.0 + 0.010 + 0.050, abs=1e-12)


def test_a_burst_queues_behind_the_rate_shared_by_both_directions() -> None:
    """Ten datagrams of 125 bytes at once, alternating up and down: the k-th (from 1)
    leaves the channel at k * 10 ms and arrives 50 ms later; the channel is one."""
    link = RadioLink(QUIET, seed=1)
    got = [link.offer(0.0, 97, "up" if k % 2 else "down") for k in range(10)]
    for k, t in enumerate(got, start=1):
        assert t.deliver_s == pytest.approx(k * 0.010 + 0.050, abs=1e-12)
    assert link.counts.max_backlog_s == pytest.approx(0.100, abs=1e-12)
    assert link.backlog_per_second() == [0.1]


def test_spaced_datagrams_do_not_queue() -> None:
    """One 125-byte datagram every 20 ms (half the rate): each takes 10 ms + 50 ms."""
    link = RadioLink(QUIET, seed=1)
    for k in range(50):
        t = 0.02 * k
        assert link.offer(t, 97, "up").deliver_s == pytest.approx(t + 0.06, abs=1e-9)


def test_the_queue_limit_drops_on_arrival_and_takes_no_air_time() -> None:
    link = RadioLink(LinkSpec(12_500.0, 0.05, 0.0, limit=3), seed=1)
    got = [link.offer(0.0, 97, "up").outcome for _ in range(5)]
    assert got == ["delivered"] * 3 + ["overflow"] * 2
    # the first has left at 10 ms: room for one, which follows the third (30 ms + 10 ms)
    later = link.offer(0.011, 97, "up")
    assert later.deliver_s == pytest.approx(0.040 + 0.050, abs=1e-12)
    assert link.counts.outcomes == {"delivered": 4, "lost": 0, "overflow": 2}


def test_loss_is_independent_seeded_and_a_lost_datagram_uses_its_air_time() -> None:
    """100,000 datagrams at 10 %: binomial mean 10,000, sd 94.9; within 4 sd. The same seed
    loses the same ones. At 100 % nothing arrives, and the channel was still busy."""
    spec = LinkSpec(1e9, 0.05, 0.10)
    fates = [RadioLink(spec, seed=7) for _ in range(2)]
    a = [fates[0].offer(k * 1e-3, 95, "up").outcome for k in range(100_000)]
    b = [fates[1].offer(k * 1e-3, 95, "up").outcome for k in range(100_000)]
    assert a == b
    lost = a.count("lost")
    assert abs(lost - 10_000) < 4 * math.sqrt(100_000 * 0.1 * 0.9), lost
    other = [RadioLink(spec, seed=8).offer(k * 1e-3, 95, "up").outcome for k in range(1000)]
    assert other != a[:1000]
    dead = RadioLink(LinkSpec(12_500.0, 0.05, 1.0), seed=1)
    assert all(dead.offer(0.0, 97, "down").deliver_s is None for _ in range(4))
    assert dead.counts.max_backlog_s == pytest.approx(0.040, abs=1e-12)


def test_bytes_offered_are_counted_per_direction_and_whole_second() -> None:
    """Counted on offer, headers included, from the first datagram's second; a quiet
    second is a zero."""
    link = RadioLink(QUIET, seed=1)
    for t, n, d in [(10.2, 72, "up"), (10.9, 72, "down"), (11.5, 172, "up"), (13.3, 2, "up")]:
        link.offer(t, n, d)
    assert link.per_second() == {
        "up": [100, 200, 0, 30],
        "down": [100, 0, 0, 0],
        "total": [200, 200, 0, 30],
    }
    assert link.counts.datagrams == {"up": 3, "down": 1}


def test_air_time_is_counted_in_the_seconds_it_spans_and_never_above_the_rate() -> None:
    """From t0 = 0: 125 bytes at 0.995 s take [0.995, 1.005) s: 62.5 bytes in second 0 and
    62.5 in second 1. Then 2,000 datagrams of 125 bytes at once at 3.0 s: 1,000 are queued
    (the limit), the rest dropped; 10 s of air: 12,500 bytes in each of seconds 3..12, none
    above the rate."""
    link = RadioLink(QUIET, seed=1)
    link.offer(0.0, 97, "up")  # [0, 0.01): 125 bytes in second 0
    link.offer(0.995, 97, "down")
    assert link.carried_per_second() == [187.5, 62.5]
    for _ in range(2000):
        link.offer(3.0, 97, "up")
    air = link.carried_per_second()
    assert air[2] == 0.0 and air[3:] == [12_500.0] * 10
    assert link.counts.outcomes["overflow"] == 1000  # the limit: 1000 queued at once


@pytest.mark.parametrize(
    "kwargs",
    [{"rate_bytes_s": 0}, {"delay_s": -1}, {"loss": 1.5}, {"limit": 0}, {"header_bytes": -1}],
)
def test_a_bad_spec_is_a_value_error(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        LinkSpec(**kwargs)


def test_a_bad_direction_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="direction"):
        RadioLink(QUIET, seed=1).offer(0.0, 10, "sideways")


# ---- twelve UAVs over the link ----------------------------------------------------------
@pytest.mark.integration
@pytest.mark.alone  # free-running at 1x: the link's rate and delay are wall-clock
@pytest.mark.slow
@pytest.mark.extended  # 400 s of flight at 1x (pytest -m extended; bench/radio_link.py)
def test_twelve_uavs_over_a_radio_like_link_hold_the_formation_within_the_budget(
    tmp_path: Path,
) -> None:
    """Issue 24's goal: 12 UAVs on the paper's ellipse, their group over 100 kbit/s, 50 ms,
    10 % loss under ``--group-budget 300`` (the star's traffic within 80 % of the link):
    they converge and, over metrics.json's window, hold cross-track p95 <= 5 m and coverage
    revisit <= 1.15. Once joined, the group never offers the link more than its share (80 %:
    10,000 bytes/s) over any 10 s, measured on the link (both directions, every header,
    retransmissions and acknowledgements); the queue never overflows and no datagram waits
    1 s (a quarter of the 3.8 s state period). Per second the load is bursty (the router
    sends each state to 11 members at once): the seconds above the share and above the rate
    are printed, not judged, and so is the join's burst (each member at 5 Hz until it hears
    the others); docs/protocol.md, "A radio-like link", says by how much."""
    from tests.radio_harness import BUDGET_BYTES_S, fly_over_radio

    fig = fly_over_radio(tmp_path, uavs=12, duration_s=400.0, budget_bytes_s=BUDGET_BYTES_S)
    print("radio_link " + json.dumps(fig))
    assert fig["exit"] == {"fleet": 0, "radio": 0, "router": 0}, fig["exit"]
    link = fig["link"]
    assert link["uavs_seen"] == 12, link
    assert fig["convergence_time_s"] is not None and fig["settled"], fig
    assert fig["cross_track_p95_m"] <= 5.0, fig
    assert fig["coverage_revisit_ratio"] <= 1.15, fig
    assert link["max_window_mean_bytes_s"] <= link["group_share_bytes_s"], link
    assert link["outcomes"]["overflow"] == 0 and link["max_backlog_s"] < 1.0, link
