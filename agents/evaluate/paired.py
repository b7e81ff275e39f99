"""The paired verdict of ``crowdloc eval --verdict POLICY``: one policy against the best fixed policy, seed by seed.

Every policy of an evaluation plays the same held-out seeds (the same env seed: the same start, the
same crowd), so two policies' episodes pair up by seed. For two policies A and B and a metric,
:func:`paired_difference` takes the per-seed difference ``A - B`` over the seeds where both have a
value, its mean and a 95 % percentile-bootstrap interval of that mean
(:func:`agents.evaluate.stats.bootstrap_ci`). Pairing removes what the seed does to both (a hard
start, a crowd in the way) from the comparison, so the interval is narrower than comparing the two
policies' separate intervals.

:func:`paired_verdict` judges a policy of the run per (localizer, crowd size) on the issue-31
metrics (:data:`VERDICT_METRICS`, every one lower-is-better): the mean position error, the failure
rate, the time to the first fix (only where the localizer starts without the pose: with a known
start every policy has its fix at once), the share of episodes that missed the goal and the time
to the goal (only in a world with a goal, :mod:`agents.evaluate.goal`) and the collisions. Against
each metric's best fixed policy: the fixed policy of the same run (not the judged one) with the
lowest mean of that metric over the run's seeds. It says "A better" when the interval lies below
0, "B better" when above, else "no significant difference" ("no pair" when no seed gave both a value).

Reading it: the best fixed policy is picked on the same seeds it is compared on, which favours it
(the verdict is conservative for the judged policy); a pair counts only where both episodes have
a value (the time to the goal of seeds where both reached it, the first fix where both had one;
``n`` says how many), which is why the goal's miss share and the fix are judged beside them; with
few seeds a difference that is the same on every seed gives a zero-width interval: use the
issue's 100 seeds or more for a verdict.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from agents.evaluate.outputs import write_csv
from agents.evaluate.spec import PPO_PREFIX, Cell, EvalSpec
from agents.evaluate.stats import EvalResult, Stat
from core.schema import ConfigError, check

#: the metrics of the verdict (every one lower-is-better), in table order
VERDICT_METRICS = ("position_error_mean_m", "failure_rate", "first_fix_s", "goal_missed", "time_to_goal_s", "collisions")
#: salts the verdict's bootstrap streams: they differ from the summary's for the same seed
_PAIRED_SALT = 0x9A12ED


@dataclass(frozen=True)
class PairedDifference(Stat):
    """The :class:`~agents.evaluate.stats.Stat` of a per-seed difference ``A - B``: its mean over seeds, its
    bootstrap 95 % interval and how many seeds had both values (``n``; NaN mean and interval when none did)."""

    @property
    def outcome(self) -> int:
        """For a lower-is-better metric: -1 when A is better (the interval lies below 0), 1 when B
        is (above 0), 0 when the interval holds 0 (or there is none)."""
        return -1 if self.high < 0 else 1 if self.low > 0 else 0


def paired_difference(a: ArrayLike, b: ArrayLike, *, resamples: int, rng: np.random.Generator) -> PairedDifference:
    """:class:`PairedDifference` of ``a - b``, per seed (``a[i]`` and ``b[i]`` from the same seed),
    over the seeds where both are finite.

    Raises:
        ValueError: ``a`` and ``b`` of different lengths (not paired).
    """
    x, y = np.asarray(a, dtype=np.float64).reshape(-1), np.asarray(b, dtype=np.float64).reshape(-1)
    if x.shape != y.shape:
        raise ValueError(f"paired_difference needs one value of each per seed, got {x.size} and {y.size}")
    both = np.isfinite(x) & np.isfinite(y)
    return PairedDifference.of(np.where(both, x - y, math.nan), resamples, rng)  # over the seeds where both are finite


@dataclass(frozen=True)
class VerdictRow:
    """One metric of one (localizer, crowd size): the judged policy against that metric's best fixed policy."""

    localizer: str
    crowd_size: int
    metric: str
    judged: str
    best_fixed: str
    judged_mean: float  # over the seeds where the judged policy had a value
    best_mean: float
    difference: PairedDifference  # judged - best fixed, per seed

    @property
    def word(self) -> str:
        """The verdict in words; "no pair" when no seed gave both policies a value (e.g. the time to
        the goal when one of them never reached it: its miss share says the rest)."""
        if not self.difference.n:
            return "no pair"
        return {-1: "A better", 1: "B better", 0: "no significant difference"}[self.difference.outcome]


def verdict_policy(given: str, spec: EvalSpec) -> str:
    """The policy of ``spec`` that ``crowdloc eval --verdict`` names (its full name or its short
    label), once it is checked that the grid has a fixed policy to judge it against.

    Raises:
        ConfigError: a name that is not a policy of the grid, or no other fixed policy in it.
    """
    found = [p for p in spec.policies if given in (p, spec.policy_label(p))]
    check(len(found) == 1, f"--verdict {given!r} is not one of --policies ({', '.join(spec.policies)}): "
                           "the judged policy must be evaluated in the same run")  # fmt: skip
    fixed = [p for p in spec.policies if not p.startswith(PPO_PREFIX) and p != found[0]]
    check(bool(fixed), f"--verdict {given!r} needs a fixed policy to be judged against: add one to --policies "
                       f"(now {', '.join(spec.policies)})")  # fmt: skip
    return found[0]


def verdict_metrics(spec: EvalSpec, localizer: str) -> tuple[str, ...]:
    """The :data:`VERDICT_METRICS` that apply to ``localizer`` in ``spec``'s world (module docstring)."""
    skipped = {"first_fix_s"} if spec.known_start(localizer) else set()
    if not spec.has_goal:
        skipped |= {"goal_missed", "time_to_goal_s"}
    return tuple(key for key in VERDICT_METRICS if key not in skipped)


def paired_verdict(result: EvalResult, judged: str) -> list[VerdictRow]:
    """The verdict on ``judged`` (a policy of the run) per localizer, crowd size and metric (module docstring).

    Raises:
        ConfigError: as :func:`verdict_policy`.
    """
    spec = result.spec
    judged = verdict_policy(judged, spec)
    fixed = [p for p in spec.policies if not p.startswith(PPO_PREFIX) and p != judged]
    by_cell = {ep.cell: ep.metrics for ep in result.episodes}
    missing = [c for c in spec.cells() if c not in by_cell]
    if missing:
        raise ConfigError(f"the verdict needs every episode of the grid; {len(missing)} are missing (first: {missing[0]})")
    rows = []
    for g, (localizer, crowd) in enumerate((loc, c) for loc in spec.localizers for c in spec.crowd_sizes):
        for m, key in enumerate(verdict_metrics(spec, localizer)):
            # per policy its values in seed order: the pairs
            values = {p: np.array([by_cell[Cell(p, localizer, crowd, s)].get(key, math.nan) for s in spec.eval_seeds])
                      for p in (judged, *fixed)}  # fmt: skip
            means = {p: _finite_mean(v) for p, v in values.items()}
            best = min(fixed, key=lambda p: means[p] if math.isfinite(means[p]) else math.inf)  # ties: the first listed
            rng = np.random.default_rng([spec.bootstrap_seed, _PAIRED_SALT, g, m])
            difference = paired_difference(values[judged], values[best], resamples=spec.bootstrap_resamples, rng=rng)
            rows.append(VerdictRow(localizer, crowd, key, judged, best, means[judged], means[best], difference))
    return rows


def _finite_mean(values: NDArray[np.float64]) -> float:
    v = values[np.isfinite(values)]
    return float(v.mean()) if v.size else math.nan


def verdict_markdown(rows: Sequence[VerdictRow], spec: EvalSpec) -> str:
    """The verdict as a markdown table: per (localizer, crowd size, metric) both means, the paired
    difference ``A - B`` with its 95 % interval and the pairs, and the verdict."""
    fmt = {m.key: m.fmt for m in spec.metrics}
    lines = ["| localizer | crowd | metric | A (judged) | B (best fixed) | A - B [95% CI] (pairs) | verdict |",
             "|---|---:|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        f, d = fmt[r.metric].format, r.difference
        diff = f"{f(d.mean)} [{f(d.low)}, {f(d.high)}] ({d.n})" if d.n else f"– ({d.n})"
        lines.append(f"| {r.localizer} | {r.crowd_size} | {r.metric} | {spec.policy_label(r.judged)}: {_text(f, r.judged_mean)} "
                     f"| {r.best_fixed}: {_text(f, r.best_mean)} | {diff} | {r.word} |")  # fmt: skip
    return "\n".join(lines)


def _text(f: object, value: float) -> str:
    return f(value) if math.isfinite(value) else "–"  # type: ignore[operator]


def write_verdict(rows: Sequence[VerdictRow], spec: EvalSpec, out_dir: Path) -> dict[str, Path]:
    """Write ``verdict.md`` (the table and how to read it) and ``verdict.csv`` (one row per line of
    the table) under ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    md, table = out_dir / "verdict.md", out_dir / "verdict.csv"
    judged = spec.policy_label(rows[0].judged) if rows else "–"
    md.write_text("\n".join([
        f"# crowdloc eval: paired verdict on {judged}",
        "",
        f"{spec.env_id}, {spec.seeds} held-out seeds per cell, {spec.episode_steps} steps per episode at most.",
        "",
        verdict_markdown(rows, spec),
        "",
        "A: the judged policy; B: the fixed policy of this run with the lowest mean of that metric (picked on these "
        "seeds, which favours it). A - B: mean over seeds of the per-seed difference (both policies play the same "
        f"seeds), over the seeds where both have a value (pairs), with its 95% percentile-bootstrap interval "
        f"({spec.bootstrap_resamples} resamples). Every metric is lower-is-better: \"A better\" when the interval lies "
        "below 0, \"B better\" above 0, else no significant difference; \"no pair\": no seed where both have a value. First fix: only where the localizer starts "
        "without the pose; goal not reached and time to goal (of the seeds where both reached it): only in a world "
        "with a goal.",
        "",
    ]))  # fmt: skip
    header = ["localizer", "crowd_size", "metric", "judged", "best_fixed", "judged_mean", "best_fixed_mean", "difference",
              "ci_low", "ci_high", "pairs", "verdict"]  # fmt: skip
    write_csv(table, header, [[r.localizer, r.crowd_size, r.metric, spec.policy_label(r.judged), r.best_fixed, r.judged_mean,
                               r.best_mean, r.difference.mean, r.difference.low, r.difference.high, r.difference.n, r.word]
                              for r in rows])  # fmt: skip
    return {"verdict_md": md, "verdict_csv": table}
