"""A benchmark run's numbers: one row per world x localizer x policy x crowd size, the crowd
sensitivity per world x localizer, and the files (``results.json``, ``results.csv``, ``leaderboard.md``).

Definitions (``docs/benchmark.md``): per episode, the position error ``e_t`` of every step from the
first fix ``t0`` on; a row's

- ``error_mean_m``: the mean over its episodes of each episode's mean ``e_t``;
- ``error_p95_m``: the 95th percentile of the pooled ``e_t`` of its episodes;
- ``failure_share``: the mean over episodes of the share of steps from ``t0`` with ``e_t >=`` the
  world's ``failure_m``;
- ``availability``: the mean share of steps with a pose; ``first_fix_s``: the mean time to ``t0``;
- ``nees_median``, ``inside_95``: the mean over episodes of the median NEES and of the share of
  steps inside the reported 95 % region (NaN for a localizer that reports no covariance);
- ``error_bound_ratio``: the mean over episodes of the RMS position error over the RMS posterior
  Cramer-Rao bound along the true path, where a bound exists (bearing localizers:
  :mod:`agents.evaluate.bearings`);
- ``update_ms``: the median over episodes of the localizer's mean wall time per step (predict and
  update) on the machine that ran it: a cost, without an interval, not comparable across machines;

each mean with a 95 % percentile bootstrap interval over the episodes
(:func:`agents.evaluate.bootstrap_ci`). The crowd sensitivity of a localizer in a world is
``error_mean_m`` at the largest crowd over ``error_mean_m`` at crowd 0, under the world's first
policy, with a paired bootstrap interval (the seeds resampled together at both sizes).
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark.protocol import crowdloc_version, protocol_digest
from agents.benchmark.run import EPISODE_KEYS, BenchmarkPlan, EpisodeScore
from agents.evaluate.stats import Stat

#: what ``crowdloc benchmark`` writes in ``--out`` (what ``--overwrite`` deletes)
BENCHMARK_OUTPUTS = ("results.json", "results.csv", "leaderboard.md", "episodes.jsonl", "plots/*.png")
RESAMPLES = 2000


@dataclass(frozen=True)
class Row:
    """One world x localizer x policy x crowd size."""

    world: str
    localizer: str
    policy: str
    crowd_size: int
    episodes: int
    stats: dict[str, Stat]
    error_p95_m: float
    update_ms: float  # the median over its episodes of each one's mean cost per step (a timing: not comparable across machines)


@dataclass(frozen=True)
class Sensitivity:
    """A localizer's crowd sensitivity in one world (``ratio``: error at ``crowd_max`` / error at 0)."""

    world: str
    localizer: str
    policy: str
    crowd_max: int
    ratio: float
    low: float
    high: float
    rank: int  # by error_mean_m at the world's default crowd under ``policy`` (1 = lowest error)


def aggregate(scores: Sequence[EpisodeScore]) -> tuple[Row, ...]:
    """The rows, in the order of the episodes (the plan's); bootstrap streams ``[group, metric]``."""
    groups: dict[tuple[str, str, str, int], list[EpisodeScore]] = {}
    for s in scores:
        groups.setdefault((s.env_id, s.cell.localizer, s.cell.policy, s.cell.crowd_size), []).append(s)
    rows = []
    for g, (key, eps) in enumerate(groups.items()):
        stats = {
            k: Stat.of([e.values[k] for e in eps], RESAMPLES, np.random.default_rng([g, m])) for m, k in enumerate(EPISODE_KEYS)
        }
        pooled = np.concatenate([e.errors_m for e in eps])
        p95 = float(np.percentile(pooled, 95)) if pooled.size else math.nan
        costs = [e.update_ms for e in eps if math.isfinite(e.update_ms)]
        cost = float(np.median(costs)) if costs else math.nan
        rows.append(Row(*key, episodes=len(eps), stats=stats, error_p95_m=p95, update_ms=cost))
    return tuple(rows)


def _ratio_ci(low_crowd: np.ndarray, high_crowd: np.ndarray, rng: np.random.Generator) -> tuple[float, float, float]:
    """Mean of ``high_crowd`` over mean of ``low_crowd`` (paired by seed; NaN pairs dropped) and its percentile interval."""
    ok = np.isfinite(low_crowd) & np.isfinite(high_crowd)
    a, b = low_crowd[ok], high_crowd[ok]
    if a.size == 0 or a.mean() <= 0:
        return math.nan, math.nan, math.nan
    idx = rng.integers(0, a.size, size=(RESAMPLES, a.size))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = b[idx].mean(axis=1) / a[idx].mean(axis=1)
    lo, hi = np.nanquantile(ratios, [0.025, 0.975])
    return float(b.mean() / a.mean()), float(lo), float(hi)


def default_crowd(env_id: str) -> int:
    """The crowd size a world has by default (0 without a crowd)."""
    from agents.evaluate.spec import world_of

    crowd = world_of(env_id, {}).crowd
    return crowd.count if crowd is not None else 0


def sensitivities(plan: BenchmarkPlan, scores: Sequence[EpisodeScore], rows: Sequence[Row]) -> tuple[Sensitivity, ...]:
    """Per world and localizer, under the world's first policy of the run."""
    out = []
    for w, world in enumerate(plan.worlds):
        policy, top = world.policies[0], world.world.crowd_sizes[-1]
        default = default_crowd(world.env_id)
        at_default = {r.localizer: r.stats["error_mean_m"].mean for r in rows
                      if r.world == world.env_id and r.policy == policy and r.crowd_size == default}  # fmt: skip
        order = sorted(at_default, key=lambda n: (not math.isfinite(at_default[n]), at_default[n]))
        for k, loc in enumerate(world.localizers):
            mine = [s for s in scores if s.env_id == world.env_id and s.cell.policy == policy and s.cell.localizer == loc]
            by = {size: {s.cell.seed: s.values["error_mean_m"] for s in mine if s.cell.crowd_size == size} for size in (0, top)}
            seeds = sorted(set(by[0]) & set(by[top]))
            ratio = _ratio_ci(np.array([by[0][s] for s in seeds]), np.array([by[top][s] for s in seeds]),
                              np.random.default_rng([w, k, 7]))  # fmt: skip
            rank = order.index(loc) + 1 if loc in order else 0
            out.append(Sensitivity(world.env_id, loc, policy, top, *ratio, rank=rank))
    return tuple(out)


def _fmt(value: float, digits: int = 2) -> str:
    return "–" if not math.isfinite(value) else f"{value:.{digits}f}"


def _fmt_stat(stat: Stat, digits: int = 2) -> str:
    if not math.isfinite(stat.mean):
        return "–"
    if stat.n < 2:
        return _fmt(stat.mean, digits)
    return f"{stat.mean:.{digits}f} [{stat.low:.{digits}f}, {stat.high:.{digits}f}]"


def header(plan: BenchmarkPlan) -> dict[str, Any]:
    """What every output says about the run: the protocol's name and digest, quick or not, the seeds."""
    return {
        "protocol": plan.protocol.name,
        "protocol_digest": protocol_digest(plan.protocol),
        "crowdloc_version": crowdloc_version(),
        "quick": plan.quick,
        "seeds": list(plan.seeds),
        "episode_steps": {w.env_id: w.spec.episode_steps for w in plan.worlds},
        "plugins": list(plan.plugins),
        "left_out": list(plan.left_out),
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
    }


def resolution(rows: Sequence[Row]) -> tuple[float, float, float]:
    """The half-width of the mean error's 95 % interval as a share of the mean, over the rows with
    one: median, 10th and 90th percentile (NaN without any)."""
    shares = [(r.stats["error_mean_m"].high - r.stats["error_mean_m"].low) / 2 / r.stats["error_mean_m"].mean
              for r in rows if r.stats["error_mean_m"].n >= 2 and r.stats["error_mean_m"].mean > 0]  # fmt: skip
    if not shares:
        return math.nan, math.nan, math.nan
    median, p10, p90 = np.percentile(shares, [50, 10, 90])
    return float(median), float(p10), float(p90)


def leaderboard(plan: BenchmarkPlan, rows: Sequence[Row], sens: Sequence[Sensitivity], head: dict[str, Any]) -> str:
    """``leaderboard.md``: the overview (rank and crowd sensitivity per world), then one table per world."""
    quick = " — QUICK RUN: a set-up check, not comparable with a full run" if plan.quick else ""
    median, p10, p90 = resolution(rows)
    lines = [f"# crowdloc benchmark: {head['protocol']}{quick}", "",
             f"Protocol `{head['protocol']}`, digest `{head['protocol_digest'][:16]}`, crowdloc {head['crowdloc_version']}; "
             f"{len(plan.seeds)} test seeds per cell ({plan.seeds[0]}..{plan.seeds[-1]}); quick: {str(plan.quick).lower()}. "
             f"Update costs measured on {head['machine']}.", ""]  # fmt: skip
    if math.isfinite(median):
        lines += [f"Resolution: with {len(plan.seeds)} seeds the 95 % interval of a row's mean error spans ±{100 * median:.0f} % "
                  f"of it (median over the rows; {100 * p10:.0f}-{100 * p90:.0f} % between the 10th and 90th percentile). "
                  "Two entries whose intervals overlap are not told apart by this run.", ""]  # fmt: skip
    worlds = [w.env_id for w in plan.worlds]
    localizers = list(dict.fromkeys(s.localizer for s in sens))
    lines += ["## Crowd sensitivity: error at the largest crowd / error at crowd 0 [95 % CI] (rank at the default crowd)", "",
              "| localizer | " + " | ".join(worlds) + " |", "|---|" + "---|" * len(worlds)]  # fmt: skip
    for loc in localizers:
        cells = []
        for env_id in worlds:
            s = next((x for x in sens if x.world == env_id and x.localizer == loc), None)
            if s is None:
                cells.append("n/a")
            else:
                ci = f" [{_fmt(s.low)}, {_fmt(s.high)}]" if math.isfinite(s.low) and len(plan.seeds) > 1 else ""
                cells.append(f"{_fmt(s.ratio)}{ci} (#{s.rank})" if s.rank else f"{_fmt(s.ratio)}{ci}")
        lines.append(f"| {loc} | " + " | ".join(cells) + " |")
    lines += papers_tables(plan, rows)
    for world in plan.worlds:
        lines += ["", f"## {world.env_id}", "",
                  f"Policies {', '.join(world.policies)}; {world.spec.episode_steps} steps per episode; start "
                  f"{world.world.start}; failure: error >= {world.world.failure_m:g} m.", "",
                  "| localizer | policy | crowd | mean error m | p95 error m | failure share | availability | "
                  "first fix s | NEES median | inside 95 % | error / CRB | update ms |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in rows:
            if r.world != world.env_id:
                continue
            st = r.stats
            nees = "no covariance" if r.stats["nees_median"].n == 0 else _fmt_stat(st["nees_median"])
            lines.append(f"| {r.localizer} | {r.policy} | {r.crowd_size} | {_fmt_stat(st['error_mean_m'])} | "
                         f"{_fmt(r.error_p95_m)} | {_fmt_stat(st['failure_share'])} | {_fmt_stat(st['availability'])} | "
                         f"{_fmt_stat(st['first_fix_s'], 1)} | {nees} | {_fmt_stat(st['inside_95'])} | "
                         f"{_fmt_stat(st['error_bound_ratio'])} | {_fmt(r.update_ms, 3)} |")  # fmt: skip
    if plan.left_out:
        lines += ["", "## Left out", ""] + [f"- {line}" for line in plan.left_out]
    return "\n".join(lines) + "\n"


def papers_tables(plan: BenchmarkPlan, rows: Sequence[Row]) -> list[str]:
    """The leaderboard's lines "The papers' methods as the crowd grows": per world whose protocol names
    ``paper_localizers``, each of them under the world's paper policy at crowd 0, the world's default
    and its maximum (mean error [95 % CI], p95, failure share [95 % CI]); none without such a world."""
    worlds = [w for w in plan.worlds if any(name in w.localizers for name in w.world.paper_localizers)]
    if not worlds:
        return []
    lines = ["", "## The papers' methods as the crowd grows", "",
             "Each world's paper's method and its baselines under the world's paper policy, at crowd 0, the world's "
             "default crowd and its largest: mean error m [95 % CI] / p95 error m / failure share [95 % CI]."]  # fmt: skip
    for world in worlds:
        policy, sizes = world.policies[0], world.world.crowd_sizes
        default = default_crowd(world.env_id)
        shown = list(dict.fromkeys(size for size in (0, default, sizes[-1]) if size in sizes))
        label = {size: f"crowd {size}" + (" (default)" if size == default else "") for size in shown}
        lines += ["", f"### {world.env_id} ({policy}, failure: error >= {world.world.failure_m:g} m)", "",
                  "| localizer | " + " | ".join(label[size] for size in shown) + " |", "|---|" + "---|" * len(shown)]  # fmt: skip
        for name in world.world.paper_localizers:
            if name not in world.localizers:
                continue
            cells = []
            for size in shown:
                r = next(
                    (r for r in rows if (r.world, r.localizer, r.policy, r.crowd_size) == (world.env_id, name, policy, size)),
                    None,
                )
                cells.append("–" if r is None else
                             f"{_fmt_stat(r.stats['error_mean_m'])} / {_fmt(r.error_p95_m)} / {_fmt_stat(r.stats['failure_share'])}")  # fmt: skip
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def _row_dict(r: Row) -> dict[str, Any]:
    out: dict[str, Any] = {"world": r.world, "localizer": r.localizer, "policy": r.policy, "crowd_size": r.crowd_size,
                           "episodes": r.episodes, "error_p95_m": r.error_p95_m, "update_ms": r.update_ms}  # fmt: skip
    for key, stat in r.stats.items():
        out.update({key: stat.mean, f"{key}_low": stat.low, f"{key}_high": stat.high, f"{key}_n": stat.n})
    return out


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    return value


def write_results(out: Path, plan: BenchmarkPlan, scores: Sequence[EpisodeScore], wall_s: float) -> dict[str, Path]:
    """Write ``results.json``, ``results.csv`` and ``leaderboard.md`` (and the plots) under ``out``."""
    rows = aggregate(scores)
    sens = sensitivities(plan, scores, rows)
    head = header(plan)
    tagged = [{"protocol": head["protocol"], "protocol_digest": head["protocol_digest"], "quick": plan.quick, **_row_dict(r)}
              for r in rows]  # fmt: skip
    written = {"json": out / "results.json", "csv": out / "results.csv", "leaderboard": out / "leaderboard.md"}
    document = {**head, "wall_s": wall_s, "rows": tagged, "crowd_sensitivity": [asdict(s) for s in sens]}
    written["json"].write_text(json.dumps(_json_safe(document), indent=1) + "\n")
    with written["csv"].open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(tagged[0]))
        writer.writeheader()
        writer.writerows(tagged)
    written["leaderboard"].write_text(leaderboard(plan, rows, sens, head))
    from agents.benchmark.plots import plot_overview, plot_worlds

    written.update(plot_worlds(out / "plots", plan, rows))
    written["overview"] = plot_overview(out / "plots" / "overview.png", plan, rows, sens)
    return written
