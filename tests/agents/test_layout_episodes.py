"""A task on seeded layouts (agents.rl.layout_episodes): disjoint splits, a layout per episode drawn
from its seed, the layouts' tasks cached and bounded."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from agents.rl.config import load_train_config
from agents.rl.layout_episodes import SPLITS, LayoutEpisodes, LayoutSplits, episode_layout
from agents.rl.train import make_task_env, make_training_env
from core.schema import ConfigError

SPLIT_KEYS = {"train": [0, 1000], "validation": [1000, 1100], "test": [1100, 1200]}


def _config(**changes: Any) -> Any:
    return load_train_config("ppo_candidate_sets", {"layouts": {**SPLIT_KEYS, **changes}})


def test_the_splits_of_a_config_are_disjoint_ranges_and_an_overlap_is_refused_naming_both() -> None:
    config = _config()
    assert isinstance(config.layouts, LayoutSplits)
    seeds = {name: set(config.layouts.seeds(name)) for name in SPLITS}
    assert len(seeds["train"]) == 1000 and len(seeds["validation"]) == 100 and len(seeds["test"]) == 100
    assert not seeds["train"] & seeds["validation"] and not seeds["train"] & seeds["test"]
    assert not seeds["validation"] & seeds["test"]
    with pytest.raises(ConfigError, match=r"layouts.train \[0, 1000\] and layouts.test \[999, 1200\] overlap"):
        _config(test=[999, 1200])
    with pytest.raises(ConfigError, match=r"layouts.validation must be \[first, end\].*got \[5, 5\]"):
        _config(validation=[5, 5])
    with pytest.raises(ConfigError, match="unknown layout split 'tests'"):
        config.layouts.seeds("tests")
    with pytest.raises(ConfigError, match="not env_kwargs.layout"):
        load_train_config("ppo_candidate_sets", {"env_kwargs.layout": 3})


def test_every_shipped_config_with_layouts_keeps_its_splits_apart() -> None:
    """What the shipped configs say is checked at load: loading every one proves none overlaps."""
    from agents.rl.config import EXPERIMENT_DIR

    for path in sorted(EXPERIMENT_DIR.glob("*.yaml")):
        config = load_train_config(path)
        if config.layouts is not None:
            ranges = sorted((config.layouts.seeds(name) for name in SPLITS), key=lambda r: r.start)
            assert all(a.stop <= b.start for a, b in zip(ranges, ranges[1:])), path


def test_an_episode_plays_the_layout_its_seed_draws_and_the_same_seed_replays_it() -> None:
    config = _config()
    env = make_task_env(config, 6, "test")
    layouts, firsts = [], []
    for seed in range(6):
        obs, info = env.reset(seed=seed)
        assert info["layout"] == episode_layout(config.layouts.seeds("test"), seed) and 1100 <= info["layout"] < 1200
        world: Any = env.unwrapped.env.unwrapped  # the current layout's world
        assert world.layout == info["layout"]
        _, _, _, _, info = env.step(env.action_space.sample())
        assert info["layout"] == world.layout
        layouts.append(info["layout"])
        firsts.append(obs)
    assert len(set(layouts)) >= 4  # episodes spread over the split
    again = make_task_env(config, 6, "test")
    for seed in (3, 1):
        obs, info = again.reset(seed=seed)
        assert info["layout"] == layouts[seed]
        for key in obs:
            np.testing.assert_array_equal(obs[key], firsts[seed][key])
    obs, info = again.reset(seed=0, options={"layout": 1150})
    assert info["layout"] == 1150
    with pytest.raises(ConfigError, match=r"layout=5 is not one of this task's layout seeds range\(1100, 1200\)"):
        again.reset(seed=0, options={"layout": 5})


def test_layouts_differ_where_their_generator_varies_them() -> None:
    config = _config()
    env = make_task_env(config, 6, "train")
    maps = []
    for layout in (0, 1):
        env.reset(seed=0, options={"layout": layout})
        maps.append(np.array([[m.x_m, m.y_m] for m in env.unwrapped.env.unwrapped.config.landmarks]))
    assert maps[0].shape == maps[1].shape and not np.allclose(maps[0], maps[1])


def test_the_cache_keeps_at_most_its_size_and_closes_what_it_drops() -> None:
    closed: list[int] = []

    class Task(gym.Env[Any, Any]):
        observation_space = gym.spaces.Box(-1.0, 1.0, (2,))
        action_space = gym.spaces.Discrete(2)

        def __init__(self, layout: int) -> None:
            self.layout = layout

        def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
            return np.zeros(2, np.float32), {}

        def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
            return np.zeros(2, np.float32), 0.0, False, False, {}

        def close(self) -> None:
            closed.append(self.layout)

    env = LayoutEpisodes(Task, range(10, 20), cache_size=2)
    for layout in (11, 12, 13, 12):
        env.reset(seed=0, options={"layout": layout})
    assert env.cached_layouts == (13, 12) and sorted(closed) == [10, 11]
    env.close()
    assert sorted(closed) == [10, 11, 12, 13]
    with pytest.raises(ConfigError, match="cache_size must be >= 1, got 0"):
        LayoutEpisodes(Task, range(3), cache_size=0)


def test_training_plays_only_training_layouts() -> None:
    config = _config()
    env = make_training_env(config, 0)
    seen = {env.reset()[1]["layout"] for _ in range(5)}
    assert seen <= set(config.layouts.seeds("train")) and len(seen) >= 3
    with pytest.raises(ConfigError, match="has no layouts"):
        make_task_env(load_train_config("ppo_candidate_sets"), 6, "train")


def test_a_replayed_training_episode_is_on_its_own_layout() -> None:
    """crowdloc train's exact resume replays an env's unfinished episode: on the layout it was on."""
    config = _config()
    env = make_training_env(config, 1)
    env.reset()
    _, info = env.reset()
    for _ in range(4):
        _, _, _, _, info = env.step(env.action_space.sample())
    position = env.position()
    fresh = make_training_env(config, 1)
    assert fresh.replay(position) == ""
    assert fresh.env.unwrapped.layout == info["layout"]


def test_an_evaluation_on_a_layout_split_plays_each_seed_on_its_layout_for_every_policy() -> None:
    from agents.evaluate.episode import rollout
    from agents.evaluate.spec import Cell, EvalSpec

    spec = EvalSpec(policies=("spin", "random_walk"), crowd_sizes=(6,), seeds=3, episode_steps=20, layouts=(1100, 1200))
    seeds = spec.eval_seeds
    layouts = [spec.layout_of(seed) for seed in seeds]
    assert layouts == [episode_layout(range(1100, 1200), seed) for seed in seeds]
    assert all(1100 <= layout < 1200 for layout in layouts)
    for policy in spec.policies:
        env = spec.make_env(policy, "candidate_sets", 6, layout=layouts[0])
        assert env.unwrapped.layout == layouts[0]
        env.close()
    first = rollout(spec, Cell("spin", "candidate_sets", 6, seeds[0]))
    own = rollout(
        EvalSpec(policies=("spin",), crowd_sizes=(6,), seeds=3, episode_steps=20), Cell("spin", "candidate_sets", 6, seeds[0])
    )
    assert first.context.landmark_map.positions_xy_m.tolist() != own.context.landmark_map.positions_xy_m.tolist()
    assert EvalSpec(policies=("spin",), crowd_sizes=(6,)).layout_of(seeds[0]) is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"layouts": (5, 5)}, r"layouts must be \[first, end\] layout seeds with 0 <= first < end, got \(5, 5\)"),
        ({"layouts": (0, 10), "env_id": "crowdloc/RoboCupStatic-v0"}, "world 'robocup_static' has no layout generator"),
        ({"layouts": (0, 10), "env_kwargs": {"layout": 3}}, "not env_kwargs.layout"),
    ],
)
def test_a_bad_evaluation_layout_range_is_refused_naming_it(kwargs: dict[str, Any], message: str) -> None:
    from agents.evaluate.spec import EvalSpec

    with pytest.raises(ConfigError, match=message):
        EvalSpec(policies=("spin",), crowd_sizes=(2,), **kwargs)


def test_eval_conditions_of_a_layout_config_default_to_its_test_split(capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import build_parser
    from agents.evaluate.cli import spec_from_args

    parser = build_parser()
    base = ["eval", "--conditions", "ppo_candidate_sets_layouts", "--policies", "spin", "--crowd-sizes", "6", "--seeds", "1"]
    config = load_train_config("ppo_candidate_sets_layouts")
    assert spec_from_args(parser.parse_args(base)).layouts == config.layouts.test
    assert spec_from_args(parser.parse_args([*base, "--layout-split", "validation"])).layouts == config.layouts.validation
    plain = ["eval", "--conditions", "ppo_candidate_sets", "--policies", "spin", "--crowd-sizes", "6", "--layout-split", "test"]
    with pytest.raises(ConfigError, match="--layout-split test: the --conditions config ppo_candidate_sets has no layouts"):
        spec_from_args(parser.parse_args(plain))


def test_eval_conditions_carry_the_configs_localizer_parameters_under_the_command_lines() -> None:
    from agents.cli import build_parser
    from agents.evaluate.cli import spec_from_args

    parser = build_parser()
    base = ["eval", "--conditions", "ppo_room_lidar_layouts", "--policies", "spin", "--crowd-sizes", "16", "--seeds", "1"]
    assert spec_from_args(parser.parse_args(base)).localizer_params == {"mcl_lidar": {"global_candidates": 100000}}
    given = spec_from_args(parser.parse_args([*base, "--localizer-set", "mcl_lidar.global_candidates=0"]))
    assert given.localizer_params == {"mcl_lidar": {"global_candidates": 0}}


def test_the_campus_task_trains_on_layouts_each_with_its_own_scene_map(tmp_path, monkeypatch) -> None:
    from localizers.range_table import CACHE_ENV

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    config = load_train_config("ppo_campus_stereo_layouts")
    env = make_training_env(config, 1)
    seen = []
    for _ in range(2):
        obs, info = env.reset()
        assert obs["belief_map"].shape == (4, 32, 32) and abs(float(obs["belief_map"].sum()) - 1.0) < 1e-4
        for _ in range(3):
            obs, _, _, _, info = env.step(env.action_space.sample())
        seen.append(info["layout"])
    assert len(set(seen)) == 2 and set(seen) <= set(config.layouts.seeds("train"))
    built = set(seen) | {config.layouts.seeds("train")[0]}  # and the first layout's: the wrapper's spaces come from it
    assert len(list((tmp_path / "scene_maps" / "layouts").glob("stereo_campus-*.npz"))) == len(built)
    env.close()
