"""``OUT/summary.png``: each key measure per scenario (a box of its runs, every run a dot)."""

from __future__ import annotations

from pathlib import Path

from companion.campaign.summary import KEY_MEASURES, scenarios_of


def plot_summary(rows: list[dict], path: Path) -> None:
    """Draw the key measures of ``rows`` per scenario (boxes of the runs that measured
    them, each run a dot; failed runs left out) into the PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = scenarios_of(rows)
    ok = [r for r in rows if not r.get("error")]
    cols = 2
    nrows = (len(KEY_MEASURES) + cols - 1) // cols
    fig, axes = plt.subplots(
        nrows, cols, figsize=(max(8.0, 1.2 * len(names) * cols), 2.8 * nrows), squeeze=False
    )
    for ax, km in zip(axes.flat, KEY_MEASURES, strict=False):
        data = [
            [float(r[km.column]) for r in ok if r["scenario"] == n and r.get(km.column) is not None]
            for n in names
        ]
        drawn = [(i, d) for i, d in enumerate(data) if d]
        if drawn:
            ax.boxplot([d for _, d in drawn], positions=[i for i, _ in drawn], widths=0.6,
                       showfliers=False)  # fmt: skip
            for i, d in drawn:
                ax.plot([i] * len(d), d, "o", ms=3, alpha=0.5, color="tab:blue")
        else:
            ax.text(0.5, 0.5, "no run measured it", transform=ax.transAxes, ha="center")
        ax.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize=8)
        ax.set_xlim(-0.7, len(names) - 0.3)
        worse = "lower is worse" if km.low_is_worse else "higher is worse"
        ax.set_title(f"{km.column} ({km.unit}; {worse})", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    for ax in list(axes.flat)[len(KEY_MEASURES) :]:
        ax.set_visible(False)
    fig.suptitle(f"campaign: {len(ok)} runs ({len(rows) - len(ok)} failed), per scenario")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
