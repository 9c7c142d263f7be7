"""The companion's link to real ArduPlane SITL firmware: a signed upload over a serial cable
(a pseudo-terminal played by socat, as ``companion fleet --companion-link serial`` wires it).

Skipped, with the reason, without an ArduPlane SITL binary (``$ARDUPLANE_SITL``;
``tests/conftest.py`` finds ``../shared/arduplane/arduplane``) or without socat (``.ci/run``
installs it). Cost: one instance on the ground, about 20 s of wall time.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.sim.arduplane import sitl
from tests.arduplane_harness import KEY, WRONG_KEY, SerialCable, arduplane
from tests.fleet_harness import companion_cli

# real ArduPlane SITL, free-running against the wall clock
pytestmark = [pytest.mark.integration, pytest.mark.alone]

REPO = Path(__file__).resolve().parents[1]
MISSION = REPO / "tests" / "data" / "ellipse_3uav.yaml"


def _have_binary() -> bool:
    try:
        sitl.find_binary(None)
    except UserError:
        return False
    return True


needs_firmware = pytest.mark.skipif(
    not _have_binary() or shutil.which("socat") is None,
    reason="needs ArduPlane SITL ($ARDUPLANE_SITL) and socat (apt-get install socat)",
)


def _key(path: Path, key: bytes) -> Path:
    path.write_text(key.hex() + "\n")
    path.chmod(0o600)
    return path


def _upload(cable: SerialCable, key: Path, listen_s: float = 3.0) -> subprocess.CompletedProcess:
    return companion_cli(
        "upload", str(MISSION), "--connect", cable.url, "--sysid", "1",
        "--link-key-file", str(key), "--listen-s", f"{listen_s:g}", timeout_s=90.0,
    )  # fmt: skip


@needs_firmware
def test_signed_upload_to_arduplane_over_a_serial_cable(tmp_path):
    """Before SETUP_SIGNING a key is refused as documented (the autopilot does not sign);
    after it, the right key uploads and verifies over the serial device and a wrong key
    exits 2 with "wrong key?" (the upload once chose MAVLink 1 and sent unsigned frames:
    "no answer to MISSION_COUNT after 5 tries" with the right key)."""
    right, wrong = _key(tmp_path / "link.key", KEY), _key(tmp_path / "wrong.key", WRONG_KEY)
    with arduplane(tmp_path, MISSION) as ap:
        cable = SerialCable(tmp_path / "ttyAP1", ap.spec.ports.serial1)
        try:
            r = _upload(cable, right)
            assert r.returncode == 2, r.stdout + r.stderr
            assert "the autopilot does not sign its frames" in r.stderr, r.stderr
            ap.setup_signing(KEY)
            r = _upload(cable, right, listen_s=5.0)
            assert r.returncode == 0, r.stdout + r.stderr
            assert "sysid 1: uploaded 16 waypoints, verified" in r.stdout, r.stdout
            r = _upload(cable, wrong)
            assert r.returncode == 2, r.stdout + r.stderr
            last = r.stderr.strip().splitlines()[-1]
            assert "bad_signature" in last and last.endswith("wrong key?)"), last
        finally:
            cable.close()
    print(f"\n{sys.version.split()[0]}: signed upload over a serial cable verified", end="")
