"""``crowdloc tune``: learn a localizer's parameters with Optuna instead of setting them by hand.

The papers (docs/papers.md) set many thresholds by hand; this module searches a localizer's
parameters for a given world, crowd density and motion scenario:

* **Search space**: ``configs/tuning/<localizer>.yaml`` (:func:`load_search_space`), per
  parameter ``{low, high[, log][, step]}`` or ``{choices: [...]}``; dotted names reach nested
  parameters (``mcl.hit_std_m``); ``sum_to_one`` groups (the beam model's mixture weights)
  are normalized before they are applied. Parameters not in the space keep their YAML
  defaults. The tunable localizers are those with a file (:func:`tunable_localizers`); the
  shipped ones without (:data:`UNTUNED`: dead reckoning, the ceiling targets) are refused
  with the reason.
* **World**: by the measurement kind the localizer reads (:data:`DEFAULT_WORLDS`): bearing
  localizers on the crowded soccer field (``crowdloc/RoboCupCrowded-v0``, Exp 2's soccer
  scenario), LIDAR ones in the far-point paper's crowded room (``crowdloc/CrowdedRoom-v0``)
  on its square path (3 laps of a 2.5 m square, as in that experiment), stereo-edge ones on
  the far-landmark paper's campus (``crowdloc/StereoCampus-v0``) along its route; ``--env-id``,
  ``--scenario`` and ``--episode-steps`` override (:func:`default_setup`). A localizer with a
  preparation hook gets what it makes once per study (``far_landmark_pf``: the world's default
  scene map, driven at the crowd of the world's file, :meth:`EpisodeSetup.prepared_params`), the same for every
  trial and held-out episode.
* **Episodes, recorded once**: ``--train-seeds`` episodes are rolled out once
  (:func:`agents.experiments.replay.record`) and every trial replays its localizer into the same
  recordings. This is exact, not an approximation: the world, the crowd, the scenario driver
  and the sensors never read the localizer (the driver steers on the *true* pose, and a
  localizer draws from its own generator; the route scenario steers on the LIDAR reference,
  which runs online beside, never on the tuned localizer), so the observation stream of a seed is the same
  whatever the parameters are; replaying it equals running the localizer online
  (``tests/agents/test_replay.py``). It also gives every trial identical data (common random
  numbers), which makes trial-to-trial differences due to the parameters alone. (An active
  policy that steers on the estimate would break this; the scenarios here never read it.)
* **Objective** (:func:`score_episode`, minimized): per episode, the mean position error
  from the localizer's first fix on (m), plus ``penalty_m`` (default 1 m) times the share of
  the episode without a valid estimate (a late first fix or lost tracks cost up to 1 m), plus
  ``failure_penalty_m`` (default 1 m) times the failure share, the share of steps whose valid
  estimate is at least ``fail_m`` from the truth (default 1 m in the LIDAR room, paper B's
  failure; 0.5 m elsewhere); a localizer that never fixes scores the map diagonal plus the
  penalty. The trial value is the mean over the training episodes. ``failure_penalty_m = 0``
  gives the earlier objective (error and availability) exactly.
* **Search**: seeded TPE with median pruning: after each episode the running mean is
  reported, and a trial whose running mean is worse than the median of earlier trials at the
  same episode is stopped (from episode ``PRUNER_WARMUP_STEPS + 1`` on, once
  ``PRUNER_STARTUP_TRIALS`` trials have finished). The YAML defaults
  (``configs/localizers/<name>.yaml``) are the first trial of a new study, run in the main
  process before the workers start, so they are always in the comparison.
* **Storage**: any SQLAlchemy URL (default ``sqlite:///results/tuning.db``); several workers
  (``--workers``, or a Ray cluster with ``--ray-address`` and a database server they can
  all reach) run ``study.optimize`` against the same study. A study remembers the episode
  setup it was created with and refuses to mix trials from another one.
* **Held-out check**: the best parameters and the defaults are replayed on ``--eval-seeds``
  episodes with env seeds ``EVAL_SEED_BASE + i`` (never a tuning seed, which are ``0..n-1``);
  ``<out>/report.md`` has the table (error, availability, failures), the paired difference of
  each metric with its 95 % bootstrap interval, a paragraph on what the number of held-out
  seeds can resolve, ``best_params.yaml`` (ready as ``localizer_params``), the parameter
  importances and the optimization history as PNG figures. An existing report is replaced
  only with ``--overwrite``.

Modules: :mod:`~agents.tune.space` (the search space), :mod:`~agents.tune.objective` (episodes,
scores, the trial function), :mod:`~agents.tune.plan` (the run's configuration and plan),
:mod:`~agents.tune.study` (storage, workers, :func:`tune`, the command line),
:mod:`~agents.tune.report` (``best_params.yaml``, figures, ``report.md``).

May import: ``envs``, ``localizers`` and every other part of ``agents`` but :mod:`agents.cli`
and :mod:`agents.demo` (the far-point paper's square path comes from :mod:`agents.papers`).
"""

from agents.tune.objective import (
    DEFAULT_ENV_ID,
    DEFAULT_FAIL_M,
    DEFAULT_FAILURE_PENALTY_M,
    DEFAULT_PENALTY_M,
    DEFAULT_WORLDS,
    SCENARIOS,
    EpisodeScore,
    EpisodeSetup,
    ObjectiveTerms,
    WorldFacts,
    default_fail_m,
    default_setup,
    eval_seeds,
    score_episode,
    tuning_seeds,
)
from agents.tune.plan import DEFAULT_STORAGE, StudyPlan, TuneConfig, TuneResult
from agents.tune.report import best_params_yaml, param_importances, resolution_text, write_report
from agents.tune.space import (
    TUNING_CONFIG_DIR,
    UNTUNED,
    ParamRange,
    SearchSpace,
    load_search_space,
    space_path,
    tunable_localizers,
)
from agents.tune.study import add_arguments, run_cli, tune

__all__ = [
    "DEFAULT_ENV_ID",
    "DEFAULT_FAILURE_PENALTY_M",
    "DEFAULT_FAIL_M",
    "DEFAULT_PENALTY_M",
    "DEFAULT_STORAGE",
    "DEFAULT_WORLDS",
    "SCENARIOS",
    "TUNING_CONFIG_DIR",
    "UNTUNED",
    "EpisodeScore",
    "EpisodeSetup",
    "ObjectiveTerms",
    "ParamRange",
    "SearchSpace",
    "StudyPlan",
    "TuneConfig",
    "TuneResult",
    "WorldFacts",
    "add_arguments",
    "best_params_yaml",
    "default_fail_m",
    "default_setup",
    "eval_seeds",
    "load_search_space",
    "param_importances",
    "resolution_text",
    "run_cli",
    "score_episode",
    "space_path",
    "tunable_localizers",
    "tune",
    "tuning_seeds",
    "write_report",
]
