"""crowdloc benchmark: the protocol's loader and seeds, the command end to end (--quick, the plug-in
localizer and policy of docs/benchmark.md, copied outside the repository), determinism across
worker counts, resuming, and its refusals."""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from agents.benchmark.protocol import RESERVED_BELOW, load_protocol, protocol_digest, protocol_path
from agents.cli import main
from agents.policies import FIXED_POLICIES
from core.schema import ConfigError
from localizers.registry import LOCALIZERS

PLUGIN = "my_crowdloc_entry"
REPO = Path(__file__).resolve().parents[2]
SMALL = ["--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "crowdloc/CrowdedRoom-v0", "--seeds", "1", "--no-progress"]


def plugin_example() -> str:
    """The complete plug-in module that docs/benchmark.md shows (the python block after its marker)."""
    text = (REPO / "docs" / "benchmark.md").read_text()
    after = text.split(f"<!-- plug-in example: {PLUGIN}.py -->", 1)[1]
    return after.split("```python\n", 1)[1].split("```", 1)[0]


@pytest.fixture
def plugin(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The docs' example written to a folder outside the repository, on sys.path; its registrations
    undone after the test (other tests walk the registries)."""
    folder = tmp_path_factory.mktemp("user_code")
    (folder / f"{PLUGIN}.py").write_text(plugin_example())
    monkeypatch.syspath_prepend(str(folder))
    yield folder
    LOCALIZERS.pop("start_pose", None)
    FIXED_POLICIES.pop("straight_ahead", None)
    sys.modules.pop(PLUGIN, None)


def _bench(tmp_path: Path, *extra: str, name: str = "out") -> dict[str, Any]:
    out = tmp_path / name
    assert main(["benchmark", *extra, "--out", str(out)]) == 0
    return json.loads((out / "results.json").read_text())  # type: ignore[no-any-return]


def test_quick_run_with_a_plugin_end_to_end(tmp_path: Path, plugin: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = _bench(tmp_path, *SMALL, "--localizers", "dead_reckoning", "start_pose", "resection",
                 "--policies", "random_walk", "straight_ahead", "--plugins", PLUGIN, "--workers", "1")  # fmt: skip
    printed = capsys.readouterr().out
    # resection reads bearings: left out of the room with a line, not an error
    assert "left out: resection in crowdloc/CrowdedRoom-v0 needs a bearing_camera sensor" in printed
    protocol = load_protocol()
    assert doc["protocol"] == protocol.name and doc["quick"] is True
    assert doc["protocol_digest"] == protocol_digest(protocol)
    rows = doc["rows"]
    assert all(r["quick"] is True and r["protocol_digest"] == doc["protocol_digest"] for r in rows)
    cells = {(r["world"], r["localizer"], r["policy"], r["crowd_size"]) for r in rows}
    static, room = protocol.worlds["crowdloc/RoboCupStatic-v0"], protocol.worlds["crowdloc/CrowdedRoom-v0"]
    expected = {("crowdloc/RoboCupStatic-v0", loc, pol, c) for loc in ("dead_reckoning", "start_pose", "resection")
                for pol in ("random_walk", "straight_ahead") for c in static.crowd_sizes}  # fmt: skip
    expected |= {("crowdloc/CrowdedRoom-v0", loc, pol, c) for loc in ("dead_reckoning", "start_pose")
                 for pol in ("random_walk", "straight_ahead") for c in room.crowd_sizes}  # fmt: skip
    assert cells == expected and len(rows) == len(expected)
    still = next(r for r in rows if r["localizer"] == "start_pose" and r["policy"] == "straight_ahead")
    assert still["error_mean_m"] > 0.0 and still["nees_median"] is None  # it moved; no covariance reported
    out = tmp_path / "out"
    board = (out / "leaderboard.md").read_text()
    assert "QUICK RUN" in board and doc["protocol_digest"][:16] in board and "| start_pose | straight_ahead |" in board
    assert len((out / "results.csv").read_text().splitlines()) == len(rows) + 1
    assert {s["localizer"] for s in doc["crowd_sensitivity"]} == {"dead_reckoning", "start_pose", "resection"}
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["crowdloc_CrowdedRoom-v0.png", "crowdloc_RoboCupStatic-v0.png",
                                                                 "overview.png"]  # fmt: skip
    assert "Update costs measured on" in board and "Resolution:" not in board  # one seed: no interval to state


def test_same_numbers_on_one_worker_and_two(tmp_path: Path, plugin: Path) -> None:
    args = ("--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "--seeds", "2", "--no-progress", "--plugins", PLUGIN,
            "--localizers", "dead_reckoning", "start_pose", "--policies", "random_walk")  # fmt: skip
    one = _bench(tmp_path, *args, "--workers", "1", name="one")
    two = _bench(tmp_path, *args, "--workers", "2", name="two")
    assert _numbers(one["rows"]) == _numbers(two["rows"]) and one["crowd_sensitivity"] == two["crowd_sensitivity"]
    board = (tmp_path / "one" / "leaderboard.md").read_text()
    assert "Resolution: with 2 seeds the 95 % interval of a row's mean error spans" in board
    assert all(r["update_ms"] > 0 for r in one["rows"] + two["rows"])  # a timing: measured, never compared


def _numbers(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows without the update cost, a timing that differs between runs."""
    return [{k: v for k, v in r.items() if k != "update_ms"} for r in rows]


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        (["--worlds", "crowdloc/Nowhere-v0"], "'crowdloc/Nowhere-v0' is not a world of crowdloc-benchmark-v2"),
        (["--localizers", "no_such_localizer"], "unknown localizer 'no_such_localizer'"),
        (["--policies", "moonwalk"], "unknown policy 'moonwalk'"),
        (["--plugins", "no_such_plugin_module"], "--plugins no_such_plugin_module: cannot import it"),
        (["--seeds", "21"], "--seeds must be from 1 to 20"),
    ],
)
def test_refusals_name_what_is_unknown(tmp_path: Path, flags: list[str], named: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["benchmark", "--quick", *flags, "--out", str(tmp_path / "out")])
    assert exit_info.value.code == 2
    assert named in capsys.readouterr().err
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_an_out_that_is_not_empty_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(SystemExit):
        main(["benchmark", *SMALL, "--localizers", "dead_reckoning", "--out", str(tmp_path)])
    assert "is not empty" in capsys.readouterr().err and (tmp_path / "keep.txt").read_text() == "mine"


def _protocol_text(edit: Any) -> str:
    data = yaml.safe_load(protocol_path("v1").read_text())
    edit(data)
    return yaml.safe_dump(data, sort_keys=False)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(colour="red"), "unknown key 'colour'"),
        (lambda d: d.pop("seeds"), "missing required key 'seeds'"),
        (
            lambda d: d["worlds"].update({"crowdloc/Nowhere-v0": d["worlds"]["crowdloc/CrowdedRoom-v0"]}),
            "worlds.crowdloc/Nowhere-v0: unknown env id",
        ),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(crowd_sizes=[0, 8, 16]), "must end at the world's maximum 30"),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(crowd_sizes=[4, 30]), "must start at 0"),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(policies=["moonwalk"]), "unknown policy 'moonwalk'"),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(policies=["route_follower"]), "'route_follower' cannot drive"),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(start="sometimes"), "'sometimes' is not one of"),
        (lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(failure_m=0), "failure_m must be finite and > 0"),
        (lambda d: d["seeds"].update(first=2**31), f"first must be >= {RESERVED_BELOW}"),
        (lambda d: d["seeds"].update(first=2**32 - 5), "first + count must be <= 2**32"),
        (lambda d: d["quick"].update(seeds=50), "quick.seeds (50) exceeds seeds.count (20)"),
        (
            lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(paper_localizers=["mcl_lidar", "pose_oracle"]),
            "paper_localizers: 'pose_oracle' is not a built-in localizer",
        ),
        (
            lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(paper_localizers=["mcl_lidar", "mcl_lidar"]),
            "paper_localizers repeat",
        ),
    ],
)
def test_the_loader_refuses_a_bad_protocol_naming_file_and_key(tmp_path: Path, edit: Any, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(_protocol_text(edit))
    with pytest.raises(ConfigError, match="bad.yaml") as info:
        load_protocol(path)
    assert message in str(info.value)


def test_the_papers_table_shows_the_paper_localizers_at_zero_default_and_most(tmp_path: Path) -> None:
    """The leaderboard's papers' table: the protocol's paper_localizers under the paper policy at crowd 0,
    the world's default (16 in the room) and its maximum, with the same numbers as the world's own table."""
    path = tmp_path / "papers.yaml"
    path.write_text(_protocol_text(lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(paper_localizers=["far_point_mcl",
                                                                                                           "mcl_lidar"])))  # fmt: skip
    doc = _bench(tmp_path, "--protocol", str(path), "--quick", "--worlds", "crowdloc/CrowdedRoom-v0", "--seeds", "1",
                 "--localizers", "mcl_lidar", "far_point_mcl", "dead_reckoning", "--policies", "patrol", "--no-progress")  # fmt: skip
    board = (tmp_path / "out" / "leaderboard.md").read_text()
    table = board.split("## The papers' methods as the crowd grows", 1)[1].split("\n## ", 1)[0]
    assert "| localizer | crowd 0 | crowd 16 (default) | crowd 30 |" in table
    lines = [line for line in table.splitlines() if line.startswith("| ") and "localizer" not in line]
    assert [line.split(" | ")[0] for line in lines] == ["| far_point_mcl", "| mcl_lidar"]  # dead_reckoning is no paper's
    for line in lines:
        name = line.split(" | ")[0][2:]
        for size, cell in zip((0, 16, 30), line.split(" | ")[1:], strict=True):
            row = next(r for r in doc["rows"] if (r["localizer"], r["crowd_size"]) == (name, size))
            assert cell.strip(" |").startswith(
                f"{row['error_mean_m']:.2f} / {row['error_p95_m']:.2f} / {row['failure_share']:.2f}"
            )


def test_a_paper_localizer_that_cannot_run_in_its_world_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(_protocol_text(lambda d: d["worlds"]["crowdloc/CrowdedRoom-v0"].update(paper_localizers=["ceiling_target"])))
    with pytest.raises(SystemExit) as exit_info:
        main(["benchmark", "--protocol", str(path), "--quick", "--worlds", "crowdloc/CrowdedRoom-v0",
              "--out", str(tmp_path / "out"), "--no-progress"])  # fmt: skip
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert (
        "bad.yaml: worlds.crowdloc/CrowdedRoom-v0.paper_localizers: 'ceiling_target' cannot run there (ceiling_target in" in err
    )
    assert not (tmp_path / "out").exists()


def test_an_unknown_protocol_name_lists_the_shipped_ones() -> None:
    with pytest.raises(ConfigError, match="shipped: v1"):
        load_protocol("v0")


def test_the_test_seeds_are_no_other_commands_seeds() -> None:
    """The seeds every other command draws, collected, meet none of the protocol's."""
    from agents.demo import VERDICT_SEEDS
    from agents.evaluate.spec import FIRST_SEED_MAX, EvalSpec
    from agents.papers.bearing_candidates.jobs import DEFAULT_PUSH_SEEDS, DEFAULT_SEEDS, DEFAULT_SWEEP_SEEDS
    from agents.papers.ceiling_target import DEFAULT_SEEDS as CEILING_SEEDS
    from agents.papers.lidar_far_point.experiment import DEFAULT_SEEDS as LIDAR_SEEDS
    from agents.papers.lidar_far_point.experiment import PILOT_SEEDS
    from agents.rl.config import EVAL_SEED_BASE
    from agents.tune.objective import eval_seeds, tuning_seeds

    mine = set(load_protocol().seeds.seeds)
    assert min(mine) >= RESERVED_BELOW
    others = set(tuning_seeds(10_000)) | set(eval_seeds(10_000)) | set(range(max(PILOT_SEEDS) + 1))
    others |= set(range(max(DEFAULT_SEEDS, DEFAULT_SWEEP_SEEDS, DEFAULT_PUSH_SEEDS, CEILING_SEEDS, LIDAR_SEEDS) + 10_000))
    others |= {EVAL_SEED_BASE + i for i in range(20 + VERDICT_SEEDS + 1000)}  # demo's table and verdict, validation at 1000
    # crowdloc eval's last reachable range: the largest first seed, with up to 2**29 - 1 seeds
    last = EvalSpec(policies=("random_walk",), localizers=("dead_reckoning",), crowd_sizes=(0,), seeds=3,
                    first_seed=FIRST_SEED_MAX, env_id="crowdloc/RoboCupStatic-v0").eval_seeds  # fmt: skip
    assert last[0] + 2**29 - 1 < RESERVED_BELOW
    others |= set(last)
    assert all(s < EVAL_SEED_BASE for s in tuning_seeds(10_000))  # training and tuning: below 2**31
    assert not mine & others


def test_the_digest_follows_the_localizers_parameters_and_not_the_plugins(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, plugin: Path
) -> None:
    """A built-in localizer's parameter values decide its numbers, so they decide the digest; a
    comment in the file does not, nor does a plug-in registered in this process (the fixture's)."""
    from localizers import registry

    protocol = load_protocol("v1")
    before = protocol_digest(protocol)
    importlib.import_module(PLUGIN)  # registers the localizer start_pose
    assert "start_pose" in LOCALIZERS and protocol_digest(protocol) == before
    edited = tmp_path / "kalman.yaml"
    text = registry.params_path("kalman").read_text()
    real = registry.params_path
    monkeypatch.setattr(registry, "params_path", lambda name: edited if name == "kalman" else real(name))
    edited.write_text("# a comment\n" + text.replace("#", "# and more:"))
    assert protocol_digest(protocol) == before
    assert "\nmax_spread_m: 1.0 " in text
    edited.write_text(text.replace("\nmax_spread_m: 1.0 ", "\nmax_spread_m: 1.5 "))  # a value
    assert protocol_digest(protocol) != before


def test_an_installed_packages_entry_point_enters_like_a_plugin(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, plugin: Path
) -> None:
    """A package that declares ``[project.entry-points."crowdloc.localizers"]`` is loaded on start and
    its localizer named like a built-in, without --plugins."""
    from agents.benchmark import run

    real = importlib.metadata.entry_points
    found = {"crowdloc.localizers": [importlib.metadata.EntryPoint("start_pose", PLUGIN, "crowdloc.localizers")]}

    def entry_points(group: str | None = None) -> Any:  # crowdloc's groups from ``found``, the rest (numba's) real
        return real() if group is None else found.get(group, [])

    monkeypatch.setattr(run.importlib.metadata, "entry_points", entry_points)
    monkeypatch.setattr(run, "_installed_loaded", False)
    # in this process: a pool's workers start fresh (forkserver) and read the real entry points,
    # which the patch above does not reach; they load them by the same load_plugins
    doc = _bench(tmp_path, *SMALL, "--localizers", "start_pose", "--policies", "random_walk", "--workers", "1")
    assert {r["localizer"] for r in doc["rows"]} == {"start_pose"}
    found = {"crowdloc.policies": [importlib.metadata.EntryPoint("oops", "no_such_module_here", "crowdloc.policies")]}
    monkeypatch.setattr(run, "_installed_loaded", False)
    with pytest.raises(ConfigError, match=r"entry point oops = no_such_module_here \(crowdloc.policies, .*ModuleNotFoundError"):
        run.load_plugins(())


def test_a_stopped_run_resumes_to_the_numbers_of_an_uninterrupted_one(tmp_path: Path, plugin: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    args = ("--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "--no-progress", "--plugins", PLUGIN,
            "--localizers", "dead_reckoning", "start_pose", "--policies", "random_walk", "--workers", "1")  # fmt: skip
    whole = _bench(tmp_path, *args, "--seeds", "2", name="whole")
    # a run stopped after its first seed (it plays seed by seed), its last line torn by the kill
    _bench(tmp_path, *args, "--seeds", "1", name="split")
    journal = tmp_path / "split" / "episodes.jsonl"
    lines = journal.read_text().splitlines(keepends=True)
    journal.write_text("".join(lines[:-1]) + lines[-1][: len(lines[-1]) // 2])
    capsys.readouterr()
    resumed = _bench(tmp_path, *args, "--seeds", "2", "--resume", name="split")
    assert "--resume: 7 of the 16 episodes are in" in capsys.readouterr().out  # 8 of seed 1, one torn
    assert _numbers(resumed["rows"]) == _numbers(whole["rows"])
    assert resumed["crowd_sensitivity"] == whole["crowd_sensitivity"]
    # a prefix of the journal's seeds: its first seed's episodes only, nothing played
    first = _bench(tmp_path, *args, "--seeds", "1", "--resume", name="split")
    assert "--resume: 8 of the 8 episodes are in" in capsys.readouterr().out
    assert all(r["episodes"] == 1 for r in first["rows"])


def test_resume_refuses_another_run_naming_what_differs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "--seeds", "1", "--no-progress", "--workers", "1",
            "--localizers", "dead_reckoning", "--policies", "random_walk"]  # fmt: skip
    _bench(tmp_path, *args)
    with pytest.raises(SystemExit):
        main(["benchmark", *args[:-1], "patrol", "--resume", "--out", str(tmp_path / "out")])
    assert "is a run of another benchmark (worlds:" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["benchmark", *args, "--resume", "--overwrite", "--out", str(tmp_path / "out")])
    assert "give one" in capsys.readouterr().err


def test_an_installed_package_outside_the_repository_enters_the_tables(plugin: Path, tmp_path: Path) -> None:
    """The docs' example as a package a user installed (a dist-info with the entry point, as pip
    leaves it), in a folder outside the repository: a fresh ``crowdloc benchmark`` run from there
    loads it without --plugins, and its entries appear in the tables beside the built-ins."""
    info = plugin / "my_crowdloc_entry-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-crowdloc-entry\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        f"[crowdloc.localizers]\nstart_pose = {PLUGIN}\n\n[crowdloc.policies]\nstraight_ahead = {PLUGIN}\n"
    )
    out = tmp_path / "bench"
    env = {**os.environ, "PYTHONPATH": str(plugin)}
    done = subprocess.run(
        [sys.executable, "-m", "agents.cli", "benchmark", "--quick", "--worlds", "crowdloc/CrowdedRoom-v0", "--seeds", "1",
         "--localizers", "dead_reckoning", "start_pose", "--policies", "straight_ahead", "--workers", "2",
         "--no-progress", "--out", str(out)],
        cwd=plugin, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert not str(plugin.resolve()).startswith(str(REPO))
    doc = json.loads((out / "results.json").read_text())
    assert {(r["localizer"], r["policy"]) for r in doc["rows"]} == {("dead_reckoning", "straight_ahead"),
                                                                   ("start_pose", "straight_ahead")}  # fmt: skip
    board = (out / "leaderboard.md").read_text()
    assert "| start_pose | straight_ahead | 30 |" in board and "| dead_reckoning | straight_ahead | 0 |" in board
    # start_pose never moves: its error grows with the distance the robot drove, dead reckoning's stays small
    rows = {r["localizer"]: r for r in doc["rows"] if r["crowd_size"] == 0}
    assert rows["start_pose"]["error_mean_m"] > rows["dead_reckoning"]["error_mean_m"]


def test_a_trained_policy_enters_where_it_observes_what_the_world_gives(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    import gymnasium as gym
    from stable_baselines3 import PPO

    world = "crowdloc/RoboCupStatic-v0"
    env = gym.make(world, localizer="dead_reckoning")
    model = PPO("MultiInputPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(32)
    path = tmp_path / "mine.zip"
    model.save(path)
    env.close()
    doc = _bench(tmp_path, "--quick", "--worlds", world, "--seeds", "1", "--no-progress", "--workers", "1",
                 "--localizers", "dead_reckoning", "kalman", "--policies", f"ppo:{path}")  # fmt: skip
    assert {(r["localizer"], r["policy"]) for r in doc["rows"]} == {("dead_reckoning", f"ppo:{path}"), ("kalman", f"ppo:{path}")}
    # the shipped soccer policies observe a sonar ring and the belief spread, which the protocol's field lacks
    shipped = REPO / "models" / "ppo_candidate_sets.zip"
    with pytest.raises(SystemExit):
        main(["benchmark", "--quick", "--worlds", world, "--policies", f"ppo:{shipped}", "--out", str(tmp_path / "no")])
    err = capsys.readouterr().err
    assert "sonar: policy (12,), env absent" in err and "the benchmark plays every entry in the protocol's conditions" in err
    assert not (tmp_path / "no").exists()


def test_the_shipped_league_table_is_the_protocols_as_the_repository_stands() -> None:
    """docs/results.json (the league table the README shows) carries the digest of v1 as its files
    are now: a change to a world's or localizer's YAML, the protocol or the version since the run
    means running it again (`crowdloc benchmark --workers 2`, docs/benchmark.md), or a v2."""
    shipped = json.loads((REPO / "docs" / "results.json").read_text())
    protocol = load_protocol()
    assert shipped["protocol"] == protocol.name and shipped["quick"] is False
    assert shipped["protocol_digest"] == protocol_digest(protocol), "re-run the shipped league table (docs/benchmark.md)"
    assert shipped["seeds"] == list(protocol.seeds.seeds) and len(shipped["rows"]) == 190
    board = (REPO / "docs" / "leaderboard.md").read_text()
    assert shipped["protocol_digest"][:16] in board


def test_the_papers_table_in_the_docs_is_the_shipped_leaderboards() -> None:
    """docs/papers.md's crowd-density table per world is the shipped leaderboard's, copied whole."""
    board = (REPO / "docs" / "leaderboard.md").read_text()
    table = board.split("## The papers' methods as the crowd grows", 1)[1].split("\n## crowdloc/", 1)[0].strip("\n")
    papers = (REPO / "docs" / "papers.md").read_text()
    copied = papers.split("<!-- papers' table: copied from docs/leaderboard.md -->\n", 1)[1].split(
        "\n<!-- end of papers' table -->", 1
    )[0]
    assert "### crowdloc/StereoCampus-v0" in table and copied == table
