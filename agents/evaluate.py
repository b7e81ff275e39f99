"""``crowdloc eval``: policies x localizers x crowd sizes x held-out seeds, with bootstrap CIs.

Every cell of the grid is one episode on a held-out seed (``EVAL_SEED_BASE + i``, never used
in training). The env is built like the training env (localizer wrapper, active-localization
reward, the episode length) and reset with the evaluation seed; a fixed policy gets its own
seed derived from it, a PPO policy acts deterministically. Cells run through
:func:`agents.sweep.run_tasks` (local processes or Ray).

Per episode the metrics are (``t0`` = the first step with a valid estimate, the first fix):

- ``position_error_mean_m`` / ``_rms_m``, ``heading_error_mean_deg`` / ``_rms_deg``: over the
  valid steps from ``t0`` on;
- ``failure_rate``: share of those steps with a position error >= 1 m;
- ``availability``: share of all steps with a valid estimate;
- ``fixed``: 1 if the localizer ever had a pose, else 0;
- ``first_fix_s`` / ``first_fix_distance_m``: time since reset and distance travelled until
  ``t0``. **Never fixed**: these and the error metrics are NaN; aggregates are taken over the
  episodes with a value (the summary shows how many), and ``fixed`` tells how often that was;
- ``third_landmark_s``: time since reset until bearings of three distinct landmarks have
  been in view (not necessarily at once): the search, the policy's part of the first fix
  (NaN if it never happened); ``fix_after_third_s``: ``first_fix_s`` minus it, the
  localizer's part (negative when a fix came from two landmarks and motion);
- ``collisions``: contact events of our robot that began during the episode;
- ``episode_return``: sum of the active-localization rewards;
- ``bound_rmse_m``: RMS over the same steps as the errors of the posterior Cramer-Rao bound
  on position RMSE along the true path (the truly visible landmarks of each step, the camera's
  bearing noise, the world's odometry alphas; prior: the known start pose for localizers that
  get it, else one as vague as the field);
- ``error_bound_ratio``: RMS position error over that RMS bound
  (:func:`agents.metrics.error_bound_ratio`; >= 1 for an unbiased estimator in expectation).

Aggregates: per (policy, localizer, crowd size) the mean over seeds and a 95% percentile
bootstrap interval of that mean (:func:`bootstrap_ci`).

Outputs (:func:`write_outputs`): ``episodes.csv``, ``summary.csv``, ``summary.md``,
``plots/<metric>.png``, ``tum/<episode>_{estimate,groundtruth}.tum`` (``evo`` reads them;
estimate rows only where valid) and ``episode.gif``. From Python::

    result = evaluate(EvalSpec(policies=("spin", "ppo:results/train/x/seed_0/model.zip"), seeds=5))
    write_outputs(result, Path("results/eval"))
"""

from __future__ import annotations

import csv
import functools
import math
import re
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

import envs  # noqa: F401  (registers the crowdloc ids)
from agents import metrics
from agents.policies import FIXED_POLICIES
from agents.replay import bound_rmse_along
from agents.rewards import ActiveLocalizationReward, RewardWeights
from agents.train import EVAL_SEED_BASE
from localizers.measurements import find_sensor, measurement_kind
from localizers.schema import ConfigError, check

Array = NDArray[np.float64]

PPO_PREFIX = "ppo:"
_POLICY_SALT = 0x9011C7  # the policy's seed differs from the env's for the same evaluation seed


@dataclass(frozen=True)
class MetricInfo:
    """How a per-episode metric is labelled and printed."""

    key: str
    label: str
    fmt: str
    in_table: bool = True


METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("position_error_mean_m", "pos. error mean [m]", "{:.3f}"),
    MetricInfo("position_error_rms_m", "pos. error RMS [m]", "{:.3f}"),
    MetricInfo("heading_error_mean_deg", "heading error mean [deg]", "{:.2f}"),
    MetricInfo("heading_error_rms_deg", "heading error RMS [deg]", "{:.2f}"),
    MetricInfo("failure_rate", "failure rate (>= 1 m)", "{:.3f}"),
    MetricInfo("availability", "availability", "{:.3f}"),
    MetricInfo("fixed", "share of episodes with a fix", "{:.2f}", in_table=False),
    MetricInfo("first_fix_s", "first fix [s]", "{:.2f}"),
    MetricInfo("first_fix_distance_m", "first fix [m travelled]", "{:.2f}"),
    MetricInfo("third_landmark_s", "third landmark seen [s]", "{:.2f}", in_table=False),
    MetricInfo("fix_after_third_s", "first fix after the third landmark [s]", "{:.2f}", in_table=False),
    MetricInfo("collisions", "collisions", "{:.1f}"),
    MetricInfo("episode_return", "episode return", "{:.1f}"),
    MetricInfo("bound_rmse_m", "bound RMSE [m]", "{:.3f}", in_table=False),
    MetricInfo("error_bound_ratio", "error / bound", "{:.2f}"),
)
METRIC_KEYS = tuple(m.key for m in METRICS)


# --------------------------------------------------------------------------- the grid
@dataclass(frozen=True)
class EvalSpec:
    """What to evaluate: the grid and the episode.

    Args:
        policies: fixed policy names (:data:`agents.policies.FIXED_POLICIES`) or
            ``"ppo:PATH/model.zip"`` (a stable-baselines3 PPO model).
        localizers: registered localizer names.
        crowd_sizes: crowd sizes (densities) of the world.
        seeds: number of held-out seeds per cell (``EVAL_SEED_BASE + first_seed + 0 .. seeds - 1``).
        first_seed: offset of the first held-out seed. The default 0 gives the test seeds that
            ``make demo`` reports on; choosing between trained policies (validation) uses
            another range, e.g. ``first_seed=1000``, so the test seeds play no part in the choice.
        episode_steps: steps per episode (450 = 15 s, the training episode length).
        env_id: a registered crowdloc id whose world has a bearing camera.
        env_kwargs: the conditions: world section overrides for ``gym.make`` (e.g.
            ``{"camera": {"fov_rad": 1.5708}}``) and ``prior`` (``"start"``: localizers get the
            true start pose; ``"none"``: they start lost; default: each localizer's own) and
            ``belief_spread`` (see ``localizers.wrappers``).
        reward: the reward weights reported as the episode return.
        bootstrap_resamples: bootstrap resamples per confidence interval.
        bootstrap_seed: seeds the bootstrap's generator.

    Raises:
        ConfigError: naming the bad value (unknown policy or localizer, missing PPO file,
            crowd size out of the world's range, fewer than one seed, ...).
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

    def __post_init__(self) -> None:
        from envs import ENV_WORLDS, load_world
        from envs.localization_env import apply_overrides
        from localizers.registry import spec as localizer_spec

        for name in ("policies", "localizers", "crowd_sizes"):  # lists from Python callers become tuples
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check(isinstance(self.seeds, int) and self.seeds >= 1, f"seeds must be an integer >= 1, got {self.seeds!r}")
        check(isinstance(self.first_seed, int) and 0 <= self.first_seed <= 2**30,
              f"first_seed must be an integer from 0 to {2**30}, got {self.first_seed!r}")  # fmt: skip
        check(isinstance(self.episode_steps, int) and self.episode_steps >= 1,
              f"episode_steps must be an integer >= 1, got {self.episode_steps!r}")  # fmt: skip
        check(self.bootstrap_resamples >= 1, f"bootstrap_resamples must be >= 1, got {self.bootstrap_resamples}")
        for name in ("policies", "localizers", "crowd_sizes"):
            values = getattr(self, name)
            check(len(values) >= 1, f"{name} needs at least one value")
            check(len(set(values)) == len(values), f"{name} repeat: {list(values)}")
        for policy in self.policies:
            check_policy(policy)
        if self.env_id not in ENV_WORLDS:
            raise ConfigError(f"unknown env id {self.env_id!r}; known: {', '.join(ENV_WORLDS)}")
        check(isinstance(self.env_kwargs, Mapping), f"env_kwargs must be a mapping, got {self.env_kwargs!r}")
        conditions = dict(self.env_kwargs)
        prior = conditions.pop("prior", None)
        check(prior in (None, "start", "none"), f"env_kwargs prior must be 'start' or 'none', got {prior!r}")
        belief = conditions.pop("belief_spread", False)
        check(isinstance(belief, bool), f"env_kwargs belief_spread must be true or false, got {belief!r}")
        for key in ("crowd_size", "max_episode_steps", "localizer", "localizer_params", "render_mode"):
            check(key not in conditions, f"env_kwargs may not set {key!r}: the evaluation grid sets it")
        world = apply_overrides(load_world(ENV_WORLDS[self.env_id]), **conditions)
        check(
            world.sensor_of_type("bearing_camera") is not None,
            f"eval needs a bearing env (a world with a camera); {self.env_id} has none",
        )
        for name in self.localizers:
            kind = measurement_kind(localizer_spec(name).measurement)
            check(
                world.sensor_of_type(kind.sensor_type) is not None,
                f"localizer {name!r} needs a {kind.sensor_type} sensor ({kind.name} measurements); {self.env_id} has none",
            )
        ppo = [policy for policy in self.policies if policy.startswith(PPO_PREFIX)]
        if ppo:
            env = gym.make(self.env_id, localizer=self.localizers[0], **dict(self.env_kwargs))
            for policy in ppo:
                check_observation_space(policy, _load_ppo(policy[len(PPO_PREFIX) :]).observation_space, env.observation_space)
            env.close()
        limit = world.crowd.max_count if world.crowd is not None else 0
        for size in self.crowd_sizes:
            check(isinstance(size, (int, np.integer)) and 0 <= size <= limit,
                  f"crowd size {size!r} out of range 0..{limit} for {self.env_id}")  # fmt: skip

    @property
    def eval_seeds(self) -> tuple[int, ...]:
        """The held-out env seeds, ``EVAL_SEED_BASE + first_seed + i``."""
        return tuple(EVAL_SEED_BASE + self.first_seed + i for i in range(self.seeds))

    def known_start(self, localizer: str) -> bool:
        """Whether ``localizer`` gets the true start pose under these conditions."""
        from localizers.registry import spec as localizer_spec

        prior = self.env_kwargs.get("prior")
        return localizer_spec(localizer).needs_prior if prior is None else prior == "start"

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

    @property
    def stem(self) -> str:
        """A file-name stem naming this episode."""
        return f"{slug(self.policy)}__{self.localizer}__crowd{self.crowd_size}__seed{self.seed}"


def check_observation_space(policy: str, expected: spaces.Space[Any], given: spaces.Space[Any]) -> None:
    """Raise a ConfigError unless the env's observation space is the one ``policy`` was trained on."""
    if expected == given:
        return
    want = {k: v.shape for k, v in expected.spaces.items()} if isinstance(expected, spaces.Dict) else {"": expected.shape}
    have = {k: v.shape for k, v in given.spaces.items()} if isinstance(given, spaces.Dict) else {"": given.shape}
    diffs = [f"{k}: policy {want.get(k, 'absent')}, env {have.get(k, 'absent')}" for k in sorted(set(want) | set(have))
             if want.get(k) != have.get(k)] or ["same keys and shapes, different bounds"]  # fmt: skip
    raise ConfigError(
        f"policy {policy!r} was trained on other observations than these conditions give ({'; '.join(diffs)}): "
        "evaluate it in its training conditions (crowdloc eval --conditions <its training config>)"
    )


def check_policy(policy: str) -> None:
    """Raise a ConfigError unless ``policy`` is a fixed policy name or ``ppo:`` an existing file."""
    if policy.startswith(PPO_PREFIX):
        path = Path(policy[len(PPO_PREFIX) :])
        check(path.is_file(), f"PPO model file {str(path)!r} does not exist (policy {policy!r})")
    elif policy not in FIXED_POLICIES:
        raise ConfigError(f"unknown policy {policy!r}; use one of {', '.join(FIXED_POLICIES)} or ppo:PATH/model.zip")


def slug(text: str) -> str:
    """``text`` with every run of characters other than letters, digits, ``-`` and ``.`` turned into ``_``."""
    return re.sub(r"[^A-Za-z0-9.-]+", "_", text).strip("_")


def policy_seed(env_seed: int) -> int:
    """The fixed policy's own seed, derived from the episode's env seed."""
    return int(np.random.SeedSequence([env_seed, _POLICY_SALT]).generate_state(1)[0])


# --------------------------------------------------------------------------- one episode
@dataclass(frozen=True)
class Episode:
    """One evaluated episode, ``T = episode_steps + 1`` rows (row 0 is the reset).

    Attributes:
        cell: which grid cell.
        time_s: ``(T,)`` simulated time.
        true_pose: ``(T, 3)`` ground truth.
        estimates: ``(T, 3)`` the localizer's poses, NaN rows where it had none.
        valid: ``(T,)`` whether it had one.
        contacts: ``(T,)`` contact events of our robot that began in each step.
        odometry: ``(T - 1, 3)`` odometry increments of steps 1..T-1.
        visible: ``(T, L)`` landmarks truly in the camera's sight.
        rewards: ``(T - 1,)`` active-localization rewards.
        bound_rmse_m: ``(T,)`` posterior-CRB position RMSE along the true path.
        metrics: the per-episode metrics (:data:`METRIC_KEYS`).
    """

    cell: Cell
    time_s: Array
    true_pose: Array
    estimates: Array
    valid: NDArray[np.bool_]
    contacts: NDArray[np.int64]
    odometry: Array
    visible: NDArray[np.bool_]
    rewards: Array
    bound_rmse_m: Array
    metrics: Mapping[str, float]


class _PPOPolicy:
    """A loaded stable-baselines3 model acting deterministically."""

    def __init__(self, path: str) -> None:
        self.model = _load_ppo(path)

    def predict(self, observation: Any) -> NDArray[np.float32]:
        action, _ = self.model.predict(observation, deterministic=True)
        return np.asarray(action, dtype=np.float32)


@functools.lru_cache(maxsize=4)
def _load_ppo(path: str) -> Any:
    from stable_baselines3 import PPO

    return PPO.load(path, device="cpu")


def _make_env(spec: EvalSpec, cell: Cell, render_mode: str | None = None) -> gym.Env[Any, Any]:
    env = gym.make(
        spec.env_id,
        crowd_size=cell.crowd_size,
        localizer=cell.localizer,
        max_episode_steps=spec.episode_steps,
        render_mode=render_mode,
        **dict(spec.env_kwargs),
    )
    return ActiveLocalizationReward(env, spec.reward)


def _make_policy(cell: Cell, env: gym.Env[Any, Any]) -> Callable[[Any], NDArray[np.float32]]:
    if cell.policy.startswith(PPO_PREFIX):
        return _PPOPolicy(cell.policy[len(PPO_PREFIX) :]).predict
    from agents.policies import make_policy

    fixed = make_policy(cell.policy, env, seed=policy_seed(cell.seed))
    return lambda obs: fixed.predict(obs, deterministic=True)[0]


def _rollout(spec: EvalSpec, cell: Cell, frame_every: int = 0) -> tuple[dict[str, Any], list[NDArray[np.uint8]]]:
    """Play one episode; with ``frame_every > 0`` also render every that many steps."""
    env = _make_env(spec, cell, "rgb_array" if frame_every else None)
    act = _make_policy(cell, env)
    obs, info = env.reset(seed=cell.seed)
    n_lm = env.unwrapped.landmark_map.count  # type: ignore[attr-defined]
    rows: dict[str, list[Any]] = {k: [] for k in ("time_s", "true_pose", "estimate", "valid", "contacts", "visible")}
    odometry: list[Array] = []
    rewards: list[float] = []
    frames: list[NDArray[np.uint8]] = []

    def keep(step: int, info: Mapping[str, Any]) -> None:
        est = info["estimate"]
        rows["time_s"].append(float(info["time_s"]))
        rows["true_pose"].append(np.asarray(info["true_pose"], dtype=np.float64).copy())
        rows["estimate"].append((est.x_m, est.y_m, est.theta_rad) if est.valid else (np.nan, np.nan, np.nan))
        rows["valid"].append(bool(est.valid))
        rows["contacts"].append(len(info["contacts"]))
        seen = np.zeros(n_lm, dtype=bool)
        seen[np.asarray(info["visible_landmarks"], dtype=np.int64)] = True
        rows["visible"].append(seen)
        if frame_every and step % frame_every == 0:
            frames.append(env.render())  # type: ignore[arg-type]

    keep(0, info)
    step = 0
    while True:
        obs, reward, terminated, truncated, info = env.step(act(obs))
        step += 1
        odometry.append(np.asarray(obs["odometry"], dtype=np.float64))
        rewards.append(float(reward))
        keep(step, info)
        if terminated or truncated:
            break
    base = env.unwrapped
    meta = base.sensor_metadata  # type: ignore[attr-defined]
    cam = meta[find_sensor("bearings", meta, "the evaluation's bound")]
    odo = next(m for m in meta.values() if m["type"] == "odometry")
    data = {
        "time_s": np.array(rows["time_s"]),
        "true_pose": np.stack(rows["true_pose"]),
        "estimates": np.array(rows["estimate"], dtype=np.float64),
        "valid": np.array(rows["valid"], dtype=bool),
        "contacts": np.array(rows["contacts"], dtype=np.int64),
        "odometry": np.array(odometry, dtype=np.float64).reshape(-1, 3),
        "visible": np.stack(rows["visible"]),
        "rewards": np.array(rewards, dtype=np.float64),
        "landmark_map": base.landmark_map,  # type: ignore[attr-defined]
        "bearing_std_rad": float(cam["noise_std_rad"]),
        "alphas": tuple(odo["alphas"]),
        "dt_s": float(base.config.dt_s),  # type: ignore[attr-defined]
    }
    env.close()
    return data, frames


def run_episode(spec: EvalSpec, cell: Cell) -> Episode:
    """Play one cell of the grid and compute its bound and metrics."""
    data, _ = _rollout(spec, cell)
    lmap = data.pop("landmark_map")
    del data["dt_s"]
    bound = bound_rmse_along(
        data["true_pose"],
        data["odometry"],
        data["visible"],
        lmap.positions_xy_m,
        data.pop("bearing_std_rad"),
        data.pop("alphas"),
        known_start=spec.known_start(cell.localizer),
        bounds_m=lmap.bounds_m,
    )
    values = episode_metrics(data["time_s"], data["true_pose"], data["estimates"], data["valid"],
                             data["contacts"], data["rewards"], bound, visible=data["visible"])  # fmt: skip
    return Episode(cell=cell, bound_rmse_m=bound, metrics=values, **data)


def _run_task(task: tuple[EvalSpec, Cell]) -> Episode:
    import torch

    torch.set_num_threads(1)  # one episode per core; no thread pools fighting each other
    return run_episode(*task)


# --------------------------------------------------------------------------- pure functions
def episode_metrics(
    time_s: ArrayLike,
    true_pose: ArrayLike,
    estimates: ArrayLike,
    valid: ArrayLike,
    contacts: ArrayLike,
    rewards: ArrayLike,
    bound_rmse_m: ArrayLike,
    *,
    visible: ArrayLike,
) -> dict[str, float]:
    """The metrics of one episode (see the module docstring), keyed by :data:`METRIC_KEYS`.

    Args:
        time_s: ``(T,)``; true_pose, estimates: ``(T, 3)`` (NaN rows where invalid);
        valid: ``(T,)``; contacts: ``(T,)`` contact events begun per step; rewards: ``(T - 1,)``;
        bound_rmse_m: ``(T,)``; visible: ``(T, L)`` landmarks in the camera's sight.
    """
    t = np.asarray(time_s, dtype=np.float64)
    truth = np.asarray(true_pose, dtype=np.float64)
    est = np.where(np.asarray(valid, dtype=bool)[:, None], np.asarray(estimates, dtype=np.float64), np.nan)
    t0 = metrics.first_fix(valid)
    pos = metrics.position_errors(est, truth)
    head = np.degrees(metrics.heading_errors(est, truth))
    first_fix_s = float(t[t0] - t[0]) if t0 is not None else math.nan
    t3 = metrics.distinct_seen(visible, 3)
    third_s = float(t[t3] - t[0]) if t3 is not None else math.nan
    return {
        "position_error_mean_m": metrics.mean_sd(pos, t0)[0],
        "position_error_rms_m": metrics.rms(pos, t0),
        "heading_error_mean_deg": metrics.mean_sd(head, t0)[0],
        "heading_error_rms_deg": metrics.rms(head, t0),
        "failure_rate": metrics.failure_rate(pos, t0, threshold=1.0),
        "availability": metrics.availability(valid),
        "fixed": float(t0 is not None),
        "first_fix_s": first_fix_s,
        "first_fix_distance_m": float(metrics.travelled(truth)[t0]) if t0 is not None else math.nan,
        "third_landmark_s": third_s,
        "fix_after_third_s": first_fix_s - third_s,
        "collisions": float(np.sum(contacts)),
        "episode_return": float(np.sum(rewards)),
        "bound_rmse_m": metrics.rms(bound_rmse_m, t0, np.isfinite(pos)),
        "error_bound_ratio": metrics.error_bound_ratio(pos, bound_rmse_m, t0),
    }


def bootstrap_ci(values: ArrayLike, n: int = 2000, *, rng: np.random.Generator, level: float = 0.95) -> tuple[float, float]:
    """Percentile-bootstrap confidence interval of the mean of the finite ``values``.

    Draws ``n`` resamples (with replacement, of the same size) and returns the
    ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles of their means. One value, or all
    equal, gives a zero-width interval; no finite value gives ``(nan, nan)``.
    """
    if n < 1 or not 0 < level < 1:
        raise ValueError(f"bootstrap_ci needs n >= 1 and 0 < level < 1, got n={n}, level={level}")
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    means = v[rng.integers(0, v.size, size=(n, v.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


# --------------------------------------------------------------------------- aggregation
@dataclass(frozen=True)
class Stat:
    """Mean over the episodes with a finite value, its bootstrap CI, and how many there were."""

    mean: float
    low: float
    high: float
    n: int


@dataclass(frozen=True)
class SummaryRow:
    """The aggregate of one (policy, localizer, crowd size)."""

    policy: str
    localizer: str
    crowd_size: int
    episodes: int
    stats: Mapping[str, Stat]


@dataclass(frozen=True)
class EvalResult:
    """Everything :func:`evaluate` measured."""

    spec: EvalSpec
    episodes: tuple[Episode, ...]
    summary: tuple[SummaryRow, ...]
    wall_s: float


def summarize(episodes: Sequence[Episode], resamples: int = 2000, seed: int = 0) -> tuple[SummaryRow, ...]:
    """Mean and bootstrap CI of every metric per (policy, localizer, crowd size), in grid order."""
    groups: dict[tuple[str, str, int], list[Episode]] = {}
    for ep in episodes:
        groups.setdefault(ep.cell.group, []).append(ep)
    rows = []
    for g, (key, eps) in enumerate(groups.items()):
        stats = {}
        for m, name in enumerate(METRIC_KEYS):
            v = np.array([ep.metrics[name] for ep in eps], dtype=np.float64)
            finite = v[np.isfinite(v)]
            lo, hi = bootstrap_ci(finite, resamples, rng=np.random.default_rng([seed, g, m]))
            stats[name] = Stat(float(finite.mean()) if finite.size else math.nan, lo, hi, int(finite.size))
        rows.append(SummaryRow(*key, episodes=len(eps), stats=stats))
    return tuple(rows)


def evaluate(
    spec: EvalSpec,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: bool = True,
    groups: Collection[tuple[str, str, int]] | None = None,
) -> EvalResult:
    """Run every cell of ``spec``'s grid (in parallel) and aggregate.

    Args:
        spec: the grid.
        workers: local processes (default: the core count; 1 runs in this process).
        ray_address: run the episodes on this Ray cluster instead.
        progress: show a progress bar.
        groups: run only these ``(policy, localizer, crowd size)`` groups of the grid, on all of
            its seeds (default: the whole grid).

    Raises:
        ConfigError: a group that is not in the grid, or no group.
    """
    from agents.sweep import run_tasks

    start = time.perf_counter()
    cells = spec.cells()
    if groups is not None:
        grid = {c.group for c in cells}
        wanted = set(groups)
        check(len(wanted) >= 1, "groups needs at least one (policy, localizer, crowd size)")
        stray = sorted(wanted - grid, key=str)
        check(not stray, f"groups {stray} are not in the grid of policies x localizers x crowd sizes")
        cells = [c for c in cells if c.group in wanted]
    episodes = run_tasks(_run_task, [(spec, c) for c in cells], workers=workers, ray_address=ray_address,
                         desc="eval", progress=progress)  # fmt: skip
    summary = summarize(episodes, spec.bootstrap_resamples, spec.bootstrap_seed)
    return EvalResult(spec, tuple(episodes), summary, time.perf_counter() - start)


# --------------------------------------------------------------------------- outputs
def yaw_to_quaternion(yaw_rad: ArrayLike) -> Array:
    """``(T, 4)`` quaternions ``(qx, qy, qz, qw)`` of rotations by ``yaw_rad`` about z."""
    half = 0.5 * np.asarray(yaw_rad, dtype=np.float64)
    zero = np.zeros_like(half)
    return np.stack([zero, zero, np.sin(half), np.cos(half)], axis=-1)


def quaternion_to_yaw(q: ArrayLike) -> Array:
    """``(T,)`` yaw in ``(-pi, pi]`` of ``(T, 4)`` quaternions ``(qx, qy, qz, qw)``."""
    qx, qy, qz, qw = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    return np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


def write_tum(path: Path, time_s: ArrayLike, poses: ArrayLike, valid: ArrayLike | None = None) -> Path:
    """Write planar poses in TUM format ``timestamp tx ty tz qx qy qz qw`` (z = 0), one row per
    step (only the ``valid`` ones when given), as ``evo`` reads them."""
    t = np.asarray(time_s, dtype=np.float64)
    p = np.asarray(poses, dtype=np.float64)
    keep = np.ones(t.shape[0], dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    q = yaw_to_quaternion(p[keep, 2])
    table = np.column_stack([t[keep], p[keep, 0], p[keep, 1], np.zeros(int(keep.sum())), q])
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        np.savetxt(f, table, fmt="%.6f %.6f %.6f %.1f %.9f %.9f %.9f %.9f")
    return path


def read_tum(path: Path) -> tuple[Array, Array]:
    """Read a planar TUM file: ``(N,)`` timestamps and ``(N, 3)`` poses ``(x, y, yaw)``."""
    table = np.loadtxt(path, comments="#", ndmin=2).reshape(-1, 8)
    return table[:, 0], np.column_stack([table[:, 1], table[:, 2], quaternion_to_yaw(table[:, 4:8])])


def format_stat(info: MetricInfo, stat: Stat, episodes: int) -> str:
    """``mean [low, high]`` in the metric's format, ``(n/episodes)`` when some episodes had no value."""
    if not math.isfinite(stat.mean):
        return "–"
    text = f"{info.fmt.format(stat.mean)} [{info.fmt.format(stat.low)}, {info.fmt.format(stat.high)}]"
    return text + (f" ({stat.n}/{episodes})" if stat.n < episodes else "")


def summary_markdown(result: EvalResult) -> str:
    """The summary as a markdown table: mean [95% CI] per metric and (policy, localizer, crowd size)."""
    shown = [m for m in METRICS if m.in_table]
    head = ["policy", "localizer", "crowd", *[m.label for m in shown]]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in result.summary:
        cells = [row.policy, row.localizer, str(row.crowd_size), *[format_stat(m, row.stats[m.key], row.episodes) for m in shown]]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    return path


def _summary_page(result: EvalResult, gif_cell: Cell | None) -> str:
    s = result.spec
    animated = ""
    if gif_cell is not None:
        animated = f"`episode.gif`: {gif_cell.policy}, {gif_cell.localizer}, crowd {gif_cell.crowd_size}, seed {gif_cell.seed}."
    return "\n".join(
        [
            "# crowdloc eval",
            "",
            f"{s.env_id}, {s.episode_steps} steps per episode, {s.seeds} held-out seeds "
            f"({EVAL_SEED_BASE} + {s.first_seed}..{s.first_seed + s.seeds - 1}) per cell, {len(result.episodes)} episodes in {result.wall_s:.0f} s.",
            "",
            summary_markdown(result),
            "",
            "Mean over seeds [95% percentile-bootstrap CI, "
            f"{s.bootstrap_resamples} resamples]; (k/N): only k of N episodes had a value (the others never had a fix). "
            "Errors, failure rate and error / bound are over the valid steps from the first fix on; failure: error >= 1 m; "
            "availability: share of all steps with a pose; first fix: time and distance travelled from the reset; "
            "collisions: contact events; error / bound: RMS position error over the RMS posterior Cramer-Rao bound "
            "along the true path (>= 1 for an unbiased estimator). Trajectories (TUM format, for evo): `tum/`. " + animated,
            "",
        ]
    )


def plot_summary(result: EvalResult, directory: Path) -> list[Path]:
    """One PNG per metric: mean and CI against crowd size, a line per policy, a panel per localizer."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory.mkdir(parents=True, exist_ok=True)
    s = result.spec
    by_key = {(r.policy, r.localizer, r.crowd_size): r for r in result.summary}
    x = np.arange(len(s.crowd_sizes), dtype=np.float64)
    dodge = 0.25 / max(len(s.policies), 1)
    paths = []
    for info in METRICS:
        fig, axes = plt.subplots(1, len(s.localizers), figsize=(4.6 * len(s.localizers) + 1.8, 3.6), squeeze=False, sharey=True)
        for ax, loc in zip(axes[0], s.localizers):
            for i, policy in enumerate(s.policies):
                st = [by_key[(policy, loc, c)].stats[info.key] for c in s.crowd_sizes]
                mean = np.array([v.mean for v in st])
                err = np.abs(np.array([[v.mean - v.low for v in st], [v.high - v.mean for v in st]]))
                xs = x + (i - (len(s.policies) - 1) / 2) * dodge
                ax.errorbar(xs, mean, yerr=err, marker="o", ms=4, capsize=3, label=policy)
            ax.set_xticks(x, [str(c) for c in s.crowd_sizes])
            ax.set_xlim(-0.5, len(x) - 0.5)
            ax.set_xlabel("crowd size")
            ax.set_title(loc, fontsize=9)
            ax.grid(alpha=0.3)
        axes[0, 0].set_ylabel(info.label)
        axes[0, -1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
        fig.suptitle(f"{info.label}: mean and 95% bootstrap CI over {s.seeds} seeds", fontsize=10)
        fig.tight_layout()
        path = directory / f"{info.key}.png"
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def render_gif(spec: EvalSpec, cell: Cell, path: Path, max_frames: int = 150, every: int = 3) -> Path:
    """Replay ``cell`` with ``rgb_array`` rendering (estimate and the localizer's
    hypotheses drawn by the wrapper) and save an animated GIF of every ``every``-th step,
    thinned further to at most ``max_frames`` frames, playing in real time."""
    from PIL import Image

    every = max(every, math.ceil((spec.episode_steps + 1) / max_frames))
    data, frames = _rollout(spec, cell, frame_every=every)
    dt_s = data["dt_s"]
    # one palette for the whole clip, from a few frames spread over it (fast, no flicker)
    sample = np.concatenate([frames[i] for i in np.linspace(0, len(frames) - 1, min(8, len(frames))).astype(int)])
    palette = Image.fromarray(sample).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    images = [Image.fromarray(f).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=max(20, round(1000 * every * dt_s)), loop=0)
    return path


def parse_gif_cell(text: str, spec: EvalSpec) -> Cell:
    """``"policy,localizer,crowd_size"`` -> that cell on the first evaluation seed (must be in the grid)."""
    parts = text.rsplit(",", 2)
    if len(parts) != 3 or not parts[2].strip().lstrip("-").isdigit():
        raise ConfigError(f"--gif-cell must be POLICY,LOCALIZER,CROWD_SIZE, got {text!r}")
    cell = Cell(parts[0].strip(), parts[1].strip(), int(parts[2]), spec.eval_seeds[0])
    check(cell in spec.cells(), f"--gif-cell {text!r} is not in the evaluated grid")
    return cell


def write_outputs(result: EvalResult, out_dir: Path, *, gif_cell: Cell | None = None, gif: bool = True) -> dict[str, Path]:
    """Write the CSV tables, ``summary.md``, the plots, TUM trajectories and a GIF under ``out_dir``.

    Args:
        result: from :func:`evaluate`.
        out_dir: created if missing.
        gif_cell: the episode to animate (default: the first cell).
        gif: whether to render the GIF at all.

    Returns:
        Name -> path of what was written (``episodes``, ``summary_csv``, ``summary_md``,
        ``plots``, ``tum``, and ``gif``: ``episode.gif``).
    """
    if gif:
        gif_cell = gif_cell or result.episodes[0].cell
    out = write_tables(result, out_dir)
    out["summary_md"] = out_dir / "summary.md"
    out["summary_md"].write_text(_summary_page(result, gif_cell if gif else None))
    out["plots"] = out_dir / "plots"
    plot_summary(result, out["plots"])
    out["tum"] = out_dir / "tum"
    out["tum"].mkdir(exist_ok=True)
    for e in result.episodes:
        write_tum(out["tum"] / f"{e.cell.stem}_estimate.tum", e.time_s, e.estimates, e.valid)
        write_tum(out["tum"] / f"{e.cell.stem}_groundtruth.tum", e.time_s, e.true_pose)
    if gif and gif_cell is not None:
        out["gif"] = render_gif(result.spec, gif_cell, out_dir / "episode.gif")
    return out


def write_tables(result: EvalResult, out_dir: Path) -> dict[str, Path]:
    """Write ``episodes.csv`` (one row per episode) and ``summary.csv`` (mean, CI and count per
    metric and group) under ``out_dir`` (created if missing); any subset of a grid will do."""
    out_dir.mkdir(parents=True, exist_ok=True)
    out: dict[str, Path] = {}
    ep_rows = [[e.cell.policy, e.cell.localizer, e.cell.crowd_size, e.cell.seed, len(e.time_s) - 1,
                *[e.metrics[k] for k in METRIC_KEYS]] for e in result.episodes]  # fmt: skip
    ep_cols = ["policy", "localizer", "crowd_size", "seed", "steps", *METRIC_KEYS]
    out["episodes"] = _write_csv(out_dir / "episodes.csv", ep_cols, ep_rows)
    stat_cols = [f"{k}{suffix}" for k in METRIC_KEYS for suffix in ("", "_ci_low", "_ci_high", "_n")]
    sum_rows = [[r.policy, r.localizer, r.crowd_size, r.episodes,
                 *[x for k in METRIC_KEYS for x in (r.stats[k].mean, r.stats[k].low, r.stats[k].high, r.stats[k].n)]]
                for r in result.summary]  # fmt: skip
    sum_cols = ["policy", "localizer", "crowd_size", "episodes", *stat_cols]
    out["summary_csv"] = _write_csv(out_dir / "summary.csv", sum_cols, sum_rows)
    return out


def run_cli(args: Any) -> EvalResult:
    """``crowdloc eval``: build the spec from parsed options, run, write, print the summary.

    Raises:
        ConfigError: for a bad option value, before any episode runs.
    """
    from agents.train import load_train_config, parse_overrides
    from agents.util import nest
    from localizers.schema import merge_nested

    given = {"policies": args.policies, "localizers": args.localizers, "crowd_sizes": args.crowd_sizes}
    conditions: dict[str, Any] = {"env_id": args.env_id}
    if args.conditions:
        trained = load_train_config(args.conditions)
        check(args.env_id in (None, trained.env_id),
              f"--env-id {args.env_id} differs from the env of --conditions {args.conditions} ({trained.env_id})")  # fmt: skip
        conditions = {"env_id": trained.env_id, "env_kwargs": dict(trained.env_kwargs), "reward": trained.reward}
    conditions["env_kwargs"] = merge_nested(conditions.get("env_kwargs", {}), nest(parse_overrides(args.env_set)))
    spec = EvalSpec(**{k: v for k, v in {**given, **conditions}.items() if v is not None}, seeds=args.seeds,
                    first_seed=args.first_seed, episode_steps=args.episode_steps)  # fmt: skip
    gif_cell = parse_gif_cell(args.gif_cell, spec) if args.gif_cell else None
    result = evaluate(spec, workers=args.workers, ray_address=args.ray_address, progress=not args.no_progress)
    written = write_outputs(result, args.out, gif_cell=gif_cell, gif=not args.no_gif)
    print(summary_markdown(result))
    names = ", ".join(p.name for p in written.values())
    print(f"\n{len(result.episodes)} episodes in {result.wall_s:.0f} s; wrote {args.out}/ ({names})")
    return result
