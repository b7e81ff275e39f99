"""The report's tables: number formats, the cells and rows of the sweeps' error tables (each
variant against the reference pose and the truth) and the consistency tables beside them.

The prose around them is :mod:`.report`'s; the claims in words are :mod:`.claims`'.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from agents.evaluate import consistency, metrics

from . import experiment, paper
from .analysis import Stats, StatsTable, fit_table, pair_stats
from .experiment import Pair, Params
from .jobs import Run

Lines = list[str]


def fmt(v: float | None, spec: str = "{:.3f}") -> str:
    """``spec`` of a finite number, else ``n/a``."""
    return "n/a" if v is None or not np.isfinite(v) else spec.format(v)


def value_set(values: Iterable[float]) -> str:
    """Swept values as ``{0.1, 0.6, 1}``; ``none`` when empty."""
    chosen = [f"{v:g}" for v in values]
    return "{" + ", ".join(chosen) + "}" if chosen else "none"


def same_or_list(values: Iterable[float]) -> str:
    """``0.2`` when all values are equal, else ``0.1, 0.2, ...``."""
    vs = list(values)
    return f"{vs[0]:g}" if len(set(vs)) == 1 else ", ".join(f"{v:g}" for v in vs)


def works_pct() -> str:
    return f"{100 * experiment.WORKS_FAILURE_RATE:.0f}"


def error_cells(s: Stats) -> str:
    """Two table cells of one configuration on one measure: error, failures (total, large)."""
    return f"{fmt(s.mean_m)} ± {fmt(s.sd_m)} | {s.failures:.2f} ({s.failures_total}, {s.large_total})"


def cell(ref: Stats, truth: Stats) -> str:
    """Five table cells of one configuration: against the reference, against the truth, runs failing (both)."""
    return f"{error_cells(ref)} | {error_cells(truth)} | {ref.failed_runs}/{ref.runs}, {truth.failed_runs}/{truth.runs}"


CELL_COLUMNS = 5  # the cells of :func:`cell`


def variant_head(label: str) -> str:
    """The header cells of :func:`cell` for one variant."""
    large = f">= {paper.LARGE_FAIL_M:g} m"
    return (
        f"{label}: error vs reference [m] | failures / run vs reference (total, {large}) | error vs truth [m] "
        f"| failures / run vs truth (total, {large}) | runs failing (vs reference, vs truth)"
    )


def table_head(x: str) -> Lines:
    return [
        f"| {x} | {variant_head('MCL only')} | {variant_head('+ far points')} |",
        "|---|" + "---:|" * (2 * CELL_COLUMNS),
    ]


def pair_rows(rows: Iterable[tuple[Any, Pair]], st: StatsTable, st_ref: StatsTable) -> Lines:
    """One table row per ``(label, pair)`` at the paper's crowd size."""
    out = []
    for label, pair in rows:
        raw, far = pair_stats(st, pair)
        raw_ref, far_ref = pair_stats(st_ref, pair)
        out.append(f"| {label} | {cell(raw_ref, raw)} | {cell(far_ref, far)} |")
    return out


def fit_cells(localizer: str, fit: metrics.Consistency) -> str:
    """Three table cells of one configuration: NEES median, inside 95 % (or "no covariance"), steps left out."""
    has = consistency.reports_covariance(localizer)
    missing = f"{100 * consistency.missing_share(fit):.0f} %" if has else consistency.NO_COVARIANCE
    return " | ".join([*consistency.cells(has, fit.nees_median, fit.inside_95), missing])


FIT_TAG = "(NEES vs truth)"  # after the first header cell of a consistency table


def fit_head(label: str) -> str:
    """The header cells of :func:`fit_cells` for one variant."""
    return f"{label}: NEES median | {label}: inside 95 % | {label}: no usable covariance"


def fit_rows(x: str, rows: Iterable[tuple[Any, Pair]], runs: Sequence[Run], crowd_size: int = experiment.CROWD_SIZE) -> Lines:
    """The consistency table beside a table of :func:`pair_rows`: the same rows, the NEES of both variants."""
    fits = fit_table(runs)
    lines = [f"| {x} {FIT_TAG} | {fit_head('MCL only')} | {fit_head('+ far points')} |", "|---|" + "---:|" * 6]
    for label, pair in rows:
        lines.append(f"| {label} | " + " | ".join(fit_cells(v.localizer, fits[v.key, crowd_size]) for v in pair) + " |")
    return [*lines, "", consistency.legend()]


def params_text(params: Params) -> str:
    """``sampling 0.1, hit 0.2`` of a configuration's sampling and hit sd."""
    p = dict(params)
    return f"sampling {p['sampling']:g}, hit {p['hit_std_m']:g}"
