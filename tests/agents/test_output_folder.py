"""Output folders keep a manifest of what their command wrote: --overwrite deletes that and nothing
else, another command's folder is refused, and a file the command has no record of stops it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from agents.cli import main
from agents.common.output_folder import MANIFEST_NAME, open_output_folder, read_manifest
from core.schema import ConfigError

PATTERNS = ("report.md", "plots/*.png", "episodes.jsonl")
TINY_EVAL = ["eval", "--policies", "spin", "--localizers", "dead_reckoning", "--crowd-sizes", "0", "--seeds", "1",
             "--episode-steps", "5", "--workers", "1", "--no-gif", "--no-progress"]  # fmt: skip
TINY_BENCHMARK = ["benchmark", "--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "--seeds", "1", "--no-progress",
                  "--workers", "1", "--localizers", "dead_reckoning", "--policies", "spin"]  # fmt: skip


def _run(out: Path, overwrite: bool = False, command: str = "crowdloc thing") -> list[str]:
    with open_output_folder(out, PATTERNS, command=command, overwrite=overwrite) as folder:
        (out / "plots").mkdir(exist_ok=True)
        (out / "report.md").write_text("report")
        (out / "plots" / "a.png").write_text("png")
        folder.record(out / "episodes.jsonl")  # recorded before it exists, as a journal is
        (out / "episodes.jsonl").write_text("{}\n")
    return sorted(folder.recorded)


def test_the_manifest_lists_what_the_command_wrote_and_nothing_else(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    assert _run(out) == ["episodes.jsonl", "plots/a.png", "report.md"]
    (out / "plots" / "mine.png").write_text("the user's")  # after the run: the user's own
    (out / "notes.txt").write_text("the user's")
    doc = read_manifest(out)
    assert doc is not None and doc["command"] == "crowdloc thing"
    assert doc["files"] == ["episodes.jsonl", "plots/a.png", "report.md"]
    assert _run(out, overwrite=True) == ["episodes.jsonl", "plots/a.png", "report.md"]
    assert (out / "plots" / "mine.png").read_text() == "the user's" and (out / "notes.txt").read_text() == "the user's"


def test_a_file_the_manifest_does_not_list_at_an_output_path_stops_the_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    _run(out)
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    manifest["files"].remove("report.md")  # as if the run had been killed before recording it
    (out / MANIFEST_NAME).write_text(json.dumps(manifest))
    with pytest.raises(ConfigError, match=r"report\.md would be replaced, but crowdloc thing has no record of writing it"):
        open_output_folder(out, PATTERNS, command="crowdloc thing", overwrite=True)
    assert (out / "plots" / "a.png").is_file() and (out / "report.md").is_file()  # nothing deleted


def test_a_folder_without_manifest_is_written_into_only_where_nothing_is_in_the_way(tmp_path: Path) -> None:
    out = tmp_path / "out"
    (out / "plots").mkdir(parents=True)
    (out / "notes.txt").write_text("the user's")
    with pytest.raises(ConfigError, match="is not empty \\(notes.txt, plots\\); give --overwrite"):
        open_output_folder(out, PATTERNS, command="crowdloc thing", overwrite=False)
    assert _run(out, overwrite=True) == ["episodes.jsonl", "plots/a.png", "report.md"]  # nothing of its own to delete
    assert (out / "notes.txt").read_text() == "the user's"
    other = tmp_path / "other"
    other.mkdir()
    (other / "report.md").write_text("the user's report")
    with pytest.raises(ConfigError, match="report.md would be replaced"):
        open_output_folder(other, PATTERNS, command="crowdloc thing", overwrite=True)
    assert (other / "report.md").read_text() == "the user's report"


def test_another_commands_folder_is_refused_whatever_the_flags(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    _run(out, command="crowdloc eval")
    for overwrite, resume in ((False, False), (True, False), (False, True)):
        with pytest.raises(ConfigError, match="holds the results of crowdloc eval .* another command's results"):
            open_output_folder(out, PATTERNS, command="crowdloc benchmark", overwrite=overwrite, resume=resume)
    assert read_manifest(out)["command"] == "crowdloc eval"  # type: ignore[index]


def test_what_was_written_before_an_error_is_recorded(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt), open_output_folder(out, PATTERNS, command="crowdloc thing", overwrite=False):
        (out / "report.md").write_text("half")
        raise KeyboardInterrupt
    assert read_manifest(out)["files"] == ["report.md"]  # type: ignore[index]


def test_a_bad_manifest_is_named(tmp_path: Path) -> None:
    (tmp_path / MANIFEST_NAME).write_text("{not json")
    (tmp_path / "x").write_text("")
    with pytest.raises(ConfigError, match="not a readable manifest"):
        open_output_folder(tmp_path, PATTERNS, command="crowdloc thing", overwrite=True)


def test_eval_overwrite_keeps_the_users_files_and_replaces_its_own(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "eval"
    assert main([*TINY_EVAL, "--out", str(out)]) == 0
    (out / "plots" / "mine.png").write_text("the user's")
    (out / "tum" / "mine.tum").write_text("the user's")
    before = read_manifest(out)["files"]  # type: ignore[index]
    assert "episodes.jsonl" in before and "summary.md" in before and "plots/mine.png" not in before
    assert main([*TINY_EVAL, "--out", str(out), "--overwrite"]) == 0
    assert (out / "plots" / "mine.png").read_text() == "the user's" and (out / "tum" / "mine.tum").read_text() == "the user's"
    assert read_manifest(out)["files"] == before  # type: ignore[index]


def test_benchmark_and_eval_refuse_each_others_folders(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    evaluated, benchmarked = tmp_path / "eval", tmp_path / "bench"
    assert main([*TINY_EVAL, "--out", str(evaluated)]) == 0
    assert main([*TINY_BENCHMARK, "--out", str(benchmarked)]) == 0
    capsys.readouterr()
    kept = {p: p.read_bytes() for folder in (evaluated, benchmarked) for p in folder.rglob("*") if p.is_file()}
    for argv in ([*TINY_BENCHMARK, "--out", str(evaluated), "--overwrite"], [*TINY_BENCHMARK, "--out", str(evaluated), "--resume"],
                 [*TINY_EVAL, "--out", str(benchmarked), "--overwrite"], [*TINY_EVAL, "--out", str(benchmarked), "--resume"]):  # fmt: skip
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert "holds the results of crowdloc" in err and "Traceback" not in err
    assert {p: p.read_bytes() for folder in (evaluated, benchmarked) for p in folder.rglob("*") if p.is_file()} == kept
