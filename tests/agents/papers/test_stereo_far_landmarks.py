"""`crowdloc reproduce stereo-far-landmarks`: the plan, the paper's numbers against the shipped configs, the
statistics on hand-made runs, the quick run's report, figures and pinned numbers."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from agents.cli import build_parser, main
from agents.evaluate.consistency import run_nees
from agents.papers.stereo_far_landmarks import analysis, jobs, paper, world
from agents.papers.stereo_far_landmarks import experiment as ex
from tests.console import assert_aligned, printed_tables
from tests.pinning import PINNED_DIR, assert_same_numbers

PINNED = PINNED_DIR / "stereo_far_landmarks_quick.json"


def parse(*argv: str):  # noqa: ANN201
    return build_parser(list(argv)).parse_args(list(argv))


def test_options_and_the_default_plan() -> None:
    args = parse("reproduce", "stereo-far-landmarks")
    assert (args.seeds, args.quick, args.out, args.crowd_sizes) == (10, False, Path("results/stereo-far-landmarks"), None)
    assert 1 <= args.workers <= 2
    plan = ex.make_plan(args)
    assert (plan.seeds, plan.densities, plan.max_steps, plan.crowd) == (10, (0, 30, 60, 100, 150), None, 30)
    quick = ex.make_plan(parse("reproduce", "stereo-far-landmarks", "--quick"))
    assert (quick.seeds, quick.densities, quick.max_steps, quick.quick) == (2, (30, 150), ex.QUICK_STEPS, True)
    # the world's own crowd is always run (the paper's experiment), whatever --crowd-sizes says
    # a list option takes its values separated by spaces, as every list option of every command does
    some = ex.make_plan(parse("reproduce", "stereo-far-landmarks", "--crowd-sizes", "60", "0", "60"))
    assert some.densities == (0, 30, 60)
    assert ex.make_plan(parse("reproduce", "stereo-far-landmarks", "--crowd-sizes", "30", "150")).densities == (30, 150)
    for bad in (["0,30"], ["0", "x"], ["-1"], ["201"], [""], []):
        with pytest.raises(SystemExit):
            parse("reproduce", "stereo-far-landmarks", "--crowd-sizes", *bad)
    with pytest.raises(SystemExit):
        parse("reproduce", "stereo-far-landmarks", "--seeds", "0")


def test_the_shipped_localizer_and_camera_carry_the_papers_numbers() -> None:
    p = world.far_landmark_defaults()
    assert p.n_particles == paper.PARTICLES and p.selection == ex.PAPER_SELECTION
    assert p.sector_rad == pytest.approx(paper.SECTOR_RAD) and p.min_range_m == paper.MIN_RANGE_M
    assert world.camera().baseline_m == paper.BASELINE_M
    assert abs(world.route_length_m() - paper.ROUTE_M) < 2.0
    # a 60 deg camera spans two 30 deg sectors: far emphasis weighs at most two detections a frame
    assert analysis.fov_deg() == pytest.approx(60.0, abs=0.1) and analysis.sectors_in_view() == 2
    a, b = world.turn_arc_m()
    assert 55 < a < b < 65
    assert [name for name, _, _ in ex.places()] == ["place 1 (the start)", "place 2 (after the turn)"]
    assert world.cars_of(30) == 3 and world.cars_of(150) == 15 and world.cars_of(0) == 0


def test_arc_length_along_the_route() -> None:
    route = world.route()
    pts = np.array([[110.0, 31.0], [100.0, 31.5], [53.0, 30.0], [50.0, 40.0], [49.0, 71.0], [120.0, 31.0]])
    arc = jobs.arc_length(pts, route)
    a, b = world.turn_arc_m()
    np.testing.assert_allclose(arc[[0, 1, 2, 5]], [0.0, 10.0, 57.0, 0.0], atol=1e-9)  # before the start: clamped to 0
    assert arc[3] == pytest.approx(b + 6.0) and arc[4] == pytest.approx(world.route_length_m())


SD_M = 0.3  # the position sd the hand-made runs' localizers report


def hand_episode(seed: int, crowd: int, errors: dict[str, list[float]], used: list[int] | None = None) -> jobs.Episode:
    """A run whose localizers are ``errors[key]`` m east of a truth standing at the origin (NaN: no pose)."""
    t = len(next(iter(errors.values())))
    truth = np.zeros((t, 3))
    est = {}
    for key in ex.KEYS:
        e = np.zeros((t, 3))
        e[:, 0] = errors.get(key, [0.0] * t)
        est[key] = np.where(np.isnan(e[:, :1]), np.nan, e)
    u = np.asarray(used if used is not None else [2] * t, dtype=np.int64)
    cov = np.broadcast_to(np.diag([SD_M**2, SD_M**2, 0.01]), (t, 3, 3))  # every localizer claims 0.3 m
    nees = {key: run_nees("far_landmark_pf", est[key], truth, cov) for key in ex.KEYS}
    return jobs.Episode(seed, crowd, 0.1 * np.arange(t), truth, np.zeros(t), est, np.full(t, 96), np.full(t, 90), u, np.zeros(t, dtype=np.int64), 0.0, True, 0,
                        0.0, nees=nees)  # fmt: skip


def test_failures_lost_steps_and_the_distance_to_the_reference_on_a_hand_made_run() -> None:
    ep = hand_episode(0, 30, {"farthest": [0.2, 1.0, float("nan"), 0.4], "reference": [0.1, 0.1, 0.1, float("nan")]})
    r = analysis.run_stats(ep, "farthest")
    assert r.failure_share == pytest.approx(0.25)  # 1.0 m counts: ">= 1 m"
    assert r.lost_share == pytest.approx(0.25) and r.bad_share == pytest.approx(0.5)
    assert r.mean_m == pytest.approx(np.mean([0.2, 1.0, 0.4])) and r.max_m == pytest.approx(1.0)
    assert r.diff_max_m == pytest.approx(0.9) and r.diff_mean_m == pytest.approx(0.5)  # where both have a pose
    ref = analysis.run_stats(ep, "reference")
    assert math.isnan(ref.diff_max_m) and ref.lost_share == pytest.approx(0.25)
    s = analysis.summarize([ep, hand_episode(1, 30, {"farthest": [0.0] * 4})], "farthest")
    assert s.runs == 2 and s.runs_failing == 1 and s.failure_share == pytest.approx(1 / 8) and s.fails
    assert s.mean_m == pytest.approx((r.mean_m + 0.0) / 2) and s.diff_run_max_m == pytest.approx((0.9, 0.0))
    # consistency over the 7 steps with a pose: NEES (e / 0.3 m)^2 = 0.44, 11.1, 1.78 and four 0; 11.1 > 7.81 is outside
    assert s.inside_95 == pytest.approx(6 / 7) and s.nees_median == 0.0 and s.covariance_missing == 0.0
    with pytest.raises(ValueError, match="no episodes"):
        analysis.summarize([], "farthest")


def test_paired_comparison_and_its_interval() -> None:
    eps = [hand_episode(s, 60, {"farthest": [0.1 + 0.01 * s] * 5, "all": [0.3] * 5}) for s in range(6)]
    p = analysis.paired(eps, "farthest", "all", 60, 0)
    assert p.a_better == 6 and p.mean_m == pytest.approx(np.mean([0.1 + 0.01 * s - 0.3 for s in range(6)]))
    assert p.ci_m[1] < 0 and p.resolved == -1
    again = analysis.paired(eps, "farthest", "all", 60, 0)
    assert again == p  # same seeds, same interval
    g = analysis.growth(
        eps + [hand_episode(s, 0, {"farthest": [0.1] * 5, "all": [0.1] * 5}) for s in range(6)], "farthest", "all"
    )
    assert g is not None and (g.low, g.high) == (0, 60) and g.growth_b_m == pytest.approx(0.2) and g.difference_ci_m[1] < 0


def test_few_landmarks_stretches_and_the_correction_after_a_peak() -> None:
    used = [2] * 40 + [0] * 30 + [2] * 60
    drift = [0.05] * 40 + [0.05 + 0.02 * k for k in range(30)] + [0.65 - 0.02 * k for k in range(30)] + [0.05] * 30
    ep = hand_episode(0, 30, {"farthest": drift, "reference": [0.0] * 130}, used)
    mask = analysis.sparse_mask(ep)
    window = round(ex.SPARSE_WINDOW_S / 0.1)
    assert not mask[:40].any() and mask[40 + window - 1 : 70].all() and not mask[-1]
    ws = analysis.weak_spot([ep], 30)
    assert ws.rate_sparse_mps > 0.0 > ws.rate_rich_mps  # it grows in the stretch, falls after it
    assert ws.corrected == (True,) and 0 < ws.correction_s[0] <= ex.CORRECTION_S
    assert ws.peaks_m[0] == pytest.approx(np.mean(drift[65:76]), abs=1e-9)  # the 1 s mean around the peak
    v = analysis._c2(ws)
    assert v.verdict == "holds" and analysis._c3(ws).verdict == "holds"
    flat = analysis.weak_spot([hand_episode(0, 30, {"farthest": drift, "reference": [0.0] * 130})], 30)
    assert flat.sparse_share == 0.0 and analysis._c2(flat).verdict == "not testable here"


def _check_report(out: Path) -> str:
    report = (out / "report.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    names = {"fig10_difference.png", "fig8_place1.png", "fig9_place2.png", "detections_route.png", "crowd_error.png",
             "crowd_failures.png"}  # fmt: skip
    assert names <= set(figures)
    for name in figures:
        assert (out / name).is_file() and (out / name).stat().st_size > 10_000, name
    for i in range(1, 8):
        assert re.search(rf"^\| C{i} \| .* \| \*\*(holds|partly holds|does not hold|not testable here)\*\* \|$", report, re.M), i
    # the paper's numbers beside ours, filled from paper.py and the configs
    assert (
        f"within about **{paper.MAX_DIFFERENCE_M:g} m**" in report
        and f"{paper.PARTICLES} particles (paper: {paper.PARTICLES})" in report
    )
    assert "largest difference 0 m over every step" in report  # the replayed reference is the one that drove
    heads = [line for line in report.splitlines() if line.startswith("| crowd | localizer |")]
    assert len(heads) == 1 and "failed steps" in heads[0] and "availability" in heads[0]
    rows = [line for line in report.splitlines() if line.startswith("| 30 (27 pedestrians, 3 cars) |")]
    assert len(rows) == len(ex.KEYS)
    paired = [line for line in report.splitlines() if re.match(r"^\| (30|150) \| farthest - all \|", line)]
    assert len(paired) == 2 and all(re.search(r"\[[+-]\d\.\d{3}, [+-]\d\.\d{3}\]", line) for line in paired)
    assert "## Detections along the route" in report and "## Differences from the paper" in report
    return report


def test_quick_run_writes_report_and_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "quick"
    assert main(["reproduce", "stereo-far-landmarks", "--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    _check_report(out)
    tables = printed_tables(printed)
    assert [t[0].split("|")[1].strip() for t in tables] == ["crowd", "claim"]
    for t in tables:
        assert_aligned(t)
    results = json.loads((out / "results.json").read_text())
    assert results["identity_max_difference_m"] == 0.0
    assert [v["id"] for v in results["verdicts"]] == [f"C{i}" for i in range(1, 8)]
    assert len(results["fig10"]) == 2 and len(results["runs"]) == 4 * len(ex.KEYS)
    # same seeds, same numbers
    pinned = json.loads(PINNED.read_text())
    assert_same_numbers(pinned, results, "results", frozenset({"timing"}))
    # a report is never overwritten unasked (refused before any work)
    with pytest.raises(SystemExit):
        main(["reproduce", "stereo-far-landmarks", "--quick", "--out", str(out)])
    assert "--overwrite" in capsys.readouterr().err


def test_the_replayed_filter_knows_the_recorded_cameras_frame_gap_as_gym_make_gives_it() -> None:
    """The reproduction's far_landmark_pf allows for the shift a turn causes between the webcams' frames,
    as the one ``gym.make`` builds does (one helper, ``rig_timing``, for both)."""
    rec, _ = jobs.record_run(seed=0, crowd_size=0, max_steps=10)
    scenes = jobs.make_map(jobs.map_tasks(ex.Plan(seeds=1, densities=(0,), max_steps=20))[0]).scenes
    pf = jobs.far_landmark_pf(rec, scenes, "farthest")
    camera = rec.sensors[world.camera_name()]
    assert pf._params.frame_gap_s == camera["frame_gap_s"] == pytest.approx(1.0 / 30.0)
    assert pf._params.baseline_m == camera["baseline_m"]
    assert pf._params.selection == "farthest"
