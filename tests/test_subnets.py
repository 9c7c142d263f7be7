"""The group beyond one LAN: two subnets joined by a router that forwards unicast only.

Namespaces per run: two switches (``<tag>-swa``, ``<tag>-swb``), each a bridge of one /24
(``10.78.A.0/24``, ``10.78.B.0/24``); a router (``<tag>-rt``) with a leg in each
(``.254``) and IPv4 forwarding on, and no multicast routing (Linux forwards no multicast
without a multicast routing daemon, and the group's TTL is 1 anyway); the simulator and
companions 1-3 on subnet A, companions 4-6 on subnet B, each host's default route via its
subnet's router leg. Every vehicle link is unicast UDP (companions 4-6 reach the
simulator through the router). The simulator runs in lockstep with the companions (10x at
most), so a loaded machine runs slower with the same flight.

* Multicast (today's default): the fleet does not form across the router; each subnet's
  companions hear only their own subnet (shown, so it is stated, not hidden).
* Zenoh peers (``--group zenoh:tcp/ROUTER:7447``, scouting on): the router process
  (``companion zenoh-router``) in the router namespace is the meeting point; the six hear
  each other and the formation converges within two loop periods, as the one-LAN
  multicast fleet of ``tests/test_multihost.py`` does.
* Zenoh clients through that router, which is stopped and started again mid-flight: the
  companions keep flying (on their last states, then each alone once the members time
  out), and re-form once it is back.

Skipped, with the reason, where namespaces cannot be made (not root, no ``ip``), as
``tests/test_multihost.py`` is.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from sitl_model.testing import SitlProcess
from tests.fleet_harness import (
    REPO,
    Companion,
    Fleet,
    companion_cli,
    final_status,
    last_truth_time,
    measures,
    quiet_mission,
    report,
    sitl_fleet_args,
    status_field,
)
from tests.test_multihost import (
    MULTIHOST_SPEEDUP,
    SetupError,
    ip,
    members_at,
    namespaces_named,
)

# real processes or sockets; alone: Zenoh scouting on the wall clock, network namespaces
pytestmark = [pytest.mark.integration, pytest.mark.alone]

N_COMPANIONS = 6
ON_A = 3  # companions 1..3 on subnet A (with the simulator), 4..6 on subnet B
BASE_PORT = 5760
MULTICAST = "239.255.78.1:14600"
ROUTER_PORT = 7447
T_END_S = 200.0  # simulated s: about two loop periods (T = 102.5 s), as test_multihost


@dataclass
class TwoSubnets:
    """The namespaces of one run (see the module docstring)."""

    tag: str
    a: int  # A of 10.78.A.0/24
    b: int
    on_a: int = ON_A  # companions 1..on_a on subnet A (6: one LAN, the baseline)
    made: list[str] = field(default_factory=list)
    build_s: float = 0.0

    @property
    def router(self) -> str:
        return f"{self.tag}-rt"

    def host(self, k: int) -> str:
        """Namespace of host ``k`` (0 = the simulator, 1..6 the companions)."""
        return f"{self.tag}-sim" if k == 0 else f"{self.tag}-c{k}"

    def subnet(self, k: int) -> int:
        return self.a if k <= self.on_a else self.b

    def addr(self, k: int) -> str:
        """IPv4 address of host ``k``: .1, .2, ... on each subnet."""
        return f"10.78.{self.subnet(k)}.{k + 1 if k <= self.on_a else k - self.on_a + 1}"

    def router_addr(self, k: int) -> str:
        """The router's leg on host ``k``'s subnet."""
        return f"10.78.{self.subnet(k)}.254"

    def prefix(self, ns: str) -> tuple[str, ...]:
        return ("ip", "netns", "exec", ns)

    def build(self) -> None:
        """Switches, router, hosts and their veths and routes (``SetupError``)."""
        t0 = time.monotonic()
        switches = {self.a: f"{self.tag}-swa", self.b: f"{self.tag}-swb"}
        for ns in [*switches.values(), self.router, *(self.host(k) for k in range(7))]:
            ip("netns", "add", ns)
            self.made.append(ns)
            ip("-n", ns, "link", "set", "lo", "up")
        for sub, sw in switches.items():
            ip("-n", sw, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0",
               "forward_delay", "0")  # fmt: skip
            ip("-n", sw, "link", "set", "br0", "up")
            leg = f"r{sub}"
            ip("-n", sw, "link", "add", "prt", "type", "veth", "peer", "name", leg, "netns",
               self.router)  # fmt: skip
            ip("-n", sw, "link", "set", "prt", "master", "br0")
            ip("-n", sw, "link", "set", "prt", "up")
            ip("-n", self.router, "addr", "add", f"10.78.{sub}.254/24", "dev", leg)
            ip("-n", self.router, "link", "set", leg, "up")
        res = subprocess.run(
            [*self.prefix(self.router), "sysctl", "-qw", "net.ipv4.ip_forward=1"],
            capture_output=True, text=True, timeout=20,
        )  # fmt: skip
        if res.returncode != 0:
            raise SetupError(f"ip_forward in the router namespace: {res.stderr.strip()}")
        for k in range(7):
            ns, sw = self.host(k), switches[self.subnet(k)]
            ip("-n", sw, "link", "add", f"p{k}", "type", "veth", "peer", "name", "veth0",
               "netns", ns)  # fmt: skip
            ip("-n", sw, "link", "set", f"p{k}", "master", "br0")
            ip("-n", sw, "link", "set", f"p{k}", "up")
            ip("-n", ns, "addr", "add", f"{self.addr(k)}/24", "dev", "veth0")
            ip("-n", ns, "link", "set", "veth0", "up")
            ip("-n", ns, "route", "add", "default", "via", self.router_addr(k))
        self.build_s = time.monotonic() - t0

    def destroy(self) -> list[int]:
        """Kill what still runs in the namespaces, delete them; the pids killed."""
        leftovers = []
        for ns in self.made:
            for pid in (int(p) for p in ip("netns", "pids", ns, check=False).stdout.split()):
                leftovers.append(pid)
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        for ns in reversed(self.made):
            ip("netns", "del", ns, check=False)
        return leftovers


@contextlib.contextmanager
def two_subnets(on_a: int = ON_A) -> Iterator[TwoSubnets]:
    """A fresh pair of subnets and their router, companions 1..``on_a`` on subnet A; always
    deleted (skips where impossible)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("network namespaces are Linux only")
    if shutil.which("ip") is None or shutil.which("sysctl") is None:
        pytest.skip("iproute2's `ip` or procps' `sysctl` not found")
    tag = f"pz{os.getpid()}-{secrets.token_hex(2)}"
    a = secrets.randbelow(126) + 1
    net = TwoSubnets(tag, a, a + 127, on_a)
    try:
        try:
            net.build()
        except SetupError as exc:
            pytest.skip(
                f"cannot build the network namespaces as uid {os.geteuid()} (needs "
                f"CAP_NET_ADMIN and CAP_SYS_ADMIN, as root has): {exc}"
            )
        yield net
    finally:
        leftovers = net.destroy()
        assert namespaces_named(tag + "-") == [], "namespaces left behind"
    assert leftovers == [], f"processes still running in the namespaces (killed): {leftovers}"


@pytest.fixture
def subnets() -> Iterator[TwoSubnets]:
    """Companions 1-3 on subnet A with the simulator, 4-6 on subnet B."""
    with two_subnets() as net:
        yield net


class Router:
    """``companion zenoh-router`` in the router namespace, on both legs."""

    def __init__(self, net: TwoSubnets) -> None:
        """Start it; returns once it says it listens."""
        env = dict(os.environ, PYTHONPATH=str(REPO))
        self.proc = subprocess.Popen(
            [*net.prefix(net.router), sys.executable, "-m", "companion", "zenoh-router",
             "--listen", f"tcp/0.0.0.0:{ROUTER_PORT}"],
            cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        line = self.proc.stdout.readline()
        if not line.startswith("zenoh-router: ready"):
            self.proc.kill()
            raise RuntimeError(f"router did not start: {line!r} {self.proc.communicate()[1]}")

    def stop(self) -> int:
        """SIGTERM to the ``ip netns exec`` we started (it execs the router: same pid)."""
        if self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGTERM)
        try:
            return self.proc.wait(timeout=20)
        finally:
            self.proc.stdout.close()
            self.proc.stderr.close()


def start(net: TwoSubnets, out: Path, mission: Path, key: Path, group_of) -> Fleet:
    """Six companions (``group_of(k)`` the ``--group`` of companion ``k``), then the
    simulator on subnet A."""
    out.mkdir(parents=True, exist_ok=True)
    sim = net.addr(0)
    companions: list[Companion] = []
    try:
        for k in range(1, N_COMPANIONS + 1):
            args = [
                "--connect", f"udpout:{sim}:{BASE_PORT + 10 * (k - 1)}",
                "--mission", str(mission),
                "--group", group_of(k),
                "--group-iface", net.addr(k),
                "--key-file", str(key),
                "--log-dir", str(out / f"c{k}"),
                "--status-interval", "5",
                "--member-timeout-s", "10",
            ]  # fmt: skip
            companions.append(Companion(args, prefix=net.prefix(net.host(k))))
        for c in companions:
            c.wait_ready()
        sitl = SitlProcess(
            *sitl_fleet_args(mission, out, MULTIHOST_SPEEDUP), "--lockstep",
            "--host", sim, "--base-port", str(BASE_PORT),
            prefix=net.prefix(net.host(0)), ready_timeout_s=90.0,
        )  # fmt: skip
    except BaseException:
        for c in companions:
            c.stop()
        raise
    return Fleet(out, mission, BASE_PORT, sitl, companions)


def fly(
    net: TwoSubnets, tmp_path: Path, group_of, t_end_s: float, during=None
) -> tuple[Fleet, dict]:
    """Fly to ``t_end_s`` (simulated); ``during(fleet)`` runs meanwhile. (fleet, figures)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    key = tmp_path / "fleet.key"
    res = companion_cli("keygen", str(key))
    assert res.returncode == 0, res.stderr
    mission = quiet_mission(tmp_path, duration_s=t_end_s + 100.0)
    out = tmp_path / "run"
    f = start(net, out, mission, key, group_of)
    t0 = time.monotonic()
    try:
        if during is not None:
            during(f)
        f.wait_sim_time(t_end_s, timeout_s=120)
    finally:
        codes = f.stop()
    assert codes == [0] * (N_COMPANIONS + 1), codes
    t_eval = t_end_s - 5.0  # the companions stop before the simulator
    m, _ = measures(out, mission)
    finals = [final_status(c) for c in f.companions]
    figures = {
        "convergence_s": m.convergence_time_s(t_eval),
        "members_at_end": {k: sorted(members_at(out, k - 1, t_eval)) for k in range(1, 7)},
        "group_rx": [int(status_field(ln, "group_rx")) for ln in finals],
        "group_drops": [json.loads(status_field(ln, "drops")) for ln in finals],
        "netns_setup_s": round(net.build_s, 2),
        "flight_wall_s": round(time.monotonic() - t0, 1),
        "t_eval": t_eval,
        "measures": m,
    }
    return f, figures


def others(k: int, among: range) -> list[int]:
    return [j for j in among if j != k]


@pytest.mark.slow
def test_multicast_fleet_does_not_form_across_a_unicast_router(
    subnets: TwoSubnets, tmp_path: Path
) -> None:
    """Multicast stays on its subnet: companions 1-3 hear only each other, 4-6 likewise,
    although every vehicle link (unicast) crosses the router."""
    _, fig = fly(subnets, tmp_path, lambda k: MULTICAST, 60.0)
    report("subnets_multicast", {k: v for k, v in fig.items() if k != "measures"})
    a, b = range(1, ON_A + 1), range(ON_A + 1, N_COMPANIONS + 1)
    for k in a:
        assert fig["members_at_end"][k] == others(k, a), fig["members_at_end"]
    for k in b:
        assert fig["members_at_end"][k] == others(k, b), fig["members_at_end"]


def zenoh_peer(net: TwoSubnets, key: str):
    """``--group`` of companion ``k``: Zenoh peer, scouting on, the router's leg on its
    subnet as the configured endpoint."""
    return lambda k: f"zenoh:tcp/{net.router_addr(k)}:{ROUTER_PORT}?key={key}"


def assert_whole_fleet(fig: dict) -> None:
    sysids = range(1, N_COMPANIONS + 1)
    for k in sysids:
        assert fig["members_at_end"][k] == others(k, sysids), fig["members_at_end"]
    for rx, drops in zip(fig["group_rx"], fig["group_drops"], strict=True):
        assert rx > 0 and set(drops) <= {"own"}, (rx, drops)


def converged(fig: dict) -> dict:
    """The figures with the last 30 s's worst splay (deg) and centre error (m)."""
    m = fig.pop("measures")
    last = (m.t_s > fig["t_eval"] - 30.0) & (m.t_s <= fig["t_eval"])
    fig["max_splay_deg_last_30s"] = round(float(np.max(m.splay_deg[last])), 3)
    fig["max_centre_m_last_30s"] = round(float(np.max(m.centre_m[last])), 2)
    return fig


@pytest.mark.slow
def test_zenoh_fleet_forms_across_the_router_and_converges(
    subnets: TwoSubnets, tmp_path: Path
) -> None:
    """Zenoh peers meeting at the router: every companion hears the five others (signed,
    nothing dropped but its own), and the formation converges (splay < 2 deg, centre < 5 m)
    with 30 s of the run to spare, as the same six on one LAN over multicast do (the
    baseline, flown first on a network of its own). Both convergence times are printed, not
    compared: the Zenoh fleet's depends on when scouting finds the peers, on the wall clock
    (three runs: 21.9, 30.3 and 50.8 s of flight, the last in the fresh-clone CI of 8e1026e,
    against 21.6-21.7 s on one LAN)."""
    with two_subnets(on_a=N_COMPANIONS) as lan:
        _, base = fly(lan, tmp_path / "lan", lambda k: MULTICAST, T_END_S)
    base = converged(base)
    report("one_lan_multicast", base)
    assert_whole_fleet(base)
    router = Router(subnets)
    try:
        _, fig = fly(subnets, tmp_path / "zenoh", zenoh_peer(subnets, "patrol/subnets"), T_END_S)
    finally:
        assert router.stop() == 0
    fig = converged(fig)
    report("subnets_zenoh_peers", fig)
    assert_whole_fleet(fig)
    assert base["convergence_s"] is not None and fig["convergence_s"] is not None
    assert fig["convergence_s"] <= fig["t_eval"] - 30.0


@pytest.mark.extended  # 330 s of flight: out of CI, as test_multihost (pytest -m extended)
@pytest.mark.slow
def test_zenoh_clients_keep_flying_while_the_router_is_down_and_reform_after(
    subnets: TwoSubnets, tmp_path: Path
) -> None:
    """Clients (every sample through the router): the router stops at 120 s for 30 s of
    flight (three member timeouts): the members leave every formation, the aircraft keep
    flying (the truth log goes on, each companion commanding alone), and once the router is
    back the six re-form and converge again before the end."""
    t_down, t_up, t_end = 120.0, 150.0, 330.0
    router = [Router(subnets)]
    key = "patrol/clients"

    def outage(f: Fleet) -> None:
        f.wait_sim_time(t_down, timeout_s=120)
        assert router[0].stop() == 0
        f.wait_sim_time(t_up, timeout_s=120)
        router[0] = Router(subnets)

    try:
        fleet, fig = fly(
            subnets,
            tmp_path,
            lambda k: f"zenoh-client:tcp/{subnets.router_addr(k)}:{ROUTER_PORT}?key={key}",
            t_end,
            during=outage,
        )
    finally:
        assert router[0].stop() == 0
    fig.pop("measures")
    out = fleet.out
    alone = {k: sorted(members_at(out, k - 1, t_up - 1.0)) for k in range(1, 7)}
    before = {k: sorted(members_at(out, k - 1, t_down - 1.0)) for k in range(1, 7)}
    fig |= {"members_before_outage": before, "members_end_of_outage": alone}
    report("subnets_zenoh_router_outage", fig)
    sysids = range(1, N_COMPANIONS + 1)
    assert all(before[k] == others(k, sysids) for k in sysids), before
    assert all(alone[k] == [] for k in sysids), alone  # timed out: each flew alone
    assert last_truth_time(out / "truth.csv") >= t_end - 1.0  # nobody stopped flying
    assert_whole_fleet(fig)  # re-formed
    assert fig["convergence_s"] is not None and fig["convergence_s"] > t_up  # re-converged
