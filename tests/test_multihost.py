"""Several hosts: the simulator and each companion in its own Linux network namespace.

Eight namespaces per run: a switch (``<tag>-sw``) holding a bridge, the simulator's host
(``<tag>-sim``) and six companion hosts (``<tag>-c1`` .. ``-c6``), each host joined to the
bridge by a veth pair and addressed on one /24 (``10.77.X.0/24``, the simulator at ``.1``).
Nothing is added to the machine's own namespace: every interface lives in a namespace of
this run, so deleting them removes the veths and the bridge with them, and no address of
the test network is reachable from (or routed to) anything outside it.

The simulator binds its vehicles to its own address (``--host``); each companion links to
its vehicle across the bridge (``udpout:10.77.X.1:PORT``) and joins the signed group on its
own interface (``--group-iface``), so the only way its states reach the others is multicast
through the bridge. The test shows the formation converging from the truth log and that
every companion heard the five others. It skips, saying why, where ``ip`` is missing or
namespaces cannot be made (not root: it needs CAP_NET_ADMIN and CAP_SYS_ADMIN).
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

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from sitl_model.testing import SitlProcess
from tests.fleet_harness import (
    SPEEDUP,
    Companion,
    Fleet,
    companion_cli,
    final_status,
    measures,
    quiet_mission,
    report,
    sitl_fleet_args,
    status_field,
)

# real processes or sockets, wall clock; alone: network namespaces, a fleet across them
pytestmark = [pytest.mark.integration, pytest.mark.alone]

N_COMPANIONS = 6
BASE_PORT = 5760  # fixed: every namespace is new, so nothing else holds it
GROUP = "239.255.77.1:14600"
T_END_S = 200.0  # simulated s: about two loop periods (T = 102.5 s)
# 10x, not the loopback tests' 20x: seven processes on two cores, and a stall of 0.25 wall s
# is 5 s of flight at 20x (20 wall s of flight here)
MULTIHOST_SPEEDUP = min(SPEEDUP, 10.0)


class SetupError(RuntimeError):
    """A command building the test network failed (the environment cannot run the test)."""


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """Run ``ip ARGS``; ``SetupError`` with its stderr if it fails and ``check``."""
    res = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and res.returncode != 0:
        raise SetupError(f"`ip {' '.join(args)}` failed: {res.stderr.strip() or res.returncode}")
    return res


@dataclass
class HostNetwork:
    """The namespaces of one run: a switch with a bridge and hosts on one /24."""

    tag: str
    subnet: int  # X of 10.77.X.0/24
    switch: str
    hosts: list[str]  # [simulator, companion 1, ..., companion N]
    made: list[str] = field(default_factory=list)  # namespaces created so far
    build_s: float = 0.0  # wall time build() took

    def addr(self, k: int) -> str:
        """IPv4 address of host ``k`` (0 = the simulator)."""
        return f"10.77.{self.subnet}.{k + 1}"

    def exec_prefix(self, k: int) -> tuple[str, ...]:
        """Command prefix that runs a program in host ``k``'s namespace."""
        return ("ip", "netns", "exec", self.hosts[k])

    def build(self) -> None:
        """Create the namespaces, the bridge and one veth pair per host (``SetupError``)."""
        t0 = time.monotonic()
        for ns in [self.switch, *self.hosts]:
            ip("netns", "add", ns)
            self.made.append(ns)
        sw = ("-n", self.switch)
        ip(*sw, "link", "set", "lo", "up")
        # no IGMP snooping: the group's datagrams are flooded to every port, as a dumb switch
        ip(*sw, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0", "forward_delay", "0")
        ip(*sw, "link", "set", "br0", "up")
        for k, ns in enumerate(self.hosts):
            port = f"p{k}"
            ip(*sw, "link", "add", port, "type", "veth", "peer", "name", "veth0", "netns", ns)
            ip(*sw, "link", "set", port, "master", "br0")
            ip(*sw, "link", "set", port, "up")
            ip("-n", ns, "link", "set", "lo", "up")
            ip("-n", ns, "addr", "add", f"{self.addr(k)}/24", "dev", "veth0")
            ip("-n", ns, "link", "set", "veth0", "up")
        self.build_s = time.monotonic() - t0

    def destroy(self) -> list[int]:
        """Kill whatever still runs in the namespaces, delete them (and with them the veths
        and the bridge); the pids that had to be killed."""
        leftovers = []
        for ns in self.made:
            res = ip("netns", "pids", ns, check=False)
            for pid in (int(p) for p in res.stdout.split()):
                leftovers.append(pid)
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
        for ns in reversed(self.made):
            ip("netns", "del", ns, check=False)
        return leftovers


def namespaces_named(prefix: str) -> list[str]:
    """Network namespaces whose name starts with ``prefix``."""
    res = ip("netns", "list", check=False)
    return [ln.split()[0] for ln in res.stdout.splitlines() if ln.startswith(prefix)]


@pytest.fixture
def hosts_net() -> Iterator[HostNetwork]:
    """A fresh bridge and 1 + N hosts; always deleted afterwards (skips where impossible)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("network namespaces are Linux only")
    if shutil.which("ip") is None:
        pytest.skip("iproute2's `ip` command not found (apt-get install iproute2)")
    tag = f"pp{os.getpid()}-{secrets.token_hex(2)}"  # unique per run
    net = HostNetwork(
        tag=tag,
        subnet=secrets.randbelow(254) + 1,
        switch=f"{tag}-sw",
        hosts=[f"{tag}-sim", *(f"{tag}-c{i + 1}" for i in range(N_COMPANIONS))],
    )
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


def start_multihost_fleet(net: HostNetwork, out: Path, mission: Path, key: Path) -> Fleet:
    """Six companions, each in its host's namespace, then the simulator in its own."""
    out.mkdir(parents=True, exist_ok=True)
    sim = net.addr(0)
    companions: list[Companion] = []
    try:
        for i in range(N_COMPANIONS):
            args = [
                "--connect",
                f"udpout:{sim}:{BASE_PORT + 10 * i}",
                "--mission",
                str(mission),
                "--group",
                GROUP,
                "--group-iface",
                net.addr(i + 1),
                "--key-file",
                str(key),
                "--log-dir",
                str(out / f"c{i + 1}"),
                "--status-interval",
                "5",
                "--member-timeout-s",
                "10",  # as in the loopback fleet tests
            ]
            companions.append(Companion(args, prefix=net.exec_prefix(i + 1)))
        for c in companions:
            c.wait_ready()
        sitl = SitlProcess(
            *sitl_fleet_args(mission, out, MULTIHOST_SPEEDUP),
            "--host",
            sim,
            "--base-port",
            str(BASE_PORT),
            prefix=net.exec_prefix(0),
            ready_timeout_s=90.0,
        )
    except BaseException:
        for c in companions:
            c.stop()
        raise
    return Fleet(out, mission, BASE_PORT, sitl, companions)


def members_at(out: Path, i: int, t_s: float) -> set[int]:
    """Companion ``i``'s neighbours at simulated ``t_s``, replayed from its events."""
    members: set[int] = set()
    for line in (out / f"c{i + 1}" / "events.jsonl").read_text().splitlines():
        ev = json.loads(line)
        if ev.get("t_s") is None or ev["t_s"] - SIM_EPOCH_UNIX_S > t_s:
            continue
        if ev["event"] == "member_joined":
            members.add(ev["member_sysid"])
        elif ev["event"] == "member_lost":
            members.discard(ev["member_sysid"])
    return members


@pytest.mark.extended
@pytest.mark.slow
def test_fleet_across_network_namespaces(hosts_net: HostNetwork, tmp_path: Path) -> None:
    """Simulator and six companions on seven hosts joined by a bridge: the signed group's
    multicast crosses it (each companion hears the five others) and the formation converges
    (splay < 2 deg, centre < 5 m) within two loop periods."""
    t0 = time.monotonic()
    key = tmp_path / "fleet.key"
    res = companion_cli("keygen", str(key))
    assert res.returncode == 0, res.stderr
    mission = quiet_mission(tmp_path, duration_s=T_END_S + 100.0)
    out = tmp_path / "run"
    f = start_multihost_fleet(hosts_net, out, mission, key)
    try:
        t_flight = time.monotonic()
        f.wait_sim_time(T_END_S, timeout_s=120)
        flight_wall_s = time.monotonic() - t_flight
    finally:
        codes = f.stop()
    assert codes == [0] * (N_COMPANIONS + 1), codes
    t_eval = T_END_S - 5.0  # the companions stop before the simulator
    m, _ = measures(out, mission)
    conv = m.convergence_time_s(t_eval)
    last = (m.t_s > t_eval - 30.0) & (m.t_s <= t_eval)
    sysids = list(range(1, N_COMPANIONS + 1))
    members = {s: sorted(members_at(out, s - 1, t_eval)) for s in sysids}
    finals = [final_status(c) for c in f.companions]
    report(
        "multihost",
        {
            "hosts": {"simulator": hosts_net.addr(0)}
            | {f"c{i + 1}": hosts_net.addr(i + 1) for i in range(N_COMPANIONS)},
            "convergence_s": conv,
            "splay_deg_end": round(float(m.splay_deg[last][-1]), 3),
            "centre_m_end": round(float(m.centre_m[last][-1]), 2),
            "max_splay_deg_last_30s": round(float(np.max(m.splay_deg[last])), 3),
            "max_centre_m_last_30s": round(float(np.max(m.centre_m[last])), 2),
            "members_at_end": members,
            "group_rx": [int(status_field(ln, "group_rx")) for ln in finals],
            "group_drops": [status_field(ln, "drops") for ln in finals],
            "netns_setup_s": round(hosts_net.build_s, 2),
            "flight_wall_s": round(flight_wall_s, 1),
            "wall_s": round(time.monotonic() - t0, 1),
        },
    )
    # the group crossed the bridge: every companion heard exactly the five others, signed
    for s in sysids:
        assert members[s] == [o for o in sysids if o != s], (s, members[s])
    for ln in finals:
        assert int(status_field(ln, "group_rx")) > 0, ln
        assert set(json.loads(status_field(ln, "drops"))) <= {"own"}, ln  # looped back to us
    # and the formation converged on it
    assert conv is not None, "not converged (splay < 2 deg, centre < 5 m) by the end"
    assert conv <= t_eval - 30.0
