"""A sensor and a crowd defined only here, registered and named in a world YAML written here,
work everywhere: in the observation, drawn, recorded, replayed into a localizer and evaluated.

Nothing outside this module knows them: if any of these steps needed an edit of the core
(an if-chain on sensor or crowd types, a per-sensor attribute), this module would fail.
"""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium import spaces
from numpy.typing import NDArray

import envs  # noqa: F401  (registers crowdloc/*)
import envs.config
from agents.evaluate import EvalSpec, evaluate
from agents.experiments.replay import record, replay
from agents.experiments.scenarios import square_driver
from core.raycast import cast_rays
from envs.config import load_world, world_path
from envs.crowds import Commands, Crowd, CrowdConfig, Taken, register_crowd
from envs.sensors import SensorBase, SensorConfig, register_sensor
from envs.state import Rows, WorldState
from localizers.base import PoseEstimate, ScanMeasurement
from localizers.mcl_lidar import CACHE_ENV
from localizers.measurements import MeasurementKind, register_measurement
from localizers.registry import LocalizerSpec, register_localizer

TOY_HIT = (1, 254, 3)  # the toy sensor's dots: a colour nothing else draws
TOY_CROWD = (2, 3, 250)
ROOM = "crowdloc/CrowdedRoom-v0"


# ------------------------------------------------------------------ a toy range sensor
@dataclass(frozen=True)
class ToyRangeConfig(SensorConfig):
    """A ring of ``beams`` noise-free ranges to the walls and the bodies."""

    key: str = "toy_ranges"
    beams: int = 16
    max_range_m: float = 8.0


@register_sensor("toy_range", ToyRangeConfig)
class ToyRange(SensorBase):
    def __init__(self, name: str, config: ToyRangeConfig, world: Any, state: WorldState) -> None:
        self.name, self.key, self.config = name, config.key, config
        self.angles = np.linspace(-math.pi, math.pi, config.beams, endpoint=False)
        self.rows = np.arange(1, state.body_count)

    def space(self) -> spaces.Box:
        return spaces.Box(0.0, self.config.max_range_m, shape=(self.config.beams,), dtype=np.float32)

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        ranges = cast_rays(
            state.positions[0],
            self.angles + state.robot_pose[2],
            self.config.max_range_m,
            state.seg_a,
            state.seg_b,
            state.positions[self.rows],
            state.radii_m[self.rows],
        )
        return ranges.astype(np.float32), {"toy_beams": self.config.beams}

    def metadata(self) -> dict[str, Any]:
        return {"beam_angles_rad": self.angles.copy(), "max_range_m": self.config.max_range_m}

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.float32], info: Mapping[str, Any]) -> None:
        pose = state.robot_pose
        directions = np.stack([np.cos(self.angles + pose[2]), np.sin(self.angles + pose[2])], axis=1)
        canvas.points(pose[:2] + reading[:, None] * directions, TOY_HIT, 4)


def decode_toy(ranges: NDArray[np.float32], metadata: Mapping[str, Any]) -> ScanMeasurement:
    return ScanMeasurement(np.asarray(ranges, dtype=np.float64), metadata["beam_angles_rad"], metadata["max_range_m"])


register_measurement(MeasurementKind("toy_scan", "toy_range", decode_toy, "the toy ring's ranges"))
# the LIDAR paper's MCL, fed from the toy ring (a small ray-cast table keeps the test quick)
register_localizer("toy_mcl", LocalizerSpec("localizers.mcl_lidar", "LidarMCL", "LidarMCLParams", "toy_scan", True, "MCL on toy"))
TOY_MCL = {"table_resolution_m": 0.1, "table_directions": 90, "n_particles": 300, "update_min_travel_m": 0.2}


# ------------------------------------------------------------------ a toy crowd
@dataclass(frozen=True)
class CirclersConfig(CrowdConfig):
    """People walking around a circle at constant speed."""

    center_xy_m: tuple[float, float] = (3.5, 3.5)
    circle_radius_m: float = 2.5


@register_crowd("toy_circlers", CirclersConfig)
class Circlers(Crowd):
    fill = TOY_CROWD

    def __init__(self, name: str, config: CirclersConfig, world: Any) -> None:
        super().__init__(name, config, world)
        self.c = config

    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        super().reset(rng, taken)
        phase = rng.uniform(0.0, 2 * math.pi) + 2 * math.pi * np.arange(self.count) / max(self.count, 1)
        out = np.asarray(self.c.center_xy_m) + self.c.circle_radius_m * np.stack([np.cos(phase), np.sin(phase)], axis=1)
        taken += [(float(x), float(y), self.config.radius_m) for x, y in out]
        return out

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        rel = state.positions[self.member_rows] - np.asarray(self.c.center_xy_m)
        tangent = np.stack([-rel[:, 1], rel[:, 0]], axis=1) / np.linalg.norm(rel, axis=1, keepdims=True)
        return Commands(tangent * self.config.speed_mps)


# ------------------------------------------------------------------ the world that names them
@pytest.fixture(scope="module")
def toy_world(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The crowded room with the toy ring instead of the LIDAR and toy circlers instead of the walkers."""
    data = yaml.safe_load(world_path("crowded_room").read_text())
    data["name"] = "toy_room"
    data["sensors"] = {"odometry": data["sensors"]["odometry"], "ring": {"type": "toy_range", "beams": 72}}
    data["crowds"]["walkers"] = {"type": "toy_circlers", "count": 3, "radius_m": 0.2, "speed_mps": 0.6}
    path = tmp_path_factory.mktemp("toy") / "toy_room.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(autouse=True)
def _table_cache(monkeypatch: pytest.MonkeyPatch, tmp_path_factory: pytest.TempPathFactory) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path_factory.getbasetemp() / "toy_cache"))


def test_the_world_file_names_them_and_loads_strictly(toy_world: Path, tmp_path: Path) -> None:
    config = load_world(toy_world)
    assert config.sensors["ring"].type_name == "toy_range" and config.sensors["ring"].beams == 72
    assert config.crowds["walkers"].type_name == "toy_circlers"
    bad = yaml.safe_load(toy_world.read_text())
    bad["sensors"]["ring"]["beems"] = 3
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    with pytest.raises(ValueError, match=r"unknown key 'beems' for ToyRangeConfig"):
        load_world(tmp_path / "bad.yaml")


def test_they_are_observed_and_drawn(toy_world: Path) -> None:
    env = gym.make(ROOM, world=str(toy_world), render_mode="rgb_array", crowd_size=0)
    obs, info = env.reset(seed=0)
    assert set(obs) == {"odometry", "toy_ranges"} and obs["toy_ranges"].shape == (72,)
    assert env.observation_space.contains(obs) and info["toy_beams"] == 72
    before = env.unwrapped.world.positions[1:4].copy()
    for _ in range(40):
        obs, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    circlers = env.unwrapped.world.positions[1:4]
    assert np.all(np.linalg.norm(circlers - before, axis=1) > 0.3)  # they walk ...
    np.testing.assert_allclose(np.linalg.norm(circlers - 3.5, axis=1), 2.5, atol=0.15)  # ... around their circle
    frame = env.render()
    for colour in (TOY_HIT, TOY_CROWD):
        assert np.all(frame == np.array(colour, dtype=np.uint8), axis=-1).sum() > 10, colour
    env.close()
    # from the room's centre the walls are 3.5 m away or more: shorter ranges end on circlers
    # (2.5 m off, 5 deg beams: each of the three is hit)
    env = gym.make(ROOM, world=str(toy_world), crowd_size=0)
    obs, _ = env.reset(seed=0, options={"robot_pose": [3.5, 3.5, 0.0]})
    assert 3 <= np.sum(obs["toy_ranges"] < 2.5) and np.all(obs["toy_ranges"] > 2.0)
    env.close()


def test_they_are_recorded_replayed_and_run_online(toy_world: Path) -> None:
    start = (2.25, 2.25, 0.0)
    kwargs = {"world": str(toy_world), "crowd_size": 4}

    def drive(env: Any) -> Any:
        return square_driver(env, center_xy=(3.5, 3.5), side_m=2.5, laps=1, speed_mps=0.5, turn_rate_rps=1.0)

    rec = record(ROOM, drive, seed=3, max_steps=300, env_kwargs=kwargs, reset_options={"robot_pose": start})
    assert set(rec.observations) == {"odometry", "toy_ranges"} and rec.sensors["ring"]["type"] == "toy_range"
    assert rec.observations["toy_ranges"].shape == (rec.steps, 72)
    result = replay(rec, "toy_mcl", rng_seed=0, params=TOY_MCL)
    assert result.valid.all()
    errors = np.linalg.norm(result.estimates[:, :2] - rec.true_pose[:, :2], axis=1)
    assert errors[-1] < 0.3, errors[-1]  # tracked through a lap among the circlers
    # the online wrapper finds the toy ring by its type and gives the same estimates
    env = gym.make(ROOM, localizer="toy_mcl", localizer_params=TOY_MCL, **kwargs)
    obs, info = env.reset(seed=3, options={"robot_pose": start})
    assert isinstance(info["estimate"], PoseEstimate) and "toy_ranges" in obs


def test_they_are_evaluated(toy_world: Path, tmp_path: Path) -> None:
    spec = EvalSpec(
        policies=("random_walk",),
        localizers=("toy_mcl",),
        crowd_sizes=(0, 4),
        seeds=2,
        episode_steps=60,
        env_id=ROOM,
        env_kwargs={"world": str(toy_world), "prior": "start"},
    )
    result = evaluate(spec, workers=1)
    assert len(result.episodes) == 4
    for episode in result.episodes:
        assert episode.cell.localizer == "toy_mcl"
        assert math.isfinite(episode.metrics["position_error_mean_m"])
        assert episode.metrics["availability"] == 1.0


# ------------------------------------------------------------------ the core names no plug-in
def test_the_world_config_imports_only_the_plugin_registries() -> None:
    """``envs.config`` reaches the sensors, crowds and features through their ``base`` modules
    (the registries) only: a plug-in, built in or like the toys above, is a module it never names."""
    tree = ast.parse(Path(envs.config.__file__).read_text())
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    plugin_imports = {m for m in imported if m.split(".")[:2] in (["envs", "sensors"], ["envs", "crowds"], ["envs", "features"])}
    assert plugin_imports == {"envs.sensors.base", "envs.crowds.base", "envs.features.base"}


def test_a_process_that_only_imports_the_loader_knows_the_builtin_plugins() -> None:
    """The built-in types register when their package is imported, which importing a registry
    does: ``from envs.config import load_world`` alone loads every shipped world."""
    code = "from envs.config import available_worlds, load_world\nfor name in available_worlds():\n    load_world(name)\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
