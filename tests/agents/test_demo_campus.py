"""The campus section of the demo: a short drive on far_landmark_pf, its two images and its numbers."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents.experiments.scene_maps import MappingDrive, build_scene_map
from agents.papers.stereo_far_landmarks.demo import SELECTED_COLOR, campus_section
from envs.config import load_world
from envs.render import frame_shape
from localizers.range_table import CACHE_ENV

SECONDS = 3.0


@pytest.fixture(scope="module")
def section(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, str]]:
    """The section over a few seconds, on a map of the route's first metres (made in a private cache)."""
    root = tmp_path_factory.mktemp("campus_demo")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(CACHE_ENV, str(root / "cache"))
        scene_map = build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0, max_steps=80)).save(root / "map.npz")
        yield root / "demo" / "campus", campus_section(root / "demo" / "campus", seed=0, seconds=SECONDS, scene_map=scene_map)


def _png(path: Path) -> np.ndarray:
    assert path.is_file() and path.stat().st_size > 0, path
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None, f"{path} is not an image"
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))


def test_the_section_saves_a_camera_image_and_a_top_view_of_the_expected_sizes(section: tuple[Path, str]) -> None:
    out, markdown = section
    world = load_world("stereo_campus")
    camera = world.sensors["stereo"]
    shot = _png(out / "campus_camera.png")
    assert shot.shape == (camera.height_px, camera.width_px, 3)  # type: ignore[attr-defined]
    assert shot.std() > 10  # a rendered scene, not a blank
    top = _png(out / "campus_top.png")
    assert top.shape == frame_shape(world)
    assert top.std() > 10
    for name in ("campus_camera.png", "campus_top.png"):
        assert f"]({out.name}/{name})" in markdown, name


def test_the_section_reports_the_measured_drive(section: tuple[Path, str]) -> None:
    out, markdown = section
    steps = round(SECONDS / load_world("stereo_campus").dt_s)
    error = re.search(r"mean ([\d.]+) m, max ([\d.]+) m over the (\d+) of (\d+) steps with a pose", markdown)
    assert error, markdown
    mean, top, valid, total = float(error[1]), float(error[2]), int(error[3]), int(error[4])
    assert total == steps and 0 < valid <= total
    assert 0 <= mean <= top < 1.0  # a known start, a few seconds: the filter stays on the route
    counts = re.search(
        r"matched (\d+) edges on average \((\d+) reported.*selected ([\d.]+) far landmarks \(at the last step (\d+)\)", markdown
    )
    assert counts, markdown
    assert int(counts[1]) >= int(counts[2]) > 0 and float(counts[3]) > 0
    if int(counts[4]) > 0:  # the sight lines to the selected far landmarks are in the top view
        top_view = _png(out / "campus_top.png")
        assert np.all(top_view == np.array(SELECTED_COLOR, dtype=np.uint8), axis=2).sum() > 20


def test_a_stretch_that_is_not_a_positive_time_is_refused(tmp_path: Path) -> None:
    for seconds in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="seconds must be finite and > 0"):
            campus_section(tmp_path, seed=0, seconds=seconds)
