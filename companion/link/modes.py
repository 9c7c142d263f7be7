"""Command authority (pure): when the companion may send setpoints.

ArduPlane modes by number (PX4's in :mod:`companion.link.px4`: the companion's mode is
OFFBOARD there, wherever this table says GUIDED), and a small explicit state machine:

========== ===================================== ==========================================
state      meaning                               setpoints
========== ===================================== ==========================================
no_link    no autopilot heartbeat (yet / lost)   none
waiting    linked, not in GUIDED, never was      none (the operator, or --take-control,
                                                 puts it in GUIDED)
commanding linked, GUIDED                        yes, every state estimate
overridden linked, left GUIDED while commanding  none until GUIDED returns
========== ===================================== ==========================================

Events: ``heartbeat(custom_mode)`` and ``link_lost()``. Each transition is returned so the
runner can log it and tell the pilot (STATUSTEXT). A transition not in the table raises.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from companion.link import px4

AuthorityState = Literal["no_link", "waiting", "commanding", "overridden"]

PLANE_MODES: dict[int, str] = {
    0: "MANUAL",
    1: "CIRCLE",
    2: "STABILIZE",
    3: "TRAINING",
    4: "ACRO",
    5: "FBWA",
    6: "FBWB",
    7: "CRUISE",
    8: "AUTOTUNE",
    10: "AUTO",
    11: "RTL",
    12: "LOITER",
    13: "TAKEOFF",
    14: "AVOID_ADSB",
    15: "GUIDED",
    17: "QSTABILIZE",
    18: "QHOVER",
    19: "QLOITER",
    20: "QLAND",
    21: "QRTL",
}
GUIDED = 15


def mode_name(custom_mode: int) -> str:
    """ArduPlane's name of a custom mode number (``MODE<n>`` if unknown)."""
    return PLANE_MODES.get(int(custom_mode), f"MODE{int(custom_mode)}")


# (state, event) -> next state; event is "guided", "other" or "lost"
TRANSITIONS: dict[tuple[AuthorityState, str], AuthorityState] = {
    ("no_link", "guided"): "commanding",
    ("no_link", "other"): "waiting",
    ("no_link", "lost"): "no_link",
    ("waiting", "guided"): "commanding",
    ("waiting", "other"): "waiting",
    ("waiting", "lost"): "no_link",
    ("commanding", "guided"): "commanding",
    ("commanding", "other"): "overridden",
    ("commanding", "lost"): "no_link",
    ("overridden", "guided"): "commanding",
    ("overridden", "other"): "overridden",
    ("overridden", "lost"): "no_link",
}


@dataclass(frozen=True)
class Transition:
    """A change of authority state, with the autopilot mode that caused it."""

    before: AuthorityState
    after: AuthorityState
    mode: str


class Authority:
    """Tracks whether the companion has command of its vehicle."""

    def __init__(self) -> None:
        """Start without a link."""
        self.state: AuthorityState = "no_link"
        self.mode: str | None = None
        self.was_commanding = False
        # modes the companion's own take-off or landing put the aircraft in (ArduPlane's:
        # companion.link.ground, PX4's AUTO ones: companion.link.px4_ground): they keep it
        # commanding, they never give it command
        self.own_modes: frozenset[int] = frozenset()

    @property
    def commanding(self) -> bool:
        """Whether setpoints may be sent now."""
        return self.state == "commanding"

    def heartbeat(self, custom_mode: int, autopilot: int | None = None) -> Transition | None:
        """The autopilot's heartbeat with its custom mode and HEARTBEAT ``autopilot``
        (MAV_AUTOPILOT: PX4's modes are its own, OFFBOARD commanding); the transition, if any."""
        if px4.is_px4(autopilot):
            self.mode = px4.mode_name(custom_mode)
            ours = px4.is_offboard(custom_mode)
        else:
            self.mode = mode_name(custom_mode)
            ours = int(custom_mode) == GUIDED
        ours = ours or (self.state == "commanding" and int(custom_mode) in self.own_modes)
        return self._step("guided" if ours else "other", self.mode)

    def link_lost(self) -> Transition | None:
        """No heartbeat for the link timeout."""
        return self._step("lost", self.mode or "")

    def _step(self, event: str, mode: str) -> Transition | None:
        key = (self.state, event)
        if key not in TRANSITIONS:
            raise ValueError(f"illegal authority event {event!r} in state {self.state!r}")
        after = TRANSITIONS[key]
        if after == "no_link":
            self.mode = None
        before, self.state = self.state, after
        if after == "commanding":
            self.was_commanding = True
        return Transition(before, after, mode) if after != before else None
