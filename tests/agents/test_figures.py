"""The reports' figures can be read: axes labelled with their units, a legend for every drawn mark that
is not self-evident, tick labels that do not run into each other, integer trial numbers.

Each figure's function runs on small synthetic data with ``plt.close`` disabled, so that the figure
it wrote can be inspected as matplotlib objects.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pytest

from agents.common import plots

UNIT = re.compile(r"\[[^\]]+\]")  # "x [m]", "measured - set rotation [deg]"

Kept = Callable[[], list[Any]]


@pytest.fixture
def kept(monkeypatch: pytest.MonkeyPatch) -> Iterator[Kept]:
    """Keep every figure open; the fixture returns a function listing those made since the test began."""
    close = plt.close
    before = set(plt.get_fignums())
    monkeypatch.setattr(plt, "close", lambda *args, **kwargs: None)
    yield lambda: [plt.figure(n) for n in plt.get_fignums() if n not in before]
    for n in set(plt.get_fignums()) - before:
        close(n)


def _panels(fig: Any) -> list[Any]:
    return [ax for ax in fig.axes if ax.get_visible()]


def _assert_labelled_with_units(fig: Any) -> None:
    for ax in _panels(fig):
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            assert UNIT.search(label), f"panel {ax.get_title()!r}: axis label {label!r} has no unit"


def _assert_tick_labels_apart(fig: Any) -> None:
    """No two shown tick labels of one axis overlap (matplotlib's minor labels on a short log axis did)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in _panels(fig):
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            shown = [t for t in axis.get_majorticklabels() + axis.get_minorticklabels()
                     if t.get_visible() and t.get_text() and lo <= (t.get_position()[0 if axis is ax.xaxis else 1]) <= hi]  # fmt: skip
            boxes = [t.get_window_extent(renderer) for t in shown]
            for (a, ta), (b, tb) in itertools.combinations(zip(boxes, shown), 2):
                assert not a.overlaps(b), f"{ax.get_title()!r}: tick labels {ta.get_text()!r} and {tb.get_text()!r} overlap"


def test_trajectory_panels_have_labelled_metre_axes(kept: Kept, tmp_path: Path) -> None:
    """exp1_trajectories.png (and the LIDAR report's trajectories) draw with :func:`plots.trajectory_panels`."""
    t = np.linspace(0.0, 1.0, 50)
    truth = np.column_stack([1 + 2 * t, 1 + t, np.zeros_like(t)])
    plots.trajectory_panels(tmp_path / "exp1_trajectories.png", truth, {"a": truth + 0.05, "b": truth - 0.05},
                            np.array([[0.0, 0.0], [4.0, 3.0]]), ("L1", "L2"), (4.0, 3.0), title="Exp 1")  # fmt: skip
    (fig,) = kept()
    _assert_labelled_with_units(fig)


def test_the_far_point_snapshot_has_labelled_metre_axes(kept: Kept, tmp_path: Path) -> None:
    walls = np.array([[0.0, 0.0, 6.0, 0.0], [6.0, 0.0, 6.0, 6.0]])
    pts = np.random.default_rng(0).uniform(0.0, 6.0, (40, 2))
    plots.scan_snapshot(tmp_path / "far_points.png", walls, np.array([3.0, 3.0, 0.5]), {"raw": pts, "far": pts[:5]},
                        people_xy=pts[:3], people_radius_m=0.25)  # fmt: skip
    (fig,) = kept()
    _assert_labelled_with_units(fig)


def test_push_recovery_explains_its_line_band_threshold_and_shading(kept: Kept, tmp_path: Path) -> None:
    t = np.linspace(-2.0, 8.0, 60)
    med = 0.05 + np.exp(-((t - 1.0) ** 2))
    plots.recovery_figure(tmp_path / "push_recovery.png", t, {"a": (med, 0.8 * med, 1.2 * med), "b": (med, med, med)},
                          threshold_m=0.2, push_s=2.0)  # fmt: skip
    (fig,) = kept()
    legend = fig.axes[0].get_legend()
    assert legend is not None
    texts = [x.get_text() for x in legend.get_texts()]
    assert texts == ["the push (2 s)", "25-75 % of the seeds", "median error", "recovered: error < 0.2 m"]
    for ax in _panels(fig):
        assert UNIT.search(ax.get_xlabel())
    assert UNIT.search(fig.axes[0].get_ylabel())


def test_tables_2_4_give_the_unit_of_each_difference(kept: Kept, tmp_path: Path) -> None:
    from agents.papers.ceiling_target import report, static

    rows = {table: [{"mean": v + 0.1, quantity: v, "sd": 0.05, "fixes": 3} for v in settings]
            for table, (quantity, settings) in static.TABLES.items()}  # fmt: skip
    curve = {"distance_m": [0.0, 1.0, 2.0], "error_m": [0.0, 0.01, 0.02]}
    report.figures(tmp_path, {"static": {"ours": rows}, "spacing": {"curve": curve}})
    tables, spacing = kept()
    _assert_labelled_with_units(tables)
    _assert_labelled_with_units(spacing)
    assert [ax.get_ylabel() for ax in tables.axes] == [
        "measured - set rotation [deg]",
        "measured - set x [cm]",
        "measured - set y [cm]",
    ]


# spreads of mcl_bearing (one power of ten inside the axis: matplotlib labelled its minor ticks, 2 x 10^-2 over
# 3 x 10^-2 ...), of candidate_sets, and over five decades
@pytest.mark.parametrize("span", [(0.015, 0.45), (0.06, 0.7), (1e-3, 1e2)])
def test_error_vs_spread_tick_labels_do_not_overlap(kept: Kept, tmp_path: Path, span: tuple[float, float]) -> None:
    from agents.evaluate.outputs import plot_error_vs_spread

    rng = np.random.default_rng(3)
    spread = 10 ** rng.uniform(math.log10(span[0]), math.log10(span[1]), 400)
    error = np.abs(rng.normal(0.0, 1.0, 400)) * spread
    episode = SimpleNamespace(cell=SimpleNamespace(localizer="mcl_bearing"), position_spreads_m=spread, position_errors=error)
    result = SimpleNamespace(spec=SimpleNamespace(localizers=("mcl_bearing",)), episodes=[episode])
    plot_error_vs_spread(result, tmp_path / "error_vs_spread.png")  # type: ignore[arg-type]
    (fig,) = kept()
    _assert_labelled_with_units(fig)
    _assert_tick_labels_apart(fig)
    ax = fig.axes[0]
    assert len([t for t in ax.xaxis.get_majorticklabels() if t.get_text()]) >= 2  # still a scale to read


def test_tuning_history_numbers_trials_in_integers(kept: Kept, tmp_path: Path) -> None:
    import optuna

    from agents.tune.report import plot_history

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.optimize(lambda trial: trial.suggest_float("x", 0.0, 1.0), n_trials=3)  # three trials: matplotlib picked 0, 0.25, ...
    plot_history(tmp_path / "history.png", study, "three trials")
    (fig,) = kept()
    ax = fig.axes[0]
    fig.canvas.draw()
    lo, hi = sorted(ax.get_xlim())
    ticks = [x for x in ax.get_xticks() if lo <= x <= hi]
    assert ticks and all(float(x).is_integer() for x in ticks), ticks
    assert UNIT.search(ax.get_ylabel()) and ax.get_xlabel() == "trial"
    assert math.isfinite(ticks[0])
