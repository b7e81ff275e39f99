"""`crowdloc reproduce bearing-candidates`: the quick run writes the report, tables and figures."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from agents.cli import build_parser, main
from agents.reproduce import bearing_candidates as bc
from tests.pinning import PINNED_DIR, assert_same_numbers

PAPERS_MD = Path(__file__).resolve().parents[2] / "docs" / "papers.md"


def parse(*argv: str):  # noqa: ANN201
    return build_parser(list(argv)).parse_args(list(argv))


def test_options_and_defaults() -> None:
    args = parse("reproduce", "bearing-candidates")
    assert (args.seeds, args.quick, args.out) == (20, False, Path("results/bearing-candidates"))
    assert 1 <= args.workers <= 2
    with pytest.raises(SystemExit):
        parse("reproduce", "bearing-candidates", "--seeds", "0")


def test_the_default_plan_runs_20_seeds_of_each_experiment() -> None:
    args = parse("reproduce", "bearing-candidates")
    jobs = bc.make_jobs(bc.make_plan(args))
    count = {s: sum(j.study == s for j in jobs) for s in ("exp1", "exp2", "density", "false", "push")}
    assert count == {"exp1": 20, "exp2": 20, "density": 6 * 5, "false": 5 * 5, "push": 10}
    exp2 = next(j for j in jobs if j.study == "exp2")
    assert exp2.env_kwargs["crowd_size"] == 1 and exp2.robot_pose == (0.0, 3.0, 0.0)
    assert {m.key for m in exp2.methods} >= {"candidate_sets", "candidate_sets_k1", "candidate_sets_k5", "kalman"}
    exp1 = next(j for j in jobs if j.study == "exp1")
    proposed = [m for m in exp1.methods if m.localizer == "candidate_sets"]
    assert proposed and all(m.landmarks == (1, 2) for m in proposed)  # L6 and L7 only
    baselines = {m.key for m in bc.BASELINES}
    assert all(m.landmarks is None for m in exp1.methods if m.key in baselines)  # the paper's baselines see L5-L7


def test_paper_values_match_papers_md() -> None:
    text = PAPERS_MD.read_text()
    section = text[text.index("## A.") : text.index("## B.")]
    for exp, rows in bc.PAPER.items():
        for (pm, ps), (hm, hs) in rows.values():
            assert f"{pm:.0f} ± {ps:.0f}" in section or f"{pm:.0f} ± {ps:.0f}".replace(" ± ", " ") in section, exp
            assert f"{hm:.1f} ± {hs:.1f}" in section, exp


def test_quick_run_writes_report_tables_and_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bc"
    assert main(["reproduce", "bearing-candidates", "--quick", "--out", str(out)]) == 0
    report = (out / "report.md").read_text()
    for table in ("(Table 1)", "(Table 2)", "(Table 3)"):
        assert table in report
    # each table row puts the paper's numbers beside ours
    assert "| (5) candidate sets, L6+L7, Exp-1 thresholds | 100 ± 87 |" in report
    assert "| (3) Kalman | 333 ± 163 |" in report
    assert "| (5) candidate sets K=1 | 157 ± 89 |" in report
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    assert len(figures) == 5
    for name in figures:
        assert (out / name).is_file() and (out / name).stat().st_size > 10_000, name
    assert (out / "results.json").is_file()
    # same seeds, same numbers as recorded before the architecture change
    pinned = json.loads((PINNED_DIR / "bearing_candidates_quick.json").read_text())
    assert_same_numbers(pinned, json.loads((out / "results.json").read_text()), "results", frozenset({"wall_s", "workers"}))
    printed = capsys.readouterr().out
    assert "exp1 (2 seeds)" in printed and "wrote" in printed
    # ours are numbers, not n/a, for the method every statistic starts from
    row = next(line for line in report.splitlines() if line.startswith("| (5) candidate sets K=10 |"))
    ours = row.split("|")[3]
    assert np.isfinite(float(ours.split("±")[0]))
