"""What the companion tells its operator on stderr: the status line (counts, rates, latency,
CPU) and its ``health`` field (one component of the
:class:`~companion.process.runner.Runner`)."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import TextIO

from companion.process.config import Counters
from companion.process.control import TakingControl
from companion.process.group_io import GroupIO
from companion.process.health import Health
from companion.process.ports import LinkState
from companion.process.setpoint import SetpointChannel
from companion.process.step import ControlStep
from companion.process.telemetry import Telemetry


class StatusLine:
    """The status line and what it reads.

    Args:
        out: where the lines go (stderr).
        wall: monotonic wall clock (s); cpu: process CPU time (s).
        link, telemetry, channel, health, control, group_io, step: the Runner's parts it
            reads (never writes).
        counters: the process's counts.
    """

    def __init__(
        self,
        out: TextIO,
        wall: Callable[[], float],
        cpu: Callable[[], float],
        *,
        link: LinkState,
        telemetry: Telemetry,
        channel: SetpointChannel,
        health: Health,
        control: TakingControl,
        group_io: GroupIO,
        step: ControlStep,
        counters: Counters,
    ) -> None:
        """The first interval starts now."""
        self.out = out
        self.wall = wall
        self.cpu = cpu
        self.link = link
        self.telemetry = telemetry
        self.channel = channel
        self.health_checks = health
        self.control = control
        self.group_io = group_io
        self.step = step
        self.counters = counters
        self._t0 = wall()
        self._sp0 = 0
        self._vt0: float | None = None
        self._cpu0: float | None = None
        self._wall0 = 0.0

    def started(self) -> None:
        """The Agent starts: CPU percentages count from now."""
        self._cpu0, self._wall0 = self.cpu(), self.wall()

    def due(self, interval_s: float) -> bool:
        """Whether ``interval_s`` wall seconds (> 0) have passed since the last line."""
        return interval_s > 0 and self.wall() - self._t0 >= interval_s

    def health(self) -> str:
        """The status line's health field: ``ok`` or the active issues, comma-separated
        (``not_flying`` while a take-over waits for a flying aircraft)."""
        names = sorted(self.health_checks.issues)
        if self.control.refused is not None and not self.control.authority.was_commanding:
            names.append("not_flying")
        return ",".join(names) if names else "ok"

    def print(self, final: bool = False) -> None:
        """One status line (``final``: the last, at the end)."""
        now = self.wall()
        dt = now - self._t0
        vt = self.telemetry.now_s
        vt0 = self._vt0 if self._vt0 is not None else self.telemetry.first_s
        c = self.counters
        rate = 0.0
        if vt is not None and vt0 is not None and vt > vt0:
            rate = (c.setpoints - self._sp0) / (vt - vt0)
        agent = self.step.agent
        members = len(agent.neighbours) + 1 if agent is not None else 0
        group = self.group_io.group
        g = group.stats if group is not None else {}
        drops = {k: v for k, v in g.items() if k not in ("accepted", "sent") and v}
        lat = c.latency_ms()
        lat_txt = f" lat_ms={lat[0]:.2f}/{lat[1]:.2f}" if lat else ""
        t_txt = f"{vt:.1f}" if vt is not None else "-"
        if self._cpu0 is not None and now > self._wall0:
            cpu_pct = 100.0 * (self.cpu() - self._cpu0) / (now - self._wall0)
            lat_txt += f" cpu_pct={cpu_pct:.2f}"
        auth = self.control.authority
        ch = self.channel
        airspeed = self.health_checks.airspeed.last_m_s
        print(
            f"companion{' final' if final else ''} sysid={self.link.sysid} t={t_txt} "
            f"auth={auth.state} ap_mode={auth.mode} mode={self.step.agent_mode} "
            f"members={members} sp/s={rate:.1f} setpoints={c.setpoints} "
            f"link_rx={self.link.counts['rx']} group_rx={g.get('accepted', 0)} "
            f"group_tx={g.get('sent', 0)} drops={json.dumps(drops, separators=(',', ':'))} "
            f"profile={ch.profile or '-'} gain={ch.shaper.gain:.3f} "
            f"airspeed={'-' if airspeed is None else f'{airspeed:.1f}'} health={self.health()}"
            f"{lat_txt} cpu={self.cpu():.2f}s wall={dt:.1f}s",
            file=self.out,
            flush=True,
        )
        self._t0, self._sp0, self._vt0 = now, c.setpoints, vt
