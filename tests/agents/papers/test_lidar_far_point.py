"""`crowdloc reproduce lidar-far-point`: the square path, the update count, failures, the replay shortcut, the
reference pose of the second LIDAR, the report."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from agents.cli import build_parser, main
from agents.evaluate import consistency, metrics
from agents.experiments.replay import Recording, record, replay
from agents.experiments.scenarios import square_driver
from agents.papers.lidar_far_point import analysis, jobs, paper, world
from agents.papers.lidar_far_point import experiment as ex
from agents.policies.paths import square_vertices
from core.geometry import wrap_angle
from tests.console import assert_aligned, printed_tables
from tests.pinning import PINNED_DIR, assert_same_numbers

NOISE_FREE = {"odometry": {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0}, "lidar": {"range_std_m": 0.0}}


def parse(*argv: str):  # noqa: ANN201
    return build_parser(list(argv)).parse_args(list(argv))


def square_lap(**kwargs: object) -> Recording:
    """One lap of the experiment's square in the empty room."""

    def make(env):  # noqa: ANN001, ANN202
        return square_driver(env, center_xy=ex.CENTER_XY, side_m=ex.SIDE_M, laps=1, speed_mps=ex.SPEED_MPS,
                             turn_rate_rps=ex.TURN_RATE_RPS)  # fmt: skip

    steps = ex.episode_steps(1)
    return record(ex.ENV_ID, make, seed=0, max_steps=steps + 10, env_kwargs={**ex.env_kwargs(0, steps + 10), **kwargs},
                  reset_options={"robot_pose": list(ex.start_pose())})  # fmt: skip


@pytest.fixture(scope="module")
def lap() -> Recording:
    return square_lap(**NOISE_FREE)


def test_the_square_closes_its_loop_and_passes_its_corners(lap: Recording) -> None:
    truth = lap.true_pose
    corners = square_vertices(ex.CENTER_XY, ex.SIDE_M)
    for corner in corners:
        assert np.min(np.hypot(*(truth[:, :2] - corner).T)) < 0.005, corner
    start = np.asarray(ex.start_pose())
    np.testing.assert_allclose(truth[0], start, atol=1e-9)
    assert np.hypot(*(truth[-1, :2] - start[:2])) < 0.005
    assert abs(float(wrap_angle(truth[-1, 2] - start[2]))) < math.radians(0.5)
    # straight sides: the path never leaves the square's outline by more than 5 mm
    x, y = truth[:, 0], truth[:, 1]
    lo, hi = corners[0][0], corners[2][0]
    off = np.minimum.reduce([np.abs(x - lo), np.abs(x - hi), np.abs(y - lo), np.abs(y - hi)])
    assert off.max() < 0.005
    assert lap.contacts.sum() == 0
    assert lap.lidar is not None and lap.lidar.shape == (lap.steps, 1081)


def test_square_driver_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="side_m"):
        square_vertices((0.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="laps"):
        square_driver(None, center_xy=(0.0, 0.0), side_m=1.0, laps=0, speed_mps=0.1, turn_rate_rps=0.5)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["mcl_lidar", "far_point_mcl"])
def test_one_estimate_per_half_metre_of_travel(lap: Recording, name: str) -> None:
    params = ex.Config(False, ex.PASS_PARAMS).mcl_params()
    out = replay(lap, name, rng_seed=0, params=params if name == "mcl_lidar" else {"mcl": params}, read="updates",
                 sensor=world.lidar_name())  # fmt: skip
    assert out.updated is not None and out.updated[0]  # the first scan is weighed
    per_lap = int(out.updated[1:].sum())
    assert abs(per_lap - 4 * ex.SIDE_M / ex.UPDATE_TRAVEL_M) <= 1
    # no update while turning in place: each update is ~0.5 m of path after the previous one
    gaps = np.diff(metrics.travelled(lap.true_pose)[out.updated])
    assert np.all((gaps >= 0.5) & (gaps < 0.51))
    err = metrics.position_errors(out.estimates[out.updated], lap.true_pose[out.updated])
    # the empty room, exact odometry: both track the square, within what the map's table (20 cm
    # from where it stands) costs
    assert np.max(err) < 0.2


def test_failure_count_on_hand_made_errors() -> None:
    errors = np.array([0.2, 1.0, 0.999, 3.5, np.nan, 1.2])
    assert metrics.failure_count(errors) == 3  # 1.0 counts: "1 m or more"
    assert metrics.failure_count(errors, threshold=3.0) == 1
    assert metrics.failure_count([]) == 0

    def run(seed: int, errs: list[float]) -> jobs.Run:
        e = np.asarray(errs)
        head = np.full(e.size, math.radians(90.0))
        return jobs.Run("k", seed, 16, np.zeros((e.size, 3)), e, head, 2 * e, head / 2, np.full(e.size, np.nan))

    s = analysis.stats_of([run(0, [0.1, 0.3, 1.5, 4.0]), run(1, [0.1, 0.1, 0.1, 0.1]), run(2, [0.2, 1.0, 0.2, 0.2])])
    assert (s.runs, s.estimates, s.failures_total, s.large_total, s.failed_runs) == (3, 4, 3, 1, 2)
    assert s.failures == pytest.approx(1.0) and s.failures_sd == pytest.approx(1.0)
    assert s.failure_rate == pytest.approx(3 / 12) and not s.works
    assert s.mean_m == pytest.approx(np.mean([0.1, 0.3, 1.5, 4.0, 0.1, 0.1, 0.1, 0.1, 0.2, 1.0, 0.2, 0.2]))
    assert s.failure_heading_deg == pytest.approx(90.0)
    assert analysis.stats_of([run(0, [0.1] * 200)]).works
    # against the reference: the same statistics of the errors against it (here twice the truth's)
    r = analysis.stats_of([run(0, [0.1, 0.3, 1.5, 4.0]), run(1, [0.1, 0.1, 0.1, 0.1]), run(2, [0.2, 1.0, 0.2, 0.2])],
                          "reference")  # fmt: skip
    assert (r.failures_total, r.large_total, r.failed_runs) == (3, 2, 2)  # 0.6 and 0.4 stay below 1 m; 3.0 is large
    assert r.mean_m == pytest.approx(2 * s.mean_m) and r.failure_heading_deg == pytest.approx(45.0)
    with pytest.raises(ValueError, match="against"):
        analysis.stats_of([run(0, [0.1])], "odometry")  # type: ignore[arg-type]


def test_options_and_the_default_plan() -> None:
    args = parse("reproduce", "lidar-far-point")
    assert (args.seeds, args.quick, args.out) == (10, False, Path("results/lidar-far-point"))
    assert 1 <= args.workers <= 2
    plan = ex.make_plan(args)
    assert (plan.seeds, plan.laps, plan.densities) == (10, 3, (0, 8, 16, 24, 30))
    assert plan.samplings == pytest.approx([0.1 * k for k in range(1, 11)])
    assert plan.hits == pytest.approx([0.1 * k for k in range(1, 11)])
    keys = [c.key for c in plan.main_configs()]
    assert len(keys) == len(set(keys))
    # 10 + 10 values with and without far points, (0.1, 0.2) shared, two AMCL rows, the density pair
    assert len(keys) == 2 * (10 + 10 - 1 + 2 + 1)
    # every episode is recorded with the reference LIDAR: the room LIDAR's format at the paper's height
    top = ex.env_kwargs(16, 100)["sensors"][ex.REFERENCE_SENSOR]
    lidar = world.lidar()
    assert top["height_m"] == paper.REFERENCE_LIDAR_HEIGHT_M and top["key"] == ex.REFERENCE_SENSOR
    assert (top["fov_rad"], top["beams"], top["max_range_m"], top["range_std_m"]) == (
        lidar.fov_rad, lidar.beams, lidar.max_range_m, lidar.range_std_m,
    )  # fmt: skip
    assert all(c.mcl_params()["update_min_rotation_rad"] >= 2 * math.pi for c in plan.main_configs())
    quick = ex.make_plan(parse("reproduce", "lidar-far-point", "--quick"))
    assert (quick.seeds, quick.laps, len(quick.samplings), len(quick.hits), len(quick.densities)) == (2, 1, 3, 3, 3)
    with pytest.raises(SystemExit):
        parse("reproduce", "lidar-far-point", "--seeds", "0")


@pytest.fixture
def small_square(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 1 m square: episodes of ~1000 steps (speed only; the experiment's geometry is tested above)."""
    monkeypatch.setattr(ex, "SIDE_M", 1.0)
    monkeypatch.setattr(ex, "SPEED_MPS", 0.3)


def test_replaying_stored_update_scans_equals_the_registered_localizers(small_square: None) -> None:
    ep = jobs.run_episode(jobs.EpisodeTask(seed=3, crowd_size=16, laps=1))
    configs = (*ex.both((("sampling", 0.7), ("hit_std_m", 0.8))), *ex.both(ex.PASS_PARAMS))
    runs = {r.key: r for r in jobs.run_chunk(jobs.ChunkTask(ep, configs))}
    # the same episode, recorded again with every LIDAR scan, replayed the ordinary way
    steps = ex.episode_steps(1)
    full = record(ex.ENV_ID, ex.driver_factory(1), 3, max_steps=steps + 10, env_kwargs=ex.env_kwargs(16, steps + 10),
                  reset_options={"robot_pose": list(ex.start_pose())})  # fmt: skip
    np.testing.assert_array_equal(full.true_pose, ep.recording.true_pose)
    assert ep.update_steps.size >= 8
    # the episode keeps neither LIDAR's leaves (the update scans are stored apart)
    assert ep.recording.sensor_of("lidar") is None and set(full.sensors) - set(ep.recording.sensors) == {"lidar", "lidar_top"}
    lidar = world.lidar_name()
    for c in configs:
        name = "far_point_mcl" if c.far else "mcl_lidar"
        params = {"mcl": c.mcl_params()} if c.far else c.mcl_params()
        out = replay(full, name, rng_seed=[3, 16, ex.RNG_SALT], params=params, read="updates", sensor=lidar)
        assert out.updated is not None
        np.testing.assert_array_equal(np.flatnonzero(out.updated), ep.update_steps)
        np.testing.assert_array_equal(out.estimates[ep.update_steps], runs[c.key].estimates)
        # and the same consistency: a far-point replay adds the window's odometry noise as far_point_mcl does
        truth_k = full.true_pose[ep.update_steps]
        nees = consistency.run_nees(name, out.estimates[ep.update_steps], truth_k, out.covariances[ep.update_steps])
        np.testing.assert_allclose(runs[c.key].nees, nees, rtol=1e-9)
        ref_err = metrics.position_errors(runs[c.key].estimates, ep.reference_estimates)
        np.testing.assert_array_equal(runs[c.key].ref_errors_m, ref_err)
    assert jobs.pass_identity([ep], list(runs.values())) == 0.0
    # the reference pose: mcl_lidar on the 1.9 m scans (its map cut at 1.9 m), the same update steps
    assert full.sensors[ex.REFERENCE_SENSOR]["height_m"] == paper.REFERENCE_LIDAR_HEIGHT_M
    seed = [3, 16, ex.REFERENCE_RNG_SALT]
    top = replay(full, "mcl_lidar", rng_seed=seed, params=ex.reference_mcl_params(), read="updates", sensor=ex.REFERENCE_SENSOR)
    assert top.updated is not None
    np.testing.assert_array_equal(np.flatnonzero(top.updated), ep.update_steps)
    np.testing.assert_array_equal(top.estimates[ep.update_steps], ep.reference_estimates)
    low = replay(full, "mcl_lidar", rng_seed=seed, params=ex.reference_mcl_params(), read="updates", sensor=lidar)
    assert not np.array_equal(low.estimates[ep.update_steps], ep.reference_estimates)  # not the 0.2 m LIDAR's
    truth = full.true_pose[ep.update_steps]
    assert np.max(metrics.position_errors(ep.reference_estimates, truth)) < 0.3  # above the crowd it tracks the truth
    (ref_run,) = jobs.reference_runs([ep])
    np.testing.assert_array_equal(ref_run.errors_m, metrics.position_errors(ep.reference_estimates, truth))
    # the processing changes what MCL sees: far-point scans differ from the raw ones
    assert not np.array_equal(ep.far_scans, ep.raw_scans.astype(np.float64))


def test_the_empty_room_of_the_beam_statistic_is_the_true_room() -> None:
    """The beams "on the wall" are cast against the room's segments where they stand at the LIDAR's height,
    not against the map, which has the table 20 cm from where it stands."""
    h = world.lidar().height_m
    true_walls = world.true_walls_at(h)
    mapped = world.room().static_segments(in_map=True)
    mapped = mapped[(mapped[:, 4] <= h) & (h < mapped[:, 5]), :4]
    assert true_walls.shape == mapped.shape
    moved = np.any(true_walls != mapped, axis=1)
    assert moved.sum() == 16  # the four legs of the table, four sides each
    table = next(f for f in world.room().furniture if f.name == "table")
    np.testing.assert_allclose(mapped[moved] - true_walls[moved], np.tile(table.map_offset_m, 2)[None].repeat(16, 0))
    # at the reference's height: the walls, the door, the bevel and the pillar; neither the shelf nor the table
    assert world.true_walls_at(paper.REFERENCE_LIDAR_HEIGHT_M).shape == (10, 4)
    assert world.furniture_text(paper.REFERENCE_LIDAR_HEIGHT_M, seen=False) == "the shelf (1.8 m) and the table (0.72 m)"


def _check_report(out: Path, printed: str) -> str:
    report = (out / "report.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    names = {"sampling_error.png", "sampling_failures.png", "hit_error.png", "hit_failures.png", "far_points.png",
             "density_error.png", "density_failures.png", "trajectories.png"}  # fmt: skip
    assert names <= set(figures)
    for name in figures:
        assert (out / name).is_file() and (out / name).stat().st_size > 10_000, name
    assert (out / "results.json").is_file()
    for i in range(1, 8):
        assert re.search(rf"\| C{i} \| .* \| \*\*(holds|partly holds|does not hold)\*\* \|", report), i
    assert "AMCL-like" in report and "Crowd size" in report
    assert "wrote" in printed or "MCL runs" in printed
    # both yardsticks in every sweep table, the verdicts on the paper's measure, the reference's own error
    heads = [line for line in report.splitlines() if line.startswith("| sampling |") or line.startswith("| hit [m] |")]
    assert len(heads) == 2
    for head in heads:
        assert head.count("error vs reference [m]") == 2 and head.count("error vs truth [m]") == 2
        assert head.count("failures / run vs reference") == 2
    assert "| verdict (vs reference) | vs truth |" in report
    assert "Reference (the paper's): a second LIDAR at 1.9 m" in report and "Its own error against the truth" in report
    assert "the simulator's true pose (the paper localized" not in report  # the old reference item
    assert "exact square with an exact map" not in report
    results = json.loads((out / "results.json").read_text())
    assert results["verdict_measure"] == "reference"
    assert set(results["stats_vs_reference"]) == set(results["stats"])
    assert [v["against"] for v in results["verdicts"]] == ["reference"] * 7
    assert [v["against"] for v in results["verdicts_vs_truth"]] == ["truth"] * 7
    assert str(ex.CROWD_SIZE) in results["reference"]
    return report


def test_quick_run_writes_report_and_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "quick"
    assert main(["reproduce", "lidar-far-point", "--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    report = _check_report(out, printed)
    tables = printed_tables(printed)  # the sampling sweep, the hit sweep, the claims
    assert [t[0].split("|")[1].strip() for t in tables] == ["sampling", "hit", "claim"]
    for t in tables:
        assert_aligned(t)
    for t in tables[:2]:
        assert "raw: error vs ref m" in t[0] and "far: error vs truth m" in t[0]
    # same seeds, same numbers as recorded before the architecture change
    pinned = json.loads((PINNED_DIR / "lidar_far_point_quick.json").read_text())
    assert_same_numbers(pinned, json.loads((out / "results.json").read_text()), "results", frozenset({"wall_s", "workers"}))
    count = int(re.search(r"\*\*(\d+)[/\d]* estimates per run\*\*", report).group(1))  # type: ignore[union-attr]
    assert abs(count - 1 - 4 * ex.SIDE_M / ex.UPDATE_TRAVEL_M) <= 1  # one lap, plus the estimate at the start
    row = next(line for line in report.splitlines() if line.startswith("| 0.1 |"))
    assert np.isfinite(float(row.split("|")[2].split("±")[0]))  # numbers, not n/a
    _check_consistency(json.loads((out / "results.json").read_text()), report)


def _check_consistency(results: dict, report: str) -> None:
    """NEES against the truth beside the errors: per configuration and crowd size, per run, for the
    reference; numbers over every estimate (both localizers report a covariance; a singular one
    counts, as inf) and in the report's consistency tables."""
    from localizers.registry import LOCALIZERS

    assert LOCALIZERS["mcl_lidar"].covariance and LOCALIZERS["far_point_mcl"].covariance
    assert set(results["consistency"]) == set(results["stats"])
    for key, fit in results["consistency"].items():
        # a number, or None in the JSON for inf: over half the updates left a collapsed (singular) particle set
        assert (fit["nees_median"] is None or fit["nees_median"] >= 0.0) and 0.0 <= fit["inside_95"] <= 1.0, key
        estimates = sum(len(r["errors_m"]) for r in results["runs"] if f"{r['key']}@{r['crowd_size']}" == key)
        assert fit["steps"] > 0 and fit["steps"] + fit["excluded"] == estimates, key  # every estimate asked for
    assert set(results["reference_consistency"]) == set(results["reference"])
    assert all(f["nees_median"] is None or f["nees_median"] >= 0.0 for f in results["reference_consistency"].values())
    assert all((r["nees_median"] is None or r["nees_median"] >= 0.0) and 0.0 <= r["inside_95"] <= 1.0 for r in results["runs"])
    assert all(ep["reference_nees_median"] is None or ep["reference_nees_median"] >= 0.0 for ep in results["episodes"])
    lines = report.splitlines()
    heads = [i for i, line in enumerate(lines) if "(NEES vs truth) |" in line and "+ far points: NEES median |" in line]
    assert len(heads) == 4  # the sampling sweep, the hit sweep, the AMCL-like rows, the crowd sizes
    sampling = lines[heads[0] + 2].split("|")  # its first row: the first sampling value, raw then far points
    pair = ex.both(ex.sampling_params(ex.QUICK_SAMPLINGS[0]))
    fits = [results["consistency"][f"{c.key}@{ex.CROWD_SIZE}"] for c in pair]
    missing = [f"{100 * f['excluded'] / (f['steps'] + f['excluded']):.0f} %" for f in fits]
    medians = [math.inf if f["nees_median"] is None else f["nees_median"] for f in fits]  # the JSON's None: inf
    want = [t for f, md, m in zip(fits, medians, missing) for t in (*consistency.cells(True, md, f["inside_95"]), m)]
    assert [c.strip() for c in sampling[2:8]] == want
    assert report.count("Consistent: median about 2.37, inside about 95 %") == 4
