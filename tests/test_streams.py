"""The companion keeps the telemetry it asked for when a ground station on the same link
changes the rates (issue 49, item 2): :class:`companion.process.streams.StreamWatch` against
a hand-written autopilot on a fake clock, then the in-memory engine (the simulator's own
SET_MESSAGE_INTERVAL and REQUEST_DATA_STREAM, sent by a second client on the link)."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav

from companion.link.outbox import CommandLong
from companion.process.events import StreamGivenUp, StreamRestored, StreamSlow
from companion.process.streams import (
    BACKOFF_CAP_S,
    MAX_REQUESTS,
    QUIET_S,
    SLOW_FRACTION,
    WINDOW_MIN_S,
    WINDOW_PERIODS,
    State,
    StreamWatch,
    backoff_s,
)

ASKED = {"GLOBAL_POSITION_INT": 10.0, "ATTITUDE": 10.0, "SYSTEM_TIME": 1.0, "VFR_HUD": 2.0}


@dataclass
class Msg:
    name: str
    time_boot_ms: int

    def get_type(self) -> str:
        return self.name


@dataclass
class Link:
    sysid: int | None = 1
    rates_hz: dict[str, float] = field(default_factory=lambda: dict(ASKED))
    counts: dict[str, int] = field(default_factory=lambda: {"ap_frames": 0, "ap_missed": 0})


class Autopilot:
    """Streams each message at its interval on a 10 ms clock; SET_MESSAGE_INTERVAL sets it."""

    def __init__(self, rates_hz: dict[str, float]) -> None:
        self.interval_s = {k: 1.0 / v for k, v in rates_hz.items()}
        self.next_s = dict.fromkeys(rates_hz, 0.0)
        self.t_s = 0.0

    def set_rate(self, name: str, hz: float) -> None:
        self.interval_s[name] = 1.0 / hz if hz > 0 else math.inf
        self.next_s[name] = self.t_s

    def command(self, c: CommandLong) -> None:
        assert c.command == mav.MAV_CMD_SET_MESSAGE_INTERVAL
        name = mav.mavlink_map[int(c.params[0])].msgname
        self.set_rate(name, 1e6 / c.params[1])

    def step(self) -> list[Msg]:
        """The messages due in the next 10 ms."""
        self.t_s = round(self.t_s + 0.01, 6)
        out = []
        for name, due in self.next_s.items():
            if self.t_s + 1e-9 >= due:
                out.append(Msg(name, round(self.t_s * 1e3)))
                self.next_s[name] = due + self.interval_s[name]
        return out


class Bench:
    """The watch and the autopilot wired together: requests are obeyed at once."""

    def __init__(self, rates_hz: dict[str, float] | None = None) -> None:
        self.ap = Autopilot(rates_hz or ASKED)
        self.link = Link()
        self.watch = StreamWatch(self.link, lambda: self.ap.t_s)
        self.events: list = []
        self.requests: list[tuple[float, str]] = []  # (s, message name)
        self.deaf = False  # what the autopilot sends is missed (its sequence numbers show it)

    def run_until(self, t_s: float, each=None) -> None:
        counts = self.link.counts
        while self.ap.t_s < t_s - 1e-9:
            for m in self.ap.step():
                if self.deaf:
                    counts["ap_missed"] += 1
                    continue
                counts["ap_frames"] += 1
                for e in self.watch.on_message(m):
                    if isinstance(e, CommandLong):
                        name = mav.mavlink_map[int(e.params[0])].msgname
                        self.requests.append((self.ap.t_s, name))
                        self.ap.command(e)
                    else:
                        self.events.append(e)
            if each is not None:
                each(self)


def test_a_halved_position_stream_is_asked_again_once_and_said_once():
    b = Bench()
    b.run_until(20.0)
    assert {n: s.state for n, s in b.watch.streams.items()} == dict.fromkeys(ASKED, State.AT_RATE)
    assert b.events == [] and b.requests == []
    b.ap.set_rate("GLOBAL_POSITION_INT", 5.0)  # a ground station halves it
    b.run_until(40.0)
    assert [r[1] for r in b.requests] == ["GLOBAL_POSITION_INT"]
    asked_s = b.requests[0][0]
    assert asked_s - 20.0 <= 2 * WINDOW_MIN_S + 0.05  # found within two windows, asked at once
    slow, restored = b.events
    assert isinstance(slow, StreamSlow) and isinstance(restored, StreamRestored)
    assert (slow.stream, slow.asked_hz) == ("GLOBAL_POSITION_INT", 10.0)
    assert slow.received_hz == pytest.approx(5.0, abs=1.1)
    assert slow.t_s == pytest.approx(asked_s)
    assert restored.requests == 1 and restored.received_hz >= 9.0
    assert restored.after_s == pytest.approx(WINDOW_MIN_S, abs=0.11)  # one window later


@pytest.mark.parametrize("name", ["ATTITUDE", "SYSTEM_TIME", "VFR_HUD"])
def test_a_stopped_stream_is_asked_again(name):
    b = Bench()
    b.run_until(20.0)
    b.ap.set_rate(name, 0.0)  # a ground station stops it
    b.run_until(40.0)
    assert [r[1] for r in b.requests] == [name]
    window = max(WINDOW_MIN_S, WINDOW_PERIODS / ASKED[name])
    assert b.requests[0][0] - 20.0 <= 2 * window + 0.05
    assert [type(e) for e in b.events] == [StreamSlow, StreamRestored]
    assert b.events[0].received_hz == 0.0


def test_a_stream_never_given_at_its_rate_is_not_watched():
    b = Bench()
    b.ap.set_rate("VFR_HUD", 0.5)  # the autopilot gives a quarter of what was asked, always
    b.run_until(60.0)
    assert b.watch.streams["VFR_HUD"].state is State.WAITING
    assert b.requests == [] and b.events == []


def test_a_ground_station_that_fights_back_meets_a_backoff_and_a_cap():
    """It halves the stream again 1.5 s after each request (the stream is back for a
    window each time): requests after 2, 4, 8, 16 s of backoff (each once the stream is found
    slow again), then the stream is given up; said once each: slow, restored, given up."""

    def fight(b: Bench) -> None:
        if b.requests and b.ap.t_s == pytest.approx(b.requests[-1][0] + 1.5):
            b.ap.set_rate("GLOBAL_POSITION_INT", 5.0)

    b = Bench()
    b.run_until(10.0)
    b.ap.set_rate("GLOBAL_POSITION_INT", 5.0)
    b.run_until(200.0, fight)
    times = [t for t, n in b.requests if n == "GLOBAL_POSITION_INT"]
    assert len(times) == MAX_REQUESTS
    gaps = [b_ - a for a, b_ in itertools.pairwise(times)]
    for k, gap in enumerate(gaps, start=1):
        assert backoff_s(k) - 1e-6 <= gap <= backoff_s(k) + 1.05, (k, gaps)
    assert [type(e) for e in b.events] == [StreamSlow, StreamRestored, StreamGivenUp]
    assert b.events[1].requests == 1 and b.events[2].requests == MAX_REQUESTS
    assert b.watch.streams["GLOBAL_POSITION_INT"].state is State.GIVEN_UP
    assert backoff_s(10) == BACKOFF_CAP_S


def test_a_slowing_after_a_quiet_minute_is_a_new_fight_said_again():
    b = Bench()
    b.run_until(10.0)
    b.ap.set_rate("ATTITUDE", 5.0)
    b.run_until(15.0)
    b.ap.set_rate("ATTITUDE", 5.0)  # again 3 s after it came back: the same fight
    b.run_until(25.0)
    assert [type(e) for e in b.events] == [StreamSlow, StreamRestored]
    assert len(b.requests) == 2
    b.run_until(25.0 + QUIET_S + 5.0)
    b.ap.set_rate("ATTITUDE", 5.0)  # after a quiet minute: a new fight
    b.run_until(25.0 + QUIET_S + 10.0)
    assert [type(e) for e in b.events] == [StreamSlow, StreamRestored] * 2
    assert b.events[-1].requests == 1


def test_a_companion_that_missed_frames_asks_nothing():
    """A stalled companion (or a lossy radio) misses the autopilot's frames: the gaps in
    their sequence numbers say so, and fewer messages then are not a slowed stream."""
    b = Bench()
    b.run_until(10.0)
    b.deaf = True
    b.run_until(12.0)  # 2 s of nothing (under the link's 3 s time-out)
    b.deaf = False
    b.run_until(30.0)
    assert b.requests == [] and b.events == []
    assert all(s.state is State.AT_RATE for s in b.watch.streams.values())


def test_a_lost_link_or_a_rebooted_autopilot_starts_the_watch_anew():
    b = Bench()
    b.run_until(10.0)
    b.watch.reset()
    assert b.watch.streams == {}
    b.run_until(12.0)
    b.ap.t_s, b.ap.next_s = 0.0, dict.fromkeys(ASKED, 0.0)  # rebooted: its clock restarts
    b.run_until(0.3)
    assert all(s.state is State.WAITING for s in b.watch.streams.values())
    assert b.requests == [] and b.events == []


# ---- a second client on the simulator's link, in memory ------------------------------------
@pytest.mark.contract
@pytest.mark.parametrize(
    ("how", "stream", "slowed_hz"),
    [("interval", "GLOBAL_POSITION_INT", 5.0), ("data_stream", "GLOBAL_POSITION_INT", 5.0),
     ("data_stream_extra1", "ATTITUDE", 2.0)],
)  # fmt: skip
def test_in_memory_a_ground_station_slows_a_stream_and_the_companion_restores_it(
    how, stream, slowed_hz
):
    """A ground station on vehicle 1's link changes a rate the companion asked for (its own
    SET_MESSAGE_INTERVAL, or REQUEST_DATA_STREAM for the message's group, as MAVProxy and
    QGroundControl do): the companion asks again, the simulator streams at the asked rate
    again within 3 s, the control steps go on at 10 Hz, said once in its events."""
    from companion.contracts.simulator import SIM_EPOCH_UNIX_S
    from companion.sim.inmemory import Engine, EngineConfig
    from tests.test_inmemory import FAST

    with Engine(EngineConfig(FAST)) as e:
        sysid = e.sysids[0]
        vehicle, runner = e.links[0], e.runners[0]
        e.run(30.0)
        assert vehicle.streams.interval_s[stream] == pytest.approx(0.1)
        changed_unix_s = SIM_EPOCH_UNIX_S + e.t_s
        if how == "interval":
            msg_id = getattr(mav, f"MAVLINK_MSG_ID_{stream}")
            e.gcs_command(sysid, mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / slowed_hz)
        else:
            group = (
                mav.MAV_DATA_STREAM_POSITION
                if how == "data_stream"
                else (mav.MAV_DATA_STREAM_EXTRA1)
            )
            e.gcs_send(sysid, mav.MAVLink_request_data_stream_message(
                sysid, 1, group, int(slowed_hz), 1))  # fmt: skip
        assert vehicle.streams.interval_s[stream] == pytest.approx(1.0 / slowed_hz)
        e.run(e.t_s + 3.0)
        assert vehicle.streams.interval_s[stream] == pytest.approx(0.1)  # back within 3 s
        steps0 = runner.counters.setpoints
        e.run(e.t_s + 10.0)
        assert runner.counters.setpoints - steps0 >= 98  # 10 Hz control steps
        mine = [
            ev for ev in e.companion_events
            if ev["sysid"] == sysid and ev["event"].startswith("stream_")
        ]  # fmt: skip
        others = [
            ev for ev in e.companion_events
            if ev["sysid"] != sysid and ev["event"].startswith("stream_")
        ]  # fmt: skip
    assert [ev["event"] for ev in mine] == ["stream_slow", "stream_restored"], mine
    slow, restored = mine
    assert slow["stream"] == stream and slow["asked_hz"] == 10.0
    assert slow["received_hz"] < SLOW_FRACTION * 10.0
    assert slow["t_s"] - changed_unix_s <= 2.5  # found and asked again
    assert restored["requests"] == 1 and restored["received_hz"] >= 8.0
    assert others == []  # the other vehicles' links were not touched


@pytest.mark.contract
def test_in_memory_a_frozen_companion_asks_nothing_when_it_thaws():
    """SIGSTOP for 2 s (under the link's time-out): what the vehicle sent meanwhile is lost,
    its sequence numbers show the gap, and no stream is taken for slowed."""
    from companion.sim.inmemory import Engine, EngineConfig
    from tests.test_inmemory import FAST

    with Engine(EngineConfig(FAST)) as e:
        sysid = e.sysids[0]
        e.run(30.0)
        e.freeze(sysid)
        e.run(e.t_s + 2.0)
        e.thaw(sysid)
        e.run(e.t_s + 10.0)
        link = e.runners[0].link
        assert link.counts["ap_missed"] >= 20  # 2 s of 10 Hz positions at least
        evs = [ev["event"] for ev in e.companion_events if ev["event"].startswith("stream_")]
        lost = [ev for ev in e.companion_events if ev["event"] == "link_lost"]
    assert evs == [] and lost == []
