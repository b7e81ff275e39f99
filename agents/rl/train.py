"""``crowdloc train``: PPO (stable-baselines3, MultiInputPolicy) on a crowdloc env with a localizer.

A run is described by a YAML file under ``configs/experiments/`` (:class:`~agents.rl.config.TrainConfig`,
read and changed from the command line by :mod:`agents.rl.config`). A run writes ``<out>/<name>/seed_<seed>/``:

- ``run.json``: the resolved config, the seed, versions and the command;
- ``checkpoints/step_<N>.zip`` + ``.state.pkl``: model, optimizer, every random state and where each env is;
- ``model.zip``: the final policy; ``tb/``: TensorBoard logs.

Exact resume, by replay (the worlds cannot be pickled, but each is deterministic given its reset
seed and actions): each episode's env seed is a pure function of (run seed, env index, episode
index), and a checkpoint (at a rollout boundary) stores where every env is: the index of its
current episode, the actions it received since that episode's reset and the observation they led
to (:class:`EnvPosition`, kept by :class:`EpisodeSeeds`), besides the torch, numpy and python
random states. A resume rebuilds each env at its episode, replays its actions (through its
``Monitor``, so that the partial episode's return is rebuilt), checks that it arrives at that
observation, and lets PPO go on without resetting the envs. Episodes may end anywhere inside
rollouts (the corridor and the campus end at the goal): training N steps in one go or in pieces
through checkpoints gives identical weights and episode logs (tests prove it, with in-process and
subprocess envs).
"""

from __future__ import annotations

import copy
import dataclasses
import pickle
import random
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the ids)
from agents.common.output_folder import OutputFolder, open_output_folder
from agents.common.util import write_run_record
from agents.rl.config import EVAL_SEED_BASE, TrainConfig

# the config's names lived here before agents.rl.config; they import from here too for one release (explicit re-exports)
from agents.rl.config import EXPERIMENT_DIR as EXPERIMENT_DIR
from agents.rl.config import PPOConfig as PPOConfig
from agents.rl.config import load_train_config as load_train_config
from agents.rl.config import parse_overrides as parse_overrides
from agents.rl.layout_episodes import LayoutEpisodes
from agents.rl.observation import ObservationConfig, RouteConfig, TaskObservation
from agents.rl.residual import MODEL_ACTION_ATTR, ActionConfig, ResidualAction
from agents.rl.rewards import ActiveLocalizationReward, RewardWeights
from core.schema import ConfigError, check, merge_nested


@dataclass(frozen=True)
class EnvPosition:
    """Where a training env is in its run: the index of its current episode, the actions it received
    since that episode's reset (one row each) and the observation they led to (:class:`EpisodeSeeds`)."""

    episode: int
    actions: np.ndarray
    obs: Any


class EpisodeSeeds(gym.Wrapper):
    """Seed every episode from ``(run_seed, env_index, episode_index)`` and keep the actions of the
    current one: an env's place in its run is then :meth:`position`, and :meth:`replay` rebuilds it.

    A seed passed to ``reset`` is ignored on purpose: stable-baselines3 re-seeds its vector
    env whenever a model is built or loaded, which would make a resumed run differ.
    Training seeds stay below :data:`EVAL_SEED_BASE`, so held-out evaluation seeds (at or
    above it) are never trained on. The actions are kept as they reach ``step`` (after
    stable-baselines3's clipping): at most one episode's, ``ppo.n_steps`` x the action size.
    """

    def __init__(self, env: gym.Env[Any, Any], run_seed: int, env_index: int) -> None:
        super().__init__(env)
        self.run_seed = run_seed
        self.env_index = env_index
        self.episode = 0  # the index of the next episode
        self.actions: list[np.ndarray] = []  # since the last reset
        self.last_obs: Any = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        state = np.random.SeedSequence([self.run_seed, self.env_index, self.episode]).generate_state(1)[0]
        episode_seed = int(state) % EVAL_SEED_BASE
        self.episode += 1
        self.actions = []
        self.last_obs, info = self.env.reset(seed=episode_seed, options=options)
        return self.last_obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        self.actions.append(np.array(action, copy=True))  # a vec env may reuse its action buffer
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.last_obs = obs
        return obs, reward, terminated, truncated, info

    def position(self) -> EnvPosition:
        """Where this env is now (after its first reset)."""
        return EnvPosition(self.episode - 1, np.array(self.actions), copy.deepcopy(self.last_obs))

    def replay(self, position: EnvPosition) -> str:
        """Reset into ``position``'s episode and step its actions: back at ``position``.

        Returns ``""`` when the env arrived there, else what went otherwise (the env does not
        play as when the position was taken: an episode of a run never ends at its position).
        """
        self.episode = position.episode
        self.reset()
        for played, action in enumerate(position.actions, start=1):
            _, _, terminated, truncated, _ = self.step(action)
            if terminated or truncated:
                return f"its episode ended after {played} of the {len(position.actions)} actions"
        if not _same_obs(self.last_obs, position.obs):
            return f"its observation after the {len(position.actions)} actions differs"
        return ""


def _same_obs(a: Any, b: Any) -> bool:
    """Whether two observations (arrays, or dicts / tuples of them) are equal, entry by entry."""
    if isinstance(a, Mapping):
        return isinstance(b, Mapping) and set(a) == set(b) and all(_same_obs(a[k], b[k]) for k in a)
    if isinstance(a, tuple):
        return isinstance(b, tuple) and len(a) == len(b) and all(map(_same_obs, a, b))
    return np.array_equal(a, b)


def make_task_env(
    config: TrainConfig, crowd_size: int | None, layout_split: str | None = None, **make_kwargs: Any
) -> gym.Env[Any, Any]:
    """The task a training config describes, at one crowd size: its world, localizer and
    conditions (``env_kwargs``, then ``make_kwargs`` on top), with the active-localization reward
    and the observation the config gives its policy.

    ``make_kwargs`` may override the localizer's parameters (``localizer_params``, merged over the
    config's key by key) but not the localizer itself (a ``ConfigError``: the task is its localizer's).
    ``layout_split`` (``"train"``, ``"validation"`` or ``"test"``, for a config with ``layouts``)
    plays every episode on a layout of that split (:class:`~agents.rl.layout_episodes.LayoutEpisodes`).
    """
    if layout_split is not None:
        if config.layouts is None:
            raise ConfigError(f"layout_split={layout_split!r}: training config {config.name!r} has no layouts")
        if "layout" in make_kwargs:
            raise ConfigError(f"give layout_split={layout_split!r} or layout={make_kwargs['layout']!r}, not both")
        seeds = config.layouts.seeds(layout_split)
        max_episode_steps = make_kwargs.pop("max_episode_steps", None)
        env: gym.Env[Any, Any] = LayoutEpisodes(
            lambda layout: make_task_env(config, crowd_size, layout=layout, **make_kwargs), seeds, config.layout_cache
        )
        return env if max_episode_steps is None else gym.wrappers.TimeLimit(env, max_episode_steps)
    kwargs = {**dict(config.env_kwargs), **make_kwargs}
    if "localizer" in kwargs:
        raise ConfigError(
            f"{config.env_id} with localizer {config.localizer!r} is the task of this training config: "
            f"localizer={kwargs['localizer']!r} cannot replace it (give it to a world id, e.g. "
            f"gym.make({config.env_id!r}, localizer={kwargs['localizer']!r}))"
        )
    extra = kwargs.pop("localizer_params", None)
    extra = {} if extra is None else extra
    if not isinstance(extra, Mapping):
        raise ConfigError(f"localizer_params must be a mapping, got {type(extra).__name__} {extra!r}")
    max_episode_steps = kwargs.pop("max_episode_steps", None)
    world = make_world(
        config.env_id,
        crowd_size=crowd_size,
        localizer=config.localizer,
        localizer_params=merge_nested(config.localizer_params, extra) or None,
        **kwargs,
    )
    env = task_wrappers(world, config.reward, config.route, config.observation, config.action)
    if max_episode_steps is not None:
        env = gym.wrappers.TimeLimit(env, max_episode_steps)
    return env


def task_wrappers(
    env: gym.Env[Any, Any],
    reward: RewardWeights,
    route: RouteConfig,
    observation: ObservationConfig | None,
    action: ActionConfig | None = None,
) -> gym.Env[Any, Any]:
    """``env`` (a world behind its localizer) as a task's policy meets it: the active-localization
    reward on the task's route; when ``action`` changes anything, the policy's action a correction
    of a fixed policy's command (:class:`~agents.rl.residual.ResidualAction`, on the raw
    observation the fixed policy reads); and, when ``observation`` changes anything, the task's
    observation (:class:`TaskObservation`). Training (:func:`make_task_env`) and ``crowdloc eval``
    (a trained policy's cells with the observation and action; a fixed policy's with neither: the
    raw sensors it reads, its own commands) build their envs with it.
    """
    env = ActiveLocalizationReward(env, reward, route)
    if action is not None and action.changes_anything:
        env = ResidualAction(env, action, route)
    if observation is not None and observation.changes_anything:
        env = TaskObservation(env, observation, route)
    return env


def make_world(env_id: str, **kwargs: Any) -> gym.Env[Any, Any]:
    """The env of registered id ``env_id`` from its entry point, without ``gym.make``'s wrappers and spec.

    A task is one env: ``gym.make(task_id)`` adds the checker, the order enforcing and the time
    limit once around the whole task and names it (``env.spec.id``, which stable-baselines3's
    ``Monitor`` and rl-zoo3 record, is the task's). A world made by ``gym.make`` inside it would
    carry the world's spec, cached by its wrappers, to the outside, and a second time limit.

    Raises:
        gymnasium.error.Error: for an id that is not registered.
    """
    from gymnasium.envs.registration import load_env_creator

    spec = gym.spec(env_id)
    creator = spec.entry_point if callable(spec.entry_point) else load_env_creator(str(spec.entry_point))
    env = creator(**{**spec.kwargs, **kwargs})
    if not isinstance(env, gym.Env):
        raise ConfigError(f"{env_id}'s entry point made a {type(env).__name__}, not an env")
    return env


def make_training_env(config: TrainConfig, env_index: int) -> gym.Env[Any, Any]:
    """One training env: the task (:func:`make_task_env`), the episode length, the episode log
    (stable-baselines3's ``Monitor``: ep_rew_mean), episode seeding and replay (:class:`EpisodeSeeds`,
    outside the ``Monitor`` so that a replay rebuilds the return of the episode it replays)."""
    from stable_baselines3.common.monitor import Monitor

    crowd = config.crowd_sizes[env_index % len(config.crowd_sizes)]
    split = None if config.layouts is None else "train"
    env = make_task_env(config, crowd, split, max_episode_steps=config.ppo.n_steps)
    return EpisodeSeeds(Monitor(env), config.seed, env_index)


def _env_factory(config: TrainConfig, env_index: int) -> Callable[[], gym.Env[Any, Any]]:
    def make() -> gym.Env[Any, Any]:
        return make_training_env(config, env_index)

    return make


def make_vec_env(config: TrainConfig) -> Any:
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    factories = [_env_factory(config, i) for i in range(config.n_envs)]
    if config.vec_env == "subproc" and config.n_envs > 1:
        return SubprocVecEnv(factories, start_method="spawn")
    return DummyVecEnv(factories)


def _random_states() -> dict[str, Any]:
    import torch  # here, not at the top: evaluation and the reproductions import this module without training

    return {"torch": torch.get_rng_state(), "numpy": np.random.get_state(), "python": random.getstate()}


def _set_random_states(states: Mapping[str, Any]) -> None:
    import torch

    torch.set_rng_state(states["torch"])
    np.random.set_state(states["numpy"])
    random.setstate(states["python"])


def run_dir(config: TrainConfig, out: Path) -> Path:
    return out / config.name / f"seed_{config.seed}"


def check_train_config(config: TrainConfig) -> None:
    """Build the run's env once per crowd size (and close it), so that a bad localizer,
    crowd size, prior or env override fails here, naming it, before anything is written.

    Raises:
        ConfigError: naming the config and what is wrong.
    """
    for size in sorted(set(config.crowd_sizes)):
        try:
            env = make_task_env(config, size)
        except gym.error.Error as exc:
            raise ConfigError(f"training config {config.name!r}: env_id {config.env_id!r}: {exc}") from None
        except ConfigError as exc:
            raise ConfigError(f"training config {config.name!r} (crowd size {size}): {exc}") from None
        env.close()


#: what a run writes in its folder (glob patterns; what its manifest may record, :mod:`agents.common.output_folder`)
TRAIN_OUTPUTS = ("run.json", "model.zip", "checkpoints/step_*", "tb/**/*")


def open_run_dir(config: TrainConfig, out: Path, *, resume: bool, overwrite: bool) -> OutputFolder:
    """The run's folder, ready before any work: a new run never starts where one already is,
    unless told to resume it or overwrite it; ``overwrite`` deletes what the earlier run there
    recorded writing (its manifest) and nothing else.

    Raises:
        ConfigError: naming the folder and the two ways on, or anything
            :func:`~agents.common.output_folder.open_output_folder` refuses.
    """
    directory = run_dir(config, out)
    held = (directory / "model.zip").exists() or any((directory / "checkpoints").glob("step_*"))
    if held and not resume and not overwrite:
        raise ConfigError(
            f"{directory} already holds a run (model.zip or checkpoints): give --resume latest to continue it "
            "or --overwrite to start it again"
        )
    return open_output_folder(directory, TRAIN_OUTPUTS, command="crowdloc train", overwrite=overwrite, resume=resume)


def train(
    config: TrainConfig,
    out: Path,
    resume: Path | None = None,
    progress_bar: bool = True,
    verbose: int = 0,
    extra_callbacks: Sequence[Any] = (),
    overwrite: bool = False,
) -> Path:
    """Train (or resume) and return the path of the final ``model.zip``.

    ``extra_callbacks`` are stable-baselines3 callbacks run beside the checkpointing (timing, logging).

    Raises:
        ConfigError: before anything is written, for a config whose env cannot be built, or a
            run folder that already holds a run (unless ``resume`` or ``overwrite``).
    """
    check_train_config(config)
    folder = open_run_dir(config, out, resume=resume is not None, overwrite=overwrite)
    state = None if resume is None else _resume_state(config, resume)
    # A 64x64 MLP is fastest on one thread; the parallelism is in the env processes. More
    # threads only fight the env workers for the cores (measured: 1.8 ms per layer on 2 busy cores).
    import torch

    torch.set_num_threads(1)
    directory = folder.path
    with folder:
        (directory / "checkpoints").mkdir(parents=True, exist_ok=True)
        _write_run_json(config, directory)
        folder.record_written()
        if resume is not None and state is not None:
            model, venv = _resumed_model(config, resume, state)
        else:
            model, venv = _new_model(config, directory, verbose)
        # PPO runs whole rollouts: round up to them, so the progress bar's total is what runs
        # (the same iterations either way: stable-baselines3 stops at the first rollout past the total)
        remaining = -(-(config.total_timesteps - model.num_timesteps) // config.rollout_steps) * config.rollout_steps
        if remaining > 0:
            model.learn(
                total_timesteps=remaining,
                callback=[_checkpoints(model, config, folder), *extra_callbacks],
                reset_num_timesteps=resume is None,
                progress_bar=progress_bar,
                tb_log_name="ppo",
            )
        final = directory / "model.zip"
        model.save(final)
        save_checkpoint(model, directory / "checkpoints" / f"step_{model.num_timesteps}")
        venv.close()
    return final


def _resume_state(config: TrainConfig, resume: Path) -> dict[str, Any]:
    """The state file of checkpoint ``resume`` (:func:`save_checkpoint`), checked against ``config``.

    Raises:
        ConfigError: for a checkpoint without its files, of another number of envs, not at a rollout
            boundary, or that predates exact resume.
    """
    state = _load_state(resume)
    done_steps = int(state["num_timesteps"])
    if done_steps % config.rollout_steps:
        raise ConfigError(f"checkpoint {resume} is not at a rollout boundary ({done_steps} steps)")
    if "envs" not in state:
        raise ConfigError(
            f"checkpoint {resume} predates exact resume ({resume.with_suffix('.state.pkl').name} has no env positions): "
            "train the run again (--overwrite)"
        )
    if len(state["envs"]) != config.n_envs:
        raise ConfigError(f"checkpoint {resume} has {len(state['envs'])} envs, the config n_envs={config.n_envs}")
    return state


def _resumed_model(config: TrainConfig, resume: Path, state: Mapping[str, Any]) -> tuple[Any, Any]:
    """The PPO model and its vec env from checkpoint ``resume``, each env replayed to where the
    run had it, random states included: ``model.learn`` goes on as if never stopped.

    The model's zip carries what stable-baselines3 holds across a rollout boundary (the last
    observation and episode starts, the episode log behind ep_rew_mean); ``force_reset=False``
    keeps the last observation, so that ``learn`` does not reset the envs. Each env checks its
    replay against the observation it had (its own: stable-baselines3 may transpose images).

    Raises:
        ConfigError: for a checkpoint whose envs do not replay to where the run had them.
    """
    from stable_baselines3 import PPO

    venv = make_vec_env(config)
    model = PPO.load(resume, env=venv, device="cpu", force_reset=False)
    for i, position in enumerate(state["envs"]):
        problem = venv.env_method("replay", position, indices=[i])[0]  # in its process, through its Monitor
        if problem:
            venv.close()
            raise ConfigError(
                f"checkpoint {resume}: env {i}, replayed into its episode {position.episode}, does not reach where the run "
                f"had it ({problem}): the task does not play as when the checkpoint was written"
            )
    _set_random_states(state["random"])  # last: an env in this process may draw from them while replaying
    return model, venv


def _new_model(config: TrainConfig, directory: Path, verbose: int) -> tuple[Any, Any]:
    """A fresh PPO model seeded with ``config.seed``, and its vec env."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.utils import set_random_seed

    set_random_seed(config.seed)
    venv = make_vec_env(config)
    p = config.ppo
    policy_kwargs: dict[str, Any] = {"net_arch": list(p.net_arch), "log_std_init": p.log_std_init}
    if config.observation.belief_map.cells:
        from agents.rl.extractor import BeliefMapExtractor

        policy_kwargs["features_extractor_class"] = BeliefMapExtractor
    model = PPO(
        "MultiInputPolicy",
        venv,
        learning_rate=p.learning_rate,
        n_steps=p.n_steps,
        batch_size=p.batch_size,
        n_epochs=p.n_epochs,
        gamma=p.gamma,
        gae_lambda=p.gae_lambda,
        clip_range=p.clip_range,
        ent_coef=p.ent_coef,
        vf_coef=p.vf_coef,
        max_grad_norm=p.max_grad_norm,
        policy_kwargs=policy_kwargs,
        tensorboard_log=str(directory / "tb"),
        seed=config.seed,
        device="cpu",
        verbose=verbose,
    )
    setattr(model, MODEL_ACTION_ATTR, config.action.as_record())  # saved with the model: eval checks it
    return model, venv


def _checkpoints(model: Any, config: TrainConfig, folder: OutputFolder) -> Any:
    """A callback that saves ``model`` every ``config.checkpoint_every`` steps, at rollout boundaries,
    and records in the run's manifest what the run has written so far."""
    from stable_baselines3.common.callbacks import BaseCallback

    every_rollouts = max(1, round(config.checkpoint_every / config.rollout_steps))

    class Checkpoints(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.rollouts = model.num_timesteps // config.rollout_steps

        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            pass

        def _on_rollout_start(self) -> None:
            # called before each rollout after the previous update: a rollout boundary
            if model.num_timesteps and model.num_timesteps // config.rollout_steps % every_rollouts == 0:
                save_checkpoint(model, folder.path / "checkpoints" / f"step_{model.num_timesteps}")
                folder.record_written()

    return Checkpoints()


def train_seeds(
    config: TrainConfig,
    out: Path,
    seeds: Sequence[int],
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> list[Path]:
    """Train ``config`` once per seed (``<out>/<name>/seed_<s>/``), the runs side by side.

    The runs go through :func:`agents.common.sweep.run_tasks`: a local process pool (``workers``,
    default the core count; each run steps its envs as its ``vec_env`` says) or a Ray cluster
    (``ray_address``; ``out`` must then be a folder every node can write). Each run equals
    ``train`` with that seed alone. Returns the ``model.zip`` paths in seed order.
    """
    from agents.common.sweep import run_tasks

    check(len(seeds) >= 1, "train_seeds needs at least one seed")
    check(len(set(seeds)) == len(seeds), f"seeds repeat: {list(seeds)}")
    runs = [dataclasses.replace(config, seed=int(seed)) for seed in seeds]
    check_train_config(config)  # here, before any run starts: not once per worker
    for run in runs:  # each run's folder ready (an earlier run's files deleted where asked) before any starts
        open_run_dir(run, Path(out), resume=False, overwrite=overwrite)
    tasks = [(run, Path(out)) for run in runs]
    return run_tasks(_train_task, tasks, workers=workers, ray_address=ray_address, desc="training runs", progress=progress)


def _train_task(task: tuple[TrainConfig, Path]) -> Path:
    config, out = task
    return train(config, out, progress_bar=False)


def save_checkpoint(model: Any, stem: Path) -> Path:
    """Write ``stem.zip`` (model + optimizer, the last observation, the episode log) and ``stem.state.pkl``
    (step count, random states, each env's :class:`EnvPosition`). At a rollout boundary."""
    model.save(stem.with_suffix(".zip"))
    positions = model.get_env().env_method("position")
    with open(stem.with_suffix(".state.pkl"), "wb") as f:
        pickle.dump({"num_timesteps": model.num_timesteps, "random": _random_states(), "envs": positions}, f)
    return stem.with_suffix(".zip")


def _load_state(checkpoint: Path) -> dict[str, Any]:
    state_path = checkpoint.with_suffix(".state.pkl")
    if not checkpoint.is_file() or not state_path.is_file():
        raise ConfigError(f"checkpoint {checkpoint} needs both {checkpoint.name} and {state_path.name}")
    with open(state_path, "rb") as f:
        state: dict[str, Any] = pickle.load(f)
    return state


def latest_checkpoint(config: TrainConfig, out: Path) -> Path | None:
    """The checkpoint with the most steps of this run, if any."""
    found = sorted((run_dir(config, out) / "checkpoints").glob("step_*.zip"), key=lambda p: int(p.stem.split("_")[1]))
    return found[-1] if found else None


def _write_run_json(config: TrainConfig, directory: Path) -> None:
    write_run_record(directory / "run.json", config=asdict(config), seed=config.seed)
