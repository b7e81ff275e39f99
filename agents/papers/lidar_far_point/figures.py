"""The report's figures: the paper's Figs 5, 7, 8, 10 and 11, the crowd-size sweep, example trajectories."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from agents.common import plots

from . import world
from .analysis import DensityRow, Stats, StatsTable
from .experiment import CROWD_SIZE, VARIANTS, Pair, Plan, both, density_note, hit_params, sampling_params
from .jobs import Episode, Run
from .paper import FAIL_M, HIT_SWEEP_SAMPLING, HIT_THRESHOLD, REFERENCE_LIDAR_HEIGHT_M, SAMPLING_THRESHOLD

Series = dict[str, tuple[np.ndarray, np.ndarray]]


def _series(stats: dict[tuple[bool, str], Sequence[Stats]]) -> tuple[Series, Series]:
    """Per (variant, measure): (mean error, its sd) and (failures per run, their sd over the runs)."""
    err: Series = {}
    fail: Series = {}
    for (far, against), ss in stats.items():
        label = f"{VARIANTS[far]}, vs {against}"
        err[label] = (np.array([s.mean_m for s in ss]), np.array([s.sd_m for s in ss]))
        fail[label] = (np.array([s.failures for s in ss]), np.array([s.failures_sd for s in ss]))
    return err, fail


def sweep_figures(out: Path, plan: Plan, st: StatsTable, st_ref: StatsTable) -> dict[str, Path]:
    """Figs 7 and 8 (sampling), 10 and 11 (hit): error and failures per run against the swept value,
    measured against the reference (the paper's) and against the truth."""
    figs: dict[str, Path] = {}
    sweeps: tuple[tuple[str, list[tuple[float, Pair]], str, str, str], ...] = (
        ("sampling", plan.sampling_configs(), "sampling parameter", "Fig. 7", "Fig. 8"),
        ("hit", plan.hit_configs(), f"hit (sd of the hit Gaussian) [m], sampling {HIT_SWEEP_SAMPLING}", "Fig. 10", "Fig. 11"),
    )
    for name, points, xlabel, fig_e, fig_f in sweeps:
        xs = [x for x, _ in points]
        err, fail = _series({(far, against): [table[pair[int(far)].key, CROWD_SIZE] for _, pair in points]
                             for against, table in (("reference", st_ref), ("truth", st)) for far in (False, True)})  # fmt: skip
        n = st[points[0][1][0].key, CROWD_SIZE]
        figs[f"{name}_error"] = plots.errorbar_sweep(
            out / f"{name}_error.png", xs, err, xlabel=xlabel, ylabel="position error [m]",
            title=f"{fig_e}: mean position error ± sd over all estimates ({n.runs} runs x {n.estimates} estimates)",
        )  # fmt: skip
        figs[f"{name}_failures"] = plots.errorbar_sweep(
            out / f"{name}_failures.png", xs, fail, xlabel=xlabel, ylabel=f"failures (error >= {FAIL_M:g} m) per run",
            title=f"{fig_f}: failures per run of {n.estimates} estimates (mean ± sd over {n.runs} runs)",
        )  # fmt: skip
    return figs


def density_figures(out: Path, rows: Sequence[DensityRow]) -> dict[str, Path]:
    """Error and failures per run against the crowd size."""
    people = [r.people for r in rows]
    err, fail = _series({(far, against): [r.variant(far, against) for r in rows]
                         for against in ("reference", "truth") for far in (False, True)})  # fmt: skip
    return {
        "density_error": plots.errorbar_sweep(out / "density_error.png", people, err, xlabel="people in the queues",
                                              ylabel="position error [m]",
                                              title=f"Crowd size ({density_note()}): mean error ± sd"),
        "density_failures": plots.errorbar_sweep(out / "density_failures.png", people, fail, xlabel="people in the queues",
                                                 ylabel=f"failures (>= {FAIL_M:g} m) per run",
                                                 title="Crowd size: failures per run (mean ± sd over runs)"),
    }  # fmt: skip


def snapshot_figure(out: Path, episodes: Sequence[Episode]) -> dict[str, Path]:
    """Fig. 5: one raw scan, the accumulated window and its far points (empty without a snapshot)."""
    ep = next((ep for ep in episodes if ep.snapshot is not None), None)
    if ep is None or ep.snapshot is None:
        return {}
    sn = ep.snapshot
    travel = world.far_point_defaults().filter.travel_m
    fov_deg = math.degrees(world.lidar().fov_rad)
    path = plots.scan_snapshot(
        out / "far_points.png", ep.scan_map.walls_m, sn.pose,
        {"one raw scan": sn.raw_xy, f"accumulated over the last {travel:g} m": sn.accumulated_xy,
         f"far points, every bin (MCL reads {fov_deg:g} deg)": sn.far_xy},
        people_xy=sn.people_xy, people_radius_m=sn.people_radius_m,
        title=f"Fig. 5: seed {ep.task.seed}, t = {ep.recording.time_s[sn.step]:.1f} s, {ep.task.crowd_size} "
        "people (green); points placed in the world frame by the true pose",
    )  # fmt: skip
    return {"far_points": path}


def trajectory_figure(out: Path, runs: Sequence[Run], episodes: Sequence[Episode]) -> dict[str, Path]:
    """The paper's Figs 6 and 9 for our first seed: both variants where raw MCL is said to degrade, and the reference."""
    ep0 = min((ep for ep in episodes if ep.task.crowd_size == CROWD_SIZE), key=lambda e: e.task.seed)
    estimates: dict[str, np.ndarray] = {}
    for label, params in ((f"sampling {SAMPLING_THRESHOLD:g}", sampling_params(SAMPLING_THRESHOLD)),
                          (f"hit {HIT_THRESHOLD:g}", hit_params(HIT_THRESHOLD))):  # fmt: skip
        for c in both(params):
            r = next((r for r in runs if r.key == c.key and r.seed == ep0.task.seed and r.crowd_size == CROWD_SIZE), None)
            if r is not None:
                estimates[f"{c.variant}, {label}"] = r.estimates
    if not estimates:
        return {}
    estimates[f"reference ({REFERENCE_LIDAR_HEIGHT_M:g} m LIDAR)"] = ep0.reference_estimates
    xmin, ymin, xmax, ymax = ep0.recording.landmark_map.bounds_m
    path = plots.trajectory_panels(
        out / "trajectories.png", ep0.recording.true_pose, estimates, np.zeros((0, 2)), (), (xmax - xmin, ymax - ymin),
        title=f"Seed {ep0.task.seed}: true path (black) and the estimate at each update (red), as the paper's Figs 6 and 9",
        cols=2,
    )  # fmt: skip
    return {"trajectories": path}


def make_figures(out: Path, plan: Plan, st: StatsTable, runs: Sequence[Run], episodes: Sequence[Episode],
                 rows: Sequence[DensityRow], st_ref: StatsTable) -> dict[str, Path]:  # fmt: skip
    """Every figure of the report, by name, written into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    return {
        **sweep_figures(out, plan, st, st_ref), **density_figures(out, rows), **snapshot_figure(out, episodes),
        **trajectory_figure(out, runs, episodes),
    }  # fmt: skip
