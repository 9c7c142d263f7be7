"""``bench/relief_bases.py``: a relief on a base nobody drew (docs/energy.md, "On bases
nobody drew").

Seed 8 of the mission generator is its smallest loop (6 on station, 1.16 km, a 51-s period);
with the staggered opening the first UAV leaves about 540 s in. 600 simulated s in memory:
the bench must give it as many spares as the companions' rotation keeps busy, and that relief
must be made in the slot, with no point unseen longer than the issue's 1.5 T/N and no
aircraft below its reserve.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_a_generated_small_base_makes_its_first_relief_in_the_slot(tmp_path):
    out = tmp_path / "bases"
    r = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "relief_bases.py"), "--seeds", "8",
         "--duration", "600", "--workers", "1", "--out", str(out)],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    (row,) = json.loads((out / "results.json").read_text())["rows"]
    assert (row["seed"], row["n"]) == (8, 6)
    assert row["spares"] == math.ceil(row["need"]) >= row["loader_min"]
    assert row["left"] >= 1 and row["on_time"] == row["left"], row
    assert row["missed"] == [] and row["passed_over"] == 0
    assert row["unseen"] <= 1.5, row
    assert row["low_pct"] >= row["reserve_pct"]
    assert "totals: 1 of 1 relieved in their slot" in r.stdout
