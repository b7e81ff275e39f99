"""A task on seeded layouts: train on some layouts, choose on others, test on layouts never seen.

A training config's ``layouts`` (:class:`LayoutSplits`) gives three disjoint half-open ranges of
layout seeds (:mod:`envs.layouts`)::

    layouts: {train: [0, 100000], validation: [100000, 101000], test: [101000, 102000]}

:class:`LayoutEpisodes` is one task env whose every episode is on a layout of one split, drawn
from the episode's seed (so a seed gives the same layout and the same rollout in every process,
and a replayed episode its own layout). Each layout's task (its world, and the maps its
localizer builds from that world) is made once and kept in a cache of at most ``cache_size``
layouts, the least recently used closed first.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np

from core.schema import ConfigError, check
from envs.layouts import checked_layout

#: the split names, in the order their ranges must run
SPLITS = ("train", "validation", "test")
#: the first word of the seed sequence a layout is drawn from: apart from every other draw of an episode's seed
_LAYOUT_DRAW = 0x5E7


@dataclass(frozen=True)
class LayoutSplits:
    """The layout seeds a task trains (``train``), is chosen (``validation``) and tested (``test``) on.

    Each is ``[first, end]``: the seeds ``first .. end - 1``. The three never overlap (checked here).
    """

    train: tuple[int, int]
    validation: tuple[int, int]
    test: tuple[int, int]

    def __post_init__(self) -> None:
        for name in SPLITS:
            first, end = getattr(self, name)
            check(0 <= first < end, f"layouts.{name} must be [first, end] with 0 <= first < end, got [{first}, {end}]")
        for i, a in enumerate(SPLITS):
            for b in SPLITS[i + 1 :]:
                (a0, a1), (b0, b1) = getattr(self, a), getattr(self, b)
                check(
                    a1 <= b0 or b1 <= a0,
                    f"layouts.{a} [{a0}, {a1}] and layouts.{b} [{b0}, {b1}] overlap: a layout seed would be in both",
                )

    def seeds(self, split: str) -> range:
        """The layout seeds of ``split`` (one of :data:`SPLITS`)."""
        if split not in SPLITS:
            raise ConfigError(f"unknown layout split {split!r} (splits: {', '.join(SPLITS)})")
        first, end = getattr(self, split)
        return range(first, end)


def episode_layout(seeds: range, episode_seed: int) -> int:
    """The layout of ``seeds`` the episode of seed ``episode_seed`` plays on."""
    rng = np.random.default_rng(np.random.SeedSequence([_LAYOUT_DRAW, episode_seed]))
    return seeds[int(rng.integers(len(seeds)))]


class LayoutEpisodes(gym.Env[Any, Any]):
    """The task ``make(layout)`` with each episode on a layout of ``seeds``, drawn from its seed.

    ``reset(seed=s)`` plays layout :func:`episode_layout` ``(seeds, s)``; ``options={"layout": N}``
    picks one (it must be in ``seeds``). A reset without a seed draws the next episode seed from the
    last seeded reset, so a run is determined by its first seed. ``info["layout"]`` names the layout.

    Args:
        make: builds the task on one layout; every layout's task must have the same spaces.
        seeds: the layout seeds episodes are drawn from (a :meth:`LayoutSplits.seeds`).
        cache_size: how many layouts' tasks are kept (>= 1).
    """

    def __init__(self, make: Callable[[int], gym.Env[Any, Any]], seeds: range, cache_size: int = 8) -> None:
        check(len(seeds) >= 1, f"LayoutEpisodes needs at least one layout seed, got {seeds!r}")
        check(cache_size >= 1, f"LayoutEpisodes cache_size must be >= 1, got {cache_size}")
        self._make, self.seeds, self.cache_size = make, seeds, cache_size
        self._cache: OrderedDict[int, gym.Env[Any, Any]] = OrderedDict()
        self._rng = np.random.default_rng()
        self.layout = seeds[0]
        self.env = self._task(self.layout)
        self.observation_space = self.env.observation_space
        self.action_space = self.env.action_space
        self.metadata = self.env.metadata
        self.render_mode = self.env.render_mode

    def _task(self, layout: int) -> gym.Env[Any, Any]:
        env = self._cache.pop(layout, None)
        if env is None:
            env = self._make(layout)
            if hasattr(self, "observation_space") and (
                env.observation_space != self.observation_space or env.action_space != self.action_space
            ):
                env.close()
                raise ConfigError(f"layout {layout}'s task has other observation or action spaces than layout {self.layout}'s")
        self._cache[layout] = env
        while len(self._cache) > self.cache_size:
            _, old = self._cache.popitem(last=False)
            old.close()
        return env

    @property
    def cached_layouts(self) -> tuple[int, ...]:
        """The layouts whose tasks are cached, least recently used first."""
        return tuple(self._cache)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        if seed is not None:
            self._rng = np.random.default_rng(np.random.SeedSequence([_LAYOUT_DRAW, seed, 1]))
            episode_seed = seed
        else:
            episode_seed = int(self._rng.integers(2**31))
        options = dict(options or {})
        layout = options.pop("layout", None)
        if layout is None:
            layout = episode_layout(self.seeds, episode_seed)
        elif checked_layout(layout, "reset option layout") not in self.seeds:
            raise ConfigError(f"reset option layout={layout!r} is not one of this task's layout seeds {self.seeds!r}")
        self.layout = int(layout)
        self.env = self._task(self.layout)
        obs, info = self.env.reset(seed=episode_seed, options=options or None)
        info["layout"] = self.layout
        return obs, info

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["layout"] = self.layout
        return obs, reward, terminated, truncated, info

    def render(self) -> Any:
        return self.env.render()

    def close(self) -> None:
        for env in self._cache.values():
            env.close()
        self._cache.clear()

    def get_wrapper_attr(self, name: str) -> Any:
        """An attribute of this env, else of the current layout's task (its localizer, its estimate)."""
        if name in self.__dict__ or hasattr(type(self), name):
            return getattr(self, name)
        return self.env.get_wrapper_attr(name)
