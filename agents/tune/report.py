"""The outputs of a ``crowdloc tune`` run: ``best_params.yaml``, importances, figures, ``report.md``.

Every number in the report comes from the study, the run's :class:`~agents.tune.plan.TuneConfig`
and :class:`~agents.tune.plan.StudyPlan`, or the held-out scores.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import optuna

from agents.common.util import nest
from agents.evaluate import METRICS, MetricInfo, bootstrap_ci, metrics
from agents.rl.config import EVAL_SEED_BASE
from agents.tune.objective import EpisodeScore, seed_base_text
from agents.tune.plan import StudyPlan, TuneConfig
from agents.tune.space import SearchSpace

_EVAL_METRICS = {m.key: m for m in METRICS}
#: the held-out table's columns (label and format as in ``crowdloc eval``) and each one's value of an episode score
_COLUMNS: tuple[tuple[MetricInfo, Callable[[EpisodeScore], float]], ...] = (
    (MetricInfo("objective_m", "objective [m]", "{:.3f}"), lambda s: s.objective),
    (MetricInfo("position_error_m", "position error [m]", "{:.3f}"), lambda s: s.position_error_m),
    (MetricInfo("heading_error_deg", "heading error [deg]", "{:.2f}"), lambda s: math.degrees(s.heading_error_rad)),
    (_EVAL_METRICS["availability"], lambda s: s.availability),
    (MetricInfo("failures", "failures [steps/run]", "{:.1f}"), lambda s: float(s.failures)),
    (MetricInfo("failure_share", "failure share", "{:.4f}"), lambda s: s.failure_share),
    (_EVAL_METRICS["first_fix_s"], lambda s: s.first_fix_s),
)
#: the metrics whose paired difference (tuned - defaults, same recording) gets an interval
_PAIRED = ("objective_m", "position_error_m", "availability", "failures", "failure_share")
#: below this many held-out seeds the percentile bootstrap's interval is too narrow to trust
_FEW_SEEDS = 5
#: confidence level of the paired difference's bootstrap interval
_CI_LEVEL = 0.95
_State = optuna.trial.TrialState


# ------------------------------------------------------------------------------------ best parameters


def _format_value(value: Any) -> str:
    """A YAML scalar that YAML 1.1 and 1.2 loaders both read back as the same type."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        if "e" in text and "." not in text.split("e")[0]:
            mantissa, exponent = text.split("e")
            text = f"{mantissa}.0e{exponent}"
        return text
    return json.dumps(str(value))


def best_params_yaml(localizer: str, best: Mapping[str, Any], space: SearchSpace, header: Sequence[str]) -> str:
    """The tuned parameters as a ``localizer_params`` YAML mapping, each with its default and range."""
    defaults = space.defaults()
    ranges = {r.name: r for r in space.params}
    lines = [f"# {h}" for h in header]
    lines.append(f"# Overrides of configs/localizers/{localizer}.yaml, ready as localizer_params; the rest keep their defaults.")

    def emit(node: Mapping[str, Any], prefix: str, indent: int) -> None:
        for key, value in node.items():
            dotted = f"{prefix}{key}"
            if isinstance(value, Mapping):
                lines.append(" " * indent + f"{key}:")
                emit(value, dotted + ".", indent + 2)
            else:
                note = f"default {_format_value(defaults[dotted])}, searched {ranges[dotted].describe()}"
                lines.append(" " * indent + f"{key}: {_format_value(value)}  # {note}")

    emit(nest(best), "", 0)
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------ importances and figures


def param_importances(study: optuna.Study) -> tuple[dict[str, float], list[str]]:
    """Optuna's parameter importances (its default evaluator, PED-ANOVA) and notes on them.

    Returns empty importances with a note when fewer than 2 trials completed.
    """
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    if len(complete) < 2:
        return {}, [f"importances need >= 2 completed trials, the study has {len(complete)}"]
    with warnings.catch_warnings(record=True) as caught:
        # with few or tied trials PED-ANOVA warns that its quantiles coincide and returns
        # equal importances, and a capped range (at_most) that a value range holds too few
        # trials; keep those warnings for the report instead of failing
        warnings.filterwarnings("always", message="Target and region quantiles", category=UserWarning)
        warnings.filterwarnings("always", message="Some regimes for parameter", category=UserWarning)
        values = optuna.importance.get_param_importances(study)
    return {k: float(v) for k, v in values.items()}, [str(w.message) for w in caught]


def _value(trial: optuna.trial.FrozenTrial) -> float:
    """The objective of a completed trial."""
    assert trial.value is not None
    return float(trial.value)


def plot_importances(path: Path, importances: Mapping[str, float], title: str) -> Path:
    """Horizontal bar chart of the importances, most important on top (PNG)."""
    from agents.common.plots import plt, save_figure

    names = list(importances)[::-1]
    fig, ax = plt.subplots(figsize=(6.0, 0.5 * max(len(names), 2) + 1.2))
    ax.barh(names, [importances[n] for n in names], color="tab:blue")
    for i, n in enumerate(names):
        ax.text(importances[n], i, f" {importances[n]:.2f}", va="center", fontsize=8)
    if not names:
        ax.text(0.5, 0.5, "not enough completed trials", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("importance (PED-ANOVA, normalized)")
    ax.set_xlim(0.0, 1.15)
    ax.set_title(title, fontsize=9)
    return save_figure(fig, path)


def plot_history(path: Path, study: optuna.Study, title: str) -> Path:
    """Objective per trial (completed: dots, pruned: last reported value, x), best so far, the defaults (star)."""
    from matplotlib.ticker import MaxNLocator

    from agents.common.plots import plt, save_figure

    fig, ax = plt.subplots(figsize=(7.0, 3.8))
    done = [t for t in study.trials if t.state == _State.COMPLETE]
    pruned = [t for t in study.trials if t.state == _State.PRUNED and t.intermediate_values]
    ax.scatter([t.number for t in done], [_value(t) for t in done], s=14, color="tab:blue", label="completed")
    if pruned:
        ax.scatter([t.number for t in pruned], [t.intermediate_values[max(t.intermediate_values)] for t in pruned],
                   s=18, marker="x", color="tab:gray", label="pruned (running mean)")  # fmt: skip
    best, xs, ys = math.inf, [], []
    for t in sorted(done, key=lambda t: t.number):
        best = min(best, _value(t))
        xs.append(t.number)
        ys.append(best)
    ax.step(xs, ys, where="post", color="tab:red", label="best so far")
    default = [t for t in done if t.user_attrs.get("defaults")]
    if default:
        ax.scatter([default[0].number], [_value(default[0])], s=90, marker="*", color="tab:orange", zorder=3,
                   label="defaults")  # fmt: skip
    ax.set_xlabel("trial")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # trial numbers, never 2.5
    ax.set_ylabel("objective [m]")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


# ------------------------------------------------------------------------------------ what the report says


@dataclass(frozen=True)
class StudyOutcome:
    """The study's trials as the report sees them.

    Attributes:
        trials: trials in the study.
        counts: trials per state, ``{"complete": n, "pruned": n, "fail": n}``.
        best: the best trial.
        defaults: the completed trial of the YAML defaults (``None`` if it did not complete).
        importances: parameter importances, most important first (empty below 2 completed trials).
        importance_notes: warnings and notes on the importances.
    """

    trials: int
    counts: Mapping[str, int]
    best: optuna.trial.FrozenTrial
    defaults: optuna.trial.FrozenTrial | None
    importances: Mapping[str, float]
    importance_notes: tuple[str, ...]


def study_outcome(study: optuna.Study) -> StudyOutcome:
    """Count, rank and find the best and the default trial of ``study``."""
    counts = {s.name.lower(): sum(t.state == s for t in study.trials) for s in (_State.COMPLETE, _State.PRUNED, _State.FAIL)}
    default = next((t for t in study.trials if t.user_attrs.get("defaults") and t.state == _State.COMPLETE), None)
    importances, notes = param_importances(study)
    return StudyOutcome(len(study.trials), counts, study.best_trial, default, importances, tuple(notes))


@dataclass(frozen=True)
class HeldOut:
    """The defaults against the tuned parameters on the held-out episodes.

    Attributes:
        seeds: the episodes' env seeds.
        rows: ``{"defaults" | "tuned": {column key: spread over seeds}}`` (the keys of ``_COLUMNS``).
        tuned_better_on: episodes where the tuned objective is lower.
        paired: spread of the per-episode objective difference, tuned - defaults (m).
        paired_ci_m: bootstrap interval of the mean paired difference (m).
        paired_metrics: per metric of ``_PAIRED``, the spread of its per-episode paired
            difference and the bootstrap interval of its mean (the objective's is ``paired``,
            ``paired_ci_m``).
    """

    seeds: tuple[int, ...]
    rows: Mapping[str, Mapping[str, metrics.Spread]]
    tuned_better_on: int
    paired: metrics.Spread
    paired_ci_m: tuple[float, float]
    paired_metrics: Mapping[str, tuple[metrics.Spread, tuple[float, float]]] = dataclasses.field(default_factory=dict)


def compare_held_out(seeds: Sequence[int], evals: Sequence[tuple[EpisodeScore, EpisodeScore]], seed: int) -> HeldOut:
    """Spreads over seeds and the paired differences; ``seed`` seeds the bootstrap.

    Every metric's interval resamples the same seeds (one generator per metric, all seeded with
    ``seed``), so the objective's interval is the one the earlier report gave.
    """
    rows = {
        label: {info.key: metrics.over_seeds([value(e[k]) for e in evals]) for info, value in _COLUMNS}
        for label, k in (("defaults", 0), ("tuned", 1))
    }
    wins = sum(t.objective < d.objective for d, t in evals)
    values = {info.key: value for info, value in _COLUMNS}
    paired = {}
    for key in _PAIRED:
        differences = [values[key](t) - values[key](d) for d, t in evals]
        ci = bootstrap_ci(differences, rng=np.random.default_rng(seed), level=_CI_LEVEL)
        paired[key] = (metrics.over_seeds(differences), ci)
    spread, ci = paired["objective_m"]
    return HeldOut(tuple(seeds), rows, wins, spread, ci, paired)


def resolution_text(held_out: HeldOut) -> str:
    """What the held-out seeds can resolve, computed from the paired objective interval.

    States the interval's width and half-width, whether it excludes zero, and (for a nonzero
    mean difference) about how many seeds an interval excluding zero at that difference needs
    (the half-width shrinks as 1 / sqrt(seeds)).
    """
    n = len(held_out.seeds)
    low, high = held_out.paired_ci_m
    mean = held_out.paired.mean
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"With {n} held-out seeds no paired objective difference was finite, so there is no interval."
    if held_out.paired.n < 2:
        return (f"With {held_out.paired.n} held-out seed with a finite paired difference the interval is a single point "
                "(zero width by construction): it resolves nothing; use --eval-seeds >= 2, better >= "
                f"{_FEW_SEEDS}.")  # fmt: skip
    width, half = high - low, (high - low) / 2
    level = f"{_CI_LEVEL * 100:g} %"
    text = (f"With {n} held-out seed{'s' if n != 1 else ''} the {level} interval of the mean paired objective difference is "
            f"{width:.4f} m wide (half-width {half:.4f} m): a mean effect smaller than about {half:.4f} m cannot be told "
            "from zero with these seeds. ")  # fmt: skip
    if low > 0 or high < 0:
        text += (f"The interval [{low:+.4f}, {high:+.4f}] m excludes zero: the tuned parameters are "
                 f"{'better' if high < 0 else 'worse'} than the defaults on these episodes.")  # fmt: skip
    else:
        text += f"The interval [{low:+.4f}, {high:+.4f}] m does not exclude zero."
        if half > 0 and mean != 0 and math.isfinite(mean):
            needed = math.ceil(n * (half / abs(mean)) ** 2)
            text += (f" Resolving the observed mean difference of {mean:+.4f} m would take about {needed} seeds "
                     "(the half-width shrinks as 1 / sqrt(seeds)).")  # fmt: skip
    if n < _FEW_SEEDS:
        text += (f" With fewer than {_FEW_SEEDS} seeds the percentile bootstrap understates the interval; "
                 "use more --eval-seeds before reading it.")  # fmt: skip
    return text


def _pm(s: metrics.Spread, fmt: str) -> str:
    """``mean ± sd`` in ``fmt`` (a sign flag applies to the mean only), ``n/a`` without a value."""
    if not s.n:
        return "n/a"
    return f"{fmt.format(s.mean)} ± {fmt.replace('{:+', '{:').format(s.sd)}"


# ------------------------------------------------------------------------------------ report


def _summary(plan: StudyPlan, config: TuneConfig, outcome: StudyOutcome, held_out: HeldOut) -> dict[str, Any]:
    """What ``summary.json`` holds."""
    best, default = outcome.best, outcome.defaults
    return {
        "study": plan.name,
        "storage": config.storage,
        **plan.attrs,
        "eval_seeds": list(held_out.seeds),
        "trials": dict(outcome.counts),
        "best_trial": best.number,
        "best_training_objective_m": best.value,
        "default_training_objective_m": None if default is None else default.value,
        "best_params": plan.space.applied(best.params),
        "defaults": plan.space.defaults(),
        "held_out": {label: {k: dataclasses.asdict(s) for k, s in row.items()} for label, row in held_out.rows.items()},
        "tuned_better_on": held_out.tuned_better_on,
        "paired_objective_difference_m": dataclasses.asdict(held_out.paired),
        "paired_objective_difference_ci95_m": list(held_out.paired_ci_m),
        "paired_differences": {
            key: {**dataclasses.asdict(spread), "ci95": list(ci)} for key, (spread, ci) in held_out.paired_metrics.items()
        },
        "resolution": resolution_text(held_out),
        "importances": dict(outcome.importances),
        "importance_notes": list(outcome.importance_notes),
    }


def _setup_section(plan: StudyPlan, config: TuneConfig, outcome: StudyOutcome) -> list[str]:
    """Title and the run's world, objective, search and best trial."""
    setup, attrs, counts, best, default = plan.setup, plan.attrs, outcome.counts, outcome.best, outcome.defaults
    seconds = f"{setup.episode_steps} steps ({setup.episode_steps * plan.world.step_s:.0f} s)"
    overrides = f", overrides `{json.dumps(attrs['env_overrides'])}`" if attrs["env_overrides"] else ""
    return [
        f"# Tuning `{config.localizer}`: study `{plan.name}`",
        "",
        f"- World `{setup.env_id}`, crowd size {attrs['crowd_size']}, scenario `{setup.scenario}`, {seconds} per episode"
        f"{overrides}.",
        *(
            [
                f"- Given to every trial and held-out episode besides the searched parameters (the localizer's preparation): "
                f"{', '.join(f'`{k}` = `{v}`' for k, v in plan.fixed.items())}."
            ]
            if plan.fixed
            else []
        ),  # fmt: skip
        f"- Objective (minimized): {plan.terms.describe()}, mean over the training episodes "
        f"(env seeds {list(attrs['train_seeds'])}), each recorded once and replayed into every trial. A failure is a "
        f"step whose valid estimate is >= {plan.terms.fail_m:g} m from the truth; failures are counted and reported "
        "whatever their penalty.",
        f"- Search: Optuna TPE (seed {config.seed}) with median pruning, storage `{config.storage}`; "
        f"{outcome.trials} trials in the study: {counts['complete']} completed, {counts['pruned']} pruned, "
        f"{counts['fail']} failed.",
        f"- Best trial #{best.number}: training objective {_value(best):.4f} m"
        + (f" (defaults, trial #{default.number}: {_value(default):.4f} m)." if default else "."),
        "",
    ]


def _held_out_section(held_out: HeldOut) -> list[str]:
    """The defaults-against-tuned table on the held-out seeds and the paired difference."""
    seeds, base = held_out.seeds, seed_base_text()
    first, last = seeds[0] - EVAL_SEED_BASE, seeds[-1] - EVAL_SEED_BASE
    lines = [
        f"## Held-out episodes ({len(seeds)}, env seeds {base} + {first} .. {base} + {last}, never tuned on)",
        "",
        "Mean ± sd over seeds (per-seed means from each localizer's first fix on).",
        "",
        "| parameters | " + " | ".join(info.label for info, _ in _COLUMNS) + " |",
        "|---|" + "---|" * len(_COLUMNS),
    ]
    for label, row in held_out.rows.items():
        lines.append(f"| {label} | " + " | ".join(_pm(row[info.key], info.fmt) for info, _ in _COLUMNS) + " |")
    low, high = held_out.paired_ci_m
    lines += [
        "",
        f"Tuned beats the defaults on {held_out.tuned_better_on} of {len(seeds)} held-out seeds; paired objective "
        f"difference (tuned - defaults, same recording): {_pm(held_out.paired, '{:+.4f}')} m, {_CI_LEVEL * 100:g} % "
        f"bootstrap CI of its mean [{low:+.4f}, {high:+.4f}] m.",
        "",
        f"Paired differences per metric (tuned - defaults on the same recording; mean ± sd over seeds, "
        f"{_CI_LEVEL * 100:g} % percentile-bootstrap interval of the mean):",
        "",
        "| metric | tuned - defaults | interval | excludes 0 |",
        "|---|---|---|---|",
    ]
    labels = {info.key: info for info, _ in _COLUMNS}
    for key, (spread, (lo, hi)) in held_out.paired_metrics.items():
        info = labels[key]
        fmt = "{:+" + info.fmt[2:]
        interval = f"[{fmt.format(lo)}, {fmt.format(hi)}]" if math.isfinite(lo) else "n/a"
        excludes = "n/a" if not math.isfinite(lo) else ("yes" if lo > 0 or hi < 0 else "no")
        lines.append(f"| {info.label} | {_pm(spread, fmt)} | {interval} | {excludes} |")
    lines += ["", resolution_text(held_out), ""]
    return lines


def _best_params_section(localizer: str, space: SearchSpace, outcome: StudyOutcome) -> list[str]:
    """Each searched parameter: its default, tuned value, range and importance."""
    lines = [
        "## Best parameters",
        "",
        f"`best_params.yaml` (ready as `localizer_params`, e.g. `localizers.registry.load_params({localizer!r}, yaml)`).",
        "",
        "| parameter | default | tuned | searched | importance |",
        "|---|---|---|---|---|",
    ]
    defaults, tuned, importances = space.defaults(), space.applied(outcome.best.params), outcome.importances
    for r in space.params:
        imp = f"{importances[r.name]:.3f}" if r.name in importances else "n/a"
        lines.append(
            f"| `{r.name}` | {_format_value(defaults[r.name])} | {_format_value(tuned.get(r.name))} | {r.describe()} | {imp} |"
        )
    return lines


def _importance_section(outcome: StudyOutcome) -> list[str]:
    """The importance ranking, its notes and the two figures."""
    lines = ["", "## Parameter importance and optimization history", ""]
    if outcome.importances:
        ranking = ", ".join(f"`{k}` {v:.2f}" for k, v in outcome.importances.items())
        lines.append(f"PED-ANOVA importances (optuna's default evaluator) over the completed trials: {ranking}.")
    lines += [f"Note: {n}" for n in outcome.importance_notes]
    return [*lines, "", "![importance](importance.png)", "", "![history](history.png)", ""]


def write_report(
    plan: StudyPlan, config: TuneConfig, study: optuna.Study, evals: Sequence[tuple[EpisodeScore, EpisodeScore]]
) -> dict[str, Any]:
    """Write ``report.md``, ``best_params.yaml``, ``summary.json`` and the two figures under ``plan.out``.

    Args:
        plan: the checked run.
        config: the run's configuration.
        study: the study, with at least one completed trial.
        evals: per held-out seed, the defaults' and the tuned parameters' scores.

    Returns:
        The summary written to ``summary.json``.
    """
    out = plan.out
    out.mkdir(parents=True, exist_ok=True)
    outcome = study_outcome(study)
    title = f"{plan.name}\n{outcome.counts['complete']} completed, {outcome.counts['pruned']} pruned trials"
    plot_importances(out / "importance.png", outcome.importances, title)
    plot_history(out / "history.png", study, title)
    best = outcome.best
    header = [f"crowdloc tune {config.localizer}: study {plan.name!r}, best trial #{best.number}, "
              f"training objective {_value(best):.4f} m"]  # fmt: skip
    if plan.space.sum_to_one:
        header.append("sum_to_one groups (" + "; ".join(", ".join(g) for g in plan.space.sum_to_one) + ") as applied: "
                      "the drawn weights divided by their sum")  # fmt: skip
    (out / "best_params.yaml").write_text(best_params_yaml(config.localizer, plan.space.applied(best.params), plan.space, header))
    held_out = compare_held_out(plan.held_out_seeds, evals, config.seed)
    summary = _summary(plan, config, outcome, held_out)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    sections = (
        _setup_section(plan, config, outcome),
        _held_out_section(held_out),
        _best_params_section(config.localizer, plan.space, outcome),
        _importance_section(outcome),
    )
    (out / "report.md").write_text("\n".join(line for section in sections for line in section))
    return summary
