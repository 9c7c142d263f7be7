"""Measure each setpoint profile on real ArduPlane SITL: one aircraft, one companion.

    python bench/arduplane_profiles.py [--profiles bank,heading,turn-rate] [--speedup 5]
        [--seconds 240] [--binary PATH] [--mission FILE]

Per profile: a fresh ArduPlane SITL instance (``--wipe``) at the mission origin, wind from
the mission, AIRSPEED_CRUISE = the mission airspeed, TKOFF_ALT = the vehicle's altitude; it
is armed and taken off in TAKEOFF mode; then ``companion run --take-control --profile P``
on SERIAL1 (tcp 5762 + 10 I) flies it for ``--seconds`` of vehicle time after GUIDED. Printed
(from SERIAL0 telemetry, skipping the first 60 s in GUIDED): airspeed median / p5, altitude
error median / max against the mission's, distance from the loop median / p95, the
companion's achieved-turn-rate gain and health from its final status line, and its
supervision events. Every process started is stopped by its pid. The binary: ``--binary``,
else ``$ARDUPLANE_SITL``, else ``../shared/arduplane/arduplane`` beside the clone where that
exists (:mod:`tests.firmware_env`).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pymap3d
from pymavlink import mavutil

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from companion.mission import load_mission
from tests.firmware_env import ARDUPLANE_VAR, provide_firmware
from tests.flown import final_status

GUIDED, TAKEOFF = 15, 13


def wait_msg(conn, kind: str, timeout_s: float, cond=lambda m: True):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        m = conn.recv_match(type=kind, blocking=True, timeout=0.5)
        if m is not None and cond(m):
            return m
    raise TimeoutError(kind)


def set_param(conn, name: str, value: float) -> None:
    for _ in range(5):
        conn.mav.param_set_send(1, 1, name.encode(), float(value), 9)
        try:
            wait_msg(conn, "PARAM_VALUE", 2.0, lambda m, n=name: m.param_id == n)
            return
        except TimeoutError:
            continue
    raise TimeoutError(f"PARAM_SET {name}")


def loop_points(mission) -> np.ndarray:
    p = mission.patrol
    return np.array([complex(p.point_at_phase(x)) for x in np.linspace(0, 2 * math.pi, 4000)])


def fly(profile: str, args, mission, out: Path) -> dict:
    o = mission.origin
    v = mission.vehicles
    alt = v.altitudes_m[0]
    work = out / profile
    work.mkdir(parents=True, exist_ok=True)
    argv = [
        str(args.binary), "--model", "plane", "-I", str(args.instance), "--sysid", str(v.sysids[0]),
        "--speedup", str(args.speedup), "--wipe",
        "--home", f"{o.lat_deg},{o.lon_deg},{o.alt_m},{v.initial[0].heading_deg}",
        "--defaults", str(Path(args.binary).parent / "plane.parm"),
    ]  # fmt: skip
    log = open(work / "arduplane.log", "w")  # noqa: SIM115
    sitl = subprocess.Popen(argv, cwd=work, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)  # fmt: skip
    comp = None
    try:
        time.sleep(1.0)
        conn = None
        for _ in range(40):
            try:
                conn = mavutil.mavlink_connection(
                    f"tcp:127.0.0.1:{5760 + 10 * args.instance}", source_system=250
                )
                break
            except OSError:
                time.sleep(0.5)
        wait_msg(conn, "HEARTBEAT", 30)
        conn.mav.request_data_stream_send(1, 1, 0, 10, 1)
        w = mission.wind
        roll = math.degrees(math.atan(v.airspeed_m_s * v.max_turn_rate_rad_s / 9.80665)) + 1.0
        for name, value in (
            ("AIRSPEED_CRUISE", v.airspeed_m_s),
            ("TKOFF_ALT", alt),
            ("ROLL_LIMIT_DEG", roll),
            ("SIM_WIND_SPD", w.speed_m_s),
            ("SIM_WIND_DIR", w.from_deg),
        ):  # fmt: skip
            set_param(conn, name, value)
        # arm (retry while the EKF settles), then TAKEOFF
        t_end = time.monotonic() + 120
        while time.monotonic() < t_end:
            conn.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
            hb = wait_msg(conn, "HEARTBEAT", 3)
            if hb.base_mode & 128:
                break
            time.sleep(1.0)
        conn.mav.command_long_send(1, 1, 176, 0, 1, TAKEOFF, 0, 0, 0, 0, 0)
        wait_msg(conn, "GLOBAL_POSITION_INT", 600 / args.speedup + 120,
                 lambda m: m.relative_alt > 0.9 * alt * 1000)  # fmt: skip
        comp = subprocess.Popen(
            [sys.executable, "-m", "companion", "run",
             "--connect", f"tcp:127.0.0.1:{5762 + 10 * args.instance}",
             "--mission", str(args.mission), "--sysid", str(v.sysids[0]), "--take-control",
             "--profile", profile, "--insecure", "--log-dir", str(work / "companion"),
             "--status-interval", "5"],
            stdout=subprocess.DEVNULL, stderr=open(work / "companion.log", "w"),  # noqa: SIM115
            start_new_session=True,
        )  # fmt: skip
        wait_msg(conn, "HEARTBEAT", 120, lambda m: m.custom_mode == GUIDED)
        t0 = None
        rows = []
        while True:
            m = conn.recv_match(type=["GLOBAL_POSITION_INT", "VFR_HUD"], blocking=True,
                                timeout=2)  # fmt: skip
            if m is None:
                continue
            if m.get_type() == "VFR_HUD":
                rows.append(("air", m.airspeed))
                continue
            t = m.time_boot_ms / 1000.0
            t0 = t if t0 is None else t0
            n, e, _ = pymap3d.geodetic2ned(m.lat * 1e-7, m.lon * 1e-7, 0, o.lat_deg, o.lon_deg, 0)
            rows.append(("pos", t - t0, complex(n, e), m.relative_alt / 1000.0))
            if t - t0 > args.seconds:
                break
    finally:
        for p in (comp, sitl):
            if p is not None and p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()
        log.close()
    pos = [r for r in rows if r[0] == "pos" and r[1] > 60.0]
    air_rows, k = [], 0
    t_pos = [r[1] for r in rows if r[0] == "pos"]
    for r in rows:  # airspeed readings after 60 s in GUIDED
        if r[0] == "pos":
            k += 1
        elif k and t_pos[k - 1] > 60.0:
            air_rows.append(r[1])
    pts = loop_points(mission)
    xtrack = np.array([np.min(np.abs(pts - r[2])) for r in pos])
    alt_err = np.array([r[3] - alt for r in pos])
    fields = final_status(work / "companion.log")
    return {
        "airspeed_med": float(np.median(air_rows)) if air_rows else math.nan,
        "airspeed_p5": float(np.percentile(air_rows, 5)) if air_rows else math.nan,
        "alt_err_med": float(np.median(alt_err)),
        "alt_err_max": float(np.max(np.abs(alt_err))),
        "xtrack_med": float(np.median(xtrack)),
        "xtrack_p95": float(np.percentile(xtrack, 95)),
        "gain": fields.get("gain", "-"),
        "health": fields.get("health", "-"),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profiles", default="bank,heading,turn-rate")
    ap.add_argument("--speedup", type=float, default=5.0)
    ap.add_argument("--seconds", type=float, default=240.0, help="vehicle s in GUIDED")
    provide_firmware()
    ap.add_argument("--binary", type=Path, default=os.environ.get(ARDUPLANE_VAR) or None)
    ap.add_argument("--mission", type=Path, default=REPO / "missions/ellipse_6uav.yaml")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--instance", type=int, default=7, help="SITL -I (ports 5760 + 10 I)")
    args = ap.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # stop what was started, then exit
    if args.binary is None:
        print(f"no ArduPlane SITL binary: pass --binary or set ${ARDUPLANE_VAR}", file=sys.stderr)
        return 2
    if not os.access(args.binary, os.X_OK):
        print(f"no ArduPlane SITL binary at {args.binary}", file=sys.stderr)
        return 2
    mission = load_mission(args.mission)
    out = args.out or Path(tempfile.mkdtemp(prefix="arduplane_profiles_"))
    print(f"ArduPlane {args.binary} at {args.speedup:g}x, {args.seconds:g} s in GUIDED, {out}")
    for prof in args.profiles.split(","):
        r = fly(prof, args, mission, out)
        print(
            f"{prof:9s} airspeed {r['airspeed_med']:.1f} m/s (p5 {r['airspeed_p5']:.1f}), "
            f"alt err {r['alt_err_med']:+.1f} m (max {r['alt_err_max']:.1f}), "
            f"off the loop {r['xtrack_med']:.1f} m (p95 {r['xtrack_p95']:.1f}), "
            f"gain {r['gain']}, health {r['health']}",
            flush=True,
        )
    if args.out is None:
        shutil.rmtree(out, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
