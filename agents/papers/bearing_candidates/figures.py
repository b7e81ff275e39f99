"""Figures of the candidate-set reproduction (:mod:`agents.common.plots`): the trajectory panels of
Exp 1 and 2 (the paper's Figs 12-16, 20-24) for the lowest seed, and the extra studies."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from agents.evaluate import metrics
from agents.papers.bearing_candidates.analysis import Analysis, PushStudy, SweepStudy, by_study
from agents.papers.bearing_candidates.jobs import (
    EXP1_FIGURE,
    EXP1_METHODS,
    EXP2_TABLE_METHODS,
    PUSH_SECONDS,
    RECOVER_M,
    SWEEP_METHODS,
    SWEEP_WARMUP_S,
    JobResult,
    Method,
)

Array = NDArray[np.float64]

#: study -> (its name, methods with a panel, what the panels show, panels per row)
TRAJECTORIES: dict[str, tuple[str, tuple[Method, ...], str, int]] = {
    "exp1": ("Exp 1", EXP1_METHODS[:EXP1_FIGURE], "true path (black) and estimates (red), first fix of each method (star)", 4),
    "exp2": ("Exp 2", EXP2_TABLE_METHODS, "true path (black) and estimates (red)", 3),
}
SWEEP_XLABELS = {
    "density": "crowd size (robots on the field besides ours)",
    "false": "false-detection probability per landmark slot and frame",
}


def trajectory_figure(out: Path, study: str, runs: Sequence[JobResult]) -> Path:
    """One panel per method along the lowest seed's true path."""
    from agents.common import plots
    from agents.policies.paths import EXP1_VERTICES

    name, methods, shows, cols = TRAJECTORIES[study]
    r = min(runs, key=lambda x: x.job.seed)
    return plots.trajectory_panels(
        out / f"{study}_trajectories.png",
        r.truth,
        {m.label: r.runs[m.key].estimates for m in methods},
        r.landmarks_xy,
        r.landmark_names,
        r.field_m,
        used={m.label: m.landmarks for m in methods},
        first_fix={m.label: metrics.first_fix(r.runs[m.key].valid) for m in methods},
        vertices=EXP1_VERTICES if study == "exp1" else None,
        title=f"{name} (seed {r.job.seed}): {shows}",
        cols=cols,
    )


def sweep_figure(out: Path, study: str, sweep: SweepStudy) -> Path:
    """Error and availability against the swept value, with sd-over-seeds bars."""
    from agents.common import plots

    def series(pick: str) -> dict[str, tuple[Array, Array]]:
        """label -> (seed mean, sd over seeds) of the cells' ``err`` or ``avail`` along the points."""
        out = {}
        for m in SWEEP_METHODS:
            values = np.array([getattr(sweep.cells[m.key][p], pick)[:2] for p in sweep.points], dtype=np.float64)
            out[m.label] = (values[:, 0], values[:, 1])
        return out

    return plots.sweep_figure(out / f"{study}_sweep.png", sweep.points, SWEEP_XLABELS[study], series("err"), series("avail"),
                              title=f"{study}: mean position error and availability (t >= {SWEEP_WARMUP_S:.0f} s)")  # fmt: skip


def push_figure(out: Path, push: PushStudy) -> Path:
    """The error around the shove, median and quartiles over the seeds."""
    from agents.common import plots

    return plots.recovery_figure(
        out / "push_recovery.png",
        push.t_rel,
        {m.label: push.stats[m.key].curve for m in SWEEP_METHODS},
        RECOVER_M,
        PUSH_SECONDS,
        title=f"Position error around a shove (median and quartiles over the {push.seeds} seeds with a pose at that time)",
    )


def make_figures(out: Path, results: Sequence[JobResult], analysis: Analysis) -> dict[str, Path]:
    """Every figure of the studies that ran, by study name."""
    out.mkdir(parents=True, exist_ok=True)
    by = by_study(results)
    figs = {study: trajectory_figure(out, study, by[study]) for study in TRAJECTORIES if by[study]}
    for study, sweep in (("density", analysis.density), ("false", analysis.false)):
        if sweep:
            figs[study] = sweep_figure(out, study, sweep)
    if analysis.push:
        figs["push"] = push_figure(out, analysis.push)
    return figs
