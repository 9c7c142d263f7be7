"""What the companion tells its operator: events to ``events.jsonl`` and the status line on
stderr (counts, rates, latency, CPU)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np


class StatusLine:
    """Events and the status line.

    Part of :class:`companion.process.runner.Runner`, whose ``__init__`` sets the state
    these methods share.
    """

    def _log(self, event: str, **fields: Any) -> None:
        ev: dict[str, Any] = {
            "t_s": round(self.now_s, 3) if self.now_s is not None else None,
            "event": event,
            "sysid": self.link.sysid,
        }
        ev.update(fields)
        self.events.write(ev)

    def latency_ms(self) -> tuple[float, float] | None:
        """Median and 99th percentile of telemetry-to-setpoint latency (wall ms)."""
        lat = self.counters.latency_s
        if not lat:
            return None
        a = np.asarray(lat) * 1e3
        return float(np.median(a)), float(np.percentile(a, 99))

    def _status(self, final: bool = False) -> None:
        now = self.wall()
        dt = now - self._status_t0
        vt = self.now_s
        rate = 0.0
        if vt is not None and self._status_vt0 is not None and vt > self._status_vt0:
            rate = (self.counters.setpoints - self._status_sp0) / (vt - self._status_vt0)
        agent = self.agent
        members = len(agent.neighbours) + 1 if agent is not None else 0
        g = self.group.stats if self.group is not None else {}
        drops = {k: v for k, v in g.items() if k not in ("accepted", "sent") and v}
        lat = self.latency_ms()
        lat_txt = f" lat_ms={lat[0]:.2f}/{lat[1]:.2f}" if lat else ""
        t_txt = f"{vt:.1f}" if vt is not None else "-"
        if self._cpu0 is not None and now > self._wall0:
            cpu_pct = 100.0 * (self.cpu() - self._cpu0) / (now - self._wall0)
            lat_txt += f" cpu_pct={cpu_pct:.2f}"
        print(
            f"companion{' final' if final else ''} sysid={self.link.sysid} t={t_txt} "
            f"auth={self.authority.state} ap_mode={self.authority.mode} mode={self.agent_mode} "
            f"members={members} sp/s={rate:.1f} setpoints={self.counters.setpoints} "
            f"link_rx={self.link.counts['rx']} group_rx={g.get('accepted', 0)} "
            f"group_tx={g.get('sent', 0)} drops={json.dumps(drops, separators=(',', ':'))} "
            f"profile={self.profile or '-'} gain={self.shaper.gain:.3f} "
            f"airspeed={self._airspeed_txt()} health={self.health()}"
            f"{lat_txt} cpu={self.cpu():.2f}s wall={dt:.1f}s",
            file=self.status_out,
            flush=True,
        )
        self._status_t0, self._status_sp0, self._status_vt0 = now, self.counters.setpoints, vt

    def _airspeed_txt(self) -> str:
        a = self.airspeed.last_m_s
        return "-" if a is None else f"{a:.1f}"
