"""What ``crowdloc eval`` writes (:func:`write_outputs`): ``episodes.csv``, ``summary.csv``,
``summary.md``, ``plots/<metric>.png``, ``plots/error_vs_spread.png`` (each valid step's position error against
the reported spread, per localizer), ``tum/<episode>_{estimate,groundtruth}.tum`` (``evo``
reads them; estimate rows only where valid) and ``episode.gif``.

The metric columns are the grid's (:attr:`EvalSpec.metrics`): the core ones and those of the
plug-ins of its localizers' measurement kinds; an episode of another kind has NaN there. The
consistency metrics (NEES, inside the 95 % region) of a localizer that reports no covariance
(``LocalizerSpec.covariance`` false) read ``no covariance`` in every table.
"""

from __future__ import annotations

import csv
import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from agents.common.util import flatten, write_run_record
from agents.evaluate.consistency import NO_COVARIANCE, reports_covariance
from agents.evaluate.episode import rollout
from agents.evaluate.goal import GOAL_NOTE
from agents.evaluate.plugins import Array, MetricInfo, localizer_kind, plugins_for
from agents.evaluate.spec import Cell, EvalSpec
from agents.evaluate.stats import EvalResult, Stat
from agents.rl.config import EVAL_SEED_BASE


# --------------------------------------------------------------------------- TUM trajectories
def yaw_to_quaternion(yaw_rad: ArrayLike) -> Array:
    """``(T, 4)`` quaternions ``(qx, qy, qz, qw)`` of rotations by ``yaw_rad`` about z."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64)
    zero = np.zeros_like(half)
    return np.stack([zero, zero, np.sin(half), np.cos(half)], axis=-1)


def quaternion_to_yaw(q: ArrayLike) -> Array:
    """``(T,)`` yaw in ``(-pi, pi]`` of ``(T, 4)`` quaternions ``(qx, qy, qz, qw)``."""
    qx, qy, qz, qw = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


def write_tum(path: Path, time_s: ArrayLike, poses: ArrayLike, valid: ArrayLike | None = None) -> Path:
    """Write planar poses in TUM format ``timestamp tx ty tz qx qy qz qw`` (z = 0), one row per
    step (only the ``valid`` ones when given), as ``evo`` reads them."""
    t = np.asarray(time_s, dtype=np.float64)
    p = np.asarray(poses, dtype=np.float64)
    keep = np.ones(t.shape[0], dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    q = yaw_to_quaternion(p[keep, 2])
    table = np.column_stack([t[keep], p[keep, 0], p[keep, 1], np.zeros(int(keep.sum())), q])
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        np.savetxt(f, table, fmt="%.6f %.6f %.6f %.1f %.9f %.9f %.9f %.9f")
    return path


def read_tum(path: Path) -> tuple[Array, Array]:
    """Read a planar TUM file: ``(N,)`` timestamps and ``(N, 3)`` poses ``(x, y, yaw)``."""
    table = np.loadtxt(path, comments="#", ndmin=2).reshape(-1, 8)
    return table[:, 0], np.column_stack([table[:, 1], table[:, 2], quaternion_to_yaw(table[:, 4:8])])


# --------------------------------------------------------------------------- tables
def _cell_value(info: MetricInfo, localizer: str, value: Any) -> Any:
    """``value``, or :data:`NO_COVARIANCE` for a consistency metric of a localizer without one."""
    return NO_COVARIANCE if info.covariance and not reports_covariance(localizer) else value


def format_stat(info: MetricInfo, stat: Stat, episodes: int) -> str:
    """``mean [low, high]`` in the metric's format, ``(n/episodes)`` when some episodes had no value."""
    if not math.isfinite(stat.mean):
        return "–"
    text = f"{info.fmt.format(stat.mean)} [{info.fmt.format(stat.low)}, {info.fmt.format(stat.high)}]"
    return text + (f" ({stat.n}/{episodes})" if stat.n < episodes else "")


def summary_markdown(result: EvalResult) -> str:
    """The summary as a markdown table: mean [95% CI] per metric and (policy, localizer, crowd size)."""
    shown = [m for m in result.metrics if m.in_table]
    head = ["policy", "localizer", "crowd", *[m.label for m in shown]]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    nothing = Stat(math.nan, math.nan, math.nan, 0)
    for row in result.summary:
        values = [_cell_value(m, row.localizer, format_stat(m, row.stats.get(m.key, nothing), row.episodes)) for m in shown]
        label = result.spec.policy_label(row.policy)
        lines.append("| " + " | ".join([label, row.localizer, str(row.crowd_size), *values]) + " |")
    return "\n".join(lines)


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    """Write ``header`` and ``rows`` to the CSV file ``path``; return ``path``."""
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def write_tables(result: EvalResult, out_dir: Path) -> dict[str, Path]:
    """Write ``episodes.csv`` (one row per episode), ``summary.csv`` (mean, CI and count per
    metric and group) and ``run.json`` (the resolved conditions and grid, the command line,
    versions and git commit) under ``out_dir`` (created if missing); any subset of a grid will do."""
    out_dir.mkdir(parents=True, exist_ok=True)
    infos = result.metrics
    keys = [m.key for m in infos]
    out: dict[str, Path] = {}
    label = result.spec.policy_label
    ep_rows = [[label(e.cell.policy), e.cell.localizer, e.cell.crowd_size, e.cell.seed, len(e.time_s) - 1,
                *[_cell_value(m, e.cell.localizer, e.metrics.get(m.key, math.nan)) for m in infos]]
               for e in result.episodes]  # fmt: skip
    ep_cols = ["policy", "localizer", "crowd_size", "seed", "steps", *keys]
    out["episodes"] = write_csv(out_dir / "episodes.csv", ep_cols, ep_rows)
    stat_cols = [f"{k}{suffix}" for k in keys for suffix in ("", "_ci_low", "_ci_high", "_n")]
    sum_rows = [[label(r.policy), r.localizer, r.crowd_size, r.episodes,
                 *[_cell_value(m, r.localizer, x) for m in infos
                   for x in (r.stats[m.key].mean, r.stats[m.key].low, r.stats[m.key].high, r.stats[m.key].n)]]
                for r in result.summary]  # fmt: skip
    sum_cols = ["policy", "localizer", "crowd_size", "episodes", *stat_cols]
    out["summary_csv"] = write_csv(out_dir / "summary.csv", sum_cols, sum_rows)
    out["run"] = write_run_record(
        out_dir / "run.json",
        spec=dataclasses.asdict(result.spec),
        policies={label(p): p for p in result.spec.policies},  # the short names of the tables, in full
        episodes=len(result.episodes),
        wall_s=result.wall_s,
    )
    return out


def conditions_text(env_kwargs: Mapping[str, Any]) -> str:
    """``camera.fov_rad=1.5708, prior=none`` for the env overrides of an evaluation, or the defaults."""
    flat = flatten(env_kwargs)
    return ", ".join(f"{key}={value!r}" if isinstance(value, str) else f"{key}={value:g}" if isinstance(value, float) else
                     f"{key}={value}" for key, value in flat.items()) or "the world's own (no overrides)"  # fmt: skip


def _summary_page(result: EvalResult, gif_cell: Cell | None) -> str:
    s = result.spec
    animated = ""
    if gif_cell is not None:
        animated = f"`episode.gif`: {s.policy_label(gif_cell.policy)}, {gif_cell.localizer}, crowd {gif_cell.crowd_size}, seed {gif_cell.seed}."
    notes = "".join(f"{p.note} " for p in plugins_for(localizer_kind(name) for name in s.localizers) if p.note)
    return "\n".join(
        [
            "# crowdloc eval",
            "",
            f"{s.env_id}, {s.episode_steps} steps per episode, {s.seeds} held-out seeds "
            f"({EVAL_SEED_BASE} + {s.first_seed}..{s.first_seed + s.seeds - 1}) per cell, {len(result.episodes)} episodes in {result.wall_s:.0f} s.",
            "",
            f"Conditions: {conditions_text(s.env_kwargs)} (all of them, with the command line and versions, in `run.json`)."
            + (f" Localizer parameters: {conditions_text(s.localizer_params)}." if s.localizer_params else ""),
            "",
            summary_markdown(result),
            "",
            "Mean over seeds [95% percentile-bootstrap CI, "
            f"{s.bootstrap_resamples} resamples]; (k/N): only k of N episodes had a value (the others never had a fix, or, "
            "for the NEES median, an infinite one); –: no value. Errors and failure rate are over the valid steps from the "
            "first fix on; failure: error >= 1 m; NEES: pose error squared over the reported covariance (x, y, heading), "
            "median 2.37 for a consistent localizer; inside 95% region: share of steps with NEES <= 7.815 (about 0.95 if "
            "consistent); singular covariance: share of steps whose covariance is singular, i.e. the localizer claims "
            "certainty along some direction (e.g. its particle set collapsed onto one pose), so any error there has NEES "
            "inf and lies outside the region (more than half such steps make an episode's NEES median inf; there is no NEES "
            "mean, one such step would make it inf); all three over the valid steps with a usable covariance; "
            f"{NO_COVARIANCE}: the localizer reports none; `plots/error_vs_spread.png`: error "
            "against reported spread; availability: share of all steps with a pose; first fix: time and distance travelled from the reset; "
            f"collisions: contact events. {GOAL_NOTE if s.has_goal else ''}{notes}Trajectories (TUM format, for evo): `tum/`. "
            f"{animated}",
            "",
        ]
    )


# --------------------------------------------------------------------------- figures
def plot_summary(result: EvalResult, directory: Path) -> list[Path]:
    """One PNG per metric: mean and CI against crowd size, a line per policy, a panel per localizer."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    s = result.spec
    by_key = {(r.policy, r.localizer, r.crowd_size): r for r in result.summary}
    x = np.arange(len(s.crowd_sizes), dtype=np.float64)
    dodge = 0.25 / max(len(s.policies), 1)
    paths = []
    for info in result.metrics:
        fig, axes = plt.subplots(1, len(s.localizers), figsize=(4.6 * len(s.localizers) + 1.8, 3.6), squeeze=False, sharey=True)
        for ax, loc in zip(axes[0], s.localizers):
            for i, policy in enumerate(s.policies):
                st = [by_key[(policy, loc, c)].stats[info.key] for c in s.crowd_sizes]
                mean = np.array([v.mean for v in st])
                err = np.abs(np.array([[v.mean - v.low for v in st], [v.high - v.mean for v in st]]))
                xs = x + (i - (len(s.policies) - 1) / 2) * dodge
                ax.errorbar(xs, mean, yerr=err, marker="o", ms=4, capsize=3, label=s.policy_label(policy))
            ax.set_xticks(x, [str(c) for c in s.crowd_sizes])
            ax.set_xlim(-0.5, len(x) - 0.5)
            ax.set_xlabel("crowd size")
            ax.set_title(loc, fontsize=9)
            ax.grid(alpha=0.3)
            if info.covariance and not reports_covariance(loc):
                ax.text(0.5, 0.5, NO_COVARIANCE, transform=ax.transAxes, ha="center", va="center", color="0.4")
        axes[0, 0].set_ylabel(info.label)
        axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
        fig.suptitle(f"{info.label}: mean and 95% bootstrap CI over {s.seeds} seeds", fontsize=10)
        fig.tight_layout()
        path = directory / f"{info.key}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_error_vs_spread(result: EvalResult, path: Path, max_points: int = 4000) -> Path:
    """Each valid step's position error against the reported position spread (sqrt of the trace of
    the position covariance), a panel per localizer, every policy, crowd size and seed pooled.

    The lines ``error = spread`` and ``error = 2 spread`` are the 1 and 2 sd lines of a consistent
    localizer (the trace is the expected squared position error): most of its points lie below
    the second, an overconfident one's above. At most ``max_points`` evenly spaced steps per
    localizer are drawn, the x axis spanning the 1 % quantile to the largest spread; a localizer
    that reports no covariance gets an empty panel saying so.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.common.plots import log_ticks, save_figure

    s = result.spec
    fig, axes = plt.subplots(1, len(s.localizers), figsize=(4.2 * len(s.localizers), 3.9), squeeze=False)
    for ax, loc in zip(axes[0], s.localizers):
        ax.set_title(loc, fontsize=9)
        ax.set_xlabel("reported spread [m]")
        ax.grid(alpha=0.3)
        if not reports_covariance(loc):
            ax.text(0.5, 0.5, NO_COVARIANCE, transform=ax.transAxes, ha="center", va="center", color="0.4")
            continue
        eps = [e for e in result.episodes if e.cell.localizer == loc]
        spread = np.concatenate([e.position_spreads_m for e in eps]) if eps else np.zeros(0)
        error = np.concatenate([e.position_errors for e in eps]) if eps else np.zeros(0)
        keep = np.isfinite(spread) & np.isfinite(error) & (spread > 0)
        spread, error = spread[keep], error[keep]
        if spread.size == 0:
            ax.text(0.5, 0.5, "no step with a reported spread", transform=ax.transAxes, ha="center", va="center", color="0.4")
            continue
        if spread.size > max_points:
            pick = np.linspace(0, spread.size - 1, max_points).astype(int)
            spread, error = spread[pick], error[pick]
        ax.scatter(spread, np.maximum(error, 1e-4), s=4, alpha=0.3, lw=0, label="steps")
        lo, hi = float(np.quantile(spread, 0.01)), float(spread.max())  # a degenerate step or two would stretch the axis
        line = np.geomspace(lo, hi, 50) if hi > lo else np.array([lo, hi])
        ax.set_xlim(0.8 * lo, 1.25 * hi)
        ax.plot(line, line, "k-", lw=1, label="error = spread (1 sd)")
        ax.plot(line, 2 * line, "k--", lw=1, label="error = 2 x spread (2 sd)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        log_ticks(ax)  # matplotlib labels the minor ticks of a short log axis, one over the other
        ax.legend(fontsize=7, loc="upper left")
    axes[0, 0].set_ylabel("position error [m]")
    return save_figure(fig, path, "position error against reported spread, every valid step")


def render_gif(spec: EvalSpec, cell: Cell, path: Path, max_frames: int = 150, every: int = 3) -> Path:
    """Replay ``cell`` with ``rgb_array`` rendering (estimate and the localizer's
    hypotheses drawn by the wrapper) and save an animated GIF of every ``every``-th step,
    thinned further to at most ``max_frames`` frames, playing in real time."""
    from PIL import Image

    every = max(every, math.ceil((spec.episode_steps + 1) / max_frames))
    played = rollout(spec, cell, frame_every=every)
    frames = played.frames
    # one palette for the whole clip, from a few frames spread over it (fast, no flicker)
    sample = np.concatenate([frames[i] for i in np.linspace(0, len(frames) - 1, min(8, len(frames))).astype(int)])
    palette = Image.fromarray(sample).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    duration = max(20, round(1000 * every * played.context.dt_s))
    images[0].save(path, save_all=True, append_images=images[1:], duration=duration, loop=0)
    return path


#: what ``crowdloc eval`` writes in its output folder (glob patterns; :func:`write_outputs` and the
#: run's journal): ``--overwrite`` deletes these and nothing else
EVAL_OUTPUTS = (
    "episodes.csv",
    "summary.csv",
    "summary.md",
    "run.json",
    "episode.gif",
    "episodes.jsonl",
    "verdict.md",
    "verdict.csv",
    "plots/*.png",
    "tum/*.tum",
)


def write_outputs(result: EvalResult, out_dir: Path, *, gif_cell: Cell | None = None, gif: bool = True) -> dict[str, Path]:
    """Write the CSV tables, ``summary.md``, the plots, TUM trajectories and a GIF under ``out_dir``.

    Args:
        result: from :func:`agents.evaluate.evaluate`.
        out_dir: created if missing.
        gif_cell: the episode to animate (default: the first cell).
        gif: whether to render the GIF at all.

    Returns:
        Name -> path of what was written (``episodes``, ``summary_csv``, ``run``, ``summary_md``,
        ``plots`` (with ``error_vs_spread.png``), ``tum``, and ``gif``: ``episode.gif``).
    """
    if gif:
        gif_cell = gif_cell or result.episodes[0].cell
    out = write_tables(result, out_dir)
    out["summary_md"] = out_dir / "summary.md"
    out["summary_md"].write_text(_summary_page(result, gif_cell if gif else None))
    out["plots"] = out_dir / "plots"
    plot_summary(result, out["plots"])
    plot_error_vs_spread(result, out["plots"] / "error_vs_spread.png")
    out["tum"] = out_dir / "tum"
    out["tum"].mkdir(exist_ok=True)
    for e in result.episodes:
        stem = e.cell.stem(result.spec.policy_label(e.cell.policy))
        write_tum(out["tum"] / f"{stem}_estimate.tum", e.time_s, e.estimates, e.valid)
        write_tum(out["tum"] / f"{stem}_groundtruth.tum", e.time_s, e.true_pose)
    if gif and gif_cell is not None:
        out["gif"] = render_gif(result.spec, gif_cell, out_dir / "episode.gif")
    return out
