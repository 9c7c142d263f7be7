"""The options of one companion's link to its autopilot (frozen): each declared once, with
its unit and bounds, and checked when made (as :class:`companion.agent.config.AgentConfig`).

A :class:`LinkConfig` is what ``companion run`` (:class:`companion.process.config.RunConfig`),
``companion simulate`` and ``companion fleet`` say of the setpoints: their profile, their
rate, whether the shaper closes the loop on the achieved turn rate. The command line's
``--profile`` and ``--rate-hz`` are built from these fields
(:func:`companion.commands.options.add_link_options`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from companion.contracts.options import check_bounds, spec
from companion.link.setpoints import PROFILE_CHOICES, ProfileChoice

LINK_OPTIONS = ("profile", "rate_hz")
"""The link options a companion command takes from its command line (``--profile``,
``--rate-hz``; ``adapt`` is ``companion run --no-adapt``)."""


@dataclass(frozen=True)
class LinkConfig:
    """How one companion sets its autopilot's course (every member of a fleet uses the same).

    Attributes:
        profile: the setpoint profile, or "auto": chosen from the autopilot's HEARTBEAT type
            (:func:`companion.link.supervision.default_profile`: bank for ArduPilot,
            attitude for PX4, turn-rate for others).
        rate_hz: state estimates and setpoints per vehicle second (Hz): the control rate.
        adapt: close the loop on the achieved turn rate (the shaper's online gain estimate);
            False: open-loop setpoints.
    """

    profile: ProfileChoice = field(
        default="auto",
        metadata=spec(
            "setpoint profile (auto: by the autopilot's type: bank for ArduPilot, attitude "
            "for PX4, docs/px4.md; turn-rate for others)",
            choices=PROFILE_CHOICES,
        ),
    )
    rate_hz: float = field(
        default=10.0,
        metadata=spec(
            "state estimates and setpoints per vehicle second",
            unit="Hz",
            at_least=1.0,
            at_most=50.0,
        ),
    )
    adapt: bool = True

    def __post_init__(self) -> None:
        """Check every option against its bounds.

        Raises:
            OptionError: a ``ValueError`` naming the first option out of its bounds.
        """
        check_bounds(self)
