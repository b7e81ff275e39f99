"""The evaluation grid: :class:`EvalSpec` (what to evaluate, checked up front) and its :class:`Cell`\\ s."""

from __future__ import annotations

import functools
import math
import re
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from agents.evaluate.goal import GOAL_METRICS
from agents.evaluate.kidnap import KIDNAP_METRICS, Kidnap
from agents.evaluate.plugins import MetricInfo, localizer_kind, localizer_metrics
from agents.policies import FIXED_POLICIES, task_route_kwargs
from agents.rl import task_ids
from agents.rl.config import EVAL_SEED_BASE, TrainConfig
from agents.rl.observation import ObservationConfig, RouteConfig
from agents.rl.residual import ActionConfig, check_trained_action
from agents.rl.rewards import RewardWeights
from agents.rl.train import task_wrappers
from core.schema import ConfigError, check, is_int
from localizers.measurements import find_sensor

if TYPE_CHECKING:
    from envs.config import WorldConfig

PPO_PREFIX = "ppo:"
_POLICY_SALT = 0x9011C7  # the policy's seed differs from the env's for the same evaluation seed
#: env_kwargs the grid sets itself
_GRID_KEYS = ("crowd_size", "max_episode_steps", "localizer", "localizer_params", "render_mode")
#: the largest first_seed: EVAL_SEED_BASE + first_seed + i stays a valid seed (< 2**32) for up to 2**30 seeds
FIRST_SEED_MAX = 2**30


def check_first_seed(value: Any, name: str = "first_seed") -> None:
    """``value`` is an evaluation seed offset, an integer from 0 to :data:`FIRST_SEED_MAX`.

    Raises:
        ConfigError: naming the value ``name`` (the keyword argument; ``crowdloc eval`` gives its flag).
    """
    check(is_int(value) and 0 <= value <= FIRST_SEED_MAX,
          f"{name} must be an integer from 0 to {FIRST_SEED_MAX}, got {value!r}")  # fmt: skip


@dataclass(frozen=True)
class EvalSpec:
    """What to evaluate: the grid and the episode.

    Args:
        policies: fixed policy names (:data:`agents.policies.FIXED_POLICIES`) or
            ``"ppo:PATH/model.zip"`` (a stable-baselines3 PPO model).
        localizers: registered localizer names; the world must have the sensor each one's
            measurement kind reads.
        crowd_sizes: crowd sizes (densities) of the world.
        seeds: number of held-out seeds per cell (``EVAL_SEED_BASE + first_seed + 0 .. seeds - 1``).
        first_seed: offset of the first held-out seed. The default 0 gives the test seeds that
            ``make demo`` reports on; choosing between trained policies (validation) uses
            another range, e.g. ``first_seed=1000``, so the test seeds play no part in the choice.
        episode_steps: steps per episode (450 = 15 s at the RoboCup worlds' 30 Hz).
        env_id: a registered crowdloc id.
        env_kwargs: the conditions: ``world`` (a YAML path or shipped world name, replacing the
            id's world), world section overrides for ``gym.make`` (e.g.
            ``{"camera": {"fov_rad": 1.5708}}``) and ``prior`` (``"start"``: localizers get the
            true start pose; ``"none"``: they start lost; default: each localizer's own) and
            ``belief_spread`` (see ``envs.wrappers``).
        reward: the reward weights reported as the episode return.
        route: the task's route, for the reward's progress term and the observation's waypoint
            (``agents.rl.observation.RouteConfig``; default: the map's).
        observation: what a trained (``ppo:``) policy observes
            (``agents.rl.observation.ObservationConfig``, a training config's ``observation:``):
            its cells' envs are wrapped in ``TaskObservation`` exactly as in training; the fixed
            policies keep the raw observation they read (the LIDAR, the camera, ...).
        action: what a trained policy's action means (``agents.rl.residual.ActionConfig``, a
            training config's ``action:``): with ``residual_to``, a correction of that fixed
            policy's command, as in training; the fixed policies send their own commands.
        bootstrap_resamples: bootstrap resamples per confidence interval.
        bootstrap_seed: seeds the bootstrap's generator.
        kidnap: carry the robot away mid-episode and score the recovery
            (:mod:`agents.evaluate.kidnap`); None: no kidnapping.
        layouts: layout seeds ``[first, end]`` (a training config's ``layouts`` split, ``envs.layouts``):
            each seed's episode is on layout :func:`agents.rl.layout_episodes.episode_layout` of the
            range, the same for every policy and localizer (so their results pair); None: the
            world's own layout.
        localizer_params: per localizer of the grid, overrides of its parameters (its
            ``configs/localizers/NAME.yaml``), e.g. ``{"mcl_lidar": {"deskew": True}}``
            (``crowdloc eval --localizer-set mcl_lidar.deskew=true``).

    Raises:
        ConfigError: naming the bad value (unknown policy or localizer, missing PPO file, a
            localizer or policy whose sensor the world lacks, crowd size out of the world's
            range, fewer than one seed, ...).
    """

    policies: tuple[str, ...] = ("random_walk", "spin", "stop_and_go", "landmark_seeking", "greedy_info_gain")
    localizers: tuple[str, ...] = ("candidate_sets",)
    crowd_sizes: tuple[int, ...] = (2, 6, 10)
    seeds: int = 10
    first_seed: int = 0
    episode_steps: int = 450
    env_id: str = "crowdloc/RoboCupCrowded-v0"
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    reward: RewardWeights = field(default_factory=RewardWeights)
    bootstrap_resamples: int = 2000
    bootstrap_seed: int = 0
    kidnap: Kidnap | None = None
    localizer_params: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    route: RouteConfig = field(default_factory=RouteConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    action: ActionConfig = field(default_factory=ActionConfig)
    layouts: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.layouts is not None:
            check(isinstance(self.layouts, Sequence) and len(self.layouts) == 2 and all(is_int(v) for v in self.layouts)
                  and 0 <= self.layouts[0] < self.layouts[1],
                  f"layouts must be [first, end] layout seeds with 0 <= first < end, got {self.layouts!r}")  # fmt: skip
            object.__setattr__(self, "layouts", (int(self.layouts[0]), int(self.layouts[1])))
            check("layout" not in self.env_kwargs, "give the layout seeds as layouts, not env_kwargs.layout")
            from envs.layouts import layout_world

            layout_world(self.world(), self.layouts[0])  # a world without a generator is refused here, naming those with one
        for name in ("policies", "localizers", "crowd_sizes"):  # lists from Python callers become tuples
            object.__setattr__(self, name, tuple(getattr(self, name)))
        self._check_grid()
        for name in ("seeds", "first_seed", "episode_steps", "bootstrap_resamples", "bootstrap_seed"):
            object.__setattr__(self, name, int(getattr(self, name)))  # a numpy integer, checked, stored as Python's
        self._check_localizer_params()
        world = self.world()
        given = self.env_kwargs.get("world")
        where = f"world {world.name!r} ({self.env_id}" + (f" with world={str(given)!r})" if given else ")")
        self._check_sensors(world, where)
        if self.kidnap is not None:
            check(isinstance(self.kidnap, Kidnap), f"kidnap must be a Kidnap, got {type(self.kidnap).__name__} {self.kidnap!r}")
            length_s = self.episode_steps * world.dt_s
            check(length_s >= self.kidnap.ends_s - 1e-9,
                  f"an episode of {self.episode_steps} steps ({length_s:g} s) ends before the kidnap's recovery window "
                  f"does (at_s {self.kidnap.at_s:g} + window_s {self.kidnap.window_s:g} = {self.kidnap.ends_s:g} s): "
                  f"raise episode_steps to at least {math.ceil(self.kidnap.ends_s / world.dt_s - 1e-9)}")  # fmt: skip
            xmin, ymin, xmax, ymax = world.arena_m
            reach = 0.5 * math.hypot(xmax - xmin, ymax - ymin)  # from the arena's middle no pose lies farther
            check(self.kidnap.min_distance_m < reach,
                  f"kidnap.min_distance_m {self.kidnap.min_distance_m:g} cannot be placed in {where}: a robot in the "
                  f"middle of its {xmax - xmin:g} x {ymax - ymin:g} m arena has no free pose that far; "
                  f"use less than {reach:.2f} m")  # fmt: skip
        self._check_task()
        limit = world.crowd.max_count if world.crowd is not None else 0
        for size in self.crowd_sizes:
            check(is_int(size) and 0 <= size <= limit, f"crowd size {size!r} out of range 0..{limit} for {where}")
        object.__setattr__(self, "crowd_sizes", tuple(int(size) for size in self.crowd_sizes))

    def _check_task(self) -> None:
        """Each trained policy was trained on the observation its cells give (the task's, when
        ``observation`` changes anything), which keeps the odometry the episode records; the
        reward's route and the observation's build (one env, when either is used)."""
        check(isinstance(self.route, RouteConfig), f"route must be a RouteConfig, got {self.route!r}")
        check(isinstance(self.observation, ObservationConfig), f"observation must be an ObservationConfig, got {self.observation!r}")  # fmt: skip
        check(isinstance(self.action, ActionConfig), f"action must be an ActionConfig, got {self.action!r}")
        ppo = [policy for policy in self.policies if policy.startswith(PPO_PREFIX)]
        if not ppo and not self.reward.progress:
            return
        env = self.make_env(ppo[0] if ppo else self.policies[0], self.localizers[0], None)
        try:
            observed = env.observation_space
            assert isinstance(observed, spaces.Dict)
            odometry = odometry_key_of(env.unwrapped.sensor_metadata)  # type: ignore[attr-defined]
            if odometry not in observed.spaces:
                raise ConfigError(f"observation.drop removes {odometry!r}, the odometry the evaluation records: keep it")
            for policy in ppo:
                model = load_ppo(policy[len(PPO_PREFIX) :])
                check_observation_space(policy, model.observation_space, observed)
                check_trained_action(policy, model, self.action)
        finally:
            env.close()

    def layout_of(self, seed: int) -> int | None:
        """The layout the episode of env seed ``seed`` plays on (None: the world's own)."""
        if self.layouts is None:
            return None
        from agents.rl.layout_episodes import episode_layout

        return episode_layout(range(*self.layouts), seed)

    def make_env(
        self, policy: str, localizer: str, crowd_size: int | None, render_mode: str | None = None, layout: int | None = None
    ) -> gym.Env[Any, Any]:
        """The env of one cell of the grid: the world (on ``layout``, a :meth:`layout_of`) under these
        conditions with ``localizer``, the active-localization reward on :attr:`route` and, for a
        trained (``ppo:``) ``policy``, the task's :attr:`observation` (:func:`agents.rl.train.task_wrappers`,
        as in training)."""
        env = gym.make(
            self.env_id,
            layout=layout,
            crowd_size=crowd_size,
            localizer=localizer,
            localizer_params=self.localizer_params.get(localizer),
            max_episode_steps=self.episode_steps,
            render_mode=render_mode,
            **dict(self.env_kwargs),
        )
        trained = policy.startswith(PPO_PREFIX)
        return task_wrappers(
            env, self.reward, self.route, self.observation if trained else None, self.action if trained else None
        )

    @functools.cached_property
    def has_goal(self) -> bool:
        """Whether the evaluated world ends an episode at a goal (:mod:`agents.evaluate.goal`)."""
        return self.world().goal is not None

    def _check_localizer_params(self) -> None:
        """Each override names a localizer of the grid and fields its parameters have."""
        from localizers.registry import load_params

        check(isinstance(self.localizer_params, Mapping),
              f"localizer_params must map localizer names to overrides, got {self.localizer_params!r}")  # fmt: skip
        for name, overrides in self.localizer_params.items():
            check(name in self.localizers, f"localizer_params names {name!r}, which is not a localizer of the grid "
                                           f"({', '.join(self.localizers)})")  # fmt: skip
            load_params(name, overrides)  # raises, naming the field and the file

    def _check_grid(self) -> None:
        """The counts, the axes of the grid, the env id and the conditions' own values."""
        check(is_int(self.seeds) and self.seeds >= 1, f"seeds must be an integer >= 1, got {self.seeds!r}")
        check_first_seed(self.first_seed)
        check(is_int(self.episode_steps) and self.episode_steps >= 1,
              f"episode_steps must be an integer >= 1, got {self.episode_steps!r}")  # fmt: skip
        check(is_int(self.bootstrap_resamples) and self.bootstrap_resamples >= 1,
              f"bootstrap_resamples must be an integer >= 1, got {self.bootstrap_resamples!r}")  # fmt: skip
        check(is_int(self.bootstrap_seed) and self.bootstrap_seed >= 0,
              f"bootstrap_seed must be an integer >= 0, got {self.bootstrap_seed!r}")  # fmt: skip
        for name in ("policies", "localizers", "crowd_sizes"):
            values = getattr(self, name)
            check(len(values) >= 1, f"{name} needs at least one value")
            check(len(set(values)) == len(values), f"{name} repeat: {list(values)}")
        known = crowdloc_ids()
        if self.env_id not in known:
            raise ConfigError(f"unknown env id {self.env_id!r}; known: {', '.join(known)}")
        check(isinstance(self.env_kwargs, Mapping), f"env_kwargs must be a mapping, got {self.env_kwargs!r}")
        prior = self.env_kwargs.get("prior")
        check(prior in (None, "start", "none"), f"env_kwargs prior must be 'start' or 'none', got {prior!r}")
        belief = self.env_kwargs.get("belief_spread", False)
        check(isinstance(belief, bool), f"env_kwargs belief_spread must be true or false, got {belief!r}")
        world = self.env_kwargs.get("world")
        check(world is None or isinstance(world, (str, Path)),
              f"env_kwargs world must be a YAML path or a shipped world name, got {world!r}")  # fmt: skip
        for key in _GRID_KEYS:
            check(key not in self.env_kwargs, f"env_kwargs may not set {key!r}: the evaluation grid sets it")

    def _check_sensors(self, world: WorldConfig, where: str) -> None:
        """Each localizer's world has the sensor its measurement kind reads; each fixed policy the one it reads."""
        have = {name: {"type": s.type_name} for name, s in world.sensors.items()}
        for name in self.localizers:
            find_sensor(localizer_kind(name, have), have, f"localizer {name!r} in {where}")  # raises, naming what is missing
        for policy in self.policies:
            check_policy(policy)
            unmet = None if policy.startswith(PPO_PREFIX) else FIXED_POLICIES[policy].unmet_need(world)
            if unmet is not None and self.drives_task_route(policy):
                unmet = None  # it drives the task's route, not a route of the map
            if unmet is not None:
                raise ConfigError(f"policy {policy!r} needs {unmet[0]} and {where} has none ({unmet[1]}); "
                                  f"fixed policies it can run: {', '.join(runnable_policies(world))}")  # fmt: skip

    def drives_task_route(self, policy: str) -> bool:
        """Whether fixed policy ``policy`` drives :attr:`route`'s points (``route_follower`` and
        ``look_then_route`` when the conditions give the points, as a task's config does) rather
        than the map's route feature."""
        return "route" in task_route_kwargs(policy, self.route.points_m)

    def world(self) -> WorldConfig:
        """The world evaluated: the id's (or ``env_kwargs["world"]``) with the conditions applied."""
        return world_of(self.env_id, self.env_kwargs)

    @property
    def metrics(self) -> tuple[MetricInfo, ...]:
        """The metric rows of this grid: the core ones, those of its localizers' kinds, with a kidnap
        the recovery's (:data:`agents.evaluate.kidnap.KIDNAP_METRICS`) and, in a world with a goal,
        the goal's (:data:`agents.evaluate.goal.GOAL_METRICS`), last, so that every other row but the
        consistency ones keeps its bootstrap stream (:func:`agents.evaluate.stats.summarize` numbers
        the consistency rows last: in a world with a goal their intervals are drawn from streams two further on)."""
        rows = localizer_metrics(self.localizers) + (KIDNAP_METRICS if self.kidnap is not None else ())
        return rows + GOAL_METRICS if self.has_goal else rows

    @property
    def eval_seeds(self) -> tuple[int, ...]:
        """The held-out env seeds, ``EVAL_SEED_BASE + first_seed + i``."""
        return tuple(EVAL_SEED_BASE + self.first_seed + i for i in range(self.seeds))

    def known_start(self, localizer: str) -> bool:
        """Whether ``localizer`` gets the true start pose under these conditions."""
        from localizers.registry import spec as localizer_spec

        prior = self.env_kwargs.get("prior")
        return localizer_spec(localizer).needs_prior if prior is None else prior == "start"

    def policy_label(self, policy: str) -> str:
        """The short name reports and file names show (:func:`policy_labels`; the full ones are in ``run.json``)."""
        return policy_labels(self.policies).get(policy) or policy_labels([policy])[policy]

    def cells(self) -> list[Cell]:
        """Every (policy, localizer, crowd size, seed), grouped by the first three."""
        return [
            Cell(p, loc, c, s)
            for p in self.policies
            for loc in self.localizers
            for c in self.crowd_sizes
            for s in self.eval_seeds
        ]


@dataclass(frozen=True)
class Cell:
    """One episode of the grid."""

    policy: str
    localizer: str
    crowd_size: int
    seed: int

    @property
    def group(self) -> tuple[str, str, int]:
        return self.policy, self.localizer, self.crowd_size

    def stem(self, policy_label: str | None = None) -> str:
        """A file-name stem naming this episode (with the policy's short name, if given)."""
        return f"{slug(policy_label or self.policy)}__{self.localizer}__crowd{self.crowd_size}__seed{self.seed}"


def runnable_policies(world: WorldConfig) -> list[str]:
    """The fixed policies whose sensor and map feature ``world`` has, in registry order."""
    return [name for name, cls in FIXED_POLICIES.items() if cls.unmet_need(world) is None]


def world_of(env_id: str, env_kwargs: Mapping[str, Any]) -> WorldConfig:
    """The world of ``env_id`` (or ``env_kwargs["world"]``) with the conditions ``env_kwargs`` applied."""
    from envs import load_world
    from envs.localization_env import apply_overrides

    conditions = {k: v for k, v in env_kwargs.items() if k not in ("prior", "belief_spread", "world")}
    name = env_kwargs.get("world") or gym.spec(env_id).kwargs["world"]
    return apply_overrides(load_world(name), **conditions)


def crowdloc_ids() -> list[str]:
    """The registered world ids of the ``crowdloc`` namespace, sorted (not the task ids, which
    bring their own localizer and reward: the grid sets those)."""

    return sorted(i for i in gym.registry if i.startswith("crowdloc/") and i not in task_ids.TASK_CONFIGS)


_TRAINING_CONDITIONS = "evaluate it in its training conditions (crowdloc eval --conditions <its training config>)"


def odometry_key_of(sensors: Mapping[str, Mapping[str, Any]]) -> str:
    """The observation key of the one odometry sensor among an env's ``sensor_metadata`` (what an episode records).

    Raises:
        ConfigError: for a world with no odometry sensor or several (naming its sensors).
    """
    return str(sensors[find_sensor("odometry", sensors, "an evaluated world (its episode record)")]["key"])


def task_conditions(trained: TrainConfig) -> dict[str, Any]:
    """The :class:`EvalSpec` fields a training config fixes: its env and conditions, reward, route,
    what its policy observes and what its action means, and its localizer (``crowdloc eval
    --conditions``, the demo's world tasks)."""
    conditions = {"env_id": trained.env_id, "env_kwargs": dict(trained.env_kwargs), "reward": trained.reward,
                  "route": trained.route, "observation": trained.observation, "action": trained.action,
                  "localizers": (trained.localizer,)}  # fmt: skip
    if trained.localizer_params:  # the localizer as it was trained with
        conditions["localizer_params"] = {trained.localizer: dict(trained.localizer_params)}
    return conditions


def check_observation_space(policy: str, expected: spaces.Space[Any], given: spaces.Space[Any],
                            hint: str = _TRAINING_CONDITIONS) -> None:  # fmt: skip
    """Raise a ConfigError (ending with ``hint``) unless the env's observation space is the one
    ``policy`` was trained on."""
    if expected == given:
        return
    want = {k: v.shape for k, v in expected.spaces.items()} if isinstance(expected, spaces.Dict) else {"": expected.shape}
    have = {k: v.shape for k, v in given.spaces.items()} if isinstance(given, spaces.Dict) else {"": given.shape}
    diffs = [f"{k}: policy {want.get(k, 'absent')}, env {have.get(k, 'absent')}" for k in sorted(set(want) | set(have))
             if want.get(k) != have.get(k)] or ["same keys and shapes, different bounds"]  # fmt: skip
    raise ConfigError(
        f"policy {policy!r} was trained on other observations than these conditions give ({'; '.join(diffs)}): {hint}"
    )


def check_policy(policy: str) -> None:
    """Raise a ConfigError unless ``policy`` is a fixed policy name or ``ppo:`` an existing file."""
    if policy.startswith(PPO_PREFIX):
        path = Path(policy[len(PPO_PREFIX) :])
        check(path.is_file(), f"PPO model file {str(path)!r} does not exist (policy {policy!r})")
        check(zipfile.is_zipfile(path),
              f"PPO model file {str(path)!r} is not a zip archive saved by stable-baselines3 (policy {policy!r})")  # fmt: skip
    elif policy not in FIXED_POLICIES:
        raise ConfigError(f"unknown policy {policy!r}; use one of {', '.join(FIXED_POLICIES)} or ppo:PATH/model.zip")


@functools.lru_cache(maxsize=4)
def load_ppo(path: str) -> Any:
    """The stable-baselines3 PPO model at ``path`` (on the CPU; the last few are cached).

    Raises:
        ConfigError: if the file is not a model stable-baselines3 can load.
    """
    from stable_baselines3 import PPO

    try:
        return PPO.load(path, device="cpu")
    except (AssertionError, ValueError, KeyError, EOFError, OSError, RuntimeError, zipfile.BadZipFile) as exc:  # noqa: B014
        # stable-baselines3 reports a zip without its data by an assert
        raise ConfigError(f"PPO model file {path!r} cannot be loaded by stable-baselines3: {exc}") from None


@functools.lru_cache(maxsize=64)
def _labels(policies: tuple[str, ...]) -> dict[str, str]:
    paths = {p: Path(p[len(PPO_PREFIX) :]).with_suffix("").parts for p in policies if p.startswith(PPO_PREFIX)}
    out = {p: p for p in policies}
    for policy, parts in paths.items():
        others = [q for other, q in paths.items() if other != policy]
        for k in range(1, len(parts) + 1):  # the shortest tail of the path that no other policy shares
            if all(q[-k:] != parts[-k:] for q in others):
                break
        out[policy] = PPO_PREFIX + "/".join(parts[-k:])
    return out


def policy_labels(policies: Sequence[str]) -> dict[str, str]:
    """Short display names: a fixed policy's own name; a trained one ``ppo:`` and the shortest
    tail of its path, without ``.zip``, that tells it apart from the others
    (``ppo:ppo_candidate_sets``; ``ppo:seed_0/model`` beside ``ppo:seed_1/model``)."""
    return _labels(tuple(policies))


def slug(text: str) -> str:
    """``text`` with every run of characters other than letters, digits, ``-`` and ``.`` turned into ``_``."""
    return re.sub(r"[^A-Za-z0-9.-]+", "_", text).strip("_")


def policy_seed(env_seed: int) -> int:
    """The fixed policy's own seed, derived from the episode's env seed."""
    return int(np.random.SeedSequence([env_seed, _POLICY_SALT]).generate_state(1)[0])
