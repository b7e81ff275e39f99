"""The episodes of ``crowdloc tune`` and how a trial is scored.

Episodes are recorded once (:func:`agents.experiments.replay.record`) and every trial replays its
localizer into the same recordings (see :mod:`agents.tune`); :func:`score_episode` is the
per-episode objective, :class:`Objective` the Optuna trial function.

The reads of the world's config (its bearing camera, crowd kind, ball, crowd count, time step) are
all in :meth:`EpisodeSetup.world` and :meth:`EpisodeSetup.facts`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import optuna

from agents.common.util import nest
from agents.evaluate import metrics
from agents.experiments.replay import Recording, record, replay
from agents.experiments.scenarios import SoccerDriver
from agents.rl.config import EVAL_SEED_BASE
from agents.tune.space import SearchSpace
from core.schema import ConfigError
from localizers.registry import load_params, prepared_params, spec

DEFAULT_ENV_ID = "crowdloc/RoboCupCrowded-v0"
#: the LIDAR paper's room (docs/papers.md section B) and its square path
ROOM_ENV_ID = "crowdloc/CrowdedRoom-v0"
#: the far-landmark stereo paper's campus (docs/papers.md section D) and its route
CAMPUS_ENV_ID = "crowdloc/StereoCampus-v0"
SCENARIOS = ("soccer", "random_walk", "square", "route")
#: the world a localizer is tuned in by default, by the measurement kind it reads: bearing
#: localizers on the crowded soccer field (paper A), LIDAR ones in the crowded room (paper B),
#: stereo-edge ones on the campus (paper D)
DEFAULT_WORLDS = {"bearings": DEFAULT_ENV_ID, "scan": ROOM_ENV_ID, "stereo_edges": CAMPUS_ENV_ID}
#: Exp 2 of the candidate-set paper: the field robot starts at (0, 3000) mm facing +x
SOCCER_START_POSE = (0.0, 3.0, 0.0)
#: steps of a soccer or random-walk episode (30 s at 30 Hz)
DEFAULT_EPISODE_STEPS = 900
#: metres added to the objective per unit of unavailability (share of steps without a pose)
DEFAULT_PENALTY_M = 1.0
#: metres added per unit of failure share (share of steps whose valid estimate is >= fail_m off).
#: Equal to DEFAULT_PENALTY_M: a confidently wrong pose costs at least what no pose costs (its own
#: error enters the mean error as well), so a localizer cannot lower the objective by answering
#: wrongly where it would otherwise abstain. 0 gives the objective of the earlier tune exactly.
DEFAULT_FAILURE_PENALTY_M = 1.0
#: metres from the truth at which a valid estimate is a failure, by world: the LIDAR paper's 1 m
#: in its room (paper B counts estimates >= 1 m off); 0.5 m on the 6 m x 9 m soccer field and
#: elsewhere (ours: a tenth of the field's width, five times the candidate-set paper's errors)
DEFAULT_FAIL_M = 0.5
FAIL_M_BY_WORLD = {ROOM_ENV_ID: 1.0}


def default_fail_m(env_id: str) -> float:
    """The failure threshold of ``env_id`` (:data:`FAIL_M_BY_WORLD`, else :data:`DEFAULT_FAIL_M`)."""
    return FAIL_M_BY_WORLD.get(env_id, DEFAULT_FAIL_M)


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


def seed_base_text() -> str:
    """``EVAL_SEED_BASE`` as prose: ``2**31`` for a power of two, else the number."""
    exponent = EVAL_SEED_BASE.bit_length() - 1
    return f"2**{exponent}" if EVAL_SEED_BASE == 1 << exponent else str(EVAL_SEED_BASE)


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
class WorldFacts:
    """What tuning reads of an episode setup's effective world.

    Attributes:
        crowd_size: the crowd's robot / person count.
        step_s: the world's time step.
    """

    crowd_size: int
    step_s: float


@dataclass(frozen=True)
class EpisodeSetup:
    """What a tuning or evaluation episode is.

    Attributes:
        env_id: a registered crowdloc id with the sensor that ``measurement`` reads.
        crowd_size: other robots / people (``None``: the world's own count).
        scenario: ``"soccer"``: Exp 2's field robot (:class:`agents.experiments.scenarios.SoccerDriver`,
            chase, dribble, shoot; start at (0, 3) m facing +x), needs a world with a ball;
            ``"random_walk"``: :class:`agents.policies.RandomWalk` from the world's start pose;
            ``"square"``: the LIDAR paper's run in ``crowdloc/CrowdedRoom-v0``
            (:mod:`agents.papers.lidar_far_point.experiment`: 3 laps of its 2.5 m square at
            0.15 m/s from the lower-left corner; the queue heads give way to the robot);
            ``"route"``: ``route_follower`` drives the world's route (a world with a ``route``
            feature and one LIDAR) steering on the LIDAR reference run online
            (:func:`agents.experiments.scene_maps.reference_env_kwargs`), never on the tuned localizer, so
            replaying a trial's parameters into the recording is exact.
        episode_steps: steps per episode (the square path stops when its laps are done, the
            route at its end).
        env_overrides: further ``gym.make`` world overrides (``{"camera": {"dropout_probability": 0.5}}``).
        measurement: the measurement kind the tuned localizer reads (:mod:`localizers.measurements`).
    """

    env_id: str = DEFAULT_ENV_ID
    crowd_size: int | None = None
    scenario: str = "soccer"
    episode_steps: int = DEFAULT_EPISODE_STEPS
    env_overrides: Mapping[str, Any] = field(default_factory=dict)
    measurement: str = "bearings"

    def world(self) -> Any:
        """The effective world config; ConfigError if this setup cannot record what the localizer reads."""
        import envs
        from envs.localization_env import apply_overrides
        from localizers.measurements import measurement_kind

        if self.env_id not in envs.ENV_WORLDS:
            raise ConfigError(f"unknown env id {self.env_id!r}; known: {', '.join(envs.ENV_WORLDS)}")
        if self.scenario not in SCENARIOS:
            raise ConfigError(f"unknown scenario {self.scenario!r}; known: {', '.join(SCENARIOS)}")
        if self.episode_steps < 1:
            raise ConfigError(f"episode steps must be >= 1, got {self.episode_steps}")
        if self.crowd_size is not None and self.crowd_size < 0:
            raise ConfigError(f"crowd size must be >= 0, got {self.crowd_size}")
        if self.scenario == "square" and self.env_id != ROOM_ENV_ID:
            raise ConfigError(f"scenario 'square' is the LIDAR paper's path in {ROOM_ENV_ID}, not in {self.env_id}")
        sensor_type = measurement_kind(self.measurement).sensor_type
        world = apply_overrides(envs.load_world(envs.ENV_WORLDS[self.env_id]), self.crowd_size, **self.world_overrides())
        if world.sensor_of_type(sensor_type) is None:
            raise ConfigError(f"{self.env_id} has no {sensor_type}; a localizer reading {self.measurement} needs one "
                              f"(its default world: {DEFAULT_WORLDS.get(self.measurement, 'none')})")  # fmt: skip
        if self.scenario == "soccer" and not any(getattr(c, "ball", False) for c in world.crowds.values()):
            raise ConfigError(f"scenario 'soccer' needs a world with a ball; {self.env_id} has none (try --scenario random_walk)")
        if self.scenario == "route":
            if not world.features_of_type("route"):
                raise ConfigError(
                    f"scenario 'route' drives the world's route; {self.env_id} has none (try --scenario random_walk)"
                )
            from agents.experiments.scene_maps import reference_env_kwargs

            reference_env_kwargs(world)  # the route is driven on the LIDAR reference: one LIDAR
        return world

    def world_overrides(self) -> dict[str, Any]:
        """The world overrides of the recording (``env_overrides``; every scenario runs the world as shipped)."""
        return dict(self.env_overrides)

    def facts(self) -> WorldFacts:
        """The crowd size and time step of :meth:`world` (same checks)."""
        world = self.world()
        return WorldFacts(int(world.crowd.count) if world.crowd is not None else 0, float(world.dt_s))

    def prepared_params(self, localizer: str) -> dict[str, Any]:
        """What ``localizer``'s preparation hook (:attr:`localizers.registry.LocalizerSpec.prepare`)
        makes from this setup's world, resolved once per study and handed to every replay:
        ``far_landmark_pf``'s scene map (the world's default, driven at the crowd of the world's
        file whatever the study's crowd size, built and cached on first use). Empty for a
        localizer without a hook."""
        import envs
        from envs.localization_env import LocalizationEnv
        from localizers.measurements import measurement_kind

        if not spec(localizer).prepare:
            return {}
        world = self.world()
        sensor = next(iter(world.sensors_of_type(measurement_kind(self.measurement).sensor_type)))
        env = LocalizationEnv(envs.ENV_WORLDS[self.env_id], crowd_size=self.crowd_size, **self.world_overrides())
        try:
            return dict(prepared_params(localizer, env, sensor, None) or {})
        finally:
            env.close()

    def env_kwargs(self) -> dict[str, Any]:
        kwargs: dict[str, Any] = {**self.world_overrides(), "max_episode_steps": self.episode_steps}
        if self.crowd_size is not None:
            kwargs["crowd_size"] = self.crowd_size
        return kwargs

    def record(self, seed: int) -> Recording:
        """Roll one episode out with env seed ``seed`` (the driver is seeded with it too)."""
        if self.scenario == "soccer":
            return record(self.env_id, SoccerDriver(seed), seed, max_steps=self.episode_steps,
                          env_kwargs=self.env_kwargs(), reset_options={"robot_pose": list(SOCCER_START_POSE)})  # fmt: skip
        if self.scenario == "square":
            from agents.papers.lidar_far_point import experiment
            from agents.papers.lidar_far_point.paper import LAPS

            return record(self.env_id, experiment.driver_factory(LAPS), seed, max_steps=self.episode_steps,
                          env_kwargs=self.env_kwargs(), reset_options={"robot_pose": list(experiment.start_pose())})  # fmt: skip
        if self.scenario == "route":
            from agents.experiments.replay import record_policy
            from agents.experiments.scene_maps import reference_env_kwargs
            from agents.policies import make_policy

            kwargs = {**self.env_kwargs(), **reference_env_kwargs(self.world())}
            return record_policy(self.env_id, lambda env: make_policy("route_follower", env, seed=seed), seed,
                                 max_steps=self.episode_steps, env_kwargs=kwargs)  # fmt: skip
        from gymnasium import spaces

        from agents.policies import RandomWalk

        policy = RandomWalk(spaces.Box(-1.0, 1.0, (2,), np.float32), seed=seed)
        return record(self.env_id, _PolicyDriver(policy), seed, max_steps=self.episode_steps, env_kwargs=self.env_kwargs())


def default_scenario(env_id: str) -> str:
    """The scenario a world is tuned with: the square path in the LIDAR room, the route where the
    world has one, soccer where there is a ball, else the random walk."""
    import envs

    if env_id == ROOM_ENV_ID:
        return "square"
    if env_id not in envs.ENV_WORLDS:
        return "random_walk"  # EpisodeSetup.world() names the unknown id
    world = envs.load_world(envs.ENV_WORLDS[env_id])
    if world.features_of_type("route"):
        return "route"
    return "soccer" if any(getattr(c, "ball", False) for c in world.crowds.values()) else "random_walk"


def default_episode_steps(scenario: str, env_id: str | None = None) -> int:
    """Steps of one episode of ``scenario``: the square path's 3 laps (plus 10 steps), the route's
    world's episode length (the drive ends at the route's end), else 30 s."""
    if scenario == "square":
        from agents.papers.lidar_far_point import experiment
        from agents.papers.lidar_far_point.paper import LAPS

        return experiment.episode_steps(LAPS) + 10
    if scenario == "route" and env_id is not None:
        import envs

        if env_id in envs.ENV_WORLDS:
            return int(envs.load_world(envs.ENV_WORLDS[env_id]).max_episode_steps)
    return DEFAULT_EPISODE_STEPS


def default_setup(
    localizer: str,
    *,
    env_id: str | None = None,
    scenario: str | None = None,
    episode_steps: int | None = None,
    crowd_size: int | None = None,
    env_overrides: Mapping[str, Any] | None = None,
) -> EpisodeSetup:
    """The episodes ``localizer`` is tuned on, unset choices from its measurement kind.

    The world defaults to :data:`DEFAULT_WORLDS` of the kind it reads (bearings: the crowded
    soccer field; scans: the LIDAR paper's crowded room), the scenario to
    :func:`default_scenario` of that world, the episode length to :func:`default_episode_steps`.

    Raises:
        ConfigError: an unknown localizer, or one whose measurement kind has no default world
            and no ``env_id`` was given.
    """
    measurement = spec(localizer).measurement
    if env_id is None:
        if measurement not in DEFAULT_WORLDS:
            raise ConfigError(f"localizer {localizer!r} reads {measurement}, which has no default tuning world; give --env-id")
        env_id = DEFAULT_WORLDS[measurement]
    scenario = scenario if scenario is not None else default_scenario(env_id)
    steps = episode_steps if episode_steps is not None else default_episode_steps(scenario, env_id)
    return EpisodeSetup(env_id, crowd_size, scenario, steps, dict(env_overrides or {}), measurement)


def record_task(task: tuple[EpisodeSetup, int]) -> Recording:
    """``setup.record(seed)`` as a :func:`agents.common.sweep.run_tasks` task."""
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
        failures: steps whose valid estimate is at least ``fail_m`` from the truth.
        failure_share: ``failures`` / all steps (disjoint from the unavailable share).
        objective: ``position_error_m + penalty_m * (1 - availability) + failure_penalty_m *
            failure_share`` (map diagonal for the error if no fix).
    """

    position_error_m: float
    heading_error_rad: float
    availability: float
    first_fix_s: float
    objective: float
    failures: int = 0
    failure_share: float = 0.0


@dataclass(frozen=True)
class ObjectiveTerms:
    """How an episode is scored (:func:`score_episode`).

    Attributes:
        penalty_m: metres per unit of unavailability.
        failure_penalty_m: metres per unit of failure share (0: the objective without failures).
        fail_m: a valid estimate at least this far from the truth is a failure.
    """

    penalty_m: float = DEFAULT_PENALTY_M
    failure_penalty_m: float = DEFAULT_FAILURE_PENALTY_M
    fail_m: float = DEFAULT_FAIL_M

    def check(self) -> None:
        """ConfigError naming a term that is not a finite number >= 0 (``fail_m`` > 0)."""
        for name, flag in (("penalty_m", "--penalty-m"), ("failure_penalty_m", "--failure-penalty-m")):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{flag} must be a finite number >= 0, got {value}")
        if not (math.isfinite(self.fail_m) and self.fail_m > 0):
            raise ConfigError(f"--fail-m must be a finite number > 0, got {self.fail_m}")

    def describe(self) -> str:
        """The objective in words (for the report)."""
        text = f"mean position error from the first fix on (m) + {self.penalty_m:g} m x (1 - availability over the whole episode)"
        if self.failure_penalty_m:
            text += f" + {self.failure_penalty_m:g} m x failure share (steps whose valid estimate is >= {self.fail_m:g} m off)"
        return text


def score_episode(
    recording: Recording,
    localizer: str,
    params: Mapping[str, Any] | None,
    penalty_m: float,
    *,
    failure_penalty_m: float = 0.0,
    fail_m: float = DEFAULT_FAIL_M,
) -> EpisodeScore:
    """Replay ``recording`` into ``localizer`` with parameter overrides ``params`` and score it.

    The localizer's generator is seeded from the env seed alone, so every parameter set sees
    the same random stream too. Failures are counted whatever ``failure_penalty_m`` is; with
    ``failure_penalty_m = 0`` the objective is ``error + penalty_m * (1 - availability)`` exactly.
    """
    out = replay(recording, localizer, rng_seed=[recording.seed, 0], params=params or None)
    fix = metrics.first_fix(out.valid)
    avail = metrics.availability(out.valid)
    errors = metrics.position_errors(out.estimates, recording.true_pose)
    failures = metrics.failure_count(np.where(out.valid, errors, np.nan), threshold=fail_m)
    share = failures / max(recording.steps, 1)
    if fix is None:
        xmin, ymin, xmax, ymax = recording.landmark_map.bounds_m
        diagonal = math.hypot(xmax - xmin, ymax - ymin)
        objective = diagonal + penalty_m * (1.0 - avail)
        return EpisodeScore(float("nan"), float("nan"), avail, float("inf"), objective, failures, share)
    pos, _ = metrics.mean_sd(errors, fix)
    head, _ = metrics.mean_sd(metrics.heading_errors(out.estimates, recording.true_pose), fix)
    first = float(recording.time_s[fix] - recording.time_s[0])
    objective = pos + penalty_m * (1.0 - avail)
    if failure_penalty_m:
        objective += failure_penalty_m * share
    return EpisodeScore(pos, head, avail, first, objective, failures, share)


def score_with(recording: Recording, localizer: str, params: Mapping[str, Any] | None, terms: ObjectiveTerms) -> EpisodeScore:
    """:func:`score_episode` with the terms of ``terms``."""
    return score_episode(recording, localizer, params, terms.penalty_m, failure_penalty_m=terms.failure_penalty_m,
                         fail_m=terms.fail_m)  # fmt: skip


def evaluate_task(
    task: tuple[EpisodeSetup, int, str, Mapping[str, Any], ObjectiveTerms, Mapping[str, Any]],
) -> tuple[EpisodeScore, EpisodeScore]:
    """One held-out episode: the defaults and the tuned parameters on the same recording (both
    with the study's prepared parameters, :meth:`EpisodeSetup.prepared_params`)."""
    setup, seed, localizer, tuned, terms, fixed = task
    rec = setup.record(seed)
    return score_with(rec, localizer, dict(fixed), terms), score_with(rec, localizer, {**fixed, **tuned}, terms)


# ------------------------------------------------------------------------------------ the trial function


@dataclass(frozen=True)
class Objective:
    """The trial function: replay the recordings with the trial's parameters (picklable); ``fixed``:
    parameters every trial gets besides (the study's prepared ones, :meth:`EpisodeSetup.prepared_params`)."""

    space: SearchSpace
    recordings: tuple[Recording, ...]
    terms: ObjectiveTerms
    fixed: Mapping[str, Any] = field(default_factory=dict)

    def __call__(self, trial: optuna.Trial) -> float:
        applied = self.space.applied(self.space.suggest(trial))
        if applied != trial.params:
            trial.set_user_attr("applied", applied)  # the sum_to_one groups as the localizer got them
        overrides = {**self.fixed, **nest(applied)}
        load_params(self.space.localizer, overrides)  # a combination the params class rejects fails the trial
        scores: list[EpisodeScore] = []
        for step, rec in enumerate(self.recordings):
            scores.append(score_with(rec, self.space.localizer, overrides, self.terms))
            running = float(np.mean([s.objective for s in scores]))
            trial.report(running, step)
            if trial.should_prune():
                raise optuna.TrialPruned()
        trial.set_user_attr("position_error_m", float(np.nanmean([s.position_error_m for s in scores])))
        trial.set_user_attr("availability", float(np.mean([s.availability for s in scores])))
        trial.set_user_attr("failure_share", float(np.mean([s.failure_share for s in scores])))
        return running
