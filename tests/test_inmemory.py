"""Contract tests: the real companion stack against the simulator, in memory, lockstepped.

Every test flies :class:`companion.sim.inmemory.Engine` (the simulator's vehicles and world,
one real ``Runner`` per vehicle, MAVLink and the signed group as bytes) on the fast ellipse
mission, whose six UAVs start near splay.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from companion.contracts.simulator import SIM_EPOCH_UNIX_S
from companion.core.measures import splay_error_deg
from companion.mission import load_mission
from companion.sim.inmemory import Engine, EngineConfig
from sitl_model.autopilot import Mode
from sitl_model.codec import Encoder, dialect

pytestmark = pytest.mark.contract

REPO = Path(__file__).resolve().parents[1]
FAST = REPO / "tests" / "data" / "companion_ellipse_fast.yaml"


def engine(out: Path | None = None, mission: Path = FAST, **kw) -> Engine:
    return Engine(EngineConfig(mission, out, **kw))


def quiet_mission(folder: Path) -> Path:
    """The fast mission without intruders."""
    path = folder / "quiet.yaml"
    path.write_text(FAST.read_text().split("scenario:")[0] + "scenario:\n  duration_s: 500\n")
    return path


def loop_phases(e: Engine, sysids: list[int] | None = None) -> np.ndarray:
    """Truth time-phases (rad) of the given vehicles, from the simulator's positions and
    courses (as the loopback tests measure them)."""
    ids = e.sysids if sysids is None else sysids
    idx = [e.sysids.index(s) for s in ids]
    _, phases = e.mission.patrol.centre_and_phase_from_course(
        e.sim.state.pos_m[idx], e.sim.course_rad[idx]
    )
    return np.asarray(phases)


def nearest_phases(e: Engine) -> np.ndarray:
    """Truth time-phases (rad) of the loop points nearest to the vehicles (insensitive to
    the course weaving of the bank profile)."""
    patrol = e.mission.patrol
    return np.array([patrol.nearest(complex(p)).phase_rad for p in e.sim.state.pos_m])


def heartbeat():
    """A ground station's HEARTBEAT."""
    return dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)


def events(e: Engine, name: str, source: str = "companion") -> list[dict]:
    pool = e.companion_events if source == "companion" else e.sim_events
    return [ev for ev in pool if ev["event"] == name]


def test_same_seed_same_bytes_and_another_seed_differs(tmp_path):
    """Same mission, seed and parameters: byte-identical truth.csv and events.jsonl; the
    seed does matter (gusts on), so the comparison can fail."""
    params = {"SIM_WIND_TURB": 1.5}
    outs = {}
    for name, seed in (("a", 7), ("b", 7), ("c", 8)):
        with engine(tmp_path / name, seed=seed, params=params) as e:
            e.run(25.0)
            e.close()
        outs[name] = tmp_path / name
    for f in ("truth.csv", "events.jsonl", "sim_events.jsonl"):
        assert (outs["a"] / f).read_bytes() == (outs["b"] / f).read_bytes(), f
    assert (outs["a"] / "truth.csv").read_bytes() != (outs["c"] / "truth.csv").read_bytes()
    truth = (outs["a"] / "truth.csv").read_text().splitlines()
    assert len(truth) == 1 + 6 * 250  # 10 rows per vehicle per simulated second
    assert any('"member_joined"' in line for line in (outs["a"] / "events.jsonl").open())
    # run again into a folder that holds a run: the same bytes, not two runs' events mixed
    with engine(outs["a"], seed=7, params=params) as e:
        e.run(25.0)
        e.close()
    for f in ("truth.csv", "events.jsonl", "sim_events.jsonl"):
        assert (outs["a"] / f).read_bytes() == (outs["b"] / f).read_bytes(), f


def test_six_uavs_converge_and_exactly_one_answers_the_alert():
    """Splayed on the ellipse before the decoy (180 s), which one UAV alone prosecutes."""
    with engine() as e:
        e.run(170.0)
        assert splay_error_deg(nearest_phases(e)) < 2.0
        # every companion commands its vehicle and is in patrol
        assert all(r.authority.state == "commanding" for r in e.runners)
        assert {r.agent_mode for r in e.runners} == {"patrol"}
        e.run(200.0)
        away = [r.link.sysid for r in e.runners if r.agent_mode != "patrol"]
        (new,) = [ev for ev in events(e, "alert_new") if ev.get("own")]
        decisions = events(e, "alert_tasked")
    assert len(away) == 1
    assert away[0] != new["sysid"]
    # every companion came to the same decision on its own: the one that went
    assert len(decisions) == 6
    assert {ev["prosecutor_sysid"] for ev in decisions} == set(away)
    detections = events(e, "detection", "sim")
    assert detections and detections[0]["intruder"] == "decoy-1"


def test_a_silent_companion_times_out_to_loiter_and_the_others_resplay(tmp_path):
    """Stop running companion 3: its vehicle loiters after GUID_TIMEOUT (3 s), the others
    drop it after the member timeout and re-splay as five; running it again resumes.

    Turn-rate setpoints to a rate-controlled autopilot (SIM_RATE_OK=1): the re-splay runs
    at the steering law's own pace, about 2 periods as over UDP (docs/reliability.md).
    """
    params = {"SIM_RATE_OK": 1.0}
    with engine(mission=quiet_mission(tmp_path), profile="turn-rate", params=params) as e:
        e.run(60.0)
        e.freeze(3)
        e.run(70.0)
        (timeout,) = events(e, "guided_timeout", "sim")
        assert timeout["sysid"] == 3 and 62.9 <= timeout["t_s"] <= 63.1
        others = [1, 2, 4, 5, 6]
        lost = [ev for ev in events(e, "member_lost") if ev.get("member_sysid") == 3]
        assert {ev["sysid"] for ev in lost} == set(others)
        assert all(len(e.runners[e.sysids.index(s)].agent.neighbours) == 4 for s in others)
        err_start = splay_error_deg(loop_phases(e, others))
        e.run(230.0)
        err_end = splay_error_deg(loop_phases(e, others))
        assert err_start > 30.0 and err_end < 0.5 * err_start, (err_start, err_end)
        assert e.sim.autopilots[2].guided_loitering
        e.thaw(3)
        e.run(236.0)
        assert events(e, "guided_resumed", "sim")
        assert e.runners[2].authority.state == "commanding"


def _settled_after(e: Engine, sysids: list[int], t_max_s: float, hold_s: float = 20.0):
    """Run in 2 s chunks until ``sysids`` have held splay < 2 deg (nearest-point phases) and
    every one within 5 m of the loop for ``hold_s`` (s); the time that began, or None by
    ``t_max_s`` (s, simulated)."""
    patrol, since = e.mission.patrol, None
    idx = [e.sysids.index(s) for s in sysids]
    while e.t_s < t_max_s:
        e.run(e.t_s + 2.0)
        near = [patrol.nearest(complex(p)) for p in e.sim.state.pos_m[idx]]
        ok = splay_error_deg([n.phase_rad for n in near]) < 2.0
        ok = ok and max(n.distance_m for n in near) < 5.0
        since = (since if since is not None else e.t_s) if ok else None
        if since is not None and e.t_s - since >= hold_s:
            return since
    return None


def test_a_killed_companion_restarted_rejoins_and_the_six_resplay(tmp_path):
    """SIGKILL companion 3 (no ``stop``, nothing more sent): its vehicle loiters after the
    GUIDED timeout (3 s), every other member drops it and the five re-splay within 4 loop
    periods; a new companion 3 takes its vehicle back, every member takes it in again
    within 2 periods, and the six re-splay within 4; nobody else restarted. The same over
    loopback UDP with a real process and SIGKILL: tests/test_reliability_fleet.py
    (extended tier)."""
    period = load_mission(FAST).patrol.period_s
    others = [1, 2, 4, 5, 6]
    with engine(tmp_path / "run", mission=quiet_mission(tmp_path)) as e:
        e.run(60.0)
        t_kill = e.t_s
        e.kill(3)
        resplay = _settled_after(e, others, t_kill + 4 * period)
        assert resplay is not None, "the five never re-splayed"
        (timeout,) = [ev for ev in events(e, "guided_timeout", "sim") if ev["sysid"] == 3]
        lost = {ev["sysid"] for ev in events(e, "member_lost") if ev.get("member_sysid") == 3}
        t_restart = e.t_s
        e.restart(3)
        rejoin = _settled_after(e, e.sysids, t_restart + 4 * period)
        joined = {  # companion events are stamped in unix seconds of vehicle time
            ev["sysid"]: ev["t_s"] - SIM_EPOCH_UNIX_S
            for ev in events(e, "member_joined")
            if ev.get("member_sysid") == 3 and ev["t_s"] - SIM_EPOCH_UNIX_S > t_restart
        }
        resumed = [ev for ev in events(e, "guided_resumed", "sim") if ev["t_s"] > t_restart]
    starts = {s: 0 for s in e.sysids}
    for ev in events(e, "start"):
        starts[ev["sysid"]] += 1
    stops = [ev["sysid"] for ev in events(e, "stop")]
    print(
        f"kill at {t_kill:.0f} s: GUIDED timeout after {timeout['t_s'] - t_kill:.1f} s, five "
        f"re-splayed after {resplay - t_kill:.0f} s; restart at {t_restart:.0f} s: joined "
        f"after {max(joined.values()) - t_restart:.1f} s, six re-splayed after "
        f"{(rejoin or math.nan) - t_restart:.0f} s (period {period:.1f} s)"
    )
    assert 2.9 <= timeout["t_s"] - t_kill <= 3.1  # 3 s after its last setpoint
    assert lost == set(others)
    assert resplay - t_kill <= 4 * period
    assert resumed and resumed[0]["sysid"] == 3
    assert set(joined) == set(others) and max(joined.values()) - t_restart <= 2 * period
    assert rejoin is not None and rejoin - t_restart <= 4 * period
    assert starts == {1: 1, 2: 1, 3: 2, 4: 1, 5: 1, 6: 1}
    assert sorted(stops) == e.sysids  # the killed one said nothing; the new one stopped


def test_pilot_override_stops_the_setpoints_and_guided_resumes_them(tmp_path):
    """The pilot selects LOITER through the vehicle's link for 15 s: that companion stops
    commanding (the vehicle then never times out in GUIDED), resumes once GUIDED is back and
    flies back into its slot: within one loop period its course-based centre error is under
    a tenth of its peak and 30 m (the check the loopback test made before it moved here,
    where the loiter's length no longer depends on the machine's load)."""
    with engine(mission=quiet_mission(tmp_path)) as e:
        e.run(20.0)
        r2 = e.runners[1]
        e.set_mode(2, Mode.LOITER)
        e.run(20.5)
        assert r2.authority.state == "overridden"
        assert [ev["autopilot_mode"] for ev in events(e, "override")] == ["LOITER"]
        sent = r2.counters.setpoints
        e.run(35.0)
        assert r2.counters.setpoints == sent  # not one setpoint while overridden
        assert e.sim.autopilots[1].mode is Mode.LOITER
        assert e.links[1].counters.refused == 0
        assert all(r.counters.setpoints > sent + 90 for r in e.runners if r is not r2)
        e.set_mode(2, Mode.GUIDED)
        e.run(36.0)
        assert r2.authority.state == "commanding" and events(e, "resumed")
        assert r2.counters.setpoints >= sent + 9
        patrol = e.mission.patrol
        centre_m = []  # vehicle 2's course-based centre error (m), each second after GUIDED
        for t in range(37, 37 + 115):
            e.run(float(t))
            c, _ = patrol.centre_and_phase_from_course(e.sim.state.pos_m[1], e.sim.course_rad[1])
            centre_m.append(abs(complex(c) - patrol.centre_m))
        peak, back = max(centre_m), max(centre_m[100:])
        assert peak > 100.0, peak  # the loiter took it well out of its slot
        assert back < min(30.0, 0.1 * peak), (peak, back)
    assert not events(e, "guided_timeout", "sim")


def test_signed_autopilot_links_fly_and_refuse_nothing():
    """Link signing on both ends (a key derived from the seed, signing timestamps from
    simulated time): every frame is signed and accepted, the companions command."""
    with engine(link_signing=True) as e:
        e.run(5.0)
        assert all(r.authority.state == "commanding" for r in e.runners)
        assert all(r.counters.setpoints >= 45 for r in e.runners)
        for link, r in zip(e.links, e.runners, strict=True):
            c = link.counters
            assert (c.unsigned, c.bad_signature, c.replayed, c.refused) == (0, 0, 0, 0)
            assert all(r.link.counts[k] == 0 for k in ("unsigned", "bad_signature", "replayed"))
        assert not events(e, "guided_timeout", "sim")
        # and the frames really are signed: an unsigned one is refused by the vehicle
        port = e.ports[0]
        before = e.links[0].counters.unsigned
        port.inbox.append((e.gcs, Encoder(255, 190).pack(heartbeat())))
        e.step()
        assert e.links[0].counters.unsigned == before + 1


@pytest.mark.parametrize(
    ("profile", "params", "gain"),
    [
        ("bank", {"SIM_TR_EFF": 0.75}, 0.75),
        ("heading", {"SIM_CRS_KP": 0.5}, 1.0),
    ],
)
def test_profiles_converge_against_imperfect_autopilots(tmp_path, profile, params, gain):
    """Bank (ArduPlane's ~0.75 turn efficiency) and heading (a course hold of gain 0.5 /s):
    each companion identifies the autopilot's gain and the formation converges (splay < 2
    deg and course-based centre < 10 m over 215-245 s; moved here from the loopback suite,
    where the same check took 40 s of wall time each)."""
    with engine(mission=quiet_mission(tmp_path), profile=profile, params=params) as e:
        patrol, splay, centre = e.mission.patrol, [], []
        for k in range(2150, 2451, 5):  # every half second, 215-245 s
            e.run(k / 10.0)
            c, ph = patrol.centre_and_phase_from_course(e.sim.state.pos_m, e.sim.course_rad)
            splay.append(splay_error_deg(np.asarray(ph)))
            centre.append(max(abs(complex(x) - patrol.centre_m) for x in np.atleast_1d(c)))
        gains = [r.shaper.gain for r in e.runners]
    assert all(abs(g - gain) < 0.1 * gain for g in gains), gains
    assert max(splay) < 2.0, max(splay)
    assert max(centre) < 10.0, max(centre)


def _airspeed_targets(e: Engine, until_s: float) -> np.ndarray:
    """Every autopilot's GUIDED airspeed target (m/s; nan: none), once a second."""
    rows = []
    while e.t_s < until_s - 1e-9:
        e.run(e.t_s + 1.0)
        rows.append(
            [
                np.nan if ln.ap.airspeed_target_m_s is None else ln.ap.airspeed_target_m_s
                for ln in e.links
            ]
        )
    return np.array(rows)


def test_airspeed_holds_the_phase_in_gusts_within_its_authority(tmp_path):
    """Gusts move each slot along the loop; the companions answer with airspeed targets on
    both sides of the mission's 20 m/s, never beyond the authority (2 m/s by default)."""
    with engine(mission=quiet_mission(tmp_path), params={"SIM_WIND_TURB": 1.5}, seed=3) as e:
        got = _airspeed_targets(e, 120.0)[30:]
    assert not np.isnan(got).any()
    assert got.min() < 19.7 and got.max() > 20.3
    authority = e.mission.gains.speed_authority_m_s
    assert authority == 2.0
    assert got.min() >= 20.0 - authority - 1e-6 and got.max() <= 20.0 + authority + 1e-6


def test_a_refused_airspeed_is_reported_once_and_the_mission_airspeed_held(tmp_path, monkeypatch):
    """An autopilot that refuses every airspeed but the mission's (ArduPlane: outside
    AIRSPEED_MIN..MAX): each companion says so once and asks for nothing else after it."""
    import sitl_model.autopilot as ap_module

    monkeypatch.setattr(ap_module, "SPEED_RANGE_FRAC", (0.999, 1.001))
    with engine(mission=quiet_mission(tmp_path), params={"SIM_WIND_TURB": 1.5}, seed=3) as e:
        got = _airspeed_targets(e, 90.0)
        denied = events(e, "airspeed_denied")
        agents = [r.agent for r in e.runners]
    assert sorted(ev["sysid"] for ev in denied) == e.sysids  # once each
    assert all(a.splay.gains.speed_authority_m_s == 0.0 for a in agents)  # steering alone now
    assert np.allclose(got[~np.isnan(got)], 20.0)
