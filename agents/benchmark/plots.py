"""The benchmark's figures: per world, mean error and failure share against crowd size, one line per
localizer (under the world's first policy), with the bootstrap intervals as bars."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from agents.common.plots import plt, save_figure
from agents.evaluate.spec import slug

if TYPE_CHECKING:
    from agents.benchmark.results import Row
    from agents.benchmark.run import BenchmarkPlan


def plot_worlds(folder: Path, plan: BenchmarkPlan, rows: Sequence[Row]) -> dict[str, Path]:
    """One PNG per world (``plots/<world>.png``); returns them by world id."""
    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    quick = " (quick run)" if plan.quick else ""
    for world in plan.worlds:
        policy = world.policies[0]
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for loc in world.localizers:
            mine = sorted((r for r in rows if r.world == world.env_id and r.localizer == loc and r.policy == policy),
                          key=lambda r: r.crowd_size)  # fmt: skip
            sizes = [r.crowd_size for r in mine]
            for ax, key in zip(axes, ("error_mean_m", "failure_share")):
                stats = [r.stats[key] for r in mine]
                means = [s.mean for s in stats]
                err = [[max(s.mean - s.low, 0.0) for s in stats], [max(s.high - s.mean, 0.0) for s in stats]]
                ax.errorbar(sizes, means, yerr=err, marker="o", capsize=3, label=loc)
        axes[0].set_ylabel("mean position error (m)")
        axes[1].set_ylabel(f"failure share (error >= {world.world.failure_m:g} m)")
        for ax in axes:
            ax.set_xlabel("crowd size")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        title = f"{world.env_id}, {policy}, {len(plan.seeds)} seeds{quick}"
        written[world.env_id] = save_figure(fig, folder / f"{slug(world.env_id)}.png", title)
    return written
