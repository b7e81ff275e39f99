"""`crowdloc reproduce bearing-candidates`: the quick run writes the report, tables and figures."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from agents.cli import build_parser, main
from agents.evaluate import consistency
from agents.papers.bearing_candidates import conditions, jobs
from agents.papers.bearing_candidates.paper import PAPER
from tests.console import assert_aligned, printed_tables
from tests.pinning import PINNED_DIR, assert_same_numbers

PAPERS_MD = Path(__file__).resolve().parents[3] / "docs" / "papers.md"


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
    planned = jobs.make_jobs(jobs.make_plan(args))
    count = {s: sum(j.study == s for j in planned) for s in ("exp1", "exp2", "density", "false", "push")}
    assert count == {"exp1": 20, "exp2": 20, "density": 6 * 5, "false": 5 * 5, "push": 10}
    exp2 = next(j for j in planned if j.study == "exp2")
    assert exp2.env_kwargs["crowd_size"] == 1 and exp2.robot_pose == (0.0, 3.0, 0.0)
    assert {m.key for m in exp2.methods} >= {"candidate_sets", "candidate_sets_k1", "candidate_sets_k5", "kalman"}
    exp1 = next(j for j in planned if j.study == "exp1")
    proposed = [m for m in exp1.methods if m.localizer == "candidate_sets"]
    assert proposed and all(m.landmarks == (1, 2) for m in proposed)  # L6 and L7 only
    baselines = {m.key for m in jobs.BASELINES}
    assert all(m.landmarks is None for m in exp1.methods if m.key in baselines)  # the paper's baselines see L5-L7


def test_the_conditions_come_from_the_configs() -> None:
    from envs.config import load_world
    from localizers.registry import load_params

    planned = jobs.make_jobs(jobs.make_plan(parse("reproduce", "bearing-candidates", "--quick")))
    cond = conditions.conditions(planned)
    static, crowded = load_world("robocup_static"), load_world("robocup_crowded")
    assert cond.worlds["exp1"].odometry_alphas == static.sensors["odometry"].alphas
    assert cond.worlds["exp1"].camera_noise_deg == pytest.approx(np.degrees(static.sensors["camera"].noise_std_rad))
    assert cond.worlds["exp2"].dropout == jobs.EXP2_DROPOUT and cond.worlds["exp2"].crowd == jobs.EXP2_CROWD
    assert cond.worlds["density"].dropout == crowded.sensors["camera"].dropout_probability
    assert cond.shipped.cs_abort_rad == load_params("candidate_sets").abort_error_rad
    assert cond.known_start == ("(1) dead reckoning", "(3) Kalman")
    geo = cond.exp1
    assert geo is not None and (geo.pole.name, [p.name for p in geo.posts]) == ("L5", ["L6", "L7"])
    assert (geo.pole_seen, geo.pole_unseen, geo.far) == ("h-a-b-c-d", "d-e-f-g-h", "d-e-f")
    assert geo.far_m == pytest.approx(7.5) and geo.subtended_deg == pytest.approx(14.93, abs=0.01)


def test_stretches_and_the_expected_eq1_error() -> None:
    names = list("abcdefgh")
    assert conditions.cyclic_stretch(names, [n in "ab" for n in names]) == "h-a-b"
    assert conditions.cyclic_stretch(names, [n in "gha" for n in names]) == "f-g-h-a"
    # n = 2: two |e| terms and one |e1 - e2| term of 1-sigma Gaussian errors
    rng = np.random.default_rng(0)
    e = rng.normal(size=(200_000, 2))
    sampled = np.abs(e).sum(axis=1) + np.abs(e[:, 0] - e[:, 1])
    assert conditions.eq1_error_sigmas(2) == pytest.approx(sampled.mean(), rel=0.01)


def test_paper_values_match_papers_md() -> None:
    text = PAPERS_MD.read_text()
    section = text[text.index("## A.") : text.index("## B.")]
    for exp, rows in PAPER.items():
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
    tables = printed_tables(printed)
    assert [t[0].split("|")[1].strip() for t in tables] == ["exp1 (2 seeds)", "exp2 (2 seeds)"]
    for t in tables:
        assert_aligned(t)
    # the "(ours)" rows (forgetting, not in the paper) beside Tables 1-3: computed by this run, not hard-coded
    results = json.loads((out / "results.json").read_text())
    ours = {"exp1_ours": ["candidate_sets_forgetting"], "exp2_ours": ["candidate_sets_forgetting"],
            "exp3_ours": ["candidate_sets_k1_forgetting", "candidate_sets_k5_forgetting", "candidate_sets_forgetting"]}  # fmt: skip
    assert {k: [r["key"] for r in results[k]] for k in ours} == ours
    for study, rows in ours.items():
        for got, key in zip(results[study], rows):
            assert got["label"].endswith(f"forgetting {jobs.OURS_FORGETTING_S:g} s (ours)")
            assert np.isfinite(got["pos_mm"][0]) and got["seeds"] == 2
            line = next(line for line in report.splitlines() if line.startswith(f"| {got['label']} |"))
            assert line.split("|")[2].strip() == "–"  # no paper column
            assert line.split("|")[3].strip().startswith(f"{got['pos_mm'][0]:.0f} ± ")
            per_seed = results[f"{study[:4]}_per_seed" if study != "exp3_ours" else "exp2_per_seed"][key]
            assert got["pos_mm"][0] == pytest.approx(np.mean([s["position_mm"][0] for s in per_seed]))
    paper_exp1 = next(r for r in results["exp1"] if r["key"] == "candidate_sets")
    assert results["exp1_ours"][0]["pos_mm"] != paper_exp1["pos_mm"]  # forgetting changes the numbers
    assert 'The "(ours)" row is not in the paper' in report
    assert sum(re.search(r"forgetting \S+ s \(ours\) +\|", line) is not None for line in printed.splitlines()) == 1 + 3
    _check_consistency(results, report)
    # ours are numbers, not n/a, for the method every statistic starts from
    row = next(line for line in report.splitlines() if line.startswith("| (5) candidate sets K=10 |"))
    ours = row.split("|")[3]
    assert np.isfinite(float(ours.split("±")[0]))


def _check_consistency(results: dict, report: str) -> None:
    """NEES beside the errors (issue 19): in every row of results.json and in the report, finite where the
    localizer reports a covariance, "no covariance" where it does not (the registry's flag)."""
    from localizers.registry import LOCALIZERS

    has = {m.key: LOCALIZERS[m.localizer].covariance for m in (*jobs.EXP1_METHODS, *jobs.EXP2_METHODS, *jobs.SWEEP_METHODS)}
    lines = report.splitlines()
    heads = [i for i, line in enumerate(lines) if line.endswith("| NEES median | inside 95 % |")]
    assert len(heads) == 3  # Tables 1-3
    for head, studies in zip(heads, (("exp1", "exp1_ours"), ("exp2", "exp2_ours"), ("exp3", "exp3_ours"))):
        rows = [got for study in studies for got in results[study]]
        for got, line in zip(rows, lines[head + 2 : head + 2 + len(rows)], strict=True):
            key, cells = got["key"], line.split("|")
            assert cells[1].strip() == got["label"]
            assert got["covariance"] == has[key], key
            if has[key]:
                assert np.isfinite(got["nees_median"]) and got["nees_median"] > 0, key
                assert 0.0 <= got["inside_95"] <= 1.0 and 0.0 <= got["covariance_missing"] < 1.0, key
            want = consistency.cells(has[key], got["nees_median"], got["inside_95"])
            assert (cells[-3].strip(), cells[-2].strip()) == want, key
    for per_seed in (results["exp1_per_seed"], results["exp2_per_seed"]):
        assert all({"nees_median", "inside_95"} <= set(seed) for rows in per_seed.values() for seed in rows)
    for sweep in ("density", "false"):
        for key, points in results[sweep].items():
            for cell in points.values():
                assert not has[key] or (np.isfinite(cell["nees_median"]) and 0.0 <= cell["inside_95"] <= 1.0), (sweep, key)
    for key, push in results["push"].items():
        for window in ("consistency_before", "consistency_peak"):
            assert not has[key] or push[window]["steps"] > 0, (key, window)
    assert report.count("Cells: NEES median, inside 95 %") == 2  # the two sweeps
    assert "| NEES median before | inside 95 % before | NEES median at the peak | inside 95 % at the peak |" in report
    assert report.count("Consistent: median about 2.37, inside about 95 %") == 6
