"""``crowdloc tune``: learn a localizer's parameters with Optuna instead of setting them by hand.

The candidate-set paper (PAPERS.md A) set its thresholds by hand; this module searches any
bearing localizer's parameters for a given world, crowd density and motion scenario:

* **Search space**: ``configs/tuning/<localizer>.yaml`` (:func:`load_search_space`), per
  parameter ``{low, high[, log][, step]}`` or ``{choices: [...]}``; dotted names reach nested
  parameters (``mcl.hit_std_m``). Parameters not in the space keep their YAML defaults.
* **Episodes, recorded once**: ``--train-seeds`` episodes are rolled out once
  (:func:`agents.replay.record`) and every trial replays its localizer into the same
  recordings. This is exact, not an approximation: the world, the crowd, the scenario driver
  and the sensors never read the localizer (the driver steers on the *true* pose, and a
  localizer draws from its own generator), so the observation stream of a seed is the same
  whatever the parameters are; replaying it equals running the localizer online
  (``tests/agents/test_replay.py``). It also gives every trial identical data (common random
  numbers), which makes trial-to-trial differences due to the parameters alone. (An active
  policy that steers on the estimate would break this; the scenarios here never read it.)
* **Objective** (:func:`score_episode`, minimized): per episode, the mean position error
  from the localizer's first fix on (m), plus ``penalty_m`` (default 1 m) times the share of
  the episode without a valid estimate (a late first fix or lost tracks cost up to 1 m); a
  localizer that never fixes scores the map diagonal plus the penalty. The trial value is
  the mean over the training episodes.
* **Search**: seeded TPE with median pruning: after each episode the running mean is
  reported, and a trial whose running mean is worse than the median of earlier trials at the
  same episode is stopped (from the second episode on, once 5 trials have finished). The
  YAML defaults (``configs/localizers/<name>.yaml``) are the first trial of a new study,
  run in the main process before the workers start, so they are always in the comparison.
* **Storage**: any SQLAlchemy URL (default ``sqlite:///results/tuning.db``); several workers
  (``--workers``, or a Ray cluster with ``--ray-address`` and a database server they can
  all reach) run ``study.optimize`` against the same study. A study remembers the episode
  setup it was created with and refuses to mix trials from another one.
* **Held-out check**: the best parameters and the defaults are replayed on ``--eval-seeds``
  episodes with env seeds ``EVAL_SEED_BASE + i`` (never a tuning seed, which are ``0..n-1``);
  ``<out>/report.md`` has the table, ``best_params.yaml`` (ready as ``localizer_params``),
  the parameter importances and the optimization history as PNG figures.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
import types
import typing
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import optuna

import crowdloc_configs
from agents import metrics
from agents.replay import Recording, record, replay
from agents.scenarios import SoccerDriver
from agents.sweep import run_tasks
from agents.train import EVAL_SEED_BASE
from agents.util import flatten, nest
from localizers.registry import LOCALIZERS, load_params, spec
from localizers.schema import ConfigError, load_yaml

TUNING_CONFIG_DIR = crowdloc_configs.path("tuning")  # package data (configs/ in the checkout)
DEFAULT_STORAGE = "sqlite:///results/tuning.db"
DEFAULT_ENV_ID = "crowdloc/RoboCupCrowded-v0"
SCENARIOS = ("soccer", "random_walk")
#: Exp 2 of the candidate-set paper: the field robot starts at (0, 3000) mm facing +x
SOCCER_START_POSE = (0.0, 3.0, 0.0)
#: metres added to the objective per unit of unavailability (share of steps without a pose)
DEFAULT_PENALTY_M = 1.0
#: median pruning: trials run unpruned until this many finished; none is pruned before its second episode
PRUNER_STARTUP_TRIALS = 5
PRUNER_WARMUP_STEPS = 1
_SPEC_KEYS = ("low", "high", "log", "step", "choices")
#: study attributes that define the objective; a stored study must match them
_SETUP_ATTRS = ("localizer", "env_id", "crowd_size", "scenario", "episode_steps", "env_overrides", "train_seeds", "penalty_m")


# ------------------------------------------------------------------------------------ seeds


def tuning_seeds(n: int) -> tuple[int, ...]:
    """Env seeds of the ``n`` training episodes: ``0 .. n - 1`` (all below ``EVAL_SEED_BASE``)."""
    if not 0 <= n <= EVAL_SEED_BASE:
        raise ConfigError(f"train seeds must be in [0, {EVAL_SEED_BASE}], got {n}")
    return tuple(range(n))


def eval_seeds(n: int) -> tuple[int, ...]:
    """Env seeds of the ``n`` held-out episodes: ``EVAL_SEED_BASE + i`` (never a tuning seed)."""
    if n < 0:
        raise ConfigError(f"eval seeds must be >= 0, got {n}")
    return tuple(EVAL_SEED_BASE + i for i in range(n))


# ------------------------------------------------------------------------------------ search space


@dataclass(frozen=True)
class ParamRange:
    """One searched parameter.

    Attributes:
        name: the parameter, dotted for nested ones (``mcl.hit_std_m``).
        kind: ``"float"``, ``"int"`` or ``"categorical"``.
        low, high: bounds (``float``/``int`` kinds), ``low < high``.
        log: sample on a log scale.
        step: discretization step (optional, not with ``log``).
        choices: the values of a categorical parameter.
    """

    name: str
    kind: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    step: float | None = None
    choices: tuple[Any, ...] = ()

    def suggest(self, trial: optuna.Trial) -> Any:
        """Draw this parameter for ``trial``."""
        if self.kind == "categorical":
            return trial.suggest_categorical(self.name, list(self.choices))
        assert self.low is not None and self.high is not None
        if self.kind == "int":
            return trial.suggest_int(self.name, int(self.low), int(self.high), step=int(self.step or 1), log=self.log)
        return trial.suggest_float(self.name, self.low, self.high, step=self.step, log=self.log)

    def contains(self, value: Any) -> bool:
        """Whether ``value`` is a point of this range (for enqueueing the defaults)."""
        if self.kind == "categorical":
            return value in self.choices
        assert self.low is not None and self.high is not None
        if not self.low <= value <= self.high:
            return False
        if self.step is not None:
            k = (value - self.low) / self.step
            return abs(k - round(k)) < 1e-9
        return True

    def describe(self) -> str:
        """Human-readable range, e.g. ``[0.5, 60] log``."""
        if self.kind == "categorical":
            return "{" + ", ".join(map(repr, self.choices)) + "}"
        text = f"[{self.low:g}, {self.high:g}]"
        if self.log:
            text += " log"
        if self.step is not None:
            text += f" step {self.step:g}"
        return text


@dataclass(frozen=True)
class SearchSpace:
    """A localizer's search space (:func:`load_search_space`)."""

    localizer: str
    path: Path
    params: tuple[ParamRange, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def suggest(self, trial: optuna.Trial) -> dict[str, Any]:
        """Draw every parameter: ``{dotted name: value}``."""
        return {p.name: p.suggest(trial) for p in self.params}

    def defaults(self) -> dict[str, Any]:
        """The YAML defaults of the searched parameters: ``{dotted name: value}``."""
        params = load_params(self.localizer)
        out = {}
        for name in self.names:
            value: Any = params
            for part in name.split("."):
                value = getattr(value, part)
            out[name] = value
        return out


def _unwrap_optional(tp: Any) -> Any:
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return rest[0] if len(rest) == 1 else tp
    return tp


def _field_type(params_cls: type, name: str, where: str, localizer: str) -> Any:
    """The annotation of dotted parameter ``name`` of ``params_cls``, or a ConfigError naming it."""
    cls: Any = params_cls
    tp: Any = None
    for i, part in enumerate(name.split(".")):
        fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
        if part not in fields:
            prefix = ".".join(name.split(".")[:i])
            valid = ", ".join(sorted(f"{prefix}.{f}" if prefix else f for f in fields))
            raise ConfigError(
                f"{where}: {name!r} is not a parameter of localizer {localizer!r} ({params_cls.__name__}; valid: {valid})"
            )
        tp = _unwrap_optional(typing.get_type_hints(cls)[part])
        cls = tp
    return tp


def _number(value: Any, integer: bool) -> bool:
    if isinstance(value, bool):
        return False
    return isinstance(value, int) if integer else isinstance(value, (int, float)) and math.isfinite(value)


def _parse_range(name: str, entry: Any, tp: Any, where: str) -> ParamRange:
    """Check one search-space entry against the parameter's type; bounds are checked by the caller."""
    here = f"{where}: {name}"
    if not isinstance(entry, Mapping):
        raise ConfigError(f"{here}: expected a mapping like {{low: 1, high: 10}} or {{choices: [...]}}, got {entry!r}")
    unknown = sorted(set(entry) - set(_SPEC_KEYS))
    if unknown:
        raise ConfigError(f"{here}: unknown key {unknown[0]!r} (valid: {', '.join(_SPEC_KEYS)})")
    if "choices" in entry:
        if set(entry) != {"choices"}:
            raise ConfigError(f"{here}: give either choices or low/high, not both")
        choices = entry["choices"]
        if not isinstance(choices, list) or len(choices) < 2:
            raise ConfigError(f"{here}: choices must be a list of at least 2 values, got {choices!r}")
        for c in choices:
            if c is not None and not isinstance(c, (bool, int, float, str)):
                raise ConfigError(f"{here}: choice {c!r} is not a number, string, bool or null")
        if len(set(map(repr, choices))) != len(choices):
            raise ConfigError(f"{here}: choices {choices!r} repeat a value")
        return ParamRange(name, "categorical", choices=tuple(choices))
    if tp not in (int, float):
        raise ConfigError(f"{here}: a {getattr(tp, '__name__', tp)} parameter needs choices: [...], not low/high")
    missing = [k for k in ("low", "high") if k not in entry]
    if missing:
        raise ConfigError(f"{here}: missing {missing[0]!r}")
    integer = tp is int
    kind = "int" if integer else "float"
    for key in ("low", "high", "step"):
        if key in entry and not _number(entry[key], integer):
            raise ConfigError(f"{here}: {key} must be {'an integer' if integer else 'a finite number'}, got {entry[key]!r}")
    low, high = entry["low"], entry["high"]
    if low >= high:
        raise ConfigError(f"{here}: low ({low!r}) must be < high ({high!r})")
    log = entry.get("log", False)
    if not isinstance(log, bool):
        raise ConfigError(f"{here}: log must be true or false, got {log!r}")
    if log and low <= 0:
        raise ConfigError(f"{here}: a log range needs low > 0, got {low!r}")
    step = entry.get("step")
    if step is not None:
        if step <= 0:
            raise ConfigError(f"{here}: step must be > 0, got {step!r}")
        if log:
            raise ConfigError(f"{here}: step and log cannot be combined")
    return ParamRange(name, kind, float(low) if not integer else low, float(high) if not integer else high, log,
                      None if step is None else (step if integer else float(step)))  # fmt: skip


def space_path(localizer: str) -> Path:
    """``configs/tuning/<localizer>.yaml``."""
    return TUNING_CONFIG_DIR / f"{localizer}.yaml"


def load_search_space(localizer: str, path: str | Path | None = None) -> SearchSpace:
    """Read and check a localizer's search space.

    The file's top level is ``parameters:``, a mapping of parameter name (dotted for nested
    parameters) to ``{low, high, log?, step?}`` or ``{choices: [...]}``. Integer parameters
    need integer bounds. Every bound and choice must itself be a valid value of the parameter
    (checked by building the localizer's parameters with it).

    Args:
        localizer: a registered localizer name.
        path: the YAML file (default ``configs/tuning/<localizer>.yaml``).

    Raises:
        ConfigError: one line naming the localizer, file, parameter or bound at fault.
    """
    s = spec(localizer)
    p = Path(path) if path is not None else space_path(localizer)
    if path is None and not p.is_file():
        raise ConfigError(f"no search space for localizer {localizer!r}: write {p} (see configs/tuning/candidate_sets.yaml)")
    data = load_yaml(p)
    unknown = sorted(set(data) - {"parameters"})
    if unknown:
        raise ConfigError(f"{p}: unknown top-level key {unknown[0]!r} (valid: parameters)")
    entries = data.get("parameters")
    if not isinstance(entries, Mapping) or not entries:
        raise ConfigError(f"{p}: 'parameters' must be a non-empty mapping of parameter name to range")
    params_cls = getattr(importlib.import_module(s.module), s.params_cls)
    ranges = []
    for name, entry in entries.items():
        if not isinstance(name, str):
            raise ConfigError(f"{p}: parameter names must be strings, got {name!r}")
        r = _parse_range(name, entry, _field_type(params_cls, name, str(p), localizer), str(p))
        points = r.choices if r.kind == "categorical" else (r.low, r.high)
        for value in points:
            try:
                load_params(localizer, nest({name: value}))
            except ConfigError as exc:
                raise ConfigError(f"{p}: {name} = {value!r} is not a valid value: {exc}") from None
        ranges.append(r)
    return SearchSpace(localizer, p, tuple(ranges))


# ------------------------------------------------------------------------------------ episodes


class _PolicyDriver:
    """A fixed policy (``agents.policies``) as a scenario driver; it sees only the observation."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy

    @property
    def done(self) -> bool:
        return False

    def reset(self, env: Any) -> None:
        del env
        self.policy.reset()

    def act(self, env: Any) -> Any:
        action, _ = self.policy.predict(env.last_observation)
        return action


@dataclass(frozen=True)
class EpisodeSetup:
    """What a tuning or evaluation episode is.

    Attributes:
        env_id: a registered crowdloc id with a bearing camera.
        crowd_size: other robots / people (``None``: the world's own count).
        scenario: ``"soccer"``: Exp 2's field robot (:class:`agents.scenarios.SoccerDriver`,
            chase, dribble, shoot; start at (0, 3) m facing +x), needs a world with a ball;
            ``"random_walk"``: :class:`agents.policies.RandomWalk` from the world's start pose.
        episode_steps: steps per episode.
        env_overrides: further ``gym.make`` world overrides (``{"camera": {"dropout_probability": 0.5}}``).
    """

    env_id: str = DEFAULT_ENV_ID
    crowd_size: int | None = None
    scenario: str = "soccer"
    episode_steps: int = 900
    env_overrides: Mapping[str, Any] = field(default_factory=dict)

    def world(self) -> Any:
        """The effective world config; ConfigError if this setup cannot record bearings."""
        import envs
        from envs.localization_env import apply_overrides

        if self.env_id not in envs.ENV_WORLDS:
            raise ConfigError(f"unknown env id {self.env_id!r}; known: {', '.join(envs.ENV_WORLDS)}")
        if self.scenario not in SCENARIOS:
            raise ConfigError(f"unknown scenario {self.scenario!r}; known: {', '.join(SCENARIOS)}")
        if self.episode_steps < 1:
            raise ConfigError(f"episode steps must be >= 1, got {self.episode_steps}")
        if self.crowd_size is not None and self.crowd_size < 0:
            raise ConfigError(f"crowd size must be >= 0, got {self.crowd_size}")
        world = apply_overrides(envs.load_world(envs.ENV_WORLDS[self.env_id]), self.crowd_size, **dict(self.env_overrides))
        if world.camera is None:
            raise ConfigError(f"{self.env_id} has no bearing camera; crowdloc tune replays bearing recordings")
        if self.scenario == "soccer" and not (world.crowd.kind == "soccer" and world.crowd.soccer.ball):
            raise ConfigError(f"scenario 'soccer' needs a world with a ball; {self.env_id} has none (try --scenario random_walk)")
        return world

    def env_kwargs(self) -> dict[str, Any]:
        kwargs: dict[str, Any] = {**self.env_overrides, "max_episode_steps": self.episode_steps}
        if self.crowd_size is not None:
            kwargs["crowd_size"] = self.crowd_size
        return kwargs

    def record(self, seed: int) -> Recording:
        """Roll one episode out with env seed ``seed`` (the driver is seeded with it too)."""
        if self.scenario == "soccer":
            return record(self.env_id, SoccerDriver(seed), seed, max_steps=self.episode_steps,
                          env_kwargs=self.env_kwargs(), reset_options={"robot_pose": list(SOCCER_START_POSE)})  # fmt: skip
        from gymnasium import spaces

        from agents.policies import RandomWalk

        policy = RandomWalk(spaces.Box(-1.0, 1.0, (2,), np.float32), seed=seed)
        return record(self.env_id, _PolicyDriver(policy), seed, max_steps=self.episode_steps, env_kwargs=self.env_kwargs())


def _record_task(task: tuple[EpisodeSetup, int]) -> Recording:
    setup, seed = task
    return setup.record(seed)


@dataclass(frozen=True)
class EpisodeScore:
    """One localizer on one recorded episode.

    Attributes:
        position_error_m: mean position error from the first fix on (NaN if it never fixed).
        heading_error_rad: mean heading error from the first fix on (NaN if it never fixed).
        availability: share of all steps with a valid estimate.
        first_fix_s: time of the first valid estimate (``inf`` if none).
        objective: ``position_error_m + penalty_m * (1 - availability)`` (map diagonal for the error if no fix).
    """

    position_error_m: float
    heading_error_rad: float
    availability: float
    first_fix_s: float
    objective: float


def score_episode(recording: Recording, localizer: str, params: Mapping[str, Any] | None, penalty_m: float) -> EpisodeScore:
    """Replay ``recording`` into ``localizer`` with parameter overrides ``params`` and score it.

    The localizer's generator is seeded from the env seed alone, so every parameter set sees
    the same random stream too.
    """
    out = replay(recording, localizer, rng_seed=[recording.seed, 0], params=params or None)
    fix = metrics.first_fix(out.valid)
    avail = metrics.availability(out.valid)
    if fix is None:
        xmin, ymin, xmax, ymax = recording.landmark_map.bounds_m
        diagonal = math.hypot(xmax - xmin, ymax - ymin)
        return EpisodeScore(float("nan"), float("nan"), avail, float("inf"), diagonal + penalty_m * (1.0 - avail))
    pos, _ = metrics.mean_sd(metrics.position_errors(out.estimates, recording.true_pose), fix)
    head, _ = metrics.mean_sd(metrics.heading_errors(out.estimates, recording.true_pose), fix)
    first = float(recording.time_s[fix] - recording.time_s[0])
    return EpisodeScore(pos, head, avail, first, pos + penalty_m * (1.0 - avail))


# ------------------------------------------------------------------------------------ search


@dataclass(frozen=True)
class _Objective:
    """The trial function: replay the recordings with the trial's parameters (picklable)."""

    space: SearchSpace
    recordings: tuple[Recording, ...]
    penalty_m: float

    def __call__(self, trial: optuna.Trial) -> float:
        overrides = nest(self.space.suggest(trial))
        load_params(self.space.localizer, overrides)  # a combination the params class rejects fails the trial
        scores: list[EpisodeScore] = []
        for step, rec in enumerate(self.recordings):
            scores.append(score_episode(rec, self.space.localizer, overrides, self.penalty_m))
            running = float(np.mean([s.objective for s in scores]))
            trial.report(running, step)
            if trial.should_prune():
                raise optuna.TrialPruned()
        trial.set_user_attr("position_error_m", float(np.nanmean([s.position_error_m for s in scores])))
        trial.set_user_attr("availability", float(np.mean([s.availability for s in scores])))
        return running


def _pruner() -> optuna.pruners.BasePruner:
    return optuna.pruners.MedianPruner(n_startup_trials=PRUNER_STARTUP_TRIALS, n_warmup_steps=PRUNER_WARMUP_STEPS)


def _storage(url: str) -> optuna.storages.BaseStorage:
    """An RDB storage for ``url``; for a SQLite file its folder is created first."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        parsed = make_url(url)
    except ArgumentError as exc:
        raise ConfigError(f"--storage {url!r} is not a database URL (e.g. sqlite:///results/tuning.db): {exc}") from None
    engine_kwargs: dict[str, Any] = {}
    if parsed.get_backend_name() == "sqlite":
        if parsed.database and parsed.database != ":memory:":
            Path(parsed.database).parent.mkdir(parents=True, exist_ok=True)
        engine_kwargs["connect_args"] = {"timeout": 60}  # parallel workers wait for the write lock
    return optuna.storages.RDBStorage(url, engine_kwargs=engine_kwargs)


@dataclass(frozen=True)
class _WorkerTask:
    storage: str
    study_name: str
    objective: _Objective
    trials: int
    sampler_seed: int
    verbose: bool


def _optimize_worker(task: _WorkerTask) -> int:
    """One worker: ``study.optimize`` for its share of trials against the shared storage."""
    optuna.logging.set_verbosity(optuna.logging.INFO if task.verbose else optuna.logging.WARNING)
    study = optuna.load_study(
        study_name=task.study_name,
        storage=_storage(task.storage),
        sampler=optuna.samplers.TPESampler(seed=task.sampler_seed),
        pruner=_pruner(),
    )
    study.optimize(task.objective, n_trials=task.trials, catch=(ConfigError,))
    return task.trials


# ------------------------------------------------------------------------------------ driver


@dataclass(frozen=True)
class TuneConfig:
    """One ``crowdloc tune`` run.

    Attributes:
        localizer: a registered bearing localizer.
        setup: the episodes.
        space_path: search-space YAML (default ``configs/tuning/<localizer>.yaml``).
        trials: trials to add to the study in this run (split over the workers).
        train_seeds: training episodes (env seeds ``0 .. n - 1``).
        eval_seeds: held-out episodes (env seeds ``EVAL_SEED_BASE + i``).
        workers: parallel workers, each running ``study.optimize`` on the shared storage.
        ray_address: run the workers on a Ray cluster instead of local processes.
        storage: SQLAlchemy database URL of the study.
        study_name: default ``<localizer>-<env>-crowd<N>-<scenario>``.
        out: report folder (default ``results/tuning/<study>``).
        seed: sampler seed.
        penalty_m: metres added per unit of unavailability.
        verbose: log every trial and show progress bars.
    """

    localizer: str
    setup: EpisodeSetup = field(default_factory=EpisodeSetup)
    space_path: Path | None = None
    trials: int = 40
    train_seeds: int = 4
    eval_seeds: int = 8
    workers: int = 1
    ray_address: str | None = None
    storage: str = DEFAULT_STORAGE
    study_name: str | None = None
    out: Path | None = None
    seed: int = 0
    penalty_m: float = DEFAULT_PENALTY_M
    verbose: bool = True


@dataclass(frozen=True)
class TuneResult:
    """What a run produced."""

    study_name: str
    report: Path
    best_params_file: Path
    best_params: dict[str, Any]
    n_trials: int
    summary: dict[str, Any]


def default_study_name(localizer: str, setup: EpisodeSetup, crowd_size: int) -> str:
    """``candidate_sets-RoboCupCrowded-v0-crowd10-soccer`` (+ ``-camera.dropout_probability=0.5`` per world override)."""
    name = f"{localizer}-{setup.env_id.split('/')[-1]}-crowd{crowd_size}-{setup.scenario}"
    for key, value in sorted(flatten(setup.env_overrides).items()):
        name += f"-{key}={value}"
    return name


def _check_config(config: TuneConfig) -> tuple[SearchSpace, int]:
    s = spec(config.localizer)
    if s.measurement != "bearings":
        bearing = ", ".join(sorted(n for n, x in LOCALIZERS.items() if x.measurement == "bearings"))
        raise ConfigError(f"localizer {config.localizer!r} consumes {s.measurement}; crowdloc tune replays bearing "
                          f"recordings (bearing localizers: {bearing})")  # fmt: skip
    for name in ("trials", "train_seeds", "eval_seeds", "workers"):
        value = getattr(config, name)
        if value < 1:
            raise ConfigError(f"{name.replace('_', '-')} must be >= 1, got {value}")
    if not (math.isfinite(config.penalty_m) and config.penalty_m >= 0):
        raise ConfigError(f"penalty must be a finite number >= 0, got {config.penalty_m}")
    world = config.setup.world()
    return load_search_space(config.localizer, config.space_path), int(world.crowd.count)


def _open_study(config: TuneConfig, name: str, attrs: Mapping[str, Any], space: SearchSpace) -> optuna.Study:
    """Create or load the study; check it was made for the same objective; enqueue the defaults once."""
    study = optuna.create_study(
        storage=_storage(config.storage),
        study_name=name,
        direction="minimize",
        load_if_exists=True,
        sampler=optuna.samplers.TPESampler(seed=config.seed),
        pruner=_pruner(),
    )
    stored = study.user_attrs
    if stored:
        diff = [k for k in _SETUP_ATTRS if stored.get(k) != attrs[k]]
        if diff:
            k = diff[0]
            raise ConfigError(f"study {name!r} in {config.storage} was created with {k}={stored.get(k)!r}, this run has "
                              f"{k}={attrs[k]!r}; use another --study-name")  # fmt: skip
    else:
        for k, v in attrs.items():
            study.set_user_attr(k, v)
    if not study.trials:
        defaults = space.defaults()
        if all(r.contains(defaults[r.name]) for r in space.params):
            study.enqueue_trial(defaults, user_attrs={"defaults": True})
    return study


def tune(config: TuneConfig) -> TuneResult:
    """Search, evaluate on held-out seeds and write the report (see the module docstring).

    Raises:
        ConfigError: a bad localizer, search space, episode setup, count or storage URL, or a
            stored study made for another setup.
    """
    space, crowd = _check_config(config)
    setup = config.setup
    name = config.study_name or default_study_name(config.localizer, setup, crowd)
    out = config.out if config.out is not None else Path("results") / "tuning" / name
    train = tuning_seeds(config.train_seeds)
    held_out = eval_seeds(config.eval_seeds)
    assert not set(train) & set(held_out)
    attrs = {
        "localizer": config.localizer,
        "env_id": setup.env_id,
        "crowd_size": crowd,
        "scenario": setup.scenario,
        "episode_steps": setup.episode_steps,
        "env_overrides": json.loads(json.dumps(dict(setup.env_overrides))),
        "train_seeds": list(train),
        "penalty_m": config.penalty_m,
        "space": {r.name: r.describe() for r in space.params},
    }
    optuna.logging.set_verbosity(optuna.logging.INFO if config.verbose else optuna.logging.WARNING)
    study = _open_study(config, name, attrs, space)
    first_new = len(study.trials)
    recordings = run_tasks(_record_task, [(setup, s) for s in train], workers=config.workers,
                           desc="record training episodes", progress=config.verbose)  # fmt: skip
    objective = _Objective(space, tuple(recordings), config.penalty_m)
    remaining = config.trials
    if study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.WAITING,)):
        # the enqueued defaults run here, before any worker starts: on SQLite two processes
        # can pop the same waiting trial (optuna issue #4002)
        study.optimize(objective, n_trials=1, catch=(ConfigError,))
        remaining -= 1
    workers = min(config.workers, remaining)
    shares = [remaining // workers + (i < remaining % workers) for i in range(workers)] if workers else []
    tasks = [
        _WorkerTask(config.storage, name, objective, n,
                    int(np.random.SeedSequence([config.seed, i, first_new]).generate_state(1)[0]), config.verbose)
        for i, n in enumerate(shares)
    ]  # fmt: skip
    if tasks:
        run_tasks(_optimize_worker, tasks, workers=workers, ray_address=config.ray_address, desc="tuning workers",
                  progress=False)  # fmt: skip

    study = optuna.load_study(study_name=name, storage=_storage(config.storage))
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    if not complete:
        raise ConfigError(f"study {name!r}: no trial completed (all pruned or failed); see the log above")
    best = study.best_trial
    tuned = nest(best.params)
    evals = run_tasks(_evaluate_task, [(setup, s, config.localizer, tuned, config.penalty_m) for s in held_out],
                      workers=config.workers, ray_address=config.ray_address, desc="held-out episodes",
                      progress=config.verbose)  # fmt: skip
    summary = write_report(out, name, config, study, space, attrs, evals, held_out)
    return TuneResult(name, out / "report.md", out / "best_params.yaml", dict(best.params), len(study.trials), summary)


def _evaluate_task(task: tuple[EpisodeSetup, int, str, Mapping[str, Any], float]) -> tuple[EpisodeScore, EpisodeScore]:
    """One held-out episode: the defaults and the tuned parameters on the same recording."""
    setup, seed, localizer, tuned, penalty_m = task
    rec = setup.record(seed)
    return score_episode(rec, localizer, None, penalty_m), score_episode(rec, localizer, tuned, penalty_m)


# ------------------------------------------------------------------------------------ report


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


def param_importances(study: optuna.Study) -> tuple[dict[str, float], list[str]]:
    """Optuna's parameter importances (its default evaluator, PED-ANOVA) and notes on them.

    Returns empty importances with a note when fewer than 2 trials completed.
    """
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    if len(complete) < 2:
        return {}, [f"importances need >= 2 completed trials, the study has {len(complete)}"]
    with warnings.catch_warnings(record=True) as caught:
        # with few or tied trials PED-ANOVA warns that its quantiles coincide and returns
        # equal importances; keep that warning for the report instead of failing
        warnings.filterwarnings("always", message="Target and region quantiles", category=UserWarning)
        values = optuna.importance.get_param_importances(study)
    return {k: float(v) for k, v in values.items()}, [str(w.message) for w in caught]


def plot_importances(path: Path, importances: Mapping[str, float], title: str) -> Path:
    """Horizontal bar chart of the importances, most important on top (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.plots import save_figure

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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.plots import save_figure

    State = optuna.trial.TrialState
    fig, ax = plt.subplots(figsize=(7.0, 3.8))
    done = [t for t in study.trials if t.state == State.COMPLETE]
    pruned = [t for t in study.trials if t.state == State.PRUNED and t.intermediate_values]
    ax.scatter([t.number for t in done], [t.value for t in done], s=14, color="tab:blue", label="completed")
    if pruned:
        ax.scatter([t.number for t in pruned], [t.intermediate_values[max(t.intermediate_values)] for t in pruned],
                   s=18, marker="x", color="tab:gray", label="pruned (running mean)")  # fmt: skip
    best, xs, ys = math.inf, [], []
    for t in sorted(done, key=lambda t: t.number):
        best = min(best, float(t.value))  # type: ignore[arg-type]
        xs.append(t.number)
        ys.append(best)
    ax.step(xs, ys, where="post", color="tab:red", label="best so far")
    default = [t for t in done if t.user_attrs.get("defaults")]
    if default:
        ax.scatter([default[0].number], [default[0].value], s=90, marker="*", color="tab:orange", zorder=3,
                   label="defaults")  # fmt: skip
    ax.set_xlabel("trial")
    ax.set_ylabel("objective (m)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def _spread(values: Sequence[float]) -> dict[str, float]:
    s = metrics.over_seeds(values)
    return {"mean": s.mean, "sd": s.sd, "n": s.n}


def _pm(s: Mapping[str, float], fmt: str) -> str:
    if not s["n"]:
        return "n/a"
    return f"{fmt.format(s['mean'])} ± {fmt.format(s['sd'])}"


def write_report(
    out: Path,
    name: str,
    config: TuneConfig,
    study: optuna.Study,
    space: SearchSpace,
    attrs: Mapping[str, Any],
    evals: Sequence[tuple[EpisodeScore, EpisodeScore]],
    held_out: Sequence[int],
) -> dict[str, Any]:
    """Write ``report.md``, ``best_params.yaml``, ``summary.json`` and the two figures under ``out``.

    Returns:
        The summary written to ``summary.json``.
    """
    out.mkdir(parents=True, exist_ok=True)
    State = optuna.trial.TrialState
    best = study.best_trial
    counts = {s.name.lower(): sum(t.state == s for t in study.trials) for s in (State.COMPLETE, State.PRUNED, State.FAIL)}
    default_trial = next((t for t in study.trials if t.user_attrs.get("defaults") and t.state == State.COMPLETE), None)
    importances, notes = param_importances(study)
    title = f"{name}\n{counts['complete']} completed, {counts['pruned']} pruned trials"
    plot_importances(out / "importance.png", importances, title)
    plot_history(out / "history.png", study, title)
    header = [f"crowdloc tune {config.localizer}: study {name!r}, best trial #{best.number}, "
              f"training objective {best.value:.4f} m"]  # fmt: skip
    (out / "best_params.yaml").write_text(best_params_yaml(config.localizer, best.params, space, header))

    rows = {}
    for label, k in (("defaults", 0), ("tuned", 1)):
        scores = [e[k] for e in evals]
        rows[label] = {
            "objective_m": _spread([s.objective for s in scores]),
            "position_error_m": _spread([s.position_error_m for s in scores]),
            "heading_error_deg": _spread([math.degrees(s.heading_error_rad) for s in scores]),
            "availability": _spread([s.availability for s in scores]),
            "first_fix_s": _spread([s.first_fix_s for s in scores]),
        }
    wins = sum(t.objective < d.objective for d, t in evals)
    from agents.evaluate import bootstrap_ci

    differences = [t.objective - d.objective for d, t in evals]
    paired = _spread(differences)
    paired_ci = bootstrap_ci(differences, rng=np.random.default_rng(config.seed))
    setup = config.setup
    summary: dict[str, Any] = {
        "study": name,
        "storage": config.storage,
        **{k: v for k, v in attrs.items()},
        "eval_seeds": list(held_out),
        "trials": counts,
        "best_trial": best.number,
        "best_training_objective_m": best.value,
        "default_training_objective_m": None if default_trial is None else default_trial.value,
        "best_params": dict(best.params),
        "defaults": space.defaults(),
        "held_out": rows,
        "tuned_better_on": wins,
        "paired_objective_difference_m": paired,
        "paired_objective_difference_ci95_m": list(paired_ci),
        "importances": importances,
        "importance_notes": notes,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")

    seconds = f"{setup.episode_steps} steps ({setup.episode_steps * float(setup.world().dt_s):.0f} s)"
    lines = [
        f"# Tuning `{config.localizer}`: study `{name}`",
        "",
        f"- World `{setup.env_id}`, crowd size {attrs['crowd_size']}, scenario `{setup.scenario}`, {seconds} per episode"
        + (f", overrides `{json.dumps(attrs['env_overrides'])}`" if attrs["env_overrides"] else "")
        + ".",
        f"- Objective (minimized): mean position error from the first fix on (m) + {config.penalty_m:g} m x "
        "(1 - availability over the whole episode), mean over the training episodes "
        f"(env seeds {list(attrs['train_seeds'])}), each recorded once and replayed into every trial.",
        f"- Search: Optuna TPE (seed {config.seed}) with median pruning, storage `{config.storage}`; "
        f"{len(study.trials)} trials in the study: {counts['complete']} completed, {counts['pruned']} pruned, "
        f"{counts['fail']} failed.",
        f"- Best trial #{best.number}: training objective {best.value:.4f} m"
        + (f" (defaults, trial #{default_trial.number}: {default_trial.value:.4f} m)." if default_trial else "."),
        "",
        f"## Held-out episodes ({len(held_out)}, env seeds 2**31 + 0 .. 2**31 + {len(held_out) - 1}, never tuned on)",
        "",
        "Mean ± sd over seeds (per-seed means from each localizer's first fix on).",
        "",
        "| parameters | objective [m] | position error [m] | heading error [deg] | availability | first fix [s] |",
        "|---|---|---|---|---|---|",
    ]
    for label, r in rows.items():
        lines.append(
            f"| {label} | {_pm(r['objective_m'], '{:.3f}')} | {_pm(r['position_error_m'], '{:.3f}')} | "
            f"{_pm(r['heading_error_deg'], '{:.2f}')} | {_pm(r['availability'], '{:.3f}')} | {_pm(r['first_fix_s'], '{:.2f}')} |"
        )
    lines += [
        "",
        f"Tuned beats the defaults on {wins} of {len(evals)} held-out seeds; paired objective difference "
        f"(tuned - defaults, same recording): {_pm(paired, '{:+.4f}')} m, 95 % bootstrap CI of its mean "
        f"[{paired_ci[0]:+.4f}, {paired_ci[1]:+.4f}] m.",
        "",
        "## Best parameters",
        "",
        f"`best_params.yaml` (ready as `localizer_params`, e.g. `localizers.registry.load_params({config.localizer!r}, yaml)`).",
        "",
        "| parameter | default | tuned | searched | importance |",
        "|---|---|---|---|---|",
    ]
    defaults = space.defaults()
    for r in space.params:
        imp = f"{importances[r.name]:.3f}" if r.name in importances else "n/a"
        tuned = best.params.get(r.name)
        lines.append(f"| `{r.name}` | {_format_value(defaults[r.name])} | {_format_value(tuned)} | {r.describe()} | {imp} |")
    lines += ["", "## Parameter importance and optimization history", ""]
    if importances:
        ranking = ", ".join(f"`{k}` {v:.2f}" for k, v in importances.items())
        lines.append(f"PED-ANOVA importances (optuna's default evaluator) over the completed trials: {ranking}.")
    for n in notes:
        lines.append(f"Note: {n}")
    lines += ["", "![importance](importance.png)", "", "![history](history.png)", ""]
    (out / "report.md").write_text("\n".join(lines))
    return summary


# ------------------------------------------------------------------------------------ command line


def add_arguments(parser: Any) -> None:
    """The ``crowdloc tune`` options."""
    import argparse

    def count(minimum: int) -> Any:
        def parse(text: str) -> int:
            try:
                value = int(text)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}") from None
            if value < minimum:
                raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {value}")
            return value

        return parse

    bearing = ", ".join(n for n, s in LOCALIZERS.items() if s.measurement == "bearings")
    parser.add_argument("localizer", help=f"a bearing localizer: {bearing}")
    parser.add_argument("--space", type=Path, help="search-space YAML (default configs/tuning/LOCALIZER.yaml)")
    parser.add_argument("--env-id", default=DEFAULT_ENV_ID, help=f"a bearing world (default {DEFAULT_ENV_ID})")
    parser.add_argument("--crowd-size", type=count(0), help="crowd size (default: the world's own)")
    parser.add_argument("--scenario", choices=SCENARIOS, default="soccer",
                        help="soccer: Exp 2's chase-dribble-shoot driver from (0, 3) m; random_walk: the RandomWalk "
                             "policy from the world's start (default soccer)")  # fmt: skip
    parser.add_argument("--episode-steps", type=count(1), default=900, help="steps per episode (default 900 = 30 s)")
    parser.add_argument("--env-set", action="append", default=[], metavar="KEY=VALUE",
                        help="world override, e.g. --env-set camera.dropout_probability=0.5 (repeatable)")  # fmt: skip
    parser.add_argument("--train-seeds", type=count(1), default=4, help="tuning episodes, env seeds 0..N-1 (default 4)")
    parser.add_argument("--eval-seeds", type=count(1), default=8, help="held-out episodes, env seeds 2**31 + i (default 8)")
    parser.add_argument("--trials", type=count(1), default=40, help="trials to add to the study (default 40)")
    parser.add_argument("--workers", type=count(1), default=1, help="parallel study.optimize workers (default 1)")
    parser.add_argument("--ray-address", help="run the workers on this Ray cluster (use a storage all nodes reach)")
    parser.add_argument("--storage", default=DEFAULT_STORAGE, help=f"SQLAlchemy database URL (default {DEFAULT_STORAGE})")
    parser.add_argument("--study-name", help="default LOCALIZER-ENV-crowdN-SCENARIO; an existing study is continued")
    parser.add_argument("--seed", type=int, default=0, help="sampler seed (default 0)")
    parser.add_argument("--penalty-m", type=float, default=DEFAULT_PENALTY_M,
                        help="metres added to the objective per unit of unavailability (default 1)")  # fmt: skip
    parser.add_argument("--out", type=Path, help="report folder (default results/tuning/STUDY)")
    parser.add_argument("--quiet", action="store_true", help="no per-trial log, no progress bars")


def run_cli(args: Any) -> TuneResult:
    """``crowdloc tune`` from parsed arguments (raises ConfigError for bad values)."""
    from agents.train import parse_overrides

    config = TuneConfig(
        localizer=args.localizer,
        setup=EpisodeSetup(
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
        verbose=not args.quiet,
    )
    return tune(config)
