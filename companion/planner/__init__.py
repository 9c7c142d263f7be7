"""Minimum-time paths for a constant-airspeed, turn-rate-limited aircraft in steady wind.

Pure numpy/scipy: no I/O, no clocks. Conventions: complex positions ``north + i east`` (m),
compass angles (rad, 0 = North, pi/2 = East), positive turn rate = right turn, SI units.

    from companion.planner import plan_path, Plan, NoPath, Segment
"""

from companion.planner.model import NoPath, Plan, Segment
from companion.planner.planner import plan_path

__all__ = ["NoPath", "Plan", "Segment", "plan_path"]
