"""``crowdloc eval``: policies x localizers x crowd sizes x held-out seeds, with bootstrap CIs.

Every cell of the grid is one episode on a held-out seed (``EVAL_SEED_BASE + i``, never used
in training) of any registered crowdloc world (``env_id``, or ``env_kwargs["world"]``, a YAML
path), with any localizer whose measurement kind's sensor that world has. Cells run through
:func:`agents.common.sweep.run_tasks` (local processes or Ray).

- :mod:`.spec`: the grid (:class:`EvalSpec`, :class:`Cell`) and its checks;
- :mod:`.episode`: the rollout, :func:`run_episode` and the core pose metrics, which apply to
  every localizer (errors, failure rate, availability, first fix, collisions, return);
- :mod:`.plugins`: metric plug-ins by measurement kind (:func:`register_metrics`); an
  episode gets its localizer's kind's, a kind without one has no such values (NaN);
- :mod:`.bearings`: the ``bearings`` plug-in (the landmark search, the posterior Cramer-Rao
  bound and error / bound);
- :mod:`.stats`: :func:`bootstrap_ci`, :func:`summarize` and :func:`evaluate`;
- :mod:`.outputs`: CSV tables, ``summary.md``, plots, TUM trajectories, the GIF;
- :mod:`.journal`: ``episodes.jsonl``, each episode written as it finishes (``--resume``);
- :mod:`.goal`: ``goal_missed`` and ``time_to_goal_s`` in a world with a goal;
- :mod:`.paired`: the paired verdict (``crowdloc eval --verdict POLICY``): a policy against the
  best fixed policy of the run, per metric the per-seed difference and its bootstrap interval;
- :mod:`.cli`: :func:`run_cli`;
- :mod:`.metrics`: the pose metrics on trajectories (errors, NEES, recovery), used by the
  episodes, ``crowdloc tune`` and the reproductions alike;
- :mod:`.consistency`: whether a localizer's reported covariance is honest (pooled NEES),
  in numbers and words.

Aggregates: per (policy, localizer, crowd size) the mean over seeds (over the episodes with a
value; the summary shows how many) and a 95% percentile bootstrap interval of that mean.
From Python::

    result = evaluate(EvalSpec(policies=("spin", "ppo:results/train/x/seed_0/model.zip"), seeds=5))
    write_outputs(result, Path("results/eval"))

May import: ``envs``, ``localizers``, :mod:`agents.common`, :mod:`agents.policies`,
:mod:`agents.experiments`, :mod:`agents.rl`; never :mod:`agents.tune`, :mod:`agents.papers`,
:mod:`agents.cli`, :mod:`agents.demo`.
"""

from __future__ import annotations

from agents.evaluate.bearings import BEARING_METRICS, bearing_metrics, bound_rmse_along
from agents.evaluate.cli import parse_gif_cell, run_cli, spec_from_args
from agents.evaluate.episode import Episode, Rollout, episode_metrics, rollout, run_episode
from agents.evaluate.goal import GOAL_METRICS, goal_metrics
from agents.evaluate.kidnap import KIDNAP_METRICS, Kidnap, kidnap_metrics
from agents.evaluate.outputs import (
    NO_COVARIANCE,
    format_stat,
    plot_error_vs_spread,
    plot_summary,
    quaternion_to_yaw,
    read_tum,
    render_gif,
    reports_covariance,
    summary_markdown,
    write_outputs,
    write_tables,
    write_tum,
    yaw_to_quaternion,
)
from agents.evaluate.paired import PairedDifference, VerdictRow, paired_difference, paired_verdict, write_verdict
from agents.evaluate.plugins import (
    CORE_METRICS,
    EpisodeContext,
    MetricInfo,
    MetricPlugin,
    PluginOutput,
    Track,
    localizer_metrics,
    metric_infos,
    metric_plugins,
    register_metrics,
    unregister_metrics,
)
from agents.evaluate.spec import (
    PPO_PREFIX,
    Cell,
    EvalSpec,
    check_observation_space,
    check_policy,
    crowdloc_ids,
    policy_seed,
    slug,
)
from agents.evaluate.stats import EvalResult, Stat, SummaryRow, bootstrap_ci, evaluate, summarize

#: the metric rows of every registered kind as imported (the core ones and the bearings
#: plug-in's); :func:`metric_infos` reads the registry as it is now
METRICS: tuple[MetricInfo, ...] = metric_infos()
METRIC_KEYS = tuple(m.key for m in METRICS)

__all__ = [
    "BEARING_METRICS",
    "CORE_METRICS",
    "GOAL_METRICS",
    "KIDNAP_METRICS",
    "NO_COVARIANCE",
    "METRICS",
    "METRIC_KEYS",
    "PPO_PREFIX",
    "PairedDifference",
    "Cell",
    "Episode",
    "EpisodeContext",
    "EvalResult",
    "EvalSpec",
    "Kidnap",
    "MetricInfo",
    "MetricPlugin",
    "PluginOutput",
    "Rollout",
    "Stat",
    "SummaryRow",
    "Track",
    "VerdictRow",
    "bearing_metrics",
    "bootstrap_ci",
    "bound_rmse_along",
    "check_observation_space",
    "check_policy",
    "crowdloc_ids",
    "episode_metrics",
    "evaluate",
    "format_stat",
    "goal_metrics",
    "kidnap_metrics",
    "localizer_metrics",
    "metric_infos",
    "metric_plugins",
    "paired_difference",
    "paired_verdict",
    "parse_gif_cell",
    "plot_error_vs_spread",
    "plot_summary",
    "policy_seed",
    "quaternion_to_yaw",
    "read_tum",
    "register_metrics",
    "render_gif",
    "reports_covariance",
    "rollout",
    "run_cli",
    "run_episode",
    "slug",
    "spec_from_args",
    "summarize",
    "summary_markdown",
    "unregister_metrics",
    "write_outputs",
    "write_tables",
    "write_tum",
    "write_verdict",
    "yaw_to_quaternion",
]
