"""Figures for the reproduction reports (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

Array = NDArray[np.float64]


def save_figure(fig: Any, path: Path, title: str | None = None) -> Path:
    """Give ``fig`` its title, lay it out, write it to ``path`` and close it; returns ``path``."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def log_ticks(ax: Any, axis: str = "both") -> None:
    """Readable ticks on log-scaled axes (call after the limits are set): labels only at 1, 2 and 5 times
    a power of ten when the axis spans less than two decades, else at the powers of ten only, written
    as plain numbers (0.02, not 2 x 10^-2), and no labels at the minor ticks. Matplotlib's own choice
    labels the minor ticks of a short log axis, and their labels run into each other."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for name in ("x", "y") if axis == "both" else (axis,):
        which = ax.xaxis if name == "x" else ax.yaxis
        lo, hi = sorted(ax.get_xlim() if name == "x" else ax.get_ylim())
        decades = math.log10(hi / lo) if lo > 0 else math.inf
        which.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0) if decades < 2.0 else (1.0,)))
        which.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        which.set_minor_locator(LogLocator(base=10.0, subs=tuple(float(k) for k in range(2, 10))))
        which.set_minor_formatter(NullFormatter())


def trajectory_panels(
    path: Path,
    truth: Array,
    estimates: Mapping[str, Array],
    landmarks_xy: Array,
    landmark_names: Sequence[str],
    field_m: tuple[float, float],
    *,
    used: Mapping[str, Sequence[int] | None] | None = None,
    first_fix: Mapping[str, int | None] | None = None,
    vertices: Mapping[str, tuple[float, float]] | None = None,
    title: str = "",
    cols: int = 3,
) -> Path:
    """One panel per method: the true path, the method's estimates, the landmarks.

    Args:
        path: PNG to write.
        truth: ``(T, 3)`` true poses.
        estimates: method label -> ``(T, 3)`` estimates (NaN rows: no pose, not drawn).
        landmarks_xy: ``(L, 2)``; ``landmark_names``: their names.
        field_m: ``(width, height)`` of the field, drawn as a rectangle from the origin.
        used: label -> landmark ids the method used (others drawn hollow); ``None``: all.
        first_fix: label -> step of its first pose (marked with a star).
        vertices: named path corners to annotate (Exp 1).
        title: figure title.
        cols: panels per row.
    """
    labels = list(estimates)
    cols = min(cols, len(labels))
    rows = math.ceil(len(labels) / cols)
    w, h = field_m
    panel_h = 4.0 * min(2.0, h / w) if w else 4.0
    fig, axes = plt.subplots(rows, cols, figsize=(4.0 * cols, panel_h * rows + 0.6), squeeze=False)
    for ax in axes.ravel()[len(labels) :]:
        ax.set_visible(False)
    for ax, label in zip(axes.ravel(), labels):
        est = estimates[label]
        ax.add_patch(plt.Rectangle((0, 0), w, h, fill=False, color="0.6", lw=1))
        ax.plot(truth[:, 0], truth[:, 1], color="0.2", lw=1.2, label="true path")
        ax.plot(est[:, 0], est[:, 1], ".", ms=1.5, color="tab:red", label="estimate")
        ids = None if used is None else used.get(label)
        for j, ((x, y), name) in enumerate(zip(landmarks_xy, landmark_names)):
            on = ids is None or j in ids
            ax.plot(x, y, "^", ms=7, mfc="tab:blue" if on else "white", mec="tab:blue")
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(3, -10), fontsize=7, color="tab:blue")
        if vertices:
            for name, (x, y) in vertices.items():
                ax.annotate(name, (x, y), textcoords="offset points", xytext=(-8, 3), fontsize=8, color="0.3")
        ff = None if first_fix is None else first_fix.get(label)
        if ff is not None and np.isfinite(est[ff]).all():
            ax.plot(est[ff, 0], est[ff, 1], "*", ms=11, color="tab:orange", label="first fix")
        ax.set_xlim(-0.3, w + 0.3)
        ax.set_ylim(-0.3, h + 0.3)
        ax.set_aspect("equal")
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("y [m]", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, loc="lower left")
    return save_figure(fig, path, title)


def sweep_figure(
    path: Path,
    x: Sequence[float],
    xlabel: str,
    error_mm: Mapping[str, tuple[Array, Array]],
    avail: Mapping[str, tuple[Array, Array]],
    *,
    title: str = "",
    log_error: bool = True,
) -> Path:
    """Error and availability against a swept setting, one line per method.

    Args:
        path: PNG to write.
        x: swept values.
        xlabel: axis label.
        error_mm: label -> (mean over seeds, sd over seeds) of the mean position error.
        avail: label -> (mean, sd) of the availability (share of steps with a pose).
        title: figure title.
        log_error: log scale for the error axis.
    """
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    xs = np.asarray(x, dtype=np.float64)
    for label, (m, s) in error_mm.items():
        ax1.errorbar(xs, m, yerr=s, marker="o", ms=4, capsize=3, label=label)
    for label, (m, s) in avail.items():
        ax2.errorbar(xs, 100 * np.asarray(m), yerr=100 * np.asarray(s), marker="o", ms=4, capsize=3, label=label)
    ax1.set_xlabel(xlabel)
    ax1.set_ylabel("mean position error [mm]")
    if log_error:
        ax1.set_yscale("log")
    ax2.set_xlabel(xlabel)
    ax2.set_ylabel("availability [% of steps with a pose]")
    ax2.set_ylim(-3, 103)
    ax1.grid(alpha=0.3)
    ax2.grid(alpha=0.3)
    ax1.legend(fontsize=7)
    return save_figure(fig, path, title)


def recovery_figure(
    path: Path,
    t_rel_s: Array,
    curves: Mapping[str, tuple[Array, Array, Array]],
    threshold_m: float,
    push_s: float,
    *,
    title: str = "",
) -> Path:
    """Position error against time around a push, one panel per method (median and quartiles over seeds).

    Args:
        path: PNG to write.
        t_rel_s: ``(n,)`` time relative to the start of the push.
        curves: label -> (median, 25th, 75th percentile) of the error in metres, each ``(n,)``.
        threshold_m: the recovery threshold, drawn dashed.
        push_s: how long the push lasts (shaded). The first panel's legend names the line, the
            band, the threshold and the shading.
        title: figure title.
    """
    labels = list(curves)
    cols = min(3, len(labels))
    rows = math.ceil(len(labels) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.0 * rows + 0.5), squeeze=False, sharey=True)
    for ax in axes.ravel()[len(labels) :]:
        ax.set_visible(False)
    for ax, label in zip(axes.ravel(), labels):
        med, lo, hi = curves[label]
        ax.axvspan(0.0, push_s, color="tab:orange", alpha=0.15, lw=0, label=f"the push ({push_s:g} s)")
        ax.fill_between(t_rel_s, lo, hi, color="tab:blue", alpha=0.25, lw=0, label="25-75 % of the seeds")
        ax.plot(t_rel_s, med, color="tab:blue", lw=1.2, label="median error")
        ax.axhline(threshold_m, color="0.3", ls="--", lw=0.8, label=f"recovered: error < {threshold_m:g} m")
        ax.set_yscale("log")
        ax.set_ylim(5e-3, 5.0)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("time since the push starts [s]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("position error [m]", fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    return save_figure(fig, path, title)


def errorbar_sweep(
    path: Path,
    x: Sequence[float],
    series: Mapping[str, tuple[Array, Array]],
    *,
    xlabel: str,
    ylabel: str,
    title: str = "",
    reference: Mapping[str, float] | None = None,
) -> Path:
    """One statistic against a swept parameter, one line with error bars per variant.

    Args:
        path: PNG to write.
        x: swept values.
        series: label -> ``(values, error bar half-widths)``, each ``(len(x),)``.
        xlabel, ylabel: axis labels.
        title: figure title.
        reference: label -> y of a horizontal dashed line (a threshold).
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    xs = np.asarray(x, dtype=np.float64)
    n = max(len(series), 1)
    step = float(np.min(np.diff(xs))) if xs.size > 1 else 1.0
    for k, (label, (m, s)) in enumerate(series.items()):
        shift = (k - (n - 1) / 2) * 0.08 * step  # side by side, so that the error bars stay readable
        ax.errorbar(xs + shift, m, yerr=s, marker="o", ms=4, capsize=3, label=label)
    for label, y in (reference or {}).items():
        ax.axhline(y, color="0.4", ls="--", lw=0.8, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_xticks(xs)
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    return save_figure(fig, path)


def scan_snapshot(
    path: Path,
    walls_m: Array,
    robot_pose: Array,
    layers: Mapping[str, Array],
    *,
    people_xy: Array | None = None,
    people_radius_m: float = 0.0,
    title: str = "",
) -> Path:
    """Point sets over the static map in the world frame, one panel per layer (Fig. 5 of the far-point paper).

    Args:
        path: PNG to write.
        walls_m: ``(S, 4)`` wall segments ``(x1, y1, x2, y2)``.
        robot_pose: ``(3,)`` the robot's pose (drawn as an arrow).
        layers: panel title -> ``(m, 2)`` points.
        people_xy: ``(P, 2)`` crowd members at that moment (drawn as circles), or None.
        people_radius_m: their radius.
        title: figure title.
    """
    names = list(layers)
    fig, axes = plt.subplots(1, len(names), figsize=(4.3 * len(names), 4.6), squeeze=False)
    lo = float(min(walls_m[:, [0, 2]].min(), walls_m[:, [1, 3]].min())) - 0.3
    hi = float(max(walls_m[:, [0, 2]].max(), walls_m[:, [1, 3]].max())) + 0.3
    for ax, name in zip(axes[0], names):
        for x1, y1, x2, y2 in walls_m:
            ax.plot([x1, x2], [y1, y2], color="0.55", lw=2.0, zorder=1)
        if people_xy is not None:
            for px, py in people_xy:
                ax.add_patch(plt.Circle((px, py), people_radius_m, fill=False, color="tab:green", lw=0.8, zorder=2))
        pts = layers[name]
        ax.plot(pts[:, 0], pts[:, 1], ".", ms=1.0 if pts.shape[0] > 5000 else 2.0, color="tab:red", zorder=3)
        x, y, th = (float(v) for v in robot_pose)
        ax.arrow(x, y, 0.35 * math.cos(th), 0.35 * math.sin(th), width=0.04, color="tab:blue", zorder=4)
        ax.set_xlim(lo, hi)
        ax.set_ylim(lo, hi)
        ax.set_aspect("equal")
        ax.set_title(f"{name} ({pts.shape[0]} points)", fontsize=9)
        ax.set_xlabel("x [m]", fontsize=8)
        ax.set_ylabel("y [m]", fontsize=8)
        ax.tick_params(labelsize=7)
    return save_figure(fig, path, title)


def learning_curves_figure(csv_path: Path, path: Path, title: str) -> Path:
    """One line per training run from a ``run,step,ep_rew_mean`` CSV (the mean training return of the
    last 100 episodes, read from the runs' TensorBoard logs), in the order the runs first appear."""
    import csv

    runs: dict[str, list[tuple[float, float]]] = {}
    with csv_path.open(newline="") as handle:
        rows = csv.DictReader(handle)
        if rows.fieldnames != ["run", "step", "ep_rew_mean"]:
            raise ValueError(f"{csv_path}: columns must be run,step,ep_rew_mean, got {rows.fieldnames}")
        for row in rows:
            runs.setdefault(row["run"], []).append((float(row["step"]), float(row["ep_rew_mean"])))
    fig, ax = plt.subplots(figsize=(7.2, 3.8))
    for run, points in runs.items():
        steps, returns = zip(*sorted(points), strict=True)
        ax.plot(steps, returns, lw=1.4, label=run)
    ax.set_xlabel("env steps")
    ax.set_ylabel("mean training return (last 100 episodes)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title(title, fontsize=10)
    return save_figure(fig, path)
