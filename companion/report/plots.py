"""Plots of a run (PNG): the map, the space-time coverage diagram, the formation errors.

Conventions on every figure: north up (map: East on x, North on y, metres), times in
simulated seconds, arc length measured along the loop from the point of course 0.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial import cKDTree

from companion.agent.events import AlertNew, ProsecutionEnd
from companion.core.measures import CENTRE_TOL_M, SPLAY_TOL_DEG
from companion.core.wind import TWO_PI
from companion.report.rundata import RunData

LOOP_SAMPLES = 4000


def _colors(n: int) -> list:
    cmap = plt.get_cmap("tab10")
    return [cmap(k % 10) for k in range(n)]


def plot_map(run: RunData, path: Path) -> None:
    """Loop, tracks, base waypoints, alert sites and prosecutors' paths, north up."""
    m = run.mission
    patrol = m.patrol
    loop = patrol.point_at_phase(np.linspace(0, TWO_PI, LOOP_SAMPLES + 1))
    fig, ax = plt.subplots(figsize=(11, 8))
    ax.plot(loop.imag, loop.real, "k-", lw=2.0, label="patrol loop C", zorder=3)
    shape = m.perimeter.shape
    if hasattr(shape, "waypoints"):
        e = [w.east_m for w in shape.waypoints]
        n = [w.north_m for w in shape.waypoints]
        ax.plot(e, n, "s", color="0.3", ms=7, label="base landmarks", zorder=4)
        for w in shape.waypoints:
            ax.annotate(
                w.name.split(" (")[0],
                (w.east_m, w.north_m),
                fontsize=7,
                xytext=(4, 4),
                textcoords="offset points",
            )
    away = run.away_windows()
    for (sysid, tr), col in zip(sorted(run.tracks.items()), _colors(len(run.tracks)), strict=True):
        ax.plot(
            tr.pos_m.imag,
            tr.pos_m.real,
            "-",
            color=col,
            lw=0.6,
            alpha=0.6,
            label=f"UAV {sysid} track",
        )
        ax.plot(tr.pos_m[0].imag, tr.pos_m[0].real, "o", color=col, ms=5)
    for k, a in enumerate(away):
        tr = run.tracks[a.sysid]
        t_end = _prosecution_end(run, a)
        fly = (tr.t_s >= a.t0_s) & (tr.t_s <= t_end)
        back = (tr.t_s >= t_end) & (tr.t_s <= a.t1_s)
        ax.plot(
            tr.pos_m[back].imag,
            tr.pos_m[back].real,
            "--",
            color="crimson",
            lw=1.0,
            label="prosecutor back into its slot" if k == 0 else None,
            zorder=5,
        )
        ax.plot(
            tr.pos_m[fly].imag,
            tr.pos_m[fly].real,
            "-",
            color="crimson",
            lw=2.8,
            label="prosecutor's minimum-time path" if k == 0 else None,
            zorder=6,
        )
    sites = [e for e in run.agent_events if isinstance(e, AlertNew) and e.own]
    for k, e in enumerate(sites):
        ax.plot(
            e.east_m,
            e.north_m,
            "X",
            color="red",
            ms=12,
            mec="k",
            zorder=6,
            label="alert site" if k == 0 else None,
        )
    ax.plot(patrol.centre_m.imag, patrol.centre_m.real, "+", color="k", ms=10, label="centre c0")
    ax.set_aspect("equal")
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    w = m.wind
    ax.set_title(
        f"{m.name}: {m.vehicles.count} UAVs at {m.vehicles.airspeed_m_s:g} m/s, "
        f"wind {w.speed_m_s:g} m/s from {w.from_deg:g} deg"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _prosecution_end(run: RunData, away) -> float:
    """When the prosecutor of ``away`` ended its flight to the site (s)."""
    for e in run.agent_events:
        if (
            isinstance(e, ProsecutionEnd)
            and e.sysid == away.sysid
            and e.alert_id == away.alert_id
            and away.t0_s <= e.t_s <= away.t1_s
        ):
            return float(e.t_s)
    return away.t1_s


def plot_coverage(run: RunData, path: Path) -> None:
    """Space-time diagram: arc length along C against time, sensor swaths shaded."""
    m = run.mission
    patrol = m.patrol
    r_s = m.sensor.footprint_radius_m
    phases = np.linspace(0, TWO_PI, LOOP_SAMPLES, endpoint=False)
    loop = patrol.point_at_phase(phases)
    arc = patrol.arc_length_at_phase(phases)
    tree = cKDTree(np.column_stack([loop.real, loop.imag]))
    period = patrol.period_s
    away = run.away_windows()
    t_all = run.times_s
    if away:
        t0, t1 = away[0].t0_s - 2 * period, away[0].t0_s + 3 * period
    else:
        t0, t1 = t_all[-1] - 4 * period, t_all[-1]
    t0, t1 = max(t0, float(t_all[0])), min(t1, float(t_all[-1]))
    fig, ax = plt.subplots(figsize=(10, 8))
    for (sysid, tr), col in zip(sorted(run.tracks.items()), _colors(len(run.tracks)), strict=True):
        sel = (tr.t_s >= t0) & (tr.t_s <= t1)
        pos, t = tr.pos_m[sel], tr.t_s[sel]
        dist, idx = tree.query(np.column_stack([pos.real, pos.imag]))
        s = arc[idx]
        half = np.sqrt(np.clip(r_s**2 - dist**2, 0.0, None))  # swath along the loop
        on = dist < r_s
        breaks = np.flatnonzero((np.abs(np.diff(s)) > 0.5 * patrol.length_m) | (np.diff(on) != 0))
        for seg in np.split(np.arange(s.size), breaks + 1):
            if seg.size < 2:
                continue
            if on[seg[0]]:
                ax.fill_betweenx(t[seg], s[seg] - half[seg], s[seg] + half[seg], color="0.75", lw=0)
            ax.plot(
                s[seg],
                t[seg],
                color=col,
                lw=1.2 if on[seg[0]] else 0.8,
                ls="-" if on[seg[0]] else ":",
            )
        ax.plot([], [], "-", color=col, label=f"UAV {sysid}")
        for a in away:
            if a.sysid != sysid:
                continue
            hop = (t >= a.t0_s) & (t <= _prosecution_end(run, a))
            if hop.any():
                ax.plot(s[hop], t[hop], ".", color="crimson", ms=3, zorder=5)
    for e in run.agent_events:
        if isinstance(e, AlertNew) and e.own and t0 <= e.t_s <= t1:
            near = patrol.nearest(complex(e.north_m, e.east_m))
            ax.plot(
                patrol.arc_length_at_phase(near.phase_rad),
                e.t_s,
                "X",
                color="red",
                ms=12,
                mec="k",
                label="alert",
            )
    ax.fill_betweenx([], [], [], color="0.75", label=f"sensor swath (r = {r_s:g} m)")
    ax.plot([], [], ":", color="k", label="more than r from the loop")
    ax.plot([], [], ".", color="crimson", label="prosecution (projected on the loop)")
    ax.set_xlim(0, patrol.length_m)
    ax.set_ylim(t0, t1)
    ax.set_xlabel("arc length along the loop (m)")
    ax.set_ylabel("time (s)")
    ax.set_title(
        f"{m.name}: space-time coverage (ideal revisit T/N = {period / m.vehicles.count:.1f} s)"
    )
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_errors(run: RunData, series: dict, path: Path) -> None:
    """Splay error and centre error against time, with the convergence thresholds."""
    t = series["t_s"]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    a1.semilogy(t, np.maximum(series["splay_deg"], 1e-4), "b-", lw=1)
    a1.axhline(SPLAY_TOL_DEG, color="g", ls="--", label=f"{SPLAY_TOL_DEG:g} deg")
    a1.set_ylabel("splay error (deg)")
    a2.semilogy(t, np.maximum(series["centre_m"], 1e-3), "m-", lw=1)
    a2.axhline(CENTRE_TOL_M, color="g", ls="--", label=f"{CENTRE_TOL_M:g} m")
    a2.set_ylabel("centre error (m)")
    a2.set_xlabel("time (s)")
    for k, a in enumerate(run.away_windows()):
        for ax in (a1, a2):
            ax.axvspan(
                a.t0_s,
                a.t1_s,
                color="orange",
                alpha=0.25,
                label="UAV away on an alert" if k == 0 and ax is a1 else None,
            )
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    a1.set_title(f"{run.mission.name}: formation errors of the shared states")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
