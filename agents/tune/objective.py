"""The episodes of ``crowdloc tune`` and how a trial is scored.

Episodes are recorded once (:func:`agents.replay.record`) and every trial replays its
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

from agents import metrics
from agents.replay import Recording, record, replay
from agents.scenarios import SoccerDriver
from agents.train import EVAL_SEED_BASE
from agents.tune.space import SearchSpace
from agents.util import nest
from localizers.registry import load_params
from localizers.schema import ConfigError

DEFAULT_ENV_ID = "crowdloc/RoboCupCrowded-v0"
SCENARIOS = ("soccer", "random_walk")
#: Exp 2 of the candidate-set paper: the field robot starts at (0, 3000) mm facing +x
SOCCER_START_POSE = (0.0, 3.0, 0.0)
#: metres added to the objective per unit of unavailability (share of steps without a pose)
DEFAULT_PENALTY_M = 1.0


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
        if world.sensor_of_type("bearing_camera") is None:
            raise ConfigError(f"{self.env_id} has no bearing camera; crowdloc tune replays bearing recordings")
        if self.scenario == "soccer" and not any(getattr(c, "ball", False) for c in world.crowds.values()):
            raise ConfigError(f"scenario 'soccer' needs a world with a ball; {self.env_id} has none (try --scenario random_walk)")
        return world

    def facts(self) -> WorldFacts:
        """The crowd size and time step of :meth:`world` (same checks)."""
        world = self.world()
        return WorldFacts(int(world.crowd.count) if world.crowd is not None else 0, float(world.dt_s))

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


def record_task(task: tuple[EpisodeSetup, int]) -> Recording:
    """``setup.record(seed)`` as a :func:`agents.sweep.run_tasks` task."""
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


def evaluate_task(task: tuple[EpisodeSetup, int, str, Mapping[str, Any], float]) -> tuple[EpisodeScore, EpisodeScore]:
    """One held-out episode: the defaults and the tuned parameters on the same recording."""
    setup, seed, localizer, tuned, penalty_m = task
    rec = setup.record(seed)
    return score_episode(rec, localizer, None, penalty_m), score_episode(rec, localizer, tuned, penalty_m)


# ------------------------------------------------------------------------------------ the trial function


@dataclass(frozen=True)
class Objective:
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
