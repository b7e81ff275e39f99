"""A training run's config: :class:`TrainConfig` (with :class:`PPOConfig`), read from a YAML file under
``configs/experiments/`` by :func:`load_train_config`, and the command line's ``--set`` / ``--replace``
changes (:func:`parse_overrides`), checked like the file itself.

The run itself (task envs, PPO, checkpoints and exact resume) is :mod:`agents.rl.train`. What only
reads a config or the evaluation seed base (:data:`EVAL_SEED_BASE`) imports this module and no trainer.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

import crowdloc_configs
from agents.common.util import nest
from agents.rl.layout_episodes import LayoutSplits
from agents.rl.observation import ObservationConfig, RouteConfig
from agents.rl.residual import ActionConfig
from agents.rl.rewards import RewardWeights
from core.schema import ConfigError, check, from_mapping, load_yaml, parse_yaml, replace_checked

EXPERIMENT_DIR = crowdloc_configs.path("experiments")  # package data (configs/ in the checkout)
#: env seeds at or above this are evaluation seeds; training episodes never use them
EVAL_SEED_BASE = 2**31


@dataclass(frozen=True)
class PPOConfig:
    """stable-baselines3 PPO hyperparameters (its names and meanings)."""

    learning_rate: float = 3e-4
    n_steps: int = 450  # per env per rollout; also the episode length (time limit)
    batch_size: int = 450
    n_epochs: int = 5
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    net_arch: tuple[int, ...] = (64, 64)
    #: the Gaussian actions' initial log standard deviation (SB3's ``policy_kwargs.log_std_init``): 0, SB3's default,
    #: explores with an sd of 1, a full-scale action; a task whose localizer is lost by an action's noise (a turn, on
    #: the campus's free-running webcams) may need less to see a localized episode at all
    log_std_init: float = 0.0

    def __post_init__(self) -> None:
        check(self.learning_rate > 0, f"ppo.learning_rate must be > 0, got {self.learning_rate}")
        check(self.n_steps >= 2, f"ppo.n_steps must be >= 2, got {self.n_steps}")
        check(self.batch_size >= 2, f"ppo.batch_size must be >= 2, got {self.batch_size}")
        check(self.n_epochs >= 1, f"ppo.n_epochs must be >= 1, got {self.n_epochs}")
        check(0 < self.gamma <= 1, f"ppo.gamma must be in (0, 1], got {self.gamma}")
        check(all(n > 0 for n in self.net_arch), f"ppo.net_arch sizes must be > 0, got {self.net_arch}")
        check(math.isfinite(self.log_std_init), f"ppo.log_std_init must be finite, got {self.log_std_init}")


@dataclass(frozen=True)
class TrainConfig:
    """One training run."""

    name: str
    env_id: str = "crowdloc/RoboCupCrowded-v0"
    crowd_sizes: tuple[int, ...] = (6,)  # env i trains at crowd_sizes[i % len]
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)  # other gym.make overrides
    localizer: str = "candidate_sets"
    localizer_params: Mapping[str, Any] = field(default_factory=dict)
    reward: RewardWeights = field(default_factory=RewardWeights)
    observation: ObservationConfig = field(default_factory=ObservationConfig)  # what the policy sees (agents.rl.observation)
    route: RouteConfig = field(default_factory=RouteConfig)  # the task's route (progress, waypoint); default the map's
    action: ActionConfig = field(default_factory=ActionConfig)  # what the policy's action means (agents.rl.residual)
    #: the layout seeds of training, validation and test (agents.rl.layout_episodes); None: the world's own layout
    layouts: LayoutSplits | None = None
    layout_cache: int = 8  # layouts whose tasks (worlds and localizer maps) one env keeps
    n_envs: int = 4
    vec_env: str = "subproc"  # "subproc" (one process per env) or "dummy" (in-process)
    seed: int = 0
    total_timesteps: int = 200_000
    checkpoint_every: int = 36_000  # env steps; rounded to whole rollouts
    ppo: PPOConfig = field(default_factory=PPOConfig)

    def __post_init__(self) -> None:
        check(self.n_envs >= 1, f"n_envs must be >= 1, got {self.n_envs}")
        check(self.vec_env in ("subproc", "dummy"), f"vec_env must be 'subproc' or 'dummy', got {self.vec_env!r}")
        check(self.total_timesteps >= 1, f"total_timesteps must be >= 1, got {self.total_timesteps}")
        check(len(self.crowd_sizes) >= 1, "crowd_sizes needs at least one crowd size")
        check(self.layout_cache >= 1, f"layout_cache must be >= 1, got {self.layout_cache}")
        check("layout" not in self.env_kwargs, "give layout seeds as layouts (train/validation/test), not env_kwargs.layout")
        check(
            "max_episode_steps" not in self.env_kwargs, "the episode length is ppo.n_steps; remove env_kwargs.max_episode_steps"
        )
        check("crowd_size" not in self.env_kwargs, "give crowd sizes as crowd_sizes, not env_kwargs.crowd_size")

    @property
    def rollout_steps(self) -> int:
        """Env steps per PPO iteration (all envs)."""
        return self.ppo.n_steps * self.n_envs


def load_train_config(
    path_or_name: str | Path, overrides: Mapping[str, Any] | None = None, replacements: Mapping[str, Any] | None = None
) -> TrainConfig:
    """Load ``configs/experiments/<name>.yaml`` (or a path) and apply dotted-key changes.

    ``replacements`` (``crowdloc train --replace``) come first and set a key's value whole, as if
    the file said so: ``{"env_kwargs": {}}`` drops every condition of the file. ``overrides``
    (``--set``) then merge on top: a mapping given to a mapping field (``env_kwargs``, ``reward``)
    changes the keys it names and keeps the others.
    """
    path = Path(path_or_name)
    if path.suffix not in (".yaml", ".yml"):
        path = EXPERIMENT_DIR / f"{path_or_name}.yaml"
    data = load_yaml(path)
    for key, value in (replacements or {}).items():
        _replace_dotted(data, key, value, where=f"replacement {key!r} of {path}")
    config = from_mapping(TrainConfig, data, where=str(path))
    if overrides:
        config = replace_checked(config, nest(overrides), where=f"overrides of {path}")
    return config


def _replace_dotted(data: dict[str, Any], dotted: str, value: Any, where: str) -> None:
    """Set ``data[a][b][c] = value`` for ``dotted = "a.b.c"``, making missing sections; the value
    replaces what was there whole (the keys are checked when the config is built from ``data``).

    Raises:
        ConfigError: when a section on the way is not a mapping.
    """
    *parents, leaf = dotted.split(".")
    node = data
    for part in parents:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(f"{where}: {part!r} is {child!r}, not a section with keys")
        node = child
    node[leaf] = value


def parse_overrides(items: Sequence[str], flag: str = "override") -> dict[str, Any]:
    """``["ppo.learning_rate=1e-3", "n_envs=2"]`` -> a dict of YAML-parsed values (``flag``: what
    an error calls an item, e.g. the command-line flag that gave it)."""
    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"{flag} {item!r} is not KEY=VALUE")
        try:
            out[key.strip()] = parse_yaml(text)
        except yaml.YAMLError as exc:
            reason = getattr(exc, "problem", None) or str(exc).splitlines()[0]  # without YAML's pointer lines
            raise ConfigError(f"{flag} {item!r}: the value is not valid YAML ({reason})") from None
    return out
