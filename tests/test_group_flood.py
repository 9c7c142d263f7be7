"""The group budget in memory (issue 24): the member time-out following a low state rate,
and a member flooding the group beyond its share, whose extra states are dropped before
decoding and counted as ``flood`` while the others fly exactly as without the flood.
Contract tests: six real ``Runner``s on the simulator, in memory (``companion.sim.inmemory``),
the signed group as bytes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from companion.contracts.signing import Signing
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.group.budget import STATE_DATAGRAM_BYTES
from companion.group.messages import MemberState
from companion.group.transport import Group
from companion.sim.inmemory import Engine, EngineConfig

pytestmark = pytest.mark.contract

REPO = Path(__file__).resolve().parents[1]
FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"
RATE_HZ = 2.0  # the budget's share of each of the six: it binds (5 Hz without it)
BUDGET = 6 * RATE_HZ * STATE_DATAGRAM_BYTES  # 1140 bytes/s
FLOOD = 20  # the flooder sends every state this many times: 20x its share
FLOODER = 3
DURATION_S = 60.0


class FloodingGroup(Group):
    """A member's group end that sends each of its states ``FLOOD`` times, each copy freshly
    signed on its own stream (so none is a replay): a member at 20x its share."""

    def send_state(self, state: MemberState) -> None:
        """The same state, ``FLOOD`` times."""
        for _ in range(FLOOD):
            super().send_state(state)


def quiet_mission(folder: Path) -> Path:
    """The fast mission without intruders."""
    path = folder / "quiet.yaml"
    path.write_text(FAST.read_text().split("scenario:")[0] + "scenario:\n  duration_s: 500\n")
    return path


def fly(mission: Path, flood: bool) -> Engine:
    """Six UAVs under the budget for ``DURATION_S``; with ``flood`` companion 3 floods."""
    e = Engine(EngineConfig(mission, None, group_budget_bytes_s=BUDGET))
    if flood:
        r = e.runners[e.sysids.index(FLOODER)]
        assert r.group is None  # made on the first heartbeat, by this factory

        def unix() -> float:
            return SIM_EPOCH_UNIX_S + e.t_s

        r.group_factory = lambda sysid: FloodingGroup(
            sysid, Signing(e.key, unix), clock=unix, sock=e.bus.join(sysid)
        )
    e.run(DURATION_S)
    e.close()
    return e


def test_a_member_at_20x_its_share_is_dropped_and_counted_and_the_others_fly_as_without(
    tmp_path: Path,
) -> None:
    mission = quiet_mission(tmp_path)
    calm, flooded = fly(mission, flood=False), fly(mission, flood=True)
    others = [i for i, s in enumerate(flooded.sysids) if s != FLOODER]
    # the budget binds: every companion sends at 2 Hz once it hears the five others
    for e in (calm, flooded):
        rates = {
            (ev["sysid"], ev["rate_hz"])
            for ev in e.companion_events
            if ev["event"] == "group_schedule"
        }
        assert {(s, RATE_HZ) for s in e.sysids} <= rates
        assert not [ev for ev in e.companion_events if ev["event"] == "member_lost"]
    # the flood: each receiver let in at most 2x the flooder's share plus the burst
    sent = flooded.runners[flooded.sysids.index(FLOODER)].group.stats["sent"]
    assert sent >= FLOOD * RATE_HZ * (DURATION_S - 2.0)
    for i in others:
        stats = flooded.runners[i].group.stats
        assert stats["flood"] >= sent - (10 + 2 * RATE_HZ * DURATION_S) - 20, stats
        assert calm.runners[i].group.stats["flood"] == 0
        assert stats["accepted"] <= calm.runners[i].group.stats["accepted"] + 10 + 2 * (
            RATE_HZ * DURATION_S
        )
    # the others (and the flooder itself) fly exactly as without the flood
    np.testing.assert_array_equal(flooded.sim.state.pos_m, calm.sim.state.pos_m)
    np.testing.assert_array_equal(flooded.sim.course_rad, calm.sim.course_rad)


def test_at_a_quarter_hertz_the_time_out_follows_the_rate_and_nobody_is_dropped(
    tmp_path: Path,
) -> None:
    """A budget of 142.5 bytes/s for six: a state every 4 s, longer than the 3 s time-out
    without a budget; the time-out becomes 16 s (4 states), on every member alike."""
    budget = 6 * 0.25 * STATE_DATAGRAM_BYTES
    with Engine(EngineConfig(quiet_mission(tmp_path), None, group_budget_bytes_s=budget)) as e:
        e.run(40.0)
        for r in e.runners:
            assert r.agent is not None and len(r.agent.neighbours) == 5
            assert r.agent.member_timeout_s == pytest.approx(16.0)
            assert r.agent.tasking.member_timeout_s == pytest.approx(16.0)
            assert r.counters.states_sent <= 40.0 / 4.0 + 3  # the first ones at 5 Hz, alone
    assert not [ev for ev in e.companion_events if ev["event"] == "member_lost"]
