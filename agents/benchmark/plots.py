"""The benchmark's figures: per world, mean error and failure share against crowd size, one line per
localizer (under the world's first policy), with the bootstrap intervals as bars; and the overview,
localizers x worlds (:func:`plot_overview`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from agents.common.plots import plt, save_figure
from agents.evaluate.spec import slug

if TYPE_CHECKING:
    from agents.benchmark.results import Row, Sensitivity
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


def _times(ratio: float) -> str:
    """A ratio in two significant digits, without an exponent."""
    return f"{ratio:.2g}" if ratio < 100 else f"{ratio:.0f}"


def _short(env_id: str) -> str:
    return env_id.removeprefix("crowdloc/").removesuffix("-v0")


def plot_overview(path: Path, plan: BenchmarkPlan, rows: Sequence[Row], sens: Sequence[Sensitivity]) -> Path:
    """``plots/overview.png``: the league at a glance, localizers x worlds under each world's first
    policy. Left: the crowd sensitivity (error at the largest crowd / at crowd 0; colour on a log
    scale, white = 1, red = the crowd hurts), its interval below it. Right: the mean error at the
    largest crowd (colour on a log scale), the rank at the default crowd below it. An empty cell: the
    world lacks the localizer's sensor."""
    import numpy as np
    from matplotlib.colors import LogNorm, TwoSlopeNorm

    worlds = [w.env_id for w in plan.worlds]
    localizers = list(dict.fromkeys(s.localizer for s in sens))
    ratio = np.full((len(localizers), len(worlds)), np.nan)
    error = np.full_like(ratio, np.nan)
    ratio_text = [["" for _ in worlds] for _ in localizers]
    error_text = [["" for _ in worlds] for _ in localizers]
    for s in sens:
        i, j = localizers.index(s.localizer), worlds.index(s.world)
        ratio[i, j] = s.ratio
        ci = f"\n[{_times(s.low)}, {_times(s.high)}]" if np.isfinite(s.low) and len(plan.seeds) > 1 else ""
        ratio_text[i][j] = f"{_times(s.ratio)}x{ci}" if np.isfinite(s.ratio) else "–"
        top = next((r for r in rows if r.world == s.world and r.localizer == s.localizer and r.policy == s.policy
                    and r.crowd_size == s.crowd_max), None)  # fmt: skip
        if top is not None:
            error[i, j] = top.stats["error_mean_m"].mean
            rank = f"\n#{s.rank}" if s.rank else ""
            error_text[i][j] = (f"{error[i, j]:.2g} m" if np.isfinite(error[i, j]) else "–") + rank
    fig, axes = plt.subplots(1, 2, figsize=(3.0 + 2.2 * len(worlds), 1.2 + 0.55 * len(localizers)))
    logs = np.log10(np.where(ratio > 0, ratio, np.nan))
    span = float(np.nanmax(np.abs(logs))) if np.isfinite(logs).any() else 1.0
    span = max(span, 0.1)
    panels = [
        (axes[0], logs, ratio_text, "RdBu_r", TwoSlopeNorm(0.0, -span, span), "crowd sensitivity\n(error at the largest crowd / at crowd 0)"),
        (axes[1], error, error_text, "viridis", LogNorm() if (error > 0).any() else None, "mean error at the largest crowd\n(#: rank at the default crowd)"),
    ]  # fmt: skip
    for ax, values, text, cmap, norm, title in panels:
        image = ax.imshow(np.ma.masked_invalid(values), cmap=cmap, norm=norm, aspect="auto")
        for i in range(len(localizers)):
            for j in range(len(worlds)):
                finite = np.isfinite(values[i, j])
                r, g, b = np.ravel(image.to_rgba(np.array([[values[i, j]]])))[:3] if finite else (1.0, 1.0, 1.0)
                dark = 0.299 * r + 0.587 * g + 0.114 * b < 0.5
                ax.text(j, i, text[i][j], ha="center", va="center", fontsize=7, color="white" if dark else "black")
        ax.set_xticks(range(len(worlds)), [_short(w) for w in worlds], rotation=20, fontsize=8)
        ax.set_yticks(range(len(localizers)), localizers, fontsize=8)
        ax.set_title(title, fontsize=9)
    quick = " (quick run)" if plan.quick else ""
    return save_figure(fig, path, f"{plan.protocol.name}: {len(plan.seeds)} seeds{quick}")
