"""``companion fleet --sim-param`` and the fleet's live measures (no processes started)."""

from pathlib import Path

import numpy as np
import pytest

from companion.commands.main import main
from companion.sim.fleet import Progress, TruthTail

ROOT = Path(__file__).resolve().parents[1]
MISSION = str(ROOT / "missions" / "ellipse_6uav.yaml")


@pytest.mark.parametrize(
    ("param", "why"),
    [
        ("SIM_WIND_SPD=99", "must be in [0, 50] m/s"),
        ("SIM_NOPE=1", "unknown parameter"),
        ("SIM_LAG", "expected NAME=VALUE"),
        ("SIM_LAG=fast", "expected NAME=VALUE"),
    ],
)
def test_a_bad_sim_param_is_refused_before_anything_starts(tmp_path, capsys, param, why):
    out = tmp_path / "run"
    assert main(["fleet", MISSION, "--sim-param", param, "--out", str(out)]) == 2
    assert why in capsys.readouterr().err
    assert not out.exists()


def test_truth_tail_reads_whole_rows_as_they_are_written(tmp_path):
    path = tmp_path / "truth.csv"
    path.write_text("t_s,sysid,north_m,east_m,alt_m\n0.1,1,10.0,-5.0,100\n0.1,2,3.0,4")
    tail = TruthTail(path)
    t, sysid, pos = tail.read()  # the second row is not finished yet
    assert t.tolist() == [0.1] and sysid.tolist() == [1] and pos.tolist() == [10 - 5j]
    with open(path, "a") as fh:
        fh.write(".5,100\n0.2,1,11.0,-5.0,100\n")
    t, sysid, pos = tail.read()
    assert t.tolist() == [0.1, 0.2] and sysid.tolist() == [2, 1]
    assert pos == pytest.approx(np.array([3 + 4.5j, 11 - 5j]))
    assert tail.read()[0].size == 0
    tail.close()


def test_progress_cross_track_leaves_out_the_uavs_away():
    p = Progress(cross_track_m={1: 2.0, 2: 80.0, 3: 4.0}, modes={1: "patrol", 2: "prosecuting"})
    assert p.cross_track_max_m() == 4.0  # UAV 3 not heard yet on the group: counted
    assert Progress().cross_track_max_m() is None
