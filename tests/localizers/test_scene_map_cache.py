"""The scene-map file and its cache: written atomically, and an unreadable file named with how to
make it again (the world's default map in the cache is made again, saying so)."""

from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from agents.experiments import scene_maps
from core.schema import ConfigError
from localizers.far_landmark_pf import scene_map
from localizers.far_landmark_pf.scene_map import SceneMap


def _map(world: str = "box") -> SceneMap:
    return SceneMap(np.array([[3.0, 4.0, 0.5]]), np.array([0, 2]), np.array([1, 4]), np.array([[4.0, 1.0], [5.0, -2.0]]), world,
                    "0123456789abcdef")  # fmt: skip


@pytest.mark.parametrize("keep", [0, 10, 0.5, -5])
def test_a_truncated_map_is_refused_naming_the_file_and_how_to_make_it_again(tmp_path: Path, keep: float) -> None:
    data = _map().save(tmp_path / "full.npz").read_bytes()
    cut = tmp_path / "cut.npz"
    cut.write_bytes(data[: int(keep * len(data)) if isinstance(keep, float) else keep])
    with pytest.raises(ConfigError, match=rf"{cut}.*is not a scene map or cannot be read.*truncated.*crowdloc map WORLD"):
        SceneMap.load(cut)


def test_a_write_killed_midway_leaves_the_old_map_and_no_temporary_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _map("old").save(tmp_path / "scenes.npz")

    def killed(f: object, **arrays: object) -> None:
        f.write(b"PK\x03\x04 half a zip")  # type: ignore[attr-defined]
        raise KeyboardInterrupt  # the process is stopped in the middle of the write

    monkeypatch.setattr(scene_map.np, "savez_compressed", killed)
    with pytest.raises(KeyboardInterrupt):
        _map("new").save(path)
    monkeypatch.undo()
    assert SceneMap.load(path).world == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenes.npz"]
    assert SceneMap.load(_map("new").save(path)).world == "new"


def test_an_unreadable_default_map_is_made_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "scene_maps" / "campus.npz"
    path.parent.mkdir()
    path.write_bytes(b"PK\x03\x04 truncated")
    built: list[object] = []
    monkeypatch.setattr(scene_maps, "default_map_path", lambda env: path)
    monkeypatch.setattr(scene_maps, "build_scene_map", lambda *args, **kwargs: built.append(args) or _map("campus"))
    monkeypatch.setattr(scene_maps, "default_drive", lambda env: (env.config, scene_maps.MappingDrive(crowd_size=0)))
    env = SimpleNamespace(config=SimpleNamespace(name="campus"), file_crowd_size=0, layout=None)
    with caplog.at_level(logging.WARNING, logger=scene_maps.__name__):
        assert scene_maps.default_scene_map(env) == path  # type: ignore[arg-type]
    assert len(built) == 1 and SceneMap.load(path).world == "campus"
    assert "cannot be read, making it again" in caplog.text and str(path) in caplog.text
    scene_maps.default_scene_map(env)  # type: ignore[arg-type]
    assert len(built) == 1  # a readable map is kept


def test_the_default_map_is_keyed_by_the_drives_conditions_not_only_the_geometry(monkeypatch: pytest.MonkeyPatch) -> None:
    """A map cached by a drive in other conditions must not be used: a campus map cached under the same name
    from a drive without the LIDAR sweep, people who see the robot or free-running webcams would give numbers a
    fresh clone cannot reproduce."""
    from envs.localization_env import LocalizationEnv

    def path(**overrides: object) -> Path:
        return scene_maps.default_map_path(LocalizationEnv("stereo_campus", **overrides))  # type: ignore[arg-type]

    default = path()
    assert path(crowd_size=5) == path(crowd_size=0) == default  # every crowd of the world gets the drive at the file's crowd
    changed = {
        "camera timing": path(stereo={"synchronised": True}),
        "LIDAR sweep": path(lidar={"sweep_s": 0.0}),
        "odometry": path(odometry={"alpha1": 0.02}),
    }
    for what, other in changed.items():
        assert other != default, what
        assert other.parent == default.parent and other.name.startswith("stereo_campus-"), what
    monkeypatch.setattr(scene_maps, "DRIVE_VERSION", scene_maps.DRIVE_VERSION + 1)
    assert path() != default  # a change of the drive's code, announced by its version
