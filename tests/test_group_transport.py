"""Real loopback multicast: two Groups in one process, faults on send, the `alert` CLI."""

from __future__ import annotations

import itertools
import json
import os
import selectors
import subprocess
import sys
import time
from pathlib import Path

import pymap3d
import pytest

from companion.contracts.errors import UserError
from companion.contracts.signing import Signing
from companion.group.address import MulticastGroup, parse_group
from companion.group.faults import FaultModel
from companion.group.keys import generate_key_file, load_key
from companion.group.messages import Alert, MemberState
from companion.group.transport import RECEIVE_BUFFER_BYTES, Group
from companion.mission import load_mission

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

ROOT = Path(__file__).resolve().parents[1]
KEY = bytes(range(32))
_ports = itertools.count()


@pytest.fixture
def addr() -> tuple[str, int]:
    """A group address and port of our own, so parallel test runs do not hear each other."""
    n = next(_ports)
    return f"239.255.{100 + os.getpid() % 100}.{1 + n % 250}", 20000 + (os.getpid() * 7 + n) % 20000


def open_group(addr: tuple[str, int], sysid: int, signing: Signing | None = None, **kw) -> Group:
    if signing is None and not kw.pop("insecure", False):
        signing = Signing(KEY, time.time)
    return Group(sysid, signing, address=addr[0], port=addr[1], **kw)


def drain(group: Group, want: int, timeout_s: float = 2.0, now_s: float | None = None) -> list:
    """Receive until ``want`` messages arrived or the timeout passed."""
    got: list = []
    deadline = time.monotonic() + timeout_s
    with selectors.DefaultSelector() as sel:
        sel.register(group.fileno(), selectors.EVENT_READ)
        while len(got) < want and (left := deadline - time.monotonic()) > 0:
            sel.select(min(left, 0.05))
            got += group.receive(now_s)
    return got


@pytest.fixture(scope="module")
def multicast_ok() -> None:
    """Skip (with the reason) if loopback multicast does not work on this machine."""
    a = ("239.255.199.199", 29999)
    try:
        with open_group(a, 1) as g1, open_group(a, 2) as g2:
            g1.send_state(MemberState(1, 1.0, 0j, 0.0))
            if not drain(g2, 1, 2.0):
                pytest.skip("loopback multicast: nothing received (no route for 239.255/16 on lo?)")
    except UserError as exc:
        pytest.skip(f"loopback multicast unavailable: {exc}")


def test_parse_group() -> None:
    assert parse_group("239.255.14.1:14600") == MulticastGroup("239.255.14.1", 14600)
    for bad in ("239.255.14.1", "10.0.0.1:14600", "host:14600", "239.1.1.1:0", "239.1.1.1:x"):
        with pytest.raises(UserError):
            parse_group(bad)


def test_two_groups_exchange_states_and_alerts(multicast_ok: None, addr: tuple[str, int]) -> None:
    with open_group(addr, 1) as g1, open_group(addr, 2) as g2:
        state = MemberState(1, 10.5, 3 + 4j, 1.0, "prosecuting", "2-1")
        alert = Alert("2-1", 100 - 50j, 2, 9.0, "new")
        for _ in range(3):
            g1.send_state(state)
        g2.send_alert(alert)
        got2 = drain(g2, 3)
        got1 = drain(g1, 1)
        assert got2 == [state] * 3  # exactly representable values survive unchanged
        assert got1 == [alert]
        time.sleep(0.05)
        g1.receive(), g2.receive()
        assert g1.stats["own"] == 3 and g2.stats["own"] == 1  # looped back, dropped
        assert g2.stats["accepted"] == 3 and g1.stats["accepted"] == 1
        assert g1.stats["sent"] == 3 and g2.stats["sent"] == 1
        assert drain(g1, 1, 0.1) == []  # nothing else arrives


def test_a_burst_the_companion_does_not_read_at_once_is_kept(
    multicast_ok: None, addr: tuple[str, int]
) -> None:
    """2,000 signed states sent while the receiver does not read (a companion descheduled on a
    loaded machine): all are there when it reads. The kernel's default buffer kept 256."""
    rmem_max = int(Path("/proc/sys/net/core/rmem_max").read_text())
    if rmem_max < RECEIVE_BUFFER_BYTES:
        pytest.skip(f"net.core.rmem_max is {rmem_max}: the group's buffer is capped below 1 MiB")
    with open_group(addr, 1) as g1, open_group(addr, 2) as g2:
        for i in range(2000):
            g1.send_state(MemberState(1, float(i), 0j, 0.0))
        got = drain(g2, 2000, timeout_s=2.0)
        assert len(got) == 2000 and g2.stats["accepted"] == 2000
        assert [m.t_s for m in got] == [float(i) for i in range(2000)]


def test_signed_group_drops_unsigned_and_wrong_key(
    multicast_ok: None, addr: tuple[str, int]
) -> None:
    with (
        open_group(addr, 1) as good,
        open_group(addr, 2, insecure=True) as plain,
        open_group(addr, 3, Signing(bytes(32), time.time)) as forger,
    ):
        plain.send_state(MemberState(2, 1.0, 0j, 0.0))
        forger.send_state(MemberState(3, 1.0, 0j, 0.0))
        deadline = time.monotonic() + 2.0
        while good.stats["unsigned"] + good.stats["bad_signature"] < 2:
            assert time.monotonic() < deadline, good.stats
            good.receive()
            time.sleep(0.01)
        assert good.stats["accepted"] == 0
        assert good.stats["unsigned"] == 1 and good.stats["bad_signature"] == 1


def test_fault_model_on_send(multicast_ok: None, addr: tuple[str, int]) -> None:
    with (
        open_group(addr, 1, faults=FaultModel(duplicate=1.0, seed=3)) as dup,
        open_group(addr, 2, faults=FaultModel(loss=1.0)) as lossy,
        open_group(addr, 3) as rx,
    ):
        for i in range(5):
            dup.send_state(MemberState(1, float(i), 0j, 0.0))
            lossy.send_state(MemberState(2, float(i), 0j, 0.0))
        while dup.next_due_s() is not None:  # delayed copies leave on flush
            time.sleep(0.005)
            dup.flush()
        got = drain(rx, 10, 1.0)
        assert {m.sysid for m in got} == {1}
        assert sorted(m.t_s for m in got) == [0.0, 1.0, 2.0, 3.0, 4.0]  # each once
        assert rx.stats["replayed"] == 5  # the duplicates (same signing timestamp)
        assert dup.stats["duplicated"] == 5 and dup.stats["sent"] == 10
        assert lossy.stats["lost"] == 5 and lossy.stats["sent"] == 0


def run_alert(*args: str, timeout: float = 30) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen(
        [sys.executable, "-m", "companion", "alert", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
    )  # fmt: skip


@pytest.fixture
def key_file(tmp_path: Path) -> Path:
    generate_key_file(tmp_path / "fleet.key")
    return tmp_path / "fleet.key"


def group_flags(addr: tuple[str, int]) -> list[str]:
    return ["--group", f"{addr[0]}:{addr[1]}", "--group-iface", "127.0.0.1"]


def test_alert_cli_is_received_by_a_group(
    multicast_ok: None, addr: tuple[str, int], key_file: Path
) -> None:
    with open_group(addr, 4, Signing(load_key(key_file), time.time)) as rx:
        proc = run_alert("--at=-40.5,120.25", "--key-file", str(key_file), "--listen-s", "0",
                         "--alert-id", "op-7", *group_flags(addr))  # fmt: skip
        got = drain(rx, 3, 20.0, now_s=555.0)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert got == [Alert("op-7", -40.5 + 120.25j, 255, 555.0, "new")] * 3
    assert rx.stats["accepted"] == 3 and rx.stats["replayed"] == 0
    line = json.loads(out)
    assert line["alert_id"] == "op-7" and line["sent"] == 3 and line["time_usec"] == 0
    assert line["time_from"] == "receipt" and line["signed"] is True
    assert list(key_file.parent.glob("fleet.key.*.sysid255.signing-ts"))


def test_alert_cli_takes_vehicle_time_from_a_member_and_lat_lon(
    multicast_ok: None, addr: tuple[str, int], key_file: Path
) -> None:
    mission = ROOT / "missions" / "ellipse_6uav.yaml"
    o = load_mission(mission).origin
    lat, lon, _ = pymap3d.ned2geodetic(300.0, -200.0, 0.0, o.lat_deg, o.lon_deg, o.alt_m)
    with open_group(addr, 4, Signing(load_key(key_file), time.time)) as member:
        proc = run_alert("--lat", repr(float(lat)), "--lon", repr(float(lon)), "--mission",
                         str(mission), "--key-file", str(key_file), "--listen-s", "10",
                         "--repeat", "1", *group_flags(addr))  # fmt: skip
        got: list = []
        deadline = time.monotonic() + 20.0
        while not got and time.monotonic() < deadline:  # a member broadcasting at 10 Hz
            member.send_state(MemberState(4, 5000.0, 0j, 0.0))
            got = drain(member, 1, 0.1)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert len(got) == 1 and isinstance(got[0], Alert)
    alert = got[0]
    assert 5000.0 <= alert.t_s < 5001.0  # the member's clock, not the receipt time
    assert abs(alert.site_m - (300 - 200j)) < 0.01
    assert json.loads(out)["time_from"] == "sysid 4"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--at", "1,2", "--insecure", "--lon", "3"], "--at takes no"),
        (["--lat", "1", "--insecure"], "needs --lon and --mission"),
        (["--at", "1;2", "--insecure"], "expected NORTH,EAST"),
        (["--at", "1,2", "--insecure", "--group", "10.0.0.1:5"], "not a multicast"),
        (["--at", "1,2", "--insecure", "--alert-id", "x" * 17], "--alert-id"),
        (["--at", "1e9,2", "--insecure"], "from the origin"),
    ],
)
def test_alert_cli_bad_input_exits_2_with_one_line(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from companion.commands.main import main

    assert main(["alert", *args, "--listen-s", "0"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and message in err and len(err.strip().splitlines()) == 1


def test_alert_cli_refuses_a_key_file_readable_by_others(key_file: Path) -> None:
    os.chmod(key_file, 0o644)
    proc = run_alert("--at", "1,2", "--key-file", str(key_file), "--listen-s", "0")
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2 and f"chmod 600 {key_file}" in err
