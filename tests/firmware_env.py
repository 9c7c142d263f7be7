"""Where the tests and the firmware benches find real firmware when nobody said.

The product looks for ArduPlane SITL only at ``--arduplane-bin`` / ``$ARDUPLANE_SITL`` and for
PX4 SITL only at ``--px4-dir`` / ``$PX4_SITL_DIR`` (``companion/sim/arduplane/sitl.py``,
``companion/sim/px4/sitl.py``). The project's CI keeps prebuilt firmware in a ``shared``
folder beside the clone (``../shared/arduplane/arduplane``, ``../shared/px4``), so
:func:`provide_firmware` (called by ``tests/conftest.py`` and by the benches that fly
firmware) sets each variable to that place when the variable is unset and the place exists.
A variable already set is never changed; nothing is set where the firmware is absent, and the
firmware tests then skip with the reason.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]  # tests/firmware_env.py -> the repository's root

ARDUPLANE_VAR = "ARDUPLANE_SITL"  # as companion.sim.arduplane.sitl.ENV_VAR
PX4_VAR = "PX4_SITL_DIR"  # as companion.sim.px4.sitl.ENV_VAR


def beside(repo: Path = REPO) -> dict[str, Path]:
    """Where the firmware sits beside the repository ``repo``, by environment variable: the
    ArduPlane SITL binary and the PX4 SITL folder under ``repo/../shared``."""
    shared = repo.parent / "shared"
    return {ARDUPLANE_VAR: shared / "arduplane" / "arduplane", PX4_VAR: shared / "px4"}


def provide_firmware(
    env: MutableMapping[str, str] = os.environ, repo: Path = REPO
) -> dict[str, str]:
    """Set ``$ARDUPLANE_SITL`` and ``$PX4_SITL_DIR`` in ``env`` to the firmware beside ``repo``
    (:func:`beside`) where the variable is unset (or empty) and that file or folder exists.

    Returns:
        The variables set here and their values (empty when nothing was set).
    """
    found = {
        ARDUPLANE_VAR: lambda p: p.is_file(),
        PX4_VAR: lambda p: p.is_dir(),
    }
    done: dict[str, str] = {}
    for var, path in beside(repo).items():
        if not env.get(var) and found[var](path):
            env[var] = done[var] = str(path)
    return done
