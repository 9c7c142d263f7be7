"""A campaign's figures per scenario, as text: rows (dicts of the table) in, lines out.

For each scenario and each key measure (:data:`KEY_MEASURES`): how many runs measured it,
the median, the 90th percentile towards the worst (the 10th for a share, where low is bad)
and the worst value with the run that gave it (its id and seed), so it can be flown again
(``companion campaign SPEC --show RUN_ID``). Failed runs are listed with their error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class KeyMeasure:
    """A table column summarised per scenario; ``low_is_worse`` for shares."""

    column: str
    unit: str
    low_is_worse: bool = False


KEY_MEASURES: tuple[KeyMeasure, ...] = (
    KeyMeasure("cross_track_p95_m", "m"),
    KeyMeasure("coverage_revisit_ratio", "T/N"),
    KeyMeasure("longest_unseen_ratio", "T/N"),
    KeyMeasure("fraction_within_bounds", "share", low_is_worse=True),
    KeyMeasure("cover_over_plan_max", "x"),
    KeyMeasure("under_track_min", "share", low_is_worse=True),
    KeyMeasure("false_clears", "count"),
)


@dataclass(frozen=True)
class Figures:
    """One measure over one scenario's runs: n, median, p90 towards the worst, worst, and
    the worst run's id and seed (None when no run measured it)."""

    n: int
    median: float | None
    p90: float | None
    worst: float | None
    worst_run: str | None
    worst_seed: int | None


def figures(rows: list[dict], km: KeyMeasure) -> Figures:
    """The figures of ``km`` over ``rows`` (rows without a value are left out)."""
    have = [r for r in rows if r.get(km.column) is not None and not r.get("error")]
    if not have:
        return Figures(0, None, None, None, None, None)
    vals = np.array([float(r[km.column]) for r in have])
    i = int(np.argmin(vals) if km.low_is_worse else np.argmax(vals))
    p90 = np.percentile(vals, 10 if km.low_is_worse else 90)
    worst = have[i]
    return Figures(
        len(have), float(np.median(vals)), float(p90), float(vals[i]),
        worst["run_id"], int(worst["seed"]),
    )  # fmt: skip


def scenarios_of(rows: list[dict]) -> list[str]:
    """The scenarios of ``rows`` in their first-seen order."""
    return list(dict.fromkeys(r["scenario"] for r in rows))


def summary_text(rows: list[dict]) -> str:
    """The per-scenario table of the key measures and the failed runs (see the module)."""
    head = (
        f"  {'measure':<24} {'unit':<5} {'n':>4} {'median':>9} {'p90':>9} {'worst':>9}  "
        "worst run (seed)"
    )
    lines: list[str] = []
    for name in scenarios_of(rows):
        mine = [r for r in rows if r["scenario"] == name]
        failed = [r for r in mine if r.get("error")]
        extra = f", {len(failed)} failed" if failed else ""
        lines += [f"scenario {name}: {len(mine)} run{'s' * (len(mine) != 1)}{extra}", head]
        for km in KEY_MEASURES:
            f = figures(mine, km)
            where = "" if f.worst_run is None else f"{f.worst_run} ({f.worst_seed})"
            lines.append(
                f"  {km.column:<24} {km.unit:<5} {f.n:>4} {_g(f.median):>9} {_g(f.p90):>9} "
                f"{_g(f.worst):>9}  {where}".rstrip()
            )
        lines.append("")
    failed = [r for r in rows if r.get("error")]
    if failed:
        lines.append(f"failed runs: {len(failed)}")
        lines += [f"  {r['run_id']} (seed {r['seed']}): {r['error']}" for r in failed]
        lines.append("")
    lines.append("p90: the 90th percentile towards the worst (the 10th for a share)")
    return "\n".join(lines)


def _g(x: float | None) -> str:
    if x is None:
        return "-"
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"
