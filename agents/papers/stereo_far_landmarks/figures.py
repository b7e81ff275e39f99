"""The report's figures: the paper's Figs 8-10, the detections along the route, the crowd-size sweep."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Polygon
from matplotlib.ticker import MultipleLocator

from agents.common import plots

from . import paper, world
from .analysis import Profile, Table, difference_m, errors_m
from .experiment import FAIL_M, KEYS, LABELS, PAPER_SELECTION, REFERENCE_KEY, Plan, places
from .jobs import Episode

#: the paper's colours (Figs 8-9: its method yellow, amcl purple), the other selections beside
COLOURS = {"farthest": "#e0b000", "all": "#2a7ab0", "nearest": "#3a9a50", REFERENCE_KEY: "#8040a0"}


def _paper_runs(episodes: Sequence[Episode], crowd: int) -> list[Episode]:
    return sorted((ep for ep in episodes if ep.crowd_size == crowd), key=lambda e: e.seed)


def fig10(out: Path, episodes: Sequence[Episode], crowd: int) -> Path:
    """Fig. 10: the distance between far_landmark_pf's estimate and the reference over time (every
    run, the first bold), and beyond the paper both errors against the truth."""
    runs = _paper_runs(episodes, crowd)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for i, ep in enumerate(runs):
        bold = i == 0
        top.plot(ep.time_s, difference_m(ep, PAPER_SELECTION), color=COLOURS[PAPER_SELECTION] if bold else "0.6",
                 lw=1.6 if bold else 0.7, zorder=3 if bold else 2, label=f"seed {ep.seed}" if bold else None)  # fmt: skip
        for key in (PAPER_SELECTION, REFERENCE_KEY):
            bottom.plot(ep.time_s, errors_m(ep, key), color=COLOURS[key], lw=1.2 if bold else 0.5, alpha=1.0 if bold else 0.5,
                        label=LABELS[key] if bold else None)  # fmt: skip
    top.axhline(
        paper.MAX_DIFFERENCE_M, color="k", ls="--", lw=1, label=f"the paper's maximum, about {paper.MAX_DIFFERENCE_M:g} m"
    )
    top.set_ylabel("distance to the LIDAR reference [m]")
    top.set_title(f"Fig. 10: far_landmark_pf (farthest) vs the LIDAR reference, {len(runs)} runs (other seeds grey)", fontsize=9)
    top.legend(fontsize=8)
    bottom.axhline(FAIL_M, color="r", ls=":", lw=1, label=f"failure ({FAIL_M:g} m)")
    bottom.set_ylabel("position error vs truth [m]")
    bottom.set_xlabel("time [s]")
    bottom.set_title("beyond the paper: both against the true pose (first seed bold)", fontsize=9)
    bottom.legend(fontsize=8)
    path = out / "fig10_difference.png"
    return plots.save_figure(fig, path, f"crowd of {crowd} (the world's), the paper's run 2")


def _window(lo_m: float, hi_m: float, margin_m: float = 3.0) -> tuple[float, float, float, float]:
    """A square around the route between two arc lengths, with a margin."""
    r, arc = world.route(), world.route_arc()
    s = np.linspace(lo_m, min(hi_m, arc[-1]), 60)
    xy = np.stack([np.interp(s, arc, r[:, 0]), np.interp(s, arc, r[:, 1])], axis=1)
    (x0, y0), (x1, y1) = xy.min(axis=0), xy.max(axis=0)
    half = 0.5 * max(x1 - x0, y1 - y0) + margin_m  # square: the grid's cells stay square on a page
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    return float(cx - half), float(cx + half), float(cy - half), float(cy + half)


def trajectory(out: Path, episodes: Sequence[Episode], crowd: int, place: int) -> Path:
    """Figs 8-9: the reference's and far_landmark_pf's trajectories near one of the paper's places,
    one mark a second on a 1 m grid (the first seed at the paper's crowd), the truth beside."""
    name, lo, hi = places()[place]
    ep = _paper_runs(episodes, crowd)[0]
    x0, x1, y0, y1 = _window(lo, hi)
    fig, ax = plt.subplots(figsize=(8, 8.4))
    for _, footprint in world.buildings():
        ax.add_patch(Polygon(footprint, closed=True, fc="0.85", ec="0.5", lw=0.8))
    r = world.route()
    ax.plot(r[:, 0], r[:, 1], color="0.75", lw=6, solid_capstyle="round", zorder=1, label="the route")
    inside = (ep.arc_m >= lo) & (ep.arc_m <= hi)
    dt = float(np.median(np.diff(ep.time_s)))
    every = max(1, round(paper.PLOT_PERIOD_S / dt))
    marks = np.zeros(ep.steps, dtype=bool)
    marks[::every] = True
    ax.plot(ep.truth[inside, 0], ep.truth[inside, 1], color="k", lw=0.8, zorder=2, label="true path (beyond the paper)")
    for key, marker in ((REFERENCE_KEY, "s"), (PAPER_SELECTION, "o")):
        e = ep.estimates[key][inside & marks]
        ax.plot(e[:, 0], e[:, 1], marker, ms=4, color=COLOURS[key], ls="none", zorder=3, label=f"{LABELS[key]}, one a second")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.xaxis.set_major_locator(MultipleLocator(5 * paper.PLOT_GRID_M))
    ax.yaxis.set_major_locator(MultipleLocator(5 * paper.PLOT_GRID_M))
    ax.xaxis.set_minor_locator(MultipleLocator(paper.PLOT_GRID_M))
    ax.yaxis.set_minor_locator(MultipleLocator(paper.PLOT_GRID_M))
    ax.grid(True, which="both", lw=0.3, color="0.8")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if not inside.any():
        ax.text(0.5, 0.5, "not reached in this run", transform=ax.transAxes, ha="center")
    ax.legend(fontsize=7, loc="best")
    figure = 8 + place
    path = out / f"fig{figure}_place{place + 1}.png"
    return plots.save_figure(fig, path, f"Fig. {figure}: {name}, arc {lo:.0f}-{hi:.0f} m, seed {ep.seed}, crowd {crowd}")


def detections_figure(out: Path, prof: Profile, crowd: int, slots: int, sectors: int) -> Path:
    """The detections a frame along the route and the errors beside them (the paper's weak spot)."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    top.plot(prof.arc_m, prof.detections, color="0.3", label=f"matched edges a frame (the camera keeps at most {slots})")
    top.plot(prof.arc_m, prof.far_detections, color="#2a7ab0", label="of them at least 3 m away")
    top.set_ylabel("detections a frame")
    top.set_ylim(0, slots * 1.05)
    twin = top.twinx()
    twin.plot(prof.arc_m, prof.used, color=COLOURS[PAPER_SELECTION], label=f"weighed by far emphasis (at most {sectors} sectors)")
    twin.set_ylim(0, sectors + 0.5)
    twin.set_ylabel("weighed a frame")
    lines = top.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    top.legend(lines[0] + more[0], lines[1] + more[1], fontsize=8, loc="lower left")
    for key in KEYS:
        bottom.plot(prof.arc_m, prof.error_m[key], color=COLOURS[key], label=f"{LABELS[key]} vs truth")
    bottom.plot(
        prof.arc_m,
        prof.difference_m,
        color=COLOURS[PAPER_SELECTION],
        ls="--",
        label="farthest vs the reference (Fig. 10's measure)",
    )
    a, b = world.turn_arc_m()
    for ax in (top, bottom):
        ax.axvspan(a, b, color="0.9", zorder=0)
    bottom.set_xlabel("arc length along the route [m] (grey: the right turn)")
    bottom.set_ylabel("mean position error [m]")
    bottom.legend(fontsize=7)
    return plots.save_figure(fig, out / "detections_route.png", f"Detections and errors along the route, crowd {crowd}, "
                             "means over every run per metre")  # fmt: skip


def crowd_figures(out: Path, table: Table) -> dict[str, Path]:
    """Error and failed or lost share against the crowd size, every localizer."""
    crowds = sorted({n for _, n in table})
    err = {LABELS[k]: (np.array([table[k, n].mean_m for n in crowds]), np.array([table[k, n].seed_sd_m for n in crowds]))
           for k in KEYS}  # fmt: skip
    bad = {LABELS[k]: (100 * np.array([table[k, n].bad_share for n in crowds]), np.zeros(len(crowds))) for k in KEYS}
    return {
        "crowd_error": plots.errorbar_sweep(out / "crowd_error.png", crowds, err, xlabel="crowd (pedestrians and cars)",
                                            ylabel="position error vs truth [m]",
                                            title="Mean position error (mean of the runs' means ± sd over seeds)"),
        "crowd_failures": plots.errorbar_sweep(out / "crowd_failures.png", crowds, bad, xlabel="crowd (pedestrians and cars)",
                                               ylabel=f"steps failed (>= {FAIL_M:g} m) or lost [%]",
                                               title="Failed or lost steps, over every step of every run"),
    }  # fmt: skip


def make_figures(out: Path, plan: Plan, episodes: Sequence[Episode], table: Table, prof: Profile, slots: int,
                 sectors: int) -> dict[str, Path]:  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    figs = {"fig10": fig10(out, episodes, plan.crowd)}
    for i in range(len(places())):
        figs[f"place{i + 1}"] = trajectory(out, episodes, plan.crowd, i)
    figs["detections"] = detections_figure(out, prof, plan.crowd, slots, sectors)
    figs.update(crowd_figures(out, table))
    return figs
