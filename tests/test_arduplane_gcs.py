"""A ground station beside the companion on real ArduPlane firmware (issue 49, item 2): one
autopilot link (ArduPlane SITL's SERIAL1) shared through a router (:mod:`tests.mavlink_router`:
in this process, or MAVProxy as docs/gcs.md gives it where ``mavproxy.py`` is on the PATH or
in ``$MAVPROXY``) by ``companion run`` and a pymavlink ground station that halves the
companion's position stream, first with SET_MESSAGE_INTERVAL, then with REQUEST_DATA_STREAM
(as MAVProxy and QGroundControl ask for their rates). The companion notices and asks again:
the ground station measures the position stream back at 10 Hz within 3 s each time, and the
companion says it once in its events (both changes are one fight: docs/gcs.md).

Skipped, with the reason, without an ArduPlane SITL binary (``$ARDUPLANE_SITL``;
``tests/conftest.py`` finds ``../shared/arduplane/arduplane``). Cost: one instance on the
ground, about 35 s of wall time per router.
"""

from __future__ import annotations

import itertools
import json
import os
import shutil
import time
from pathlib import Path

import pytest
from pymavlink import mavutil

from companion.contracts.errors import UserError
from companion.sim.arduplane import sitl
from tests.arduplane_harness import arduplane
from tests.fleet_harness import Companion, free_udp_port
from tests.mavlink_router import MavproxyRouter, UdpRouter

# real ArduPlane SITL, free-running against the wall clock
pytestmark = [pytest.mark.integration, pytest.mark.alone]

REPO = Path(__file__).resolve().parents[1]
MISSION = REPO / "tests" / "data" / "ellipse_3uav.yaml"
BACK_WITHIN_S = 3.0


def _have_binary() -> bool:
    try:
        sitl.find_binary(None)
    except UserError:
        return False
    return True


needs_firmware = pytest.mark.skipif(
    not _have_binary(), reason="needs ArduPlane SITL ($ARDUPLANE_SITL)"
)


class PositionRate:
    """The ground station: GLOBAL_POSITION_INT from system 1 as it arrives (wall s)."""

    def __init__(self, conn) -> None:
        self.conn = conn
        self.times: list[float] = []

    def pump(self, duration_s: float) -> None:
        end = time.monotonic() + duration_s
        while time.monotonic() < end:
            m = self.conn.recv_match(blocking=True, timeout=0.05)
            if (
                m is not None
                and m.get_type() == "GLOBAL_POSITION_INT"
                and m.get_srcSystem() == 1
                and m.get_srcComponent() == 1
            ):
                self.times.append(time.monotonic())

    def hz(self, start: float, end: float) -> float:
        return sum(start <= t < end for t in self.times) / (end - start)

    def gaps(self, start: float, end: float, at_least_s: float) -> int:
        """How many gaps between two positions in [start, end) were ``at_least_s`` long."""
        ts = [t for t in self.times if start <= t < end]
        return sum(b - a >= at_least_s for a, b in itertools.pairwise(ts))

    def last_gap_end(self, start: float, end: float, at_least_s: float) -> float | None:
        """The arrival ending the last gap of ``at_least_s`` or more in [start, end) (wall
        s): from then on the stream is at its rate again; None: no such gap."""
        ts = [t for t in self.times if start <= t < end]
        ends = [b for a, b in itertools.pairwise(ts) if b - a >= at_least_s]
        return ends[-1] if ends else None


def _events(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


MAVPROXY = os.environ.get("MAVPROXY") or shutil.which("mavproxy.py")


@needs_firmware
@pytest.mark.parametrize(
    "router_kind",
    [
        "bytes",
        pytest.param("mavproxy", marks=pytest.mark.skipif(
            MAVPROXY is None, reason="needs MAVProxy (pip install mavproxy; or $MAVPROXY)")),
    ],
)  # fmt: skip
def test_a_ground_station_halving_the_position_stream_on_arduplane(tmp_path, router_kind):
    log = tmp_path / "c1"
    with arduplane(tmp_path, MISSION) as ap:
        router: UdpRouter | MavproxyRouter
        if router_kind == "mavproxy":
            assert MAVPROXY is not None
            router = MavproxyRouter(MAVPROXY, ap.spec.ports.serial1, tmp_path / "mavproxy")
            gcs_port, companion_port = router.ports
        else:
            router = UdpRouter(ap.spec.ports.serial1)
            gcs_port = companion_port = router.port
        gcs = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{gcs_port}", source_system=255, source_component=190
        )
        c = Companion([
            "--connect", f"udpout:127.0.0.1:{companion_port}", "--mission", str(MISSION),
            "--sysid", "1", "--insecure", "--group", f"239.255.14.9:{free_udp_port()}",
            "--log-dir", str(log),
        ])  # fmt: skip
        try:
            rate = PositionRate(gcs)
            gcs.mav.heartbeat_send(6, 8, 0, 0, 0)  # the router learns the ground station
            deadline = time.monotonic() + 60.0
            while not any(e["event"] == "link_up" for e in _events(log / "events.jsonl")):
                assert time.monotonic() < deadline, "".join(c.lines)
                gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
                rate.pump(1.0)
            rate.pump(8.0)  # the companion's rates asked, accepted and seen at rate
            now = time.monotonic()
            before = rate.hz(now - 3.0, now)
            assert before >= 9.0, before
            figures = [f"before {before:.1f} Hz"]
            changes = {
                "SET_MESSAGE_INTERVAL": lambda: gcs.mav.command_long_send(
                    1, 1, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                    mavutil.mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 200_000, 0, 0, 0, 0, 0,
                ),
                "REQUEST_DATA_STREAM": lambda: gcs.mav.request_data_stream_send(
                    1, 1, mavutil.mavlink.MAV_DATA_STREAM_POSITION, 5, 1
                ),
            }  # fmt: skip
            for how, change in changes.items():
                changed = time.monotonic()
                change()
                rate.pump(6.0)
                slowed = rate.gaps(changed, changed + 6.0, at_least_s=0.17)
                back = rate.last_gap_end(changed, changed + 6.0, at_least_s=0.17)
                assert slowed >= 2 and back is not None, (how, slowed)  # slowed to 5 Hz
                after = rate.hz(back, back + 3.0)
                figures.append(
                    f"{how}: {slowed} gaps of 5 Hz, the last ending {back - changed:.1f} s "
                    f"after, then {after:.1f} Hz"
                )
                assert back - changed <= BACK_WITHIN_S, (how, back - changed)
                assert after >= 9.0, (how, after)  # back at its rate, and stays there
                rate.pump(3.0)
        finally:
            c.stop()
            gcs.close()
            router.close()
    evs = [e for e in _events(log / "events.jsonl") if e["event"].startswith("stream_")]
    print(f"\nArduPlane SITL via {router_kind}, GLOBAL_POSITION_INT: " + "; ".join(figures),
          end="")  # fmt: skip
    pos = [e for e in evs if e["stream"] == "GLOBAL_POSITION_INT"]
    # the second change came within a minute of the first restoring: the same fight, asked
    # again (the rate came back) but not said again
    assert [e["event"] for e in pos] == ["stream_slow", "stream_restored"], evs
    assert pos[1]["requests"] == 1
