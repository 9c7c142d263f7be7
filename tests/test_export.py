"""``companion export RUN_DIR --mcap OUT.mcap`` (docs/export.md): the file read back with the
``mcap`` package's reader and every topic checked against the run's own files.

The run: a real ``companion fleet`` run (lockstepped, about 40 s) of a test mission made from
``tests/data/ellipse_walker_fast.yaml``: six UAVs near splay, a 50-minute battery and one
spare on the ground (battery columns in ``truth.csv``, a base on the map), and a walker that
appears at 20 s, is detected, prosecuted, tracked (``sighted`` passes) and vanishes at 60 s
(the alert lost). The expected values are read here from ``truth.csv`` (csv), ``events.jsonl``
(json), the tlogs (pymavlink) and the mission, not from the exporter's own readers; positions
go back to local metres with pymap3d at the mission's origin.

Also: a real companion's log folder (its tlog and events only, as ``companion run --log-dir``
writes it), with and without ``--mission``; and a missing or wrong folder refused in one line,
exit 2.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from mcap.reader import make_reader
from pymavlink import mavutil

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.export import foxglove as fg
from companion.mission import load_mission

ROOT = Path(__file__).resolve().parents[1]
SETPOINT_TYPES = ("SET_ATTITUDE_TARGET", "SET_POSITION_TARGET_GLOBAL_INT")
GUIDED_CHANGE_HEADING = 43002


# the fields of Foxglove's well-known schemas (as Foxglove publishes them): each message of
# these must carry all of them, so that Foxglove draws it without set-up
FOXGLOVE_FIELDS = {
    "foxglove.LocationFix": {"timestamp", "frame_id", "latitude", "longitude", "altitude",
                             "position_covariance", "position_covariance_type"},
    "foxglove.PoseInFrame": {"timestamp", "frame_id", "pose"},
    "foxglove.FrameTransform": {"timestamp", "parent_frame_id", "child_frame_id", "translation",
                                "rotation"},
    "foxglove.GeoJSON": {"geojson"},
    "foxglove.Log": {"timestamp", "level", "message", "name", "file", "line"},
}  # fmt: skip
JSON_TYPES = {"number": (int, float), "integer": (int,), "string": (str,), "boolean": (bool,),
              "array": (list,), "object": (dict,)}  # fmt: skip


def conforms(value, schema: dict, where: str = "") -> None:
    """Assert ``value`` has the types ``schema`` (a JSON Schema subset) gives it: an object's
    keys among its properties, each of its type; a oneOf of consts one of them."""
    if "oneOf" in schema:
        assert value in [c["const"] for c in schema["oneOf"]], where
        return
    kind = schema.get("type")
    ok = JSON_TYPES[kind]
    assert isinstance(value, ok) and not (kind != "boolean" and isinstance(value, bool)), where
    if kind == "object" and "properties" in schema:
        assert set(value) <= set(schema["properties"]), (where, set(value))
        for k, v in value.items():
            conforms(v, schema["properties"][k], f"{where}.{k}")
    if kind == "array":
        for v in value:
            conforms(v, schema["items"], f"{where}[]")


def companion(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "companion", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=900,
    )


def export_mission(folder: Path) -> Path:
    """The walker mission with a battery, one spare and an early walker (module doc)."""
    src = (ROOT / "tests/data/ellipse_walker_fast.yaml").read_text()
    edits = [
        ("name: ellipse_walker_fast", "name: export_test"),
        ("appear_t_s: 180.0", "appear_t_s: 20.0"),
        ("vanish_t_s: 300.0", "vanish_t_s: 60.0"),
        ("duration_s: 420.0", "duration_s: 130.0"),
        (
            "      - {north_m: -368.6, east_m: -77.7, heading_deg: 299.1}\n",
            "      - {north_m: -368.6, east_m: -77.7, heading_deg: 299.1}\n"
            "  battery: {capacity_mah: 5000, reserve_pct: 20, endurance_min: 50}\n"
            "  spares:\n"
            "    - {sysid: 10, ground: {north_m: 0.0, east_m: 300.0, heading_deg: 180.0},"
            " turnaround_s: 60}\n",
        ),
    ]
    for old, new in edits:
        assert src.count(old) == 1, old
        src = src.replace(old, new)
    path = folder / "export_test.yaml"
    path.write_text(src)
    return path


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("export")
    out = tmp / "run"
    done = companion("fleet", str(export_mission(tmp)), "--out", str(out), "--no-progress")
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return out


def read_mcap(path: Path) -> tuple[dict[str, list[tuple[int, dict]]], dict, dict, list]:
    """(topic -> [(log time ns, message)], topic -> (schema name, schema encoding, message
    encoding), metadata name -> dict, attachments)."""
    topics: dict[str, list[tuple[int, dict]]] = defaultdict(list)
    kinds: dict[str, tuple[str, str, str]] = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        for schema, channel, msg in reader.iter_messages(log_time_order=True):
            data = json.loads(msg.data)
            topics[channel.topic].append((msg.log_time, data))
            assert msg.publish_time == msg.log_time
            kinds[channel.topic] = (schema.name, schema.encoding, channel.message_encoding)
            js = json.loads(schema.data)  # a JSON schema, the message of its types
            assert js["title"] == schema.name
            conforms(data, js, channel.topic)
            if schema.name in FOXGLOVE_FIELDS:
                assert set(js["properties"]) == set(data) == FOXGLOVE_FIELDS[schema.name]
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        attachments = [(a.name, a.data) for a in reader.iter_attachments()]
    assert summary.statistics.message_count == sum(len(v) for v in topics.values())
    return dict(topics), kinds, meta, attachments


def read_truth(run: Path) -> dict[int, list[dict]]:
    rows: dict[int, list[dict]] = defaultdict(list)
    with open(run / "truth.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            rows[int(r["sysid"])].append(r)
    for r in rows.values():
        r.sort(key=lambda x: float(x["t_s"]))
    return dict(rows)


def read_events(path: Path) -> list[dict]:
    out = []
    for line in path.read_text().splitlines():
        ev = json.loads(line)
        if isinstance(ev.get("t_s"), int | float):
            out.append(ev)
    return out


def vehicle_packets(tlog: Path, types: tuple[str, ...]) -> list:
    """The tlog's messages of ``types`` stamped in vehicle time (the simulated clock's day)."""
    conn = mavutil.mavlink_connection(str(tlog), dialect="ardupilotmega")
    out = []
    while (m := conn.recv_match(type=list(types))) is not None:
        if SIM_EPOCH_UNIX_S <= m._timestamp < SIM_EPOCH_UNIX_S + 86400:
            out.append(m)
    conn.close()
    return out


def companion_setpoints(tlog: Path) -> list:
    got = vehicle_packets(tlog, (*SETPOINT_TYPES, "COMMAND_INT", "COMMAND_LONG"))
    return [
        m
        for m in got
        if m.get_srcComponent() != 1
        and (m.get_type() in SETPOINT_TYPES or m.command == GUIDED_CHANGE_HEADING)
    ]


def to_local(origin, lat: float, lon: float, alt: float) -> tuple[float, float, float]:
    n, e, d = pymap3d.geodetic2ned(lat, lon, alt, origin.lat_deg, origin.lon_deg, origin.alt_m)
    return float(n), float(e), -float(d)


def ns(t_unix_s: float) -> int:
    """A tlog's or a companion's own time (unix s, microseconds at most) in ns."""
    return round(t_unix_s * 1e6) * 1000


def sim_ns(t_s: float | str) -> int:
    """A simulated time (s, ``truth.csv`` or the merged events) in vehicle time, ns, exact."""
    return SIM_EPOCH_UNIX_S * 10**9 + round(float(t_s) * 1e9)


def heading_of(q: dict) -> float:
    """Heading (deg, clockwise from north) of an ENU yaw quaternion."""
    yaw = 2.0 * math.atan2(q["z"], q["w"])
    return (90.0 - math.degrees(yaw)) % 360.0


def roll_of(q) -> float:
    """Roll (rad) of a MAVLink quaternion (w, x, y, z)."""
    w, x, y, z = q
    return math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))


@pytest.mark.integration
@pytest.mark.slow
def test_every_topic_of_a_fleet_run_holds_the_runs_files(run_dir, tmp_path):
    out = tmp_path / "run.mcap"
    done = companion("export", str(run_dir), "--mcap", str(out))
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1].startswith(f"export: wrote {out}")
    topics, kinds, meta, attachments = read_mcap(out)
    mission = load_mission(run_dir / "mission.yaml")
    origin = mission.origin
    truth = read_truth(run_dir)
    events = read_events(run_dir / "events.jsonl")
    sysids = sorted(truth)
    assert sysids == [1, 2, 3, 4, 5, 6, 10]

    expected_topics = {
        "/events",
        "/mission/loop",
        "/mission/fence",
        "/alerts",
        "/alerts/changes",
        "/tracks",
        "/tracks/sightings",
    }
    sent = {s: companion_setpoints(run_dir / f"uav{s}" / "autopilot.tlog") for s in sysids}
    targeted = {ev["sysid"] for ev in events if ev["event"] == "guided_targets"}
    for s in sysids:
        expected_topics |= {
            f"/uav{s}/{t}" for t in ("fix", "pose", "tf", "velocity", "mode", "battery")
        }
        expected_topics |= {f"/uav{s}/setpoint"} if sent[s] else set()
        expected_topics |= {f"/uav{s}/targets"} if s in targeted else set()
    assert all(sent[s] for s in range(1, 7)) and not sent[10]  # the spare stayed on the ground
    assert set(topics) == expected_topics
    schema_of = {
        "fix": "foxglove.LocationFix",
        "pose": "foxglove.PoseInFrame",
        "tf": "foxglove.FrameTransform",
        "velocity": "patrol.Velocity",
        "mode": "patrol.Mode",
        "battery": "patrol.Battery",
        "setpoint": "patrol.Setpoint",
        "targets": "patrol.Targets",
    }
    for topic, (schema, encoding, msg_encoding) in kinds.items():
        assert (encoding, msg_encoding) == ("jsonschema", "json"), topic
        if topic.startswith("/uav"):
            assert schema == schema_of[topic.split("/")[2]], topic
    for topic in ("/mission/loop", "/mission/fence", "/alerts", "/tracks"):
        assert kinds[topic][0] == "foxglove.GeoJSON"
    assert kinds["/events"][0] == "foxglove.Log"

    for s in sysids:
        rows = truth[s]
        t = [sim_ns(r["t_s"]) for r in rows]
        fix, pose, tf = topics[f"/uav{s}/fix"], topics[f"/uav{s}/pose"], topics[f"/uav{s}/tf"]
        vel, bat = topics[f"/uav{s}/velocity"], topics[f"/uav{s}/battery"]
        for got in (fix, pose, tf, vel, bat):  # every truth row, in vehicle time
            assert len(got) == len(rows)
            assert got[0][0] == t[0] and got[-1][0] == t[-1]
        picks = sorted({0, len(rows) - 1, *range(0, len(rows), 97)})  # first, last, a sample
        for k in picks:
            r = rows[k]
            n, e, alt = float(r["north_m"]), float(r["east_m"]), float(r["alt_m"])
            f = fix[k][1]
            assert f["timestamp"] == {"sec": t[k] // 10**9, "nsec": t[k] % 10**9}
            back = to_local(origin, f["latitude"], f["longitude"], f["altitude"])
            assert back == pytest.approx((n, e, alt), abs=1e-3), (s, k)
            p = pose[k][1]
            assert p["frame_id"] == "local"
            xyz = p["pose"]["position"]
            assert (xyz["x"], xyz["y"], xyz["z"]) == pytest.approx((e, n, alt), abs=1e-9)
            heading = heading_of(p["pose"]["orientation"])
            assert math.remainder(heading - float(r["heading_deg"]), 360.0) == pytest.approx(
                0.0, abs=1e-6
            )
            x = tf[k][1]
            assert (x["parent_frame_id"], x["child_frame_id"]) == ("local", f"uav{s}")
            assert x["translation"] == xyz and x["rotation"] == p["pose"]["orientation"]
            v = vel[k][1]
            gs, course = float(r["groundspeed_m_s"]), math.radians(float(r["course_deg"]))
            assert v["groundspeed_m_s"] == gs and v["turn_rate_deg_s"] == float(
                r["turn_rate_deg_s"]
            )
            assert (v["north_m_s"], v["east_m_s"]) == pytest.approx(
                (gs * math.cos(course), gs * math.sin(course)), abs=1e-9
            )
            b = bat[k][1]
            assert b["remaining_pct"] == float(r["battery_remaining_pct"])
            assert b["consumed_mah"] == float(r["battery_consumed_mah"])
            assert b["voltage_v"] == float(r["battery_voltage_v"])
        changes = [
            (sim_ns(r["t_s"]), r["mode"])
            for i, r in enumerate(rows)
            if i == 0 or r["mode"] != rows[i - 1]["mode"]
        ]
        assert [(tt, m["mode"]) for tt, m in topics[f"/uav{s}/mode"]] == changes
        # setpoints: every one the companion sent, from its tlog
        sp = topics.get(f"/uav{s}/setpoint", [])
        assert len(sp) == len(sent[s])
        for (tt, got), m in zip(sp[:1] + sp[-1:], sent[s][:1] + sent[s][-1:], strict=True):
            assert tt == ns(m._timestamp)
            assert got["kind"] == "bank" and m.get_type() == "SET_ATTITUDE_TARGET"
            assert got["roll_rad"] == pytest.approx(roll_of(m.q), abs=1e-9)
        targets = [ev for ev in events if ev["event"] == "guided_targets" and ev["sysid"] == s]
        got = topics.get(f"/uav{s}/targets", [])
        assert [(tt, m["airspeed_m_s"], m["alt_amsl_m"]) for tt, m in got] == [
            (sim_ns(ev["t_s"]), ev["airspeed_m_s"], ev["alt_amsl_m"]) for ev in targets
        ]

    # the log: every event with a time, and the autopilots' STATUSTEXT
    statustext = sum(
        len(vehicle_packets(run_dir / f"uav{s}" / "autopilot.tlog", ("STATUSTEXT",)))
        for s in sysids
    )
    log = topics["/events"]
    assert len(log) == len(events) + statustext
    assert log[0][0] == sim_ns(events[0]["t_s"])
    assert log[0][1]["message"].split()[0] == events[0]["event"]

    # alerts: one change per alert id and state, the site on the map
    firsts: dict[tuple[str, str], dict] = {}
    state_of = {
        "alert_new": "new",
        "alert_confirmed": "confirmed",
        "alert_cleared": "cleared",
        "alert_lost": "lost",
    }
    for ev in events:
        if ev["event"] in state_of:
            firsts.setdefault((ev["alert_id"], state_of[ev["event"]]), ev)
    assert ("6-1", "new") in firsts or any(k[1] == "new" for k in firsts)
    got = [(m["alert_id"], m["state"]) for _, m in topics["/alerts/changes"]]
    assert got == list(firsts) and len(got) >= 2  # new, then lost (or cleared)
    assert [tt for tt, _ in topics["/alerts/changes"]] == [
        sim_ns(ev["t_s"]) for ev in firsts.values()
    ]
    (new,) = [ev for (a, st), ev in firsts.items() if st == "new"]
    last = json.loads(topics["/alerts"][-1][1]["geojson"])
    (feature,) = last["features"]
    lon, lat = feature["geometry"]["coordinates"]
    assert to_local(origin, lat, lon, origin.alt_m)[:2] == pytest.approx(
        (new["north_m"], new["east_m"]), abs=1e-3
    )
    assert feature["properties"]["state"] == got[-1][1]
    # tracks: every sighted pass, the newest track on the map
    sighted = [ev for ev in events if ev["event"] == "sighted"]
    sightings = topics["/tracks/sightings"]
    assert len(sightings) == len(sighted) == len(topics["/tracks"]) > 0
    assert sightings[-1][1]["sigma_m"] == sighted[-1]["sigma_m"]
    assert sightings[-1][0] == sim_ns(sighted[-1]["t_s"])
    (track,) = json.loads(topics["/tracks"][-1][1]["geojson"])["features"]
    lon, lat = track["geometry"]["coordinates"]
    assert to_local(origin, lat, lon, origin.alt_m)[:2] == pytest.approx(
        (sighted[-1]["north_m"], sighted[-1]["east_m"]), abs=1e-3
    )

    # the loop and the fence, once, at the start
    ((t_loop, loop),) = topics["/mission/loop"]
    ((_, fence),) = topics["/mission/fence"]
    assert t_loop == min(v[0][0] for v in topics.values())
    features = json.loads(loop["geojson"])["features"]
    ring = next(f for f in features if f["geometry"]["type"] == "LineString")
    pts = [to_local(origin, la, lo, origin.alt_m) for lo, la in ring["geometry"]["coordinates"]]
    assert pts[0] == pytest.approx(pts[-1], abs=1e-6)  # closed
    dense = np.asarray(mission.patrol.sample_by_time(20000), dtype=complex)
    off = [float(np.min(np.abs(dense - complex(n, e)))) for n, e, _ in pts]
    assert max(off) < 0.5  # on the patrol loop
    bases = [f for f in features if f["geometry"]["type"] == "Point"]
    assert len(bases) == len(mission.vehicles.spares) == 1
    (poly,) = json.loads(fence["geojson"])["features"]
    ring = poly["geometry"]["coordinates"][0]
    got = [to_local(origin, la, lo, origin.alt_m)[:2] for lo, la in ring[:-1]]
    want = [(v.north_m, v.east_m) for v in mission.fence.vertices]
    assert np.allclose(got, want, atol=1e-3)

    # metadata: the run, metrics.json, the mission attached
    assert meta["run"]["layout"] == "run" and meta["run"]["mission"] == "export_test"
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert {k: json.loads(v) for k, v in meta["metrics"].items()} == metrics
    assert attachments == [("mission.yaml", (run_dir / "mission.yaml").read_bytes())]


@pytest.mark.integration
@pytest.mark.slow
def test_a_companions_own_log_folder_exports_its_tlog_and_events(run_dir, tmp_path):
    """A companion's ``--log-dir`` (tlog and events of UAV 3): positions from its
    GLOBAL_POSITION_INT near the truth, its setpoints, mode and battery; with ``--mission``
    the mission's origin, loop and fence, without it the first fix's home."""
    logs = tmp_path / "uav3-logs"
    logs.mkdir()
    for name in ("autopilot.tlog", "events.jsonl"):
        shutil.copy(run_dir / "uav3" / name, logs / name)
    out = tmp_path / "uav3.mcap"
    mission = load_mission(run_dir / "mission.yaml")
    done = companion(
        "export", str(logs), "--mcap", str(out), "--mission", str(run_dir / "mission.yaml")
    )
    assert done.returncode == 0, done.stderr
    topics, _, meta, _ = read_mcap(out)
    assert meta["run"]["layout"] == "companion" and meta["run"]["uavs"] == "3"
    fixes = vehicle_packets(logs / "autopilot.tlog", ("GLOBAL_POSITION_INT",))
    fixes = [m for m in fixes if m.get_srcComponent() == 1]
    fix = topics["/uav3/fix"]
    assert len(fix) == len(fixes) > 100
    assert fix[0][0] == ns(fixes[0]._timestamp) and fix[-1][0] == ns(fixes[-1]._timestamp)
    rows = read_truth(run_dir)[3]
    tt = np.array([SIM_EPOCH_UNIX_S + float(r["t_s"]) for r in rows])
    tn = np.array([float(r["north_m"]) for r in rows])
    te = np.array([float(r["east_m"]) for r in rows])
    err = []
    for t, f in fix[:: max(1, len(fix) // 50)]:
        n, e, _ = to_local(mission.origin, f["latitude"], f["longitude"], f["altitude"])
        s = t / 1e9
        if tt[0] <= s <= tt[-1]:
            err.append(abs(complex(n, e) - complex(np.interp(s, tt, tn), np.interp(s, tt, te))))
    assert len(err) > 20 and float(np.median(err)) < 3.0 and max(err) < 10.0
    assert len(topics["/uav3/setpoint"]) == len(companion_setpoints(logs / "autopilot.tlog"))
    assert "GUIDED" in [m["mode"] for _, m in topics["/uav3/mode"]]
    assert topics["/uav3/battery"] and "remaining_pct" in topics["/uav3/battery"][-1][1]
    assert {"/mission/loop", "/mission/fence", "/events"} <= set(topics)
    own = read_events(logs / "events.jsonl")  # its own log: vehicle time already
    lines = [(tt, m) for tt, m in topics["/events"] if m["name"] == "uav3"]
    assert len(lines) == len(own) > 0
    assert lines[0][0] == ns(min(ev["t_s"] for ev in own))
    assert lines[-1][0] == ns(max(ev["t_s"] for ev in own))

    # no mission: the local frame at the first fix's home, no loop or fence
    done = companion("export", str(logs), "--mcap", str(tmp_path / "bare.mcap"))
    assert done.returncode == 0, done.stderr
    bare, _, meta, attachments = read_mcap(tmp_path / "bare.mcap")
    assert meta["run"]["origin_source"] == "first fix" and attachments == []
    assert "/mission/loop" not in bare and len(bare["/uav3/fix"]) == len(fixes)
    f0 = fixes[0]
    home = (f0.lat * 1e-7, f0.lon * 1e-7, (f0.alt - f0.relative_alt) / 1000.0)
    p = bare["/uav3/pose"][0][1]["pose"]["position"]
    assert (p["x"], p["y"]) == pytest.approx((0.0, 0.0), abs=1e-6)  # at its home
    assert p["z"] == pytest.approx(f0.relative_alt / 1000.0, abs=1e-3)
    assert float(meta["run"]["origin_lat_deg"]) == home[0]


def test_a_missing_or_wrong_folder_is_refused_in_one_line(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "truth.csv").write_text("time,x,y\n1,2,3\n")
    (tmp_path / "file.txt").write_text("x")
    out = str(tmp_path / "out.mcap")
    cases = [
        ([str(tmp_path / "nowhere"), "--mcap", out], "no such folder"),
        ([str(tmp_path / "file.txt"), "--mcap", out], "not a folder"),
        ([str(empty), "--mcap", out], "not a run folder"),
        ([str(bad), "--mcap", out], "expected the columns"),
        ([str(empty), "--mcap", str(tmp_path / "out.txt")], "must end in .mcap"),
        ([str(empty), "--mcap", str(tmp_path / "no" / "o.mcap")], "no such folder"),
        ([str(empty), "--mcap", out, "--mission", str(tmp_path / "m.yaml")], "not a run"),
    ]
    for args, words in cases:
        done = companion("export", *args)
        assert done.returncode == 2, (args, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("companion export: error: "), lines
        assert words in lines[0], lines
        assert not (tmp_path / "out.mcap").exists()


def test_foxglove_messages_follow_the_conventions():
    """Pure: times as {sec, nsec}; the local frame ENU, a heading of 0 (north) is a yaw of
    +90 deg about up, 90 (east) a yaw of 0."""
    assert fg.stamp(SIM_EPOCH_UNIX_S + 0.1) == {"sec": SIM_EPOCH_UNIX_S, "nsec": 100_000_000}
    q = fg.yaw_quaternion(fg.enu_yaw_rad(0.0))
    assert (q["z"], q["w"]) == pytest.approx((math.sin(math.pi / 4), math.cos(math.pi / 4)))
    assert fg.enu_yaw_rad(90.0) == 0.0
    p = fg.pose_in_frame(1.0, east_m=3.0, north_m=4.0, up_m=5.0, heading_deg=180.0)
    assert p["pose"]["position"] == {"x": 3.0, "y": 4.0, "z": 5.0}
    assert heading_of(p["pose"]["orientation"]) == pytest.approx(180.0)
    fc = json.loads(fg.geojson([])["geojson"])
    assert fc == {"type": "FeatureCollection", "features": []}
    assert fg.LOCATION_FIX["title"] == "foxglove.LocationFix"
    assert set(fg.LOCATION_FIX["properties"]) >= {"timestamp", "latitude", "longitude"}
