"""Minimum-time paths for a constant-airspeed, turn-rate-limited aircraft in steady wind.

Pure numpy/scipy: no I/O, no clocks. Conventions: complex positions ``north + i east`` (m),
compass angles (rad, 0 = North, pi/2 = East), positive turn rate = right turn, SI units.

    from companion.planner import Aircraft, Goal, Pose, plan_path, Plan, NoPath

    plan = plan_path(Pose(0j, 0.0), Goal(500 + 300j, course_rad=1.0), Aircraft(20.0, 0.2), wind)

"No path" is a result (:class:`NoPath`), never an exception nor None; a ``ValueError`` means
the caller passed bad numbers.
"""

from companion.planner.model import Aircraft, Goal, NoPath, Plan, Pose, Segment
from companion.planner.planner import plan_path

__all__ = ["Aircraft", "Goal", "NoPath", "Plan", "Pose", "Segment", "plan_path"]
