"""A relief run as the live page hears it: ``missions/ellipse_relief.yaml`` with UAV 3's battery
at 5800 mAh used (the issue's run), in memory (:mod:`companion.sim.inmemory`), and a passive
listener on the in-memory group (the fleet key, as ``companion dashboard`` listens) keeping
every member's last state. Every ``every_s`` simulated seconds it takes a *frame*: the last
state heard from each member. The run covers the spares on the ground, spare 10 climbing out
(about 330 s), in UAV 3's slot (about 390 s) and UAV 3 going home and landing (about 470 s).

The figures a frame should show are computed here from the states alone, independently of
:mod:`companion.dashboard.model`: which aircraft are in the formation (the modes the
companions splay with), the spares, those climbing out and those going home (the relief role
of a member in mode spare), and the splay error over the formation's phases extrapolated to
the frame's newest time, by brute force over the sorted phases.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from companion.contracts.signing import Signing
from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.group.messages import MemberState
from companion.group.transport import Group
from companion.sim.inmemory import Engine, EngineConfig

REPO = Path(__file__).resolve().parents[1]
MISSION = REPO / "missions" / "ellipse_relief.yaml"
TIRED, USED_MAH = 3, 5800.0
LISTENER = 250  # the listener's system id on the in-memory group (it never sends)
FORMATION = ("patrol", "prosecuting", "searching", "rejoining")  # the companions' own rule
APART = {"spare": "spares", "unavailable": "spares", "relieving": "climbing_out",
         "home": "going_home"}  # fmt: skip


@dataclass(frozen=True)
class Frame:
    """The last state heard from each member at simulated time ``t_s`` (s)."""

    t_s: float
    states: dict[int, MemberState]

    def expected(self, period_s: float) -> dict[str, float | int | None]:
        """What the page must show for this frame: ``members`` (in the formation),
        ``spares``, ``climbing_out``, ``going_home``, ``ideal_s`` (T/N, s) and ``splay_deg``."""
        out: dict[str, float | int | None] = {"spares": 0, "climbing_out": 0, "going_home": 0}
        members = [st for st in self.states.values() if str(st.mode) in FORMATION]
        for st in self.states.values():
            if str(st.mode) == "spare" and st.energy is not None:
                out[APART.get(st.energy.role, "spares")] += 1
        out["members"] = len(members)
        out["ideal_s"] = period_s / len(members) if members else None
        newest = max(st.t_s for st in self.states.values())
        phases = sorted(
            (st.phase_rad + 2 * math.pi * (newest - st.t_s) / period_s) % (2 * math.pi)
            for st in members
        )
        worst = 0.0
        for k, p in enumerate(phases):  # each gap against 2 pi / n
            nxt = phases[k + 1] if k + 1 < len(phases) else phases[0] + 2 * math.pi
            worst = max(worst, abs((nxt - p) - 2 * math.pi / len(phases)))
        out["splay_deg"] = math.degrees(worst) if len(phases) > 1 else (0.0 if phases else None)
        return out


def relief_frames(duration_s: float = 490.0, every_s: float = 10.0) -> list[Frame]:
    """Fly the relief run for ``duration_s`` simulated s and take a frame every ``every_s`` s
    (from ``every_s`` on)."""
    eng = Engine(EngineConfig(MISSION, None, battery_used_mah=((TIRED, USED_MAH),)))

    def clock() -> float:
        return SIM_EPOCH_UNIX_S + eng.t_s

    ear = Group(LISTENER, Signing(eng.key, clock), clock=clock, sock=eng.bus.join(LISTENER))
    last: dict[int, MemberState] = {}
    frames: list[Frame] = []
    steps_per_read = 10  # 0.2 s at 50 Hz: as often as the members send
    k = 0
    try:
        while eng.t_s < duration_s - 1e-9:
            eng.step()
            k += 1
            if k % steps_per_read:
                continue
            for msg in ear.receive(clock()):
                if isinstance(msg, MemberState):
                    last[msg.sysid] = msg
            if eng.t_s + 1e-9 >= every_s * (len(frames) + 1):
                frames.append(Frame(round(eng.t_s, 3), dict(last)))
    finally:
        ear.close()
        eng.close()
    return frames
