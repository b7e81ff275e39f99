"""``crowdloc map WORLD``: the scene map it writes, and the input it refuses (one line naming it, exit status 2)."""

from __future__ import annotations

import contextlib
import io
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents.cli import main
from localizers.far_landmark_pf.scene_map import SceneMap
from localizers.range_table import CACHE_ENV

WORLD = "stereo_campus"


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """A private cache (the LIDAR reference's table) for the module: nothing lands in the user's."""
    root = tmp_path_factory.mktemp("crowdloc_cache")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(CACHE_ENV, str(root))
        yield root


@pytest.fixture(scope="module")
def built(cache: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``crowdloc map stereo_campus --out .../campus.npz --crowd-size 0``: the file and what it printed."""
    out = tmp_path_factory.mktemp("maps") / "campus.npz"
    printed = io.StringIO()  # capsys is function-scoped: capture stdout by hand
    with contextlib.redirect_stdout(printed):
        assert main(["map", WORLD, "--out", str(out), "--crowd-size", "0"]) == 0
    return out, printed.getvalue()


def _refused(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """Run ``crowdloc map ARGV``; it must exit with status 2 and a one-line message; the message."""
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["map", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_map_writes_a_scene_map_of_the_world(built: tuple[Path, str]) -> None:
    out, printed = built
    scenes = SceneMap.load(out)
    assert scenes.world == WORLD
    assert scenes.scene_count > 10 and scenes.landmark_count > scenes.scene_count
    assert scenes.source["crowd_size"] == 0 and scenes.source["period_s"] == 1.0 and scenes.source["max_shift_px"] == 1.0
    # a scene a second of the drive (dt 0.1 s): about one per 10 steps driven
    assert abs(scenes.scene_count - scenes.source["steps"] / 10) <= 1
    said = re.search(r"wrote (.+) \((\d+) scenes, (\d+) landmarks\)", printed)
    assert said, printed
    assert Path(said[1]) == out and int(said[2]) == scenes.scene_count and int(said[3]) == scenes.landmark_count


def test_a_second_run_refuses_to_replace_the_map_unless_told_to(
    built: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = shutil.copy(built[0], tmp_path / "campus.npz")
    before = out.read_bytes()
    err = _refused(capsys, WORLD, "--out", str(out), "--crowd-size", "0")
    assert str(out) in err and "--overwrite" in err
    assert out.read_bytes() == before  # untouched
    assert main(["map", WORLD, "--out", str(out), "--crowd-size", "0", "--period-s", "2", "--overwrite"]) == 0
    replaced = SceneMap.load(out)
    assert out.read_bytes() != before
    assert replaced.source["period_s"] == 2.0 and replaced.scene_count < SceneMap.load(built[0]).scene_count


def test_an_out_file_that_is_not_npz_is_refused(cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "campus.map"
    err = _refused(capsys, WORLD, "--out", str(out), "--crowd-size", "0")
    assert str(out) in err and ".npz" in err
    assert not out.exists()


def test_an_unknown_world_is_a_clear_error(cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _refused(capsys, "no_such_world", "--out", str(tmp_path / "x.npz"), "--crowd-size", "0")
    assert "unknown world 'no_such_world'" in err and WORLD in err  # and the worlds there are
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("option", ["--period-s", "--max-shift-px"])
@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf"])
def test_a_bad_period_or_shift_is_refused_naming_the_option(
    option: str, value: str, cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(capsys, WORLD, "--out", str(tmp_path / "x.npz"), "--crowd-size", "0", option, value)
    assert option in err and f"got {float(value)}" in err
    assert not (tmp_path / "x.npz").exists()


def test_a_negative_crowd_is_refused_naming_the_option(cache: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _refused(capsys, WORLD, "--out", str(tmp_path / "x.npz"), "--crowd-size", "-3")
    assert "--crowd-size" in err and "-3" in err
    assert not (tmp_path / "x.npz").exists()
