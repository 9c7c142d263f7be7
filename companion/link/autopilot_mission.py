"""A mission when no file is given: the loop from the autopilot's stored waypoints.

Not implemented yet: ``companion run`` needs ``--mission FILE``.
"""

from __future__ import annotations

from companion.errors import UserError
from companion.mission import Mission


def mission_from_autopilot(link: object) -> Mission:
    """The mission built from the autopilot's stored waypoints (not implemented yet)."""
    raise UserError(
        "--mission FILE is required (reading the loop from the autopilot is not implemented)"
    )
