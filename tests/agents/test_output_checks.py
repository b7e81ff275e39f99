"""Every command checks where it will write before its work: a file where a folder goes, a folder
where a file goes, a path that cannot be made, or a file it would replace unasked is one line
under the command's usage (exit 2), and the work never starts."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from agents.cli import main


class Started(Exception):
    """The command's work began (it must not, with a bad --out)."""


def _never(*args: Any, **kwargs: Any) -> Any:
    raise Started


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()[-1]) > 0
    return err.strip().splitlines()[-1]


@pytest.fixture
def a_file(tmp_path: Path) -> Path:
    path = tmp_path / "a_file"
    path.write_text("the user's")
    return path


TUNE = ["tune", "candidate_sets", "--trials", "1", "--crowd-size", "0", "--episode-steps", "5", "--train-seeds", "1",
        "--eval-seeds", "1", "--quiet"]  # fmt: skip


@pytest.mark.parametrize("where", ["file", "proc"])
def test_tune_checks_its_out_before_the_study(where: str, a_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    import agents.tune.study as study

    monkeypatch.setattr(study, "_open_study", _never)
    out = a_file if where == "file" else Path("/proc/x")
    line = _refused([*TUNE, "--storage", f"sqlite:///{tmp_path / 't.db'}", "--out", str(out)], capsys)
    assert f"--out {out}" in line
    assert a_file.read_text() == "the user's"


@pytest.mark.parametrize("where", ["proc", "folder"])
def test_fit_checks_its_out_before_fitting(where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    import agents.papers.ceiling_target.fit as fit

    monkeypatch.setattr(fit, "fit", _never)
    out = Path("/proc/x/f.yaml") if where == "proc" else tmp_path
    line = _refused(["fit", "ceiling_target", "--out", str(out), "--overwrite"], capsys)
    assert f"--out {out}" in line and ("is a folder" in line if where == "folder" else "cannot create" in line)


def test_map_checks_its_out_before_the_drive(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import agents.experiments.scene_maps as scene_maps

    monkeypatch.setattr(scene_maps, "build_scene_map", _never)
    line = _refused(["map", "stereo_campus", "--out", "/proc/x/m.npz"], capsys)
    assert "--out /proc/x/m.npz" in line and "cannot create" in line


def test_train_into_a_file_is_one_line(a_file: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import agents.rl.train as train

    monkeypatch.setattr(train, "_new_model", _never)
    line = _refused(["train", "ppo_candidate_sets", "--out", str(a_file), "--no-progress"], capsys)
    assert str(a_file) in line and "cannot create the output folder" in line
    assert a_file.read_text() == "the user's"
