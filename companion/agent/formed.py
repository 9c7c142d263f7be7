"""Whether this UAV's formation has formed (pure): from then on it re-splays along the loop.

Until a UAV has held its slot once, the steering acquires the splay as the paper's law does,
off the loop if need be. Once it has held its slot, within the airspeed's reach of it
(``speed_authority_m_s * speed_tau_s``) and on the loop, for :data:`FORMED_HOLD_S`, the
steering takes out at most :data:`RESPLAY_STEER_M` of slot error and the airspeed the rest:
a member leaving the formation (a tracker, a lost UAV) or coming back is re-splayed along the
loop, where the sensor still sees it (docs/alerts.md, "Persistent intruders").
Times are vehicle seconds, distances metres.
"""

from __future__ import annotations

import math

from companion.guidance.steering import XTRACK_SAT_M

FORMED_HOLD_S = 10.0  # held in its slot this long (s), the formation is formed
RESPLAY_STEER_M = 16.0  # once formed, most slot error left to the steering (along-track m)


class Formed:
    """The formed flag of one UAV.

    Args:
        reach_m: the slot error the airspeed takes out (along-track m).
    """

    def __init__(self, reach_m: float) -> None:
        """Not formed yet."""
        self.reach_m = float(reach_m)
        self.formed = False
        self._since_s: float | None = None

    def note(self, t_s: float, heard_any: bool, off_m: float, slot_error_m: float) -> None:
        """One look at ``t_s`` (s): others heard (``heard_any``), this UAV ``off_m`` (m)
        from the loop and ``slot_error_m`` (along-track m) from its slot."""
        if self.formed:
            return
        if heard_any and abs(slot_error_m) <= self.reach_m and off_m <= XTRACK_SAT_M:
            if self._since_s is None:
                self._since_s = t_s
            self.formed = t_s - self._since_s >= FORMED_HOLD_S
        else:
            self._since_s = None

    @property
    def steer_limit_m(self) -> float:
        """Most slot error (along-track m) left to the steering: unbounded until formed."""
        return RESPLAY_STEER_M if self.formed else math.inf
