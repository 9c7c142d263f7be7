"""A companion away from its aircraft in a flying firmware fleet (issue 48's goals): its serial
cable pulled for 20 s of vehicle time (ArduPlane), or the companion frozen (SIGSTOP) for 5 s
of wall time (ArduPlane and PX4), with ``--retake-after-failsafe``.

Goals: while its companion is away the aircraft stays inside the fence and within 100 m of
the loop; once its companion is back it flies in the loop's sense and is in its slot (the
splay of all N within ``bench/firmware_fleets.py``'s SLOT_DEG) within one loop period. The
companion's own account: the outage's length on its clock, a cable pull said at once, a
near-idle companion while the device is gone.

``bench/firmware_fleets.py`` flies them and prints the figures (``result: {...}``); these
tests assert on that line. Extended tier (each is one fleet of three, 7-25 minutes of wall time
on a loaded 2-core machine): ``pytest -m extended tests/test_firmware_away.py -s``.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from companion.contracts.errors import UserError
from companion.sim.arduplane.sitl import find_binary
from companion.sim.px4.sitl import find_px4_dir

pytestmark = [pytest.mark.integration, pytest.mark.alone, pytest.mark.extended]

REPO = Path(__file__).resolve().parents[1]
BENCH = REPO / "bench" / "firmware_fleets.py"
AP_MISSION = REPO / "tests" / "data" / "ellipse_3uav.yaml"  # 5 m/s wind, decoy at 400 s
PX4_MISSION = REPO / "tests" / "data" / "ellipse_3uav_still.yaml"


def _found(find) -> bool:
    try:
        find(None)
    except UserError:
        return False
    return True


HAVE = {"arduplane": _found(find_binary), "px4": _found(find_px4_dir)}


def _bench(*args: str, timeout_s: float = 3600.0) -> tuple[dict, str]:
    proc = subprocess.run(
        [sys.executable, str(BENCH), *args], capture_output=True, text=True, cwd=REPO,
        timeout=timeout_s,
    )  # fmt: skip
    text = proc.stdout + proc.stderr
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("result: ")]
    assert proc.returncode == 0 and lines, text[-4000:]
    print("\n" + proc.stdout)
    return json.loads(lines[-1].removeprefix("result: ")), text


def _goals(r: dict) -> None:
    assert r["max_off_loop_m"] <= 100.0, r
    assert r["inside_fence"] is True, r
    assert r["loop_sense_after_s"] is not None, r
    assert r["in_slot_after_s"] is not None and r["in_slot_after_s"] <= r["period_s"], r


@pytest.mark.skipif(
    not HAVE["arduplane"] or shutil.which("socat") is None,
    reason="needs ArduPlane SITL ($ARDUPLANE_SITL) and socat",
)
def test_arduplane_keeps_near_the_loop_while_its_serial_cable_is_pulled_for_20_s(tmp_path):
    r, _ = _bench(
        "outage", str(AP_MISSION), "--autopilot", "arduplane", "--at", "260",
        "--outage-s", "20", "--duration", "395", "--out", str(tmp_path),
    )  # fmt: skip
    _goals(r)
    assert r["link_lost_silent_s"] and r["link_lost_silent_s"][0] < 1.0  # at once
    outage = r["link_restored_outage_s"][0]
    assert outage == pytest.approx(r["wall_s"], abs=2.5)  # its own clock, not vehicle time
    assert r["companion_cpu_while_gone"] < 0.2  # cores: no spinning
    assert not [o for o in r["overrides"] if o["event"] == "override"]  # GUIDED throughout


@pytest.mark.parametrize(
    ("autopilot", "mission"), [("arduplane", AP_MISSION), ("px4", PX4_MISSION)]
)
def test_a_companion_frozen_for_5_s_is_back_in_its_slot_within_a_loop_period(
    tmp_path, autopilot, mission
):
    if not HAVE[autopilot]:
        pytest.skip(f"no {autopilot} SITL ($ARDUPLANE_SITL / $PX4_SITL_DIR)")
    r, _ = _bench(
        "freeze", str(mission), "--autopilot", autopilot, "--at", "260",
        "--freeze-s", "5", "--duration", "395", "--out", str(tmp_path),
    )  # fmt: skip
    _goals(r)
    if autopilot == "px4":  # its offboard-loss action (Hold), cleared when setpoints resume
        assert "AUTO.LOITER" in r["modes_while_away"], r["modes_while_away"]
        assert r["modes_while_away"][-1] == "OFFBOARD", r["modes_while_away"]
