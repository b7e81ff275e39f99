"""What a benchmark run plays: the plan (worlds x localizers x policies x crowd sizes x seeds) and its episodes.

Every episode is ``crowdloc eval``'s (:func:`agents.evaluate.run_episode` on an
:class:`~agents.evaluate.EvalSpec` of the world's conditions) on one of the protocol's test
seeds; :func:`score_task` turns it into the benchmark's per-episode values at the world's
failure threshold.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.benchmark.protocol import Protocol, WorldProtocol
from agents.evaluate import metrics
from agents.evaluate.episode import run_episode
from agents.evaluate.spec import (
    PPO_PREFIX,
    Cell,
    EvalSpec,
    check_observation_space,
    check_policy,
    crowdloc_ids,
    load_ppo,
    runnable_policies,
    world_of,
)
from agents.policies import FIXED_POLICIES
from core.schema import ConfigError, check
from localizers.measurements import find_sensor
from localizers.registry import LOCALIZERS, measurement_in
from localizers.registry import spec as localizer_spec

#: the per-episode values of :func:`score_task`, in the tables' order (a new key goes last: each key's
#: index is its bootstrap stream, so the others keep their intervals)
EPISODE_KEYS = ("error_mean_m", "failure_share", "availability", "first_fix_s", "nees_median", "inside_95",
                "error_bound_ratio")  # fmt: skip


#: the entry-point groups under which an installed package registers localizers and fixed policies
#: (each entry point names a module, imported like a ``--plugins`` module: it registers on import)
ENTRY_POINT_GROUPS = ("crowdloc.localizers", "crowdloc.policies")
_installed_loaded = False  # the installed packages' entry points are loaded once a process


def load_installed_plugins() -> tuple[str, ...]:
    """Import every module that an installed package names under :data:`ENTRY_POINT_GROUPS`
    (the way pytest and Gymnasium find plug-ins), once a process; returns ``group:name`` of each.

    Raises:
        ConfigError: naming an entry point that cannot be loaded, its package and why.
    """
    global _installed_loaded
    loaded: list[str] = []
    if _installed_loaded:
        return ()
    for group in ENTRY_POINT_GROUPS:
        for entry in importlib.metadata.entry_points(group=group):
            try:
                entry.load()
            except Exception as exc:  # the package's own error, in one line
                package = entry.dist.name if entry.dist is not None else "an installed package"
                raise ConfigError(f"entry point {entry.name} = {entry.value} ({group}, from {package}): "
                                  f"cannot load it ({type(exc).__name__}: {exc})") from None  # fmt: skip
            loaded.append(f"{group}:{entry.name}")
    _installed_loaded = True
    return tuple(loaded)


def load_plugins(modules: Sequence[str]) -> None:
    """Load the installed packages' plug-ins (:func:`load_installed_plugins`), then import the
    user's modules (``--plugins``): each registers its localizers or policies on import.

    Raises:
        ConfigError: naming an entry point or a module that cannot be imported, and why.
    """
    load_installed_plugins()
    for name in modules:
        try:
            importlib.import_module(name)
        except Exception as exc:  # a plug-in's own error is the user's to read, in one line
            raise ConfigError(f"--plugins {name}: cannot import it ({type(exc).__name__}: {exc})") from None


@dataclass(frozen=True)
class WorldPlan:
    """One world of a run: its conditions, the spec its episodes run under and who plays."""

    env_id: str
    world: WorldProtocol
    spec: EvalSpec
    localizers: tuple[str, ...]
    policies: tuple[str, ...]


@dataclass(frozen=True)
class BenchmarkPlan:
    """A run: the worlds with their players, the seeds, whether quick, the lines of what was left out."""

    protocol: Protocol
    worlds: tuple[WorldPlan, ...]
    seeds: tuple[int, ...]
    quick: bool
    left_out: tuple[str, ...]
    plugins: tuple[str, ...] = ()

    def tasks(self) -> list[Task]:
        """Every episode, world by world, then policy, localizer, crowd size and seed."""
        return [
            Task(self.plugins, w.spec, Cell(p, loc, c, s), w.env_id, w.world.failure_m)
            for w in self.worlds
            for p in w.policies
            for loc in w.localizers
            for c in w.world.crowd_sizes
            for s in self.seeds
        ]


@dataclass(frozen=True)
class Task:
    """One episode: the plug-ins to import first (in a fresh worker), the spec, the cell, the world's failure threshold."""

    plugins: tuple[str, ...]
    spec: EvalSpec
    cell: Cell
    env_id: str
    failure_m: float

    @property
    def key(self) -> tuple[str, Cell]:
        """Which task of the plan it is (its :class:`EpisodeScore` has the same)."""
        return self.env_id, self.cell


@dataclass(frozen=True)
class EpisodeScore:
    """One episode's values (:data:`EPISODE_KEYS`), its position errors from the first fix on (finite
    ones) and the localizer's mean cost per step in ms on the machine that played it (not a value:
    it differs between runs)."""

    env_id: str
    cell: Cell
    values: dict[str, float]
    errors_m: NDArray[np.float64]
    update_ms: float = math.nan

    @property
    def key(self) -> tuple[str, Cell]:
        """Which task of the plan it scores."""
        return self.env_id, self.cell


def _supports(localizer: str, sensors: dict[str, dict[str, Any]], env_id: str) -> str | None:
    """None if ``localizer`` can run in a world with ``sensors``, else the line saying why not."""
    try:
        find_sensor(measurement_in(localizer, sensors), sensors, f"{localizer} in {env_id}")
    except ConfigError as exc:
        return f"left out: {exc}"
    return None


def _check_ppo(policy: str, env_id: str, localizer: str, env_kwargs: dict[str, Any]) -> None:
    """A trained policy enters where it observes what the protocol's world gives, nothing else.

    Raises:
        ConfigError: a missing file, or a policy trained on other observations (naming them).
    """
    import gymnasium as gym

    check_policy(policy)
    env = gym.make(env_id, localizer=localizer, **env_kwargs)
    try:
        check_observation_space(policy, load_ppo(policy[len(PPO_PREFIX) :]).observation_space, env.observation_space,
                                hint=f"the benchmark plays every entry in the protocol's conditions: train it on {env_id} "
                                "as the protocol has it (no added sensors or conditions)")  # fmt: skip
    finally:
        env.close()


def plan_benchmark(
    protocol: Protocol,
    *,
    worlds: Sequence[str] | None = None,
    localizers: Sequence[str] | None = None,
    policies: Sequence[str] | None = None,
    seeds: int | None = None,
    quick: bool = False,
    plugins: Sequence[str] = (),
) -> BenchmarkPlan:
    """The episodes of a run (plug-ins already imported).

    Args:
        worlds: env ids of the protocol (default: all of them).
        localizers: registered localizers (default: every one); each runs in the worlds that
            have its sensor, and a line says where it is left out.
        policies: fixed policies (default: each world's protocol policies); each drives the
            worlds it can, and a line says where it cannot.
        seeds: the first ``seeds`` of the protocol's test seeds (default: all; quick: the quick count).
        quick: the protocol's quick mode (fewer seeds, short episodes).

    Raises:
        ConfigError: an unknown world, localizer or policy (naming it), a seed count beyond the
            protocol's, or nothing left to run.
    """
    chosen_worlds = tuple(worlds) if worlds else tuple(protocol.worlds)
    for env_id in chosen_worlds:
        if env_id not in protocol.worlds:
            registered = "a registered env id" if env_id in crowdloc_ids() else "not a registered env id"
            raise ConfigError(f"--worlds: {env_id!r} is not a world of {protocol.name} ({registered}); "
                              f"its worlds: {', '.join(protocol.worlds)}")  # fmt: skip
    for name in localizers or ():
        localizer_spec(name)  # raises, naming the known ones
    for name in policies or ():
        check(name in FIXED_POLICIES or name.startswith(PPO_PREFIX),
              f"--policies: unknown policy {name!r}; fixed policies: {', '.join(FIXED_POLICIES)}, "
              f"or {PPO_PREFIX}PATH.zip for a trained one")  # fmt: skip
    limit = protocol.quick.seeds if quick and seeds is None else protocol.seeds.count
    count = limit if seeds is None else seeds
    check(1 <= count <= protocol.seeds.count,
          f"--seeds must be from 1 to {protocol.seeds.count} (the protocol's test seeds), got {count}")  # fmt: skip
    left_out: list[str] = []
    plans = []
    for env_id in chosen_worlds:
        world = protocol.worlds[env_id]
        prior = world.prior
        config = world_of(env_id, {})
        sensors = {n: {"type": s.type_name} for n, s in config.sensors.items()}
        for name in world.paper_localizers:
            why = _supports(name, sensors, env_id)
            check(why is None, f"{protocol.path}: worlds.{env_id}.paper_localizers: {name!r} cannot run there "
                  f"({str(why).removeprefix('left out: ')})")  # fmt: skip
        runs = []
        for name in localizers or tuple(LOCALIZERS):
            why = _supports(name, sensors, env_id)
            if why is None:
                runs.append(name)
            else:
                left_out.append(why)
        drivers = []
        for name in policies or world.policies:
            if name.startswith(PPO_PREFIX) or name in runnable_policies(config):  # _check_ppo checks its observations
                drivers.append(name)
            else:
                left_out.append(
                    f"left out: policy {name!r} cannot drive {env_id} (it lacks {FIXED_POLICIES[name].unmet_need(config)[0]})"
                )
        if not runs or not drivers:
            left_out.append(f"left out: {env_id}: no {'localizer' if not runs else 'policy'} of this run can play there")
            continue
        kwargs = {} if prior is None else {"prior": prior}
        for name in drivers:
            if name.startswith(PPO_PREFIX):
                _check_ppo(name, env_id, runs[0], kwargs)
        steps = protocol.quick.episode_steps if quick else world.episode_steps
        spec = EvalSpec(policies=tuple(drivers), localizers=tuple(runs), crowd_sizes=world.crowd_sizes, seeds=1,
                        episode_steps=steps, env_id=env_id, env_kwargs=kwargs)  # fmt: skip
        plans.append(WorldPlan(env_id, world, spec, tuple(runs), tuple(drivers)))
    check(bool(plans), "nothing to run: " + "; ".join(left_out))
    return BenchmarkPlan(protocol, tuple(plans), protocol.seeds.seeds[:count], quick, tuple(left_out), tuple(plugins))


def score_task(task: Task) -> EpisodeScore:
    """Play one episode (importing the plug-ins first, for a worker that has not) and score it."""
    load_plugins(task.plugins)
    episode = run_episode(task.spec, task.cell)
    errors, t0 = episode.position_errors, episode.fix_index
    fit = metrics.consistency(episode.nees, dof=3, mask=episode.valid)
    covariance = localizer_spec(task.cell.localizer).covariance
    values = {
        "error_mean_m": episode.metrics["position_error_mean_m"],
        "failure_share": metrics.failure_rate(errors, t0, threshold=task.failure_m),
        "availability": episode.metrics["availability"],
        "first_fix_s": episode.metrics["first_fix_s"],
        "nees_median": fit.nees_median if covariance else math.nan,
        "inside_95": fit.inside_95 if covariance else math.nan,
        "error_bound_ratio": episode.metrics.get("error_bound_ratio", math.nan),  # where a bound exists (bearings)
    }
    kept = errors[t0:] if t0 is not None else errors[:0]
    finite = np.asarray(kept[np.isfinite(kept)], dtype=np.float64)
    return EpisodeScore(task.env_id, task.cell, values, finite, episode.update_ms)
