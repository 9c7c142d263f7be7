"""Coordinates on the command line (issue 14): ``--at -450,0`` works as written, in every
form, for every option that takes numbers, in ``companion`` and ``sitl-model``; and
``companion alert --mission`` uses the mission's origin and fence."""

from __future__ import annotations

import contextlib
import io
import json
import socket

import pytest

from companion.commands.main import build_parser, main
from companion.contracts.argv import join_negative_values
from sitl_model.cli import build_parser as sitl_parser

pytestmark = pytest.mark.integration  # real processes or sockets, wall clock

PAPER = "missions/ellipse_6uav.yaml"


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def run_cli(*argv: str) -> tuple[int, str, str]:
    """``companion`` in process: (status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(list(argv))
    return status, out.getvalue(), err.getvalue()


def alert(*where: str) -> tuple[int, dict | None, str]:
    """Send one unsigned alert to a private loopback group; (status, JSON printed, stderr)."""
    group = f"239.255.14.{77}:{_free_port()}"
    status, out, err = run_cli(
        "alert", *where, "--insecure", "--listen-s", "0", "--repeat", "1", "--group", group
    )
    return status, (json.loads(out) if status == 0 else None), err


@pytest.mark.parametrize(
    ("where", "north", "east"),
    [
        (("--at", "-450,0"), -450.0, 0.0),
        (("--at=-450,0",), -450.0, 0.0),
        (("--at", "-40,-120.5"), -40.0, -120.5),
        (("--at", "-1e2,-.5"), -100.0, -0.5),
        (("--at", "120,-40"), 120.0, -40.0),
        (("--at", "-450,0", "--mission", PAPER), -450.0, 0.0),
    ],
)
def test_alert_at_in_every_form(where, north, east):
    status, sent, err = alert(*where)
    assert status == 0, err
    assert (sent["north_m"], sent["east_m"]) == (north, east)


def test_alert_lat_lon_keeps_working_with_negative_longitude():
    # 0.001 deg south and west of the paper mission's origin (39.8, -84.0)
    status, sent, err = alert("--lat", "39.799", "--lon", "-84.001", "--mission", PAPER)
    assert status == 0, err
    assert sent["north_m"] == pytest.approx(-111.0, abs=1.0)
    assert sent["east_m"] == pytest.approx(-85.5, abs=1.0)


@pytest.mark.parametrize(
    ("where", "words"),
    [
        (("--at", "-900,0", "--mission", PAPER), "outside the fence"),
        (("--at", "-660,0", "--mission", PAPER), "a turn past it needs 80 m"),
        (("--lat", "39.79", "--lon", "-84.0", "--mission", PAPER), "outside the fence"),
    ],
)
def test_alert_outside_the_missions_fence_is_refused(where, words):
    status, sent, err = alert(*where)
    assert status == 2 and sent is None
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "refused by the fence" in lines[0] and words in lines[0]


def test_bad_coordinates_still_exit_2():
    status, _, err = alert("--at", "-450")
    assert status == 2 and "expected NORTH,EAST" in err
    status, _, err = alert("--at", "-450,0", "--lon", "3")
    assert status == 2 and "--at takes no --lon" in err


def test_every_value_option_takes_a_negative_number():
    p = build_parser()
    args = p.parse_args(
        join_negative_values(
            p,
            [
                "plan", "--start-north-m", "-1e3", "--start-east-m", "-5", "--start-heading-deg",
                "-90", "--goal-north-m", "-.5", "--goal-east-m", "0", "--airspeed-m-s", "20",
                "--max-turn-rate-deg-s", "18", "--wind-speed-m-s", "5", "--wind-from-deg", "-45",
            ],
        )
    )  # fmt: skip
    assert (args.start_north_m, args.start_east_m, args.goal_north_m) == ("-1e3", "-5", "-.5")
    assert args.wind_from_deg == "-45"
    # a flag is never joined to what follows, and "--" ends the options
    assert join_negative_values(p, ["run", "--insecure", "-3"]) == ["run", "--insecure", "-3"]
    assert join_negative_values(p, ["alert", "--", "--at", "-1,2"])[-2:] == ["--at", "-1,2"]
    sp = sitl_parser()
    s_args = sp.parse_args(join_negative_values(sp, ["--wind-speed", "5", "--wind-from", "-1e1"]))
    assert s_args.wind_from == -10.0


def test_plan_with_negative_coordinates_runs():
    status, out, err = run_cli(
        "plan", "--start-north-m", "-1e3", "--start-east-m", "-50", "--start-heading-deg", "0",
        "--goal-north-m", "-600", "--goal-east-m", "-200", "--airspeed-m-s", "20",
        "--max-turn-rate-deg-s", "18", "--wind-speed-m-s", "5", "--wind-from-deg", "-90",
    )  # fmt: skip
    assert status == 0, err
    assert json.loads(out)["time_s"] > 0
