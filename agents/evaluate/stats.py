"""Running the grid and aggregating it: per (policy, localizer, crowd size) the mean over seeds
and a 95% percentile bootstrap interval of that mean (:func:`bootstrap_ci`)."""

from __future__ import annotations

import math
import time
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Self

import numpy as np
from numpy.typing import ArrayLike

from agents.evaluate.episode import Episode, run_task
from agents.evaluate.plugins import MetricInfo, localizer_metrics
from agents.evaluate.spec import EvalSpec

if TYPE_CHECKING:
    from agents.evaluate.journal import EpisodeJournal
from core.schema import check


def bootstrap_ci(values: ArrayLike, n: int = 2000, *, rng: np.random.Generator, level: float = 0.95) -> tuple[float, float]:
    """Percentile-bootstrap confidence interval of the mean of the finite ``values``.

    Draws ``n`` resamples (with replacement, of the same size) and returns the
    ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles of their means. One value, or all
    equal, gives a zero-width interval; no finite value gives ``(nan, nan)``.
    """
    if n < 1 or not 0 < level < 1:
        raise ValueError(f"bootstrap_ci needs n >= 1 and 0 < level < 1, got n={n}, level={level}")
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    means = v[rng.integers(0, v.size, size=(n, v.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


@dataclass(frozen=True)
class Stat:
    """Mean over the episodes with a finite value, its bootstrap CI, and how many there were."""

    mean: float
    low: float
    high: float
    n: int

    @classmethod
    def of(cls, values: ArrayLike, resamples: int, rng: np.random.Generator) -> Self:
        """The mean of the finite ``values``, its :func:`bootstrap_ci` and their count."""
        v = np.asarray(values, dtype=np.float64).reshape(-1)
        finite = v[np.isfinite(v)]
        lo, hi = bootstrap_ci(finite, resamples, rng=rng)
        return cls(float(finite.mean()) if finite.size else math.nan, lo, hi, int(finite.size))


@dataclass(frozen=True)
class SummaryRow:
    """The aggregate of one (policy, localizer, crowd size)."""

    policy: str
    localizer: str
    crowd_size: int
    episodes: int
    stats: Mapping[str, Stat]


@dataclass(frozen=True)
class EvalResult:
    """Everything :func:`evaluate` measured."""

    spec: EvalSpec
    episodes: tuple[Episode, ...]
    summary: tuple[SummaryRow, ...]
    wall_s: float

    @property
    def metrics(self) -> tuple[MetricInfo, ...]:
        """The metric rows of the tables: the core ones and the plug-ins' of the grid's kinds."""
        return self.spec.metrics


def summarize(
    episodes: Sequence[Any], resamples: int = 2000, seed: int = 0, metrics: Sequence[MetricInfo] | None = None
) -> tuple[SummaryRow, ...]:
    """Mean and bootstrap CI of every metric per (policy, localizer, crowd size), in grid order.

    Args:
        episodes: :class:`Episode`\\ s (anything with a ``cell`` and ``metrics``).
        resamples, seed: of the bootstrap; metric ``m`` of group ``g`` draws from ``[seed, g, m]``,
            ``m`` counting the rows with the consistency ones (``MetricInfo.covariance``) last.
        metrics: the rows to aggregate (default: those of the episodes' localizers); a metric
            an episode has not got (another kind's) counts as no value.
    """
    rows_of = localizer_metrics(dict.fromkeys(ep.cell.localizer for ep in episodes)) if metrics is None else metrics
    keys = [m.key for m in rows_of]
    # the bootstrap stream of each metric: its index among the rows with the consistency rows moved
    # last, so that adding those rows left every other metric's interval as it was
    stream = {m.key: i for i, m in enumerate([m for m in rows_of if not m.covariance] + [m for m in rows_of if m.covariance])}
    groups: dict[tuple[str, str, int], list[Any]] = {}
    for ep in episodes:
        groups.setdefault(ep.cell.group, []).append(ep)
    rows = []
    for g, (key, eps) in enumerate(groups.items()):
        stats = {}
        for name in keys:
            values = [ep.metrics.get(name, math.nan) for ep in eps]
            stats[name] = Stat.of(values, resamples, np.random.default_rng([seed, g, stream[name]]))
        rows.append(SummaryRow(*key, episodes=len(eps), stats=stats))
    return tuple(rows)


def evaluate(
    spec: EvalSpec,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: bool = True,
    groups: Collection[tuple[str, str, int]] | None = None,
    journal: EpisodeJournal | None = None,
) -> EvalResult:
    """Run every cell of ``spec``'s grid (in parallel) and aggregate.

    Args:
        spec: the grid.
        workers: local processes (default: the core count; 1 runs in this process).
        ray_address: run the episodes on this Ray cluster instead.
        progress: show a progress bar.
        groups: run only these ``(policy, localizer, crowd size)`` groups of the grid, on all of
            its seeds (default: the whole grid).
        journal: write each episode to it as it finishes, and run only the cells it has not
            got (:mod:`agents.evaluate.journal`, ``crowdloc eval --resume``); the result is the
            same as without it.

    Raises:
        ConfigError: a group that is not in the grid, or no group.
    """
    from agents.common.sweep import run_tasks

    start = time.perf_counter()
    cells = spec.cells()
    if groups is not None:
        grid = {c.group for c in cells}
        wanted = set(groups)
        check(len(wanted) >= 1, "groups needs at least one (policy, localizer, crowd size)")
        stray = sorted(wanted - grid, key=str)
        check(not stray, f"groups {stray} are not in the grid of policies x localizers x crowd sizes")
        cells = [c for c in cells if c.group in wanted]
    done = {} if journal is None else journal.done
    todo = [c for c in cells if c not in done]
    ran = run_tasks(run_task, [(spec, c) for c in todo], workers=workers, ray_address=ray_address, desc="eval",
                    progress=progress, on_result=None if journal is None else lambda _, episode: journal.append(episode))  # fmt: skip
    by_cell: dict[Any, Episode] = {**done, **dict(zip(todo, ran))}
    episodes = [by_cell[c] for c in cells]  # grid order, however the episodes finished or were split between runs
    summary = summarize(episodes, spec.bootstrap_resamples, spec.bootstrap_seed, spec.metrics)
    return EvalResult(spec, tuple(episodes), summary, time.perf_counter() - start)
