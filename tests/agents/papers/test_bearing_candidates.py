"""`crowdloc reproduce bearing-candidates`: the quick run writes the report, tables and figures."""

from __future__ import annotations

import json
import math
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
    _check_the_paper_measure(results, report, printed)
    # ours are numbers, not n/a, for the method every statistic starts from
    row = next(line for line in report.splitlines() if line.startswith("| (5) candidate sets K=10 |"))
    ours = row.split("|")[3]
    assert np.isfinite(float(ours.split("±")[0]))


def _check_the_paper_measure(results: dict, report: str, printed: str) -> None:
    """Exp 1 also on the paper's measure: every Table 1 row and "(ours)" row, the true error beside it
    equal to Table 1's, the claims judged on it, in the report and on stdout."""
    from agents.papers.bearing_candidates.report import PATH_MEASURE, TRUE_MEASURE

    table1 = {r["key"]: r for r in results["exp1"] + results["exp1_ours"]}
    assert [r["key"] for r in results["exp1_path"]] == [m.key for m in jobs.EXP1_METHODS]
    for got in results["exp1_path"]:
        assert got["true"]["mm"] == pytest.approx(table1[got["key"]]["pos_mm"], rel=1e-12)  # the same steps as Table 1
        assert 0.0 <= got["path"]["mm"][0] <= got["true"]["mm"][0]  # the distance to the line never exceeds the error
        line = next(line for line in report.splitlines() if line.startswith(f"| {got['label']} |") and line.count("[") == 2)
        assert line.split("|")[3].strip().startswith(f"{got['path']['mm'][0]:.0f} ± ")
    assert f"| {PATH_MEASURE} [mm] |" in report and f"| {TRUE_MEASURE} [mm] |" in report
    assert [c["claim_id"] for c in results["exp1_claims"]] == ["E1a", "E1b"]
    for c in results["exp1_claims"]:
        row = next(line for line in report.splitlines() if line.startswith(f"| {c['claim_id']} |")).split("|")
        assert (row[3].strip(), row[5].strip()) == (f"**{c['path']['outcome']}**", f"**{c['true']['outcome']}**")
    assert "to drawn path mm" in printed


def _check_consistency(results: dict, report: str) -> None:
    """NEES beside the errors: in every row of results.json and in the report, finite where the
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


# ------------------------------------------------------------------------------------ Exp 1 on the paper's measure


def test_distance_to_a_polyline_analytically() -> None:
    from core.geometry import polyline_distance

    square = [(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]
    # on a segment: 0; beyond an end: the distance to that end point (the projection is clipped)
    assert polyline_distance([1.0, 0.0], square, closed=True) == 0.0
    assert polyline_distance([[3.0, -1.0], [-0.6, -0.8]], square, closed=True) == pytest.approx([math.sqrt(2.0), 1.0])
    assert polyline_distance([5.0, 0.0], [(0.0, 0.0), (2.0, 0.0)], closed=False) == pytest.approx(3.0)
    # inside the closed polygon: the nearest side (0.3 from the bottom, 0.5 from the left)
    assert polyline_distance([[1.0, 0.3], [0.5, 1.2]], square, closed=True) == pytest.approx([0.3, 0.5])
    # open, the closing side d-a is not there: (0, 1) is 1 from the rest
    assert polyline_distance([0.0, 1.0], square, closed=False) == pytest.approx(1.0)
    assert polyline_distance([0.0, 1.0], square, closed=True) == 0.0
    assert np.isnan(polyline_distance([np.nan, 1.0], square, closed=True))
    assert polyline_distance([1.0, 1.0], [(0.0, 0.0)], closed=False) == pytest.approx(math.sqrt(2.0))  # one vertex
    with pytest.raises(ValueError, match="vertices_xy"):
        polyline_distance([0.0, 0.0], [0.0, 1.0, 2.0], closed=True)
    # the metric: an (T, 3) estimate series, NaN rows stay NaN, the heading plays no part
    from agents.evaluate import metrics

    est = np.array([[1.0, 0.3, 2.0], [np.nan, np.nan, np.nan], [2.5, 1.0, -1.0]])
    got = metrics.path_distances(est, square, closed=True)
    assert got[0] == pytest.approx(0.3) and np.isnan(got[1]) and got[2] == pytest.approx(0.5)


def _hand_made_exp1(seeds: int = 3) -> list:
    """Exp 1 runs along the leg a-b: (5) sits on the line 0.3 m ahead of the robot, the Kalman filter
    0.1 m beside it, the paper's MCL 0.2 m beside it (each offset 1 % longer per seed, so that the seeds differ)."""
    from types import SimpleNamespace

    a, b = jobs.EXP1_DRAWN_PATH[0], jobs.EXP1_DRAWN_PATH[1]
    assert a[1] == b[1] and b[0] - a[0] > 0.8  # a-b runs along +x
    x = np.linspace(a[0] + 0.1, a[0] + 0.5, 50)
    truth = np.column_stack([x, np.full_like(x, a[1]), np.zeros_like(x)])
    offsets = {"candidate_sets": (0.3, 0.0), "kalman": (0.0, 0.1), "mcl_bearing_paper": (0.0, 0.2)}
    results = []
    for s in range(seeds):
        runs = {}
        for key, (dx, dy) in offsets.items():
            est = truth + np.array([dx, dy, 0.0]) * (1.0 + 0.01 * s)
            runs[key] = SimpleNamespace(estimates=est, valid=np.ones(x.size, dtype=bool),
                                        position_error_m=np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1]))  # fmt: skip
        results.append(SimpleNamespace(runs=runs, truth=truth, job=SimpleNamespace(seed=s)))
    return results


def test_on_the_line_but_far_along_it_the_paper_measure_and_the_true_error_differ() -> None:
    from agents.papers.bearing_candidates import analysis

    results = _hand_made_exp1()
    methods = [m for m in jobs.EXP1_TABLE_METHODS if m.key in ("kalman", "mcl_bearing_paper", "candidate_sets")]
    rows = {r.key: r for r in analysis.path_rows(results, methods, analysis.references(methods))}
    assert rows["candidate_sets"].path.mm == pytest.approx((0.0, 0.0), abs=1e-9)  # on the line ...
    assert rows["candidate_sets"].true.mm[0] == pytest.approx(303.0)  # ... 0.3 m (+ 1 % on average) along it
    assert rows["kalman"].path.mm[0] == pytest.approx(101.0) and rows["kalman"].true.mm[0] == pytest.approx(101.0)
    lo, hi = rows["kalman"].path.ci_mm
    assert 99.9 < lo < 101.0 < hi < 102.1 and rows["kalman"].path.seeds == 3  # within the seeds' 100, 101, 102
    assert analysis.robot_off_path(results).mm[0] == pytest.approx(0.0, abs=1e-9)
    # the paper's claims judged on its measure: (5) beats the Kalman filter there, not on the true error
    claims = {c.baseline: c for c in analysis.exp1_claims(results)}
    kf, mcl = claims["kalman"], claims["mcl_bearing_paper"]
    assert (kf.path.outcome, kf.true.outcome) == ("holds", "does not hold")
    assert kf.path.mean_mm == pytest.approx(-101.0) and kf.true.mean_mm == pytest.approx(202.0)
    assert (mcl.path.outcome, mcl.true.outcome) == ("holds", "does not hold")
    assert analysis.difference([1.0, 2.0], [1.5, 1.5]).outcome == "not separated"


def test_the_report_shows_both_measures_and_judges_the_claims_on_the_paper_measure() -> None:
    from agents.papers.bearing_candidates import analysis, report

    results = _hand_made_exp1()
    methods = [m for m in jobs.EXP1_TABLE_METHODS if m.key in ("kalman", "mcl_bearing_paper", "candidate_sets")]
    exp1 = analysis.Exp1Stats(rows=[], per_seed={}, seeds=3, path_m=0.4, all_in_view=1.0, ours_rows=[],
                              path_rows=analysis.path_rows(results, methods, analysis.references(methods)),
                              robot_off_path=analysis.robot_off_path(results), claims=analysis.exp1_claims(results))  # fmt: skip
    lines = report.measures_section(exp1)
    head = next(line for line in lines if line.startswith("| method |"))
    assert "| paper's measure: distance to the drawn path [mm] |" in head and "| error against the true pose [mm] |" in head
    cs = next(line for line in lines if line.startswith("| (5) candidate sets, L6+L7, Exp-1 thresholds |")).split("|")
    assert [c.strip() for c in cs[2:4]] == ["100 ± 87", "0 ± 0"] and cs[6].strip().startswith("303 ± ")
    claim_head = next(line for line in lines if line.startswith("| # |")).split("|")
    assert "verdict (paper's measure: distance to the drawn path)" in claim_head[3]
    e1a = next(line for line in lines if line.startswith("| E1a |")).split("|")
    assert [c.strip() for c in e1a[3:5]] == ["**holds**", "-101 [-102, -100]"]
    assert e1a[5].strip() == "**does not hold**" and e1a[6].strip().startswith("+202 [")
    text = "\n".join(lines)
    assert "Ranked on the paper's measure (mm): (5) candidate sets, L6+L7, Exp-1 thresholds 0 < (3) Kalman 101" in text
    assert "so here the two measures differ by the error along the line only" in text
