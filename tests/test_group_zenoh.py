"""The group over Zenoh: the same signed datagrams and the same Group as over multicast.

Unit: ``--group`` parsing (a table). Loopback integration: two Groups over Zenoh peers, the
codec's refusals of unsigned, forged and replayed frames published on the key expression,
and clients through a ``companion zenoh-router`` process that dies and returns.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import selectors
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import MulticastGroup, ZenohGroup, parse_group
from companion.group.messages import Alert, MemberState
from companion.group.transport import Group, open_group

ROOT = Path(__file__).resolve().parents[1]
KEY = bytes(range(32))
_keys = itertools.count()


# ---- parsing (pure) ---------------------------------------------------------------------
PARSED = [
    ("239.255.14.1:14600", MulticastGroup("239.255.14.1", 14600)),
    ("zenoh", ZenohGroup()),
    ("zenoh:", ZenohGroup()),
    ("zenoh:tcp/10.0.1.1:7447", ZenohGroup(connect=("tcp/10.0.1.1:7447",))),
    (
        "zenoh:tcp/10.0.1.1:7447,udp/10.0.2.1:7447?key=patrol/blue&scout=off",
        ZenohGroup(
            connect=("tcp/10.0.1.1:7447", "udp/10.0.2.1:7447"),
            key_expr="patrol/blue",
            scouting=False,
        ),
    ),
    ("zenoh?listen=tcp/0.0.0.0:7450", ZenohGroup(listen=("tcp/0.0.0.0:7450",))),
    ("zenoh-client:tcp/[::1]:7447", ZenohGroup("client", ("tcp/[::1]:7447",))),
]


@pytest.mark.parametrize(("text", "want"), PARSED)
def test_group_text_parses_to_multicast_or_zenoh_and_prints_back(text: str, want: object) -> None:
    got = parse_group(text)
    assert got == want
    assert parse_group(str(got)) == got  # the text a fleet hands its companions


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("239.255.14.1", "expected ADDR:PORT"),
        ("10.0.0.1:14600", "not a multicast"),
        ("zenoh:10.0.1.1:7447", "not a Zenoh endpoint"),
        ("zenoh:tcp/10.0.1.1", "not a Zenoh endpoint"),
        ("zenoh?key=patrol/*", "without wildcards"),
        ("zenoh?key=", "without wildcards"),
        ("zenoh?scout=maybe", "on or off"),
        ("zenoh?mode=router", "unknown setting"),
        ("zenoh?key", "NAME=VALUE"),
        ("zenoh-client:?scout=off", "needs a router"),
    ],
)
def test_bad_group_text_is_one_user_error_naming_the_option(text: str, message: str) -> None:
    with pytest.raises(UserError, match="--group") as err:
        parse_group(text)
    assert message in str(err.value)


def test_zenoh_config_is_the_mode_endpoints_and_scouting() -> None:
    cfg = ZenohGroup("client", ("tcp/10.0.1.1:7447",), scouting=False).config()
    assert cfg == {
        "mode": '"client"',
        "connect/endpoints": '["tcp/10.0.1.1:7447"]',
        "scouting/multicast/enabled": "false",
        "connect/timeout_ms": "30000",  # a slow link delays the handshake: keep trying
    }
    assert "connect/timeout_ms" not in ZenohGroup().config()  # a peer retries anyway
    assert ZenohGroup(listen=("tcp/0.0.0.0:1",)).config()["listen/endpoints"] == (
        '["tcp/0.0.0.0:1"]'
    )


# ---- over real Zenoh sessions on loopback -----------------------------------------------
def free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def key_expr() -> str:
    """A key expression of this test's own: parallel runs never hear each other."""
    return f"patrol/test-{os.getpid()}-{next(_keys)}"


def drain(group: Group, want: int, timeout_s: float = 5.0) -> list:
    """Receive until ``want`` messages arrived or ``timeout_s`` (a limit, not a measure)."""
    got: list = []
    deadline = time.monotonic() + timeout_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)
        while len(got) < want and (left := deadline - time.monotonic()) > 0:
            sel.select(min(left, 0.05))
            got += group.receive()
    return got


def exchange(tx: Group, rx: Group, sysid: int, t0: float, timeout_s: float = 10.0) -> list:
    """Send states every 50 ms until ``rx`` accepts one (Zenoh routes a new subscription
    within a few hundred ms); what ``rx`` accepted."""
    deadline = time.monotonic() + timeout_s
    got: list = []
    k = 0
    while not got and time.monotonic() < deadline:
        tx.send_state(MemberState(sysid, t0 + k, 0j, 0.0))
        k += 1
        got = drain(rx, 1, 0.05)
    return got


@pytest.fixture
def pair() -> Iterator[tuple[Group, Group, ZenohGroup]]:
    """Two signed members: one listens on a loopback endpoint, the other connects to it."""
    ep = f"tcp/127.0.0.1:{free_tcp_port()}"
    key = key_expr()
    a_where = ZenohGroup(listen=(ep,), key_expr=key, scouting=False)
    b_where = ZenohGroup(connect=(ep,), key_expr=key, scouting=False)
    a = open_group(a_where, 1, Signing(KEY, time.time))
    try:
        b = open_group(b_where, 2, Signing(KEY, time.time))
    except BaseException:
        a.close()
        raise
    with a, b:
        yield a, b, b_where


@pytest.mark.integration
def test_two_zenoh_peers_exchange_states_and_alerts_as_over_multicast(
    pair: tuple[Group, Group, ZenohGroup],
) -> None:
    a, b, _ = pair
    assert exchange(a, b, 1, 1.0)  # the route exists
    state = MemberState(1, 10.5, 3 + 4j, 1.0, "prosecuting", "2-1")
    alert = Alert("2-1", 100 - 50j, 2, 9.0, "new")
    for _ in range(3):
        a.send_state(state)
    b.send_alert(alert)
    assert drain(b, 3) == [state] * 3  # exactly representable values survive unchanged
    assert drain(a, 1) == [alert]
    assert a.stats["sent"] >= 4 and a.stats["send_errors"] == 0
    assert b.stats["bad_signature"] == b.stats["unsigned"] == b.stats["replayed"] == 0
    assert b.stats["own"] == 1  # a session hears its own samples, as multicast loops back


@pytest.mark.integration
def test_unsigned_forged_and_replayed_frames_over_zenoh_are_refused(
    pair: tuple[Group, Group, ZenohGroup],
) -> None:
    """An attacker on the Zenoh network (its own session on the key expression, no fleet
    key) publishes an unsigned frame, a frame signed with another key and a copy of a
    genuine frame it captured: the member accepts none, each counted under its reason."""
    from companion.group.zenoh_socket import ZenohSocket

    a, b, where = pair
    assert exchange(a, b, 1, 1.0)
    with (
        Group(3, None, sock=ZenohSocket(where)) as plain,
        Group(4, Signing(bytes(32), time.time), sock=ZenohSocket(where)) as forger,
        ZenohSocket(where) as tap,
    ):
        captured: bytes | None = None
        deadline = time.monotonic() + 10.0
        while captured is None and time.monotonic() < deadline:  # a's next genuine frame
            a.send_state(MemberState(1, 500.0, 0j, 0.0))
            with selectors.DefaultSelector() as sel:
                sel.register(tap.fileno(), selectors.EVENT_READ)
                sel.select(0.05)
                with contextlib.suppress(BlockingIOError):
                    captured = tap.recv(281)
        assert captured is not None
        drain(b, 100, 0.5)  # b takes a's genuine frames before the attack
        before = dict(b.stats)
        plain.send_state(MemberState(3, 1.0, 0j, 0.0))
        forger.send_state(MemberState(4, 1.0, 0j, 0.0))
        tap.sendto(captured)  # the replay, byte for byte
        deadline = time.monotonic() + 10.0
        refused = ("unsigned", "bad_signature", "replayed")
        while sum(b.stats[r] - before[r] for r in refused) < 3 and time.monotonic() < deadline:
            assert drain(b, 1, 0.05) == []
        assert {r: b.stats[r] - before[r] for r in refused} == dict.fromkeys(refused, 1)
        assert b.stats["accepted"] == before["accepted"]


def start_router(endpoint: str) -> subprocess.Popen:
    """``companion zenoh-router --listen ENDPOINT``, returned once it says it is ready."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "companion", "zenoh-router", "--listen", endpoint],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
    )  # fmt: skip
    line = proc.stdout.readline()
    if not line.startswith("zenoh-router: ready"):
        proc.kill()
        raise AssertionError(f"router did not start: {line!r} {proc.communicate()[1]}")
    return proc


def stop_router(proc: subprocess.Popen) -> int:
    """SIGTERM to the router we started (by pid); its exit status."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
    try:
        return proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise
    finally:
        proc.stdout.close()
        proc.stderr.close()


@pytest.mark.integration
def test_clients_through_a_router_that_dies_and_returns_lose_then_regain_the_group() -> None:
    """Two clients (every sample through the router): while the router is down sends do not
    fail the member (best effort, as multicast) and nothing arrives; once a router listens on
    the same endpoint again the clients reconnect on their own and the group flows."""
    ep = f"tcp/127.0.0.1:{free_tcp_port()}"
    where = ZenohGroup("client", (ep,), key_expr=key_expr(), scouting=False)
    router = start_router(ep)
    try:
        with (
            open_group(where, 1, Signing(KEY, time.time)) as a,
            open_group(where, 2, Signing(KEY, time.time)) as b,
        ):
            assert exchange(a, b, 1, 1.0)
            assert stop_router(router) == 0
            for k in range(20):  # the router is gone: 20 states into the void
                a.send_state(MemberState(1, 100.0 + k, 0j, 0.0))
            assert drain(b, 1, 1.0) == []
            router = start_router(ep)
            got = exchange(a, b, 1, 200.0, timeout_s=30.0)
            assert got and got[0].t_s >= 200.0  # a state sent after the return
            assert b.stats["replayed"] == 0 and b.stats["bad_signature"] == 0
    finally:
        stop_router(router)


def test_a_zenoh_fleet_meets_at_its_observer_on_a_key_of_its_own(tmp_path: Path) -> None:
    """``companion fleet --group zenoh``: every companion connects to the endpoint the
    observer listens on, the run gets a key expression of its own, and the text handed to
    the companions parses back; multicast gives both the same group."""
    from companion.sim.fleet import FleetConfig, fleet_groups

    def cfg(group: str | None) -> FleetConfig:
        return FleetConfig(ROOT / "missions" / "ellipse_6uav.yaml", tmp_path, group=group)

    members, observer = fleet_groups(cfg("zenoh:tcp/10.0.0.1:7447"))
    assert isinstance(members, ZenohGroup) and isinstance(observer, ZenohGroup)
    assert members.connect[0] == "tcp/10.0.0.1:7447" and members.connect[1:] == observer.listen
    assert members.key_expr == observer.key_expr != "patrol/group"
    assert fleet_groups(cfg("zenoh"))[0].key_expr != members.key_expr  # another run
    assert parse_group(str(members)) == members
    multicast = fleet_groups(cfg(None))
    assert multicast[0] == multicast[1] and isinstance(multicast[0], MulticastGroup)
    assert fleet_groups(cfg("239.255.9.9:15000")) == (MulticastGroup("239.255.9.9", 15000),) * 2


def test_an_observer_group_joins_elsewhere_on_the_companions_key(tmp_path: Path) -> None:
    """``companion fleet --observer-group``: the companions' group is used as given (no
    observer endpoint added), the observer joins where it says, on the companions' key; a
    multicast group or another key is one user error."""
    from companion.sim.fleet import FleetConfig, fleet_groups

    def cfg(group: str | None, observer: str) -> FleetConfig:
        return FleetConfig(
            ROOT / "missions" / "ellipse_6uav.yaml", tmp_path, group=group, observer_group=observer
        )

    radio = "zenoh-client:tcp/127.0.0.1:7500?key=patrol/radio&scout=off"
    members, observer = fleet_groups(cfg(radio, "zenoh-client:tcp/127.0.0.1:7448?scout=off"))
    assert members == parse_group(radio)
    assert observer == ZenohGroup("client", ("tcp/127.0.0.1:7448",), (), "patrol/radio", False)
    for group, observer_text, message in [
        (None, "zenoh-client:tcp/127.0.0.1:7448", "needs a Zenoh --group"),
        (radio, "239.255.9.9:15000", "expected zenoh"),
        (radio, "zenoh-client:tcp/127.0.0.1:7448?key=patrol/other", "not the companions'"),
    ]:
        with pytest.raises(UserError, match=message):
            fleet_groups(cfg(group, observer_text))


@pytest.mark.integration
def test_alert_cli_over_zenoh_is_received_by_a_member(tmp_path: Path) -> None:
    """``companion alert --group zenoh:ENDPOINT?key=...``: the operator's signed copies
    reach a member listening on that endpoint, signed with the fleet key."""
    from companion.group.keys import generate_key_file, load_key

    key_file = tmp_path / "fleet.key"
    generate_key_file(key_file)
    ep, key = f"tcp/127.0.0.1:{free_tcp_port()}", key_expr()
    where = ZenohGroup(listen=(ep,), key_expr=key, scouting=False)
    with open_group(where, 4, Signing(load_key(key_file), time.time)) as member:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        proc = subprocess.Popen(
            [sys.executable, "-m", "companion", "alert", "--at", "10,20", "--key-file",
             str(key_file), "--listen-s", "1", "--repeat", "3", "--interval-s", "0.2",
             "--alert-id", "op-z", "--group", f"zenoh:{ep}?key={key}&scout=off"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
        )  # fmt: skip
        got = drain(member, 1, 30.0)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert got and got[0].alert_id == "op-z" and got[0].site_m == 10 + 20j
    assert member.stats["bad_signature"] == member.stats["unsigned"] == 0
    assert '"group": "zenoh:' in out


class _FakeSample:
    """What the subscriber's callback reads of a Zenoh sample: ``payload.to_bytes()``."""

    def __init__(self, data: bytes) -> None:
        self.payload = self
        self._data = data

    def to_bytes(self) -> bytes:
        return self._data


@pytest.mark.integration
def test_a_full_receive_pair_drops_and_counts_as_a_full_udp_buffer_would() -> None:
    """Samples arriving while nobody reads: the pair queues what its buffer holds, the rest
    is counted in ``overflow``, none is lost unaccounted and none blocks Zenoh's thread."""
    from companion.group.zenoh_socket import ZenohSocket

    ep = f"tcp/127.0.0.1:{free_tcp_port()}"
    with ZenohSocket(ZenohGroup(listen=(ep,), key_expr=key_expr(), scouting=False)) as sock:
        n = 10_000
        for i in range(n):
            sock._deliver(_FakeSample(i.to_bytes(2, "big") + bytes(93)))  # 95-byte states
        got = []
        with contextlib.suppress(BlockingIOError):
            while True:
                got.append(sock.recv(281))
        assert got and sock.overflow > 0
        assert len(got) + sock.overflow == n
        assert [int.from_bytes(d[:2], "big") for d in got] == list(range(len(got)))  # in order
