"""Running a ``crowdloc tune`` study: checking its configuration, storage, workers and :func:`tune`.

The study lives in any SQLAlchemy database (SQLite by default); several workers (local
processes or a Ray cluster) run ``study.optimize`` against it. A study remembers the episode
setup it was created with and refuses to mix trials from another one.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import optuna

from agents.common.sweep import run_tasks
from agents.common.util import at_least, make_out_dir, nest, refuse_to_overwrite, seed_int
from agents.tune.objective import (
    DEFAULT_EPISODE_STEPS,
    DEFAULT_FAIL_M,
    DEFAULT_WORLDS,
    FAIL_M_BY_WORLD,
    SCENARIOS,
    SOCCER_START_POSE,
    EpisodeSetup,
    Objective,
    ObjectiveTerms,
    WorldFacts,
    default_fail_m,
    default_setup,
    eval_seeds,
    evaluate_task,
    record_task,
    seed_base_text,
    tuning_seeds,
)
from agents.tune.plan import DEFAULT_STORAGE, StudyPlan, TuneConfig, TuneResult, default_study_name
from agents.tune.report import write_report
from agents.tune.space import UNTUNED, SearchSpace, load_search_space, tunable_localizers
from core.schema import ConfigError
from localizers.registry import spec

#: median pruning: trials run unpruned until this many finished; none is pruned before its second episode
PRUNER_STARTUP_TRIALS = 5
PRUNER_WARMUP_STEPS = 1
#: study attributes that define the objective; a stored study must match them
_SETUP_ATTRS = ("localizer", "env_id", "crowd_size", "scenario", "episode_steps", "env_overrides", "train_seeds", "penalty_m",
                "failure_penalty_m", "fail_m")  # fmt: skip


def check_tunable(localizer: str, space: Path | None = None) -> None:
    """ConfigError for an unknown localizer, or one in :data:`~agents.tune.space.UNTUNED` without ``space``."""
    spec(localizer)
    if space is None and localizer in UNTUNED:
        raise ConfigError(f"localizer {localizer!r} is not tunable: {UNTUNED[localizer]} (tunable: "
                          f"{', '.join(tunable_localizers())})")  # fmt: skip


def _check_config(config: TuneConfig) -> tuple[SearchSpace, EpisodeSetup, ObjectiveTerms, WorldFacts]:
    s = spec(config.localizer)
    check_tunable(config.localizer, config.space_path)
    for name in ("trials", "train_seeds", "eval_seeds", "workers"):
        value = getattr(config, name)
        if value < 1:
            raise ConfigError(f"{name.replace('_', '-')} must be >= 1, got {value}")
    setup = config.setup if config.setup is not None else default_setup(config.localizer)
    setup = dataclasses.replace(setup, measurement=s.measurement)
    fail_m = config.fail_m if config.fail_m is not None else default_fail_m(setup.env_id)
    terms = ObjectiveTerms(config.penalty_m, config.failure_penalty_m, fail_m)
    terms.check()
    world = setup.facts()
    return load_search_space(config.localizer, config.space_path), setup, terms, world


def plan_study(config: TuneConfig) -> StudyPlan:
    """Check ``config`` and settle the study name, report folder, episodes, seeds and study attributes."""
    space, setup, terms, world = _check_config(config)
    name = config.study_name or default_study_name(config.localizer, setup, world.crowd_size)
    out = config.out if config.out is not None else Path("results") / "tuning" / name
    train = tuning_seeds(config.train_seeds)
    held_out = eval_seeds(config.eval_seeds)
    assert not set(train) & set(held_out)
    attrs = {
        "localizer": config.localizer,
        "env_id": setup.env_id,
        "crowd_size": world.crowd_size,
        "scenario": setup.scenario,
        "episode_steps": setup.episode_steps,
        "env_overrides": json.loads(json.dumps(dict(setup.env_overrides))),
        "train_seeds": list(train),
        "penalty_m": terms.penalty_m,
        "failure_penalty_m": terms.failure_penalty_m,
        "fail_m": terms.fail_m,
        "space": {r.name: r.describe() for r in space.params},
    }
    if space.sum_to_one:
        attrs["sum_to_one"] = [list(g) for g in space.sum_to_one]
    return StudyPlan(name, out, space, setup, terms, world, train, held_out, attrs, setup.prepared_params(config.localizer))


def _stored_attr(stored: Mapping[str, Any], key: str, attrs: Mapping[str, Any]) -> Any:
    """A stored study's setup attribute; a study made before failures were counted has none for
    ``failure_penalty_m`` (its objective had no failure term: 0) and ``fail_m`` (irrelevant then)."""
    if key in stored:
        return stored[key]
    if key == "failure_penalty_m":
        return 0.0
    if key == "fail_m" and "failure_penalty_m" not in stored and attrs["failure_penalty_m"] == 0:
        return attrs[key]
    return None


# ------------------------------------------------------------------------------------ storage and workers


def _set_log_level(verbose: bool) -> None:
    optuna.logging.set_verbosity(optuna.logging.INFO if verbose else optuna.logging.WARNING)


def _sampler(seed: int) -> optuna.samplers.BaseSampler:
    return optuna.samplers.TPESampler(seed=seed)


def _pruner() -> optuna.pruners.BasePruner:
    return optuna.pruners.MedianPruner(n_startup_trials=PRUNER_STARTUP_TRIALS, n_warmup_steps=PRUNER_WARMUP_STEPS)


def _storage(url: str) -> optuna.storages.BaseStorage:
    """An RDB storage for ``url``; for a SQLite file its folder is created first.

    Raises:
        ConfigError: one line naming ``--storage`` and ``url``, for a URL that is not a database
            URL, names a database kind SQLAlchemy has no driver for, or a database that cannot be
            reached or created.
    """
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError, SQLAlchemyError

    def refused(why: str) -> ConfigError:
        return ConfigError(f"--storage {url!r}: {why} (e.g. {DEFAULT_STORAGE})")

    try:
        parsed = make_url(url)
    except ArgumentError as exc:
        raise refused(f"not a database URL: {exc}") from None
    engine_kwargs: dict[str, Any] = {}
    try:
        if parsed.get_backend_name() == "sqlite":
            if parsed.database and parsed.database != ":memory:":
                Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
            engine_kwargs["connect_args"] = {"timeout": 60}  # parallel workers wait for the write lock
        return optuna.storages.RDBStorage(url, engine_kwargs=engine_kwargs)
    except (SQLAlchemyError, ImportError) as exc:  # no such dialect (NoSuchModuleError), no driver, cannot connect
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise refused(f"cannot open the database ({type(exc).__name__}: {reason})") from None
    except OSError as exc:
        raise refused(f"cannot create its folder ({exc.strerror or exc})") from None


def _open_study(config: TuneConfig, plan: StudyPlan) -> optuna.Study:
    """Create or load the study; check it was made for the same objective; enqueue the defaults once."""
    name, attrs, space = plan.name, plan.attrs, plan.space
    study = optuna.create_study(
        storage=_storage(config.storage),
        study_name=name,
        direction="minimize",
        load_if_exists=True,
        sampler=_sampler(config.seed),
        pruner=_pruner(),
    )
    stored = study.user_attrs
    if stored:
        diff = [k for k in _SETUP_ATTRS if _stored_attr(stored, k, attrs) != attrs[k]]
        if diff:
            k = diff[0]
            raise ConfigError(f"study {name!r} in {config.storage} was created with {k}={_stored_attr(stored, k, attrs)!r}, this run has "
                              f"{k}={attrs[k]!r}; use another --study-name")  # fmt: skip
    else:
        for k, v in attrs.items():
            study.set_user_attr(k, v)
    if not study.trials:
        defaults = space.defaults()
        if space.contains(defaults):
            study.enqueue_trial(defaults, user_attrs={"defaults": True})
    return study


@dataclass(frozen=True)
class _WorkerTask:
    storage: str
    study_name: str
    objective: Objective
    trials: int
    sampler_seed: int
    verbose: bool


def _optimize_worker(task: _WorkerTask) -> int:
    """One worker: ``study.optimize`` for its share of trials against the shared storage."""
    _set_log_level(task.verbose)
    study = optuna.load_study(
        study_name=task.study_name,
        storage=_storage(task.storage),
        sampler=_sampler(task.sampler_seed),
        pruner=_pruner(),
    )
    study.optimize(task.objective, n_trials=task.trials, catch=(ConfigError,))
    return task.trials


def _optimize(config: TuneConfig, study: optuna.Study, objective: Objective, first_new: int) -> None:
    """Run ``config.trials`` trials: the enqueued defaults here, the rest split over the workers.

    Worker ``i`` samples with seed ``SeedSequence([config.seed, i, first_new])``, ``first_new``
    being the study's trial count when this run opened it.
    """
    remaining = config.trials
    if study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.WAITING,)):
        # the enqueued defaults run here, before any worker starts: on SQLite two processes
        # can pop the same waiting trial (https://github.com/optuna/optuna/issues/4002)
        study.optimize(objective, n_trials=1, catch=(ConfigError,))
        remaining -= 1
    workers = min(config.workers, remaining)
    shares = [remaining // workers + (i < remaining % workers) for i in range(workers)] if workers else []
    tasks = [
        _WorkerTask(config.storage, study.study_name, objective, n,
                    int(np.random.SeedSequence([config.seed, i, first_new]).generate_state(1)[0]), config.verbose)
        for i, n in enumerate(shares)
    ]  # fmt: skip
    if tasks:
        run_tasks(_optimize_worker, tasks, workers=workers, ray_address=config.ray_address, desc="tuning workers",
                  progress=False)  # fmt: skip


# ------------------------------------------------------------------------------------ driver


def tune(config: TuneConfig) -> TuneResult:
    """Search, evaluate on held-out seeds and write the report (see :mod:`agents.tune`).

    Raises:
        ConfigError: a bad localizer, search space, episode setup, count or storage URL, or a
            stored study made for another setup.
    """
    plan = plan_study(config)
    setup = plan.setup
    refuse_to_overwrite(plan.out / "report.md", config.overwrite)
    make_out_dir(plan.out)  # before the study: a report that cannot be written fails now, not after the last trial
    _set_log_level(config.verbose)
    study = _open_study(config, plan)
    first_new = len(study.trials)
    recordings = run_tasks(record_task, [(setup, s) for s in plan.train_seeds], workers=config.workers,
                           desc="record training episodes", progress=config.verbose)  # fmt: skip
    fixed = plan.fixed
    _optimize(config, study, Objective(plan.space, tuple(recordings), plan.terms, fixed), first_new)

    study = optuna.load_study(study_name=plan.name, storage=_storage(config.storage))
    if not any(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials):
        raise ConfigError(f"study {plan.name!r}: no trial completed (all pruned or failed); see the log above")
    best = study.best_trial
    applied = plan.space.applied(best.params)
    tasks = [(setup, s, config.localizer, nest(applied), plan.terms, fixed) for s in plan.held_out_seeds]
    evals = run_tasks(evaluate_task, tasks, workers=config.workers, ray_address=config.ray_address,
                      desc="held-out episodes", progress=config.verbose)  # fmt: skip
    summary = write_report(plan, config, study, evals)
    out = plan.out
    return TuneResult(plan.name, out / "report.md", out / "best_params.yaml", applied, len(study.trials), summary)


# ------------------------------------------------------------------------------------ command line


def add_arguments(parser: Any) -> None:
    """The ``crowdloc tune`` options; their defaults are :class:`TuneConfig`'s and :class:`EpisodeSetup`'s."""
    config = TuneConfig(localizer="")
    shipped = ", ".join(tunable_localizers())
    untuned = ", ".join(UNTUNED)
    worlds = "; ".join(f"{kind}: {env_id}" for kind, env_id in DEFAULT_WORLDS.items())
    x_m, y_m, _ = SOCCER_START_POSE
    parser.add_argument("localizer", help=f"a localizer with a search space: {shipped} (not tunable: {untuned}; "
                                          "others: give --space)")  # fmt: skip
    parser.add_argument("--space", type=Path, help="search-space YAML (default configs/tuning/LOCALIZER.yaml)")
    parser.add_argument("--env-id", help=f"the world (default by what the localizer reads: {worlds})")
    parser.add_argument("--crowd-size", type=at_least(0), help="crowd size (default: the world's own)")
    parser.add_argument("--scenario", choices=SCENARIOS,
                        help=f"soccer: Exp 2's chase-dribble-shoot driver from ({x_m:g}, {y_m:g}) m; random_walk: the "
                             "RandomWalk policy from the world's start; square: the LIDAR paper's 3 laps of a 2.5 m "
                             "square in the crowded room; route: route_follower drives the world's route on the LIDAR "
                             "reference (default: square in the room, route where the world has one, soccer where "
                             "there is a ball, else random_walk)")  # fmt: skip
    parser.add_argument("--episode-steps", type=at_least(1),
                        help=f"steps per episode (default {DEFAULT_EPISODE_STEPS}; square: its 3 laps; route: the "
                             "world's episode length)")  # fmt: skip
    parser.add_argument("--env-set", action="append", default=[], metavar="KEY=VALUE",
                        help="world override, e.g. --env-set camera.dropout_probability=0.5 (repeatable)")  # fmt: skip
    parser.add_argument("--train-seeds", type=at_least(1), default=config.train_seeds,
                        help=f"tuning episodes, env seeds 0..N-1 (default {config.train_seeds})")  # fmt: skip
    parser.add_argument("--eval-seeds", type=at_least(1), default=config.eval_seeds,
                        help=f"held-out episodes, env seeds {seed_base_text()} + i (default {config.eval_seeds})")  # fmt: skip
    parser.add_argument("--trials", type=at_least(1), default=config.trials,
                        help=f"trials to add to the study (default {config.trials})")  # fmt: skip
    parser.add_argument("--workers", type=at_least(1), default=config.workers,
                        help=f"parallel study.optimize workers (default {config.workers})")  # fmt: skip
    parser.add_argument("--ray-address", help="run the workers on this Ray cluster (use a storage all nodes reach)")
    parser.add_argument("--storage", default=config.storage, help=f"SQLAlchemy database URL (default {config.storage})")
    parser.add_argument("--study-name", help="default LOCALIZER-ENV-crowdN-SCENARIO; an existing study is continued")
    parser.add_argument("--seed", type=seed_int, default=config.seed, help=f"sampler seed (default {config.seed})")
    parser.add_argument("--penalty-m", type=float, default=config.penalty_m,
                        help=f"metres added to the objective per unit of unavailability (default {config.penalty_m:g})")  # fmt: skip
    parser.add_argument("--failure-penalty-m", type=float, default=config.failure_penalty_m,
                        help="metres added per unit of failure share, the share of steps whose valid estimate is "
                             f">= --fail-m off (default {config.failure_penalty_m:g}; 0: error and availability only, "
                             "the earlier objective)")  # fmt: skip
    by_world = ", ".join(f"{env_id}: {m:g}" for env_id, m in FAIL_M_BY_WORLD.items())
    parser.add_argument("--fail-m", type=float,
                        help=f"failure threshold in metres (default by world: {by_world}; else {DEFAULT_FAIL_M:g})")  # fmt: skip
    parser.add_argument("--out", type=Path, help="report folder (default results/tuning/STUDY)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing report in --out")
    parser.add_argument("--quiet", action="store_true", help="no per-trial log, no progress bars")


def run_cli(args: Any) -> TuneResult:
    """``crowdloc tune`` from parsed arguments (raises ConfigError for bad values)."""
    from agents.rl.config import parse_overrides

    check_tunable(args.localizer, args.space)
    config = TuneConfig(
        localizer=args.localizer,
        setup=default_setup(
            args.localizer,
            env_id=args.env_id,
            crowd_size=args.crowd_size,
            scenario=args.scenario,
            episode_steps=args.episode_steps,
            env_overrides=nest(parse_overrides(args.env_set)),
        ),
        space_path=args.space,
        trials=args.trials,
        train_seeds=args.train_seeds,
        eval_seeds=args.eval_seeds,
        workers=args.workers,
        ray_address=args.ray_address,
        storage=args.storage,
        study_name=args.study_name,
        out=args.out,
        seed=args.seed,
        penalty_m=args.penalty_m,
        failure_penalty_m=args.failure_penalty_m,
        fail_m=args.fail_m,
        overwrite=args.overwrite,
        verbose=not args.quiet,
    )
    return tune(config)
