"""Measure one companion setpoint profile on real PX4 SITL (fixed-wing SIH), docs/px4.md.

    python bench/px4_profiles.py --profile attitude --speed 3 --vehicle-s 200

Starts PX4 instance ``--instance`` (default 5) with the 20 m/s airframe, takes it off into
AUTO.LOITER at 100 m, runs ``companion run --take-control --profile P`` with the one-UAV
ellipse (tests/data/ellipse_1uav.yaml) for ``--vehicle-s`` of OFFBOARD, stops everything by
pid and prints, from the companion's own tlog, the cross-track to the ellipse, the airspeed
and the altitude errors after ``--settle-s``, and the achieved / commanded turn-rate slope.
Plumbing from ``tests/px4_harness.py``; the PX4 folder from ``$PX4_SITL_DIR``, else
``../shared/px4`` beside the clone where that exists (:mod:`tests.firmware_env`).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from companion.mission import load_mission
from tests.firmware_env import provide_firmware
from tests.flown import flown_from_tlog, summary
from tests.px4_harness import (
    FAST_AIRFRAME,
    OFFBOARD,
    REPO,
    Gcs,
    Px4Instance,
    read_events,
    start_companion,
    stop_process,
)

G = 9.80665


def turn_slope(tlog: Path, airspeed_m_s: float) -> tuple[float, float]:
    """Achieved course rate against the commanded turn rate (0.5 s later, 1 s averages):
    (slope, correlation). The command is ``g tan(phi) / V`` of an attitude setpoint, or the
    acceleration's normal part over the speed of a path setpoint, as sent."""
    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    cmd, rows, prev = None, [], None
    while (m := conn.recv_match()) is not None:
        t = m.get_type()
        if t == "SET_POSITION_TARGET_GLOBAL_INT":
            v, a = complex(m.vx, m.vy), complex(m.afx, m.afy)
            cmd = (a / v).imag if abs(v) > 1 else 0.0
        elif t == "SET_ATTITUDE_TARGET" and m.type_mask == 0x07:
            w, x, y, z = m.q
            cmd = (
                G * np.tan(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))) / airspeed_m_s
            )
        elif t == "GLOBAL_POSITION_INT" and m.get_srcComponent() == 1:
            crs = np.arctan2(m.vy, m.vx)
            if prev is not None and cmd is not None and 0 < m.time_boot_ms - prev[0] < 500:
                rate = np.angle(np.exp(1j * (crs - prev[1]))) / ((m.time_boot_ms - prev[0]) / 1e3)
                rows.append((cmd, rate))
            prev = (m.time_boot_ms, crs)
    conn.close()
    r = np.array(rows[200:])
    lag = 5
    smooth = np.ones(10) / 10
    c = np.convolve(r[: len(r) - lag, 0], smooth, "same")
    y = np.convolve(r[lag:, 1], smooth, "same")
    return float(np.polyfit(c, y, 1)[0]), float(np.corrcoef(c, y)[0, 1])


def main() -> int:
    """Run one measurement; print the figures."""
    provide_firmware()  # $PX4_SITL_DIR, else ../shared/px4 beside the clone
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="attitude", choices=("attitude", "path"))
    ap.add_argument("--speed", type=float, default=3.0, help="PX4_SIM_SPEED_FACTOR")
    ap.add_argument("--vehicle-s", type=float, default=200.0, help="vehicle s in OFFBOARD")
    ap.add_argument("--settle-s", type=float, default=60.0, help="vehicle s not judged")
    ap.add_argument("--instance", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("/tmp/px4_profiles"))
    a = ap.parse_args()
    mission_path = REPO / "tests" / "data" / "ellipse_1uav.yaml"
    mission = load_mission(mission_path)
    run = a.out / f"{a.profile}_x{a.speed:g}"
    shutil.rmtree(run, ignore_errors=True)
    params = {**FAST_AIRFRAME, "MIS_TAKEOFF_ALT": "100"}
    inst = Px4Instance(a.instance, run / f"uav{a.instance}", speed=a.speed, params=params)
    t0 = time.monotonic()
    inst.start()
    gcs = Gcs(inst)
    comp = None
    try:
        print(f"take-off {gcs.take_off(90.0):.1f} s wall", flush=True)
        comp = start_companion(inst, mission_path, run / "companion", "--profile", a.profile)
        b0, w0, entered = gcs.boot_ms, time.monotonic(), None
        while comp.poll() is None and time.monotonic() - w0 < 3 * a.vehicle_s / a.speed + 120:
            gcs.pump(0.5)
            if entered is None and gcs.mode == OFFBOARD:
                entered = gcs.boot_ms
                print(f"OFFBOARD {(entered - b0) / 1e3:.1f} s (vehicle) after the start")
            if entered is not None and gcs.boot_ms > entered + a.vehicle_s * 1e3:
                break
        print(f"achieved speed-up {(gcs.boot_ms - b0) / 1e3 / (time.monotonic() - w0):.2f}")
    finally:
        rc = stop_process(comp) if comp is not None else None
        gcs.close()
        print(f"exit: companion {rc}, px4 {inst.stop()}; {time.monotonic() - t0:.0f} s wall")
    names = [e["event"] for e in read_events(run / "companion")]
    issues = [n for n in names if n in ("profile_ignored", "offboard_refused", "airspeed_off")]
    print(f"issues: {issues or 'none'}")
    tlog = run / "companion" / "autopilot.tlog"
    flown = flown_from_tlog(tlog, (39.8, -84.0, 250.0), inst.sysid, OFFBOARD)
    print(json.dumps({k: round(v, 2) for k, v in summary(flown, mission, a.settle_s).items()}))
    slope, corr = turn_slope(tlog, mission.vehicles.airspeed_m_s)
    print(f"achieved / commanded turn rate: slope {slope:.2f}, correlation {corr:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
