"""One evaluated episode: the rollout, the core pose metrics and the plug-ins' metrics.

The env is built like the training env (:meth:`EvalSpec.make_env`: localizer wrapper,
active-localization reward on the task's route, the episode length; a PPO policy's cells observe
through the task's ``TaskObservation``, a fixed policy reads the raw sensors) and reset with the
cell's evaluation seed; a fixed policy gets its own seed derived from it, a PPO policy acts
deterministically. An episode ends at ``episode_steps`` or earlier, when a world with a goal ends
it there (:mod:`agents.evaluate.goal`); every metric is over the steps it had.

The core metrics of every episode (``t0`` = the first step with a valid estimate, the first fix):

- ``position_error_mean_m`` / ``_rms_m``, ``heading_error_mean_deg`` / ``_rms_deg``: over the
  valid steps from ``t0`` on;
- ``failure_rate``: share of those steps with a position error >= 1 m;
- ``nees_median``: the median of the normalized estimation error squared ``e^T P^-1 e`` of the
  pose error ``e`` (heading wrapped) against the reported covariance ``P`` of (x, y, theta), over
  the valid steps with a usable ``P`` (finite, no negative variance); 2.37 for a consistent
  localizer, more for an overconfident one. A singular ``P`` (a particle set collapsed onto one
  pose) claims certainty: its NEES is ``inf`` (outside every region), so the median is ``inf``
  when more than half the steps are singular. No mean: a single such step makes it ``inf``;
- ``singular_share``: share of those steps whose ``P`` is singular (NEES ``inf``);
- ``inside_95``: share of those steps whose error lies inside the reported 95 % region
  (NEES <= 7.815, the chi-square 0.95 quantile for 3 dof; about 0.95 for a consistent localizer);
- ``covariance_missing``: share of the valid steps without a usable covariance (excluded from
  the three above). A localizer registered with ``covariance=False`` (``LocalizerSpec``) reports
  none: these are NaN and the tables say "no covariance";
- ``availability``: share of all steps with a valid estimate;
- ``fixed``: 1 if the localizer ever had a pose, else 0;
- ``first_fix_s`` / ``first_fix_distance_m``: time since reset and distance travelled until
  ``t0``. **Never fixed**: these and the error metrics are NaN;
- ``collisions``: contact events of our robot that began during the episode;
- ``episode_return``: sum of the active-localization rewards.

The metric plug-ins of the localizer's measurement kind (:mod:`agents.evaluate.plugins`; for
bearings :mod:`agents.evaluate.bearings`) add theirs; with ``EvalSpec.kidnap`` the robot is
carried away mid-episode and the recovery is scored (:mod:`agents.evaluate.kidnap`); a world
with a goal adds ``goal_missed`` and ``time_to_goal_s`` (:mod:`agents.evaluate.goal`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import agents.evaluate.metrics as metrics
from agents.evaluate.goal import goal_metrics
from agents.evaluate.kidnap import KIDNAP_SALT, kidnap_metrics
from agents.evaluate.plugins import EpisodeContext, MetricPlugin, Track, localizer_kind, metric_plugins
from agents.evaluate.spec import PPO_PREFIX, Cell, EvalSpec, load_ppo, odometry_key_of, policy_seed
from agents.experiments.scenarios import kidnap as carry_away
from localizers.registry import spec as localizer_spec


@dataclass(frozen=True)
class Episode(Track):
    """One evaluated episode: the core arrays (:class:`Track`), its cell, metrics and plug-in arrays.

    Attributes:
        cell: which grid cell.
        metrics: the per-episode metrics: the core ones and those of its kind's plug-ins.
        series: the plug-ins' per-step arrays by name (bearings: ``visible`` ``(T, L)``,
            ``bound_rmse_m`` ``(T,)``); each also reads as an attribute (``episode.visible``).
    """

    cell: Cell = field(kw_only=True)
    metrics: Mapping[str, float] = field(kw_only=True)
    series: Mapping[str, NDArray[Any]] = field(default_factory=dict, kw_only=True)
    #: mean wall time (ms) of the localizer's predict and update per step on the machine that played
    #: it: a cost, not a metric (it differs between runs and machines; no table of eval shows it)
    update_ms: float = field(default=float("nan"), kw_only=True)

    def __getattr__(self, name: str) -> NDArray[Any]:  # only called for names that are not attributes
        series = self.__dict__.get("series", {})  # not self.series: unpickling asks before the fields exist
        if name.startswith("__") or name not in series:
            raise AttributeError(f"{type(self).__name__} has no attribute or series {name!r} (series: {sorted(series)})")
        return series[name]  # type: ignore[no-any-return]


@dataclass(frozen=True)
class Rollout:
    """What one played episode gave, before any metric."""

    track: Track
    collected: Mapping[str, NDArray[Any]]  # the plug-ins' per-step values, stacked
    context: EpisodeContext
    frames: list[NDArray[np.uint8]]
    jump_index: int | None = None  # with a kidnap: the first row recorded after the jump (None: no jump)
    update_ms: float = float("nan")  # mean wall time of the localizer's predict and update per step
    goal_reached: bool | None = None  # the world ended the episode at its goal (None: the world has no goal)


class _PPOPolicy:
    """A loaded stable-baselines3 model acting deterministically."""

    def __init__(self, path: str) -> None:
        self.model = load_ppo(path)

    def predict(self, observation: Any) -> NDArray[np.float32]:
        action, _ = self.model.predict(observation, deterministic=True)
        return np.asarray(action, dtype=np.float32)


def _make_policy(spec: EvalSpec, cell: Cell, env: gym.Env[Any, Any]) -> Callable[[Any], NDArray[np.float32]]:
    if cell.policy.startswith(PPO_PREFIX):
        return _PPOPolicy(cell.policy[len(PPO_PREFIX) :]).predict
    from agents.policies import make_policy, task_route_kwargs

    fixed = make_policy(cell.policy, env, seed=policy_seed(cell.seed), **task_route_kwargs(cell.policy, spec.route.points_m))
    return lambda obs: fixed.predict(obs, deterministic=True)[0]


_NO_COVARIANCE = np.full((3, 3), np.nan)


class _Recorder:
    """The rows of one rollout: the core ones and what each plug-in collects."""

    def __init__(self, plugins: tuple[MetricPlugin, ...], context: EpisodeContext, covariance: bool = True) -> None:
        self.plugins, self.context, self.covariance = plugins, context, covariance
        self.rows: dict[str, list[Any]] = {
            k: [] for k in ("time_s", "true_pose", "estimates", "valid", "contacts", "covariances")
        }
        self.collected: dict[str, list[Any]] = {}
        self.odometry: list[NDArray[np.float64]] = []
        self.rewards: list[float] = []

    def keep(self, info: Mapping[str, Any]) -> None:
        est = info["estimate"]
        self.rows["time_s"].append(float(info["time_s"]))
        self.rows["true_pose"].append(np.asarray(info["true_pose"], dtype=np.float64).copy())
        self.rows["estimates"].append((est.x_m, est.y_m, est.theta_rad) if est.valid else (np.nan, np.nan, np.nan))
        self.rows["valid"].append(bool(est.valid))
        kept = self.covariance and est.valid and np.shape(est.covariance) == (3, 3)
        self.rows["covariances"].append(np.array(est.covariance, dtype=np.float64) if kept else _NO_COVARIANCE)
        self.rows["contacts"].append(len(info["contacts"]))
        for plugin in self.plugins:
            for name, value in plugin.collect(info, self.context).items():
                self.collected.setdefault(name, []).append(np.asarray(value))

    def track(self) -> Track:
        r = self.rows
        return Track(
            time_s=np.array(r["time_s"]),
            true_pose=np.stack(r["true_pose"]),
            estimates=np.array(r["estimates"], dtype=np.float64),
            valid=np.array(r["valid"], dtype=bool),
            contacts=np.array(r["contacts"], dtype=np.int64),
            odometry=np.array(self.odometry, dtype=np.float64).reshape(-1, 3),
            rewards=np.array(self.rewards, dtype=np.float64),
            covariances=np.array(r["covariances"], dtype=np.float64).reshape(-1, 3, 3),
        )


def rollout(spec: EvalSpec, cell: Cell, frame_every: int = 0) -> Rollout:
    """Play one episode of ``cell``; with ``frame_every > 0`` also render every that many steps."""
    env = spec.make_env(
        cell.policy, cell.localizer, cell.crowd_size, "rgb_array" if frame_every else None, spec.layout_of(cell.seed)
    )
    act = _make_policy(spec, cell, env)
    obs, info = env.reset(seed=cell.seed)
    base = env.unwrapped
    sensors = base.sensor_metadata  # type: ignore[attr-defined]
    context = EpisodeContext(sensors, base.landmark_map, float(base.config.dt_s), spec.known_start(cell.localizer))  # type: ignore[attr-defined]
    odometry_key = odometry_key_of(sensors)
    recorder = _Recorder(
        metric_plugins(localizer_kind(cell.localizer, sensors)), context, localizer_spec(cell.localizer).covariance
    )
    frames: list[NDArray[np.uint8]] = []

    def keep(step: int, info: Mapping[str, Any]) -> None:
        recorder.keep(info)
        if frame_every and step % frame_every == 0:
            frames.append(env.render())  # type: ignore[arg-type]

    keep(0, info)
    step, done, terminated = 0, False, False
    kidnap, jump_index = spec.kidnap, None
    kidnap_rng = np.random.default_rng([cell.seed, KIDNAP_SALT])
    while not done:
        obs, reward, terminated, truncated, info = env.step(act(obs))
        step += 1
        recorder.odometry.append(np.asarray(obs[odometry_key], dtype=np.float64))
        recorder.rewards.append(float(reward))
        keep(step, info)
        done = bool(terminated or truncated)
        if kidnap is not None and jump_index is None and not done and float(info["time_s"]) >= kidnap.at_s - 1e-9:
            carry_away(base.world, kidnap_rng, kidnap.min_distance_m,  # type: ignore[attr-defined]
                       max_distance_m=kidnap.max_distance_m, keep_heading=kidnap.keep_heading)  # fmt: skip
            jump_index = step + 1
    seconds, updates = env.get_wrapper_attr("update_seconds"), env.get_wrapper_attr("updates")
    reached = bool(terminated) if base.config.goal is not None else None  # type: ignore[attr-defined]
    env.close()
    collected = {name: np.stack(values) for name, values in recorder.collected.items()}
    return Rollout(recorder.track(), collected, context, frames, jump_index, 1000.0 * seconds / max(updates, 1), reached)


def episode_metrics(track: Track) -> dict[str, float]:
    """The core metrics of one episode (see the module docstring), keyed by ``CORE_METRICS``."""
    t0, pos, head = track.fix_index, track.position_errors, track.heading_errors_deg
    fit = metrics.consistency(track.nees, dof=3, mask=track.valid)
    return {
        "position_error_mean_m": metrics.mean_sd(pos, t0)[0],
        "position_error_rms_m": metrics.rms(pos, t0),
        "heading_error_mean_deg": metrics.mean_sd(head, t0)[0],
        "heading_error_rms_deg": metrics.rms(head, t0),
        "singular_share": fit.singular_share,
        "nees_median": fit.nees_median,
        "inside_95": fit.inside_95,
        "covariance_missing": fit.excluded / (fit.steps + fit.excluded) if fit.steps + fit.excluded else float("nan"),
        "failure_rate": metrics.failure_rate(pos, t0, threshold=1.0),
        "availability": metrics.availability(track.valid),
        "fixed": float(t0 is not None),
        "first_fix_s": track.first_fix_s,
        "first_fix_distance_m": float(metrics.travelled(track.true_pose)[t0]) if t0 is not None else float("nan"),
        "collisions": float(np.sum(track.contacts)),
        "episode_return": float(np.sum(track.rewards)),
    }


def run_episode(spec: EvalSpec, cell: Cell) -> Episode:
    """Play one cell of the grid and compute its metrics: the core ones and its kind's plug-ins'."""
    played = rollout(spec, cell)
    track = played.track
    values = episode_metrics(track)
    if played.goal_reached is not None:
        values.update(goal_metrics(track, played.goal_reached))
    if spec.kidnap is not None:
        values.update(kidnap_metrics(track, spec.kidnap, played.jump_index))
    series: dict[str, NDArray[Any]] = dict(played.collected)
    for plugin in metric_plugins(localizer_kind(cell.localizer, played.context.sensors)):
        got, arrays = plugin.compute(track, played.collected, played.context)
        if set(got) != set(plugin.keys):
            raise ValueError(f"metric plug-in {plugin.name!r} returned {sorted(got)}, not its metrics {sorted(plugin.keys)}")
        clash = set(arrays) & set(series)
        if clash:
            raise ValueError(f"metric plug-in {plugin.name!r}: per-step arrays {sorted(clash)} are another's too")
        values.update(got)
        series.update(arrays)
    core = {f.name: getattr(track, f.name) for f in dataclasses.fields(Track)}
    return Episode(**core, cell=cell, metrics=values, series=series, update_ms=played.update_ms)


def run_task(task: tuple[EvalSpec, Cell]) -> Episode:
    """:func:`run_episode` in a worker process (one torch thread)."""
    import torch

    torch.set_num_threads(1)  # one episode per core; no thread pools fighting each other
    return run_episode(*task)
