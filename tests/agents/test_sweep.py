"""run_tasks: local pool keeps order; Ray runs the same tasks on a local cluster started here."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from agents.common.sweep import run_tasks


def square_and_pid(x: int) -> tuple[int, int]:
    return x * x, os.getpid()


@pytest.mark.parametrize("workers", [1, 2])
def test_local_pool_keeps_task_order(workers: int) -> None:
    results = run_tasks(square_and_pid, list(range(7)), workers=workers, progress=False)
    assert [r[0] for r in results] == [x * x for x in range(7)]
    pids = {r[1] for r in results}
    if workers == 1:
        assert pids == {os.getpid()}
    else:
        assert os.getpid() not in pids


@pytest.mark.parametrize("workers", [1, 2])
def test_on_result_sees_every_result_in_this_process_as_it_finishes(workers: int) -> None:
    seen: list[tuple[int, int, int]] = []
    results = run_tasks(square_and_pid, list(range(7)), workers=workers, progress=False,
                        on_result=lambda i, r: seen.append((i, r[0], os.getpid())))  # fmt: skip
    assert sorted(seen) == [(i, i * i, os.getpid()) for i in range(7)]  # each once, called here (not in a worker)
    assert [r[0] for r in results] == [x * x for x in range(7)]  # the returned list keeps the task order


def test_bad_worker_count_is_refused() -> None:
    with pytest.raises(ValueError, match="0"):
        run_tasks(square_and_pid, [1], workers=0)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow
def test_ray_cluster_runs_the_tasks_a_multi_seed_training_and_the_benchmark(tmp_path: Path) -> None:
    import ray  # noqa: F401  (the [distributed] extra, installed by make)

    ray_cli = shutil.which("ray", path=str(Path(sys.executable).parent))
    assert ray_cli is not None
    port = _free_port()
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    # a short temp dir (Ray's unix sockets live there, and their paths are length-limited) and
    # loopback only: this one-machine cluster must not listen on any other address
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")
    start = [
        ray_cli,
        "start",
        "--head",
        f"--port={port}",
        "--node-ip-address=127.0.0.1",
        "--num-cpus=2",
        "--include-dashboard=false",
        f"--temp-dir={temp}",
        "--disable-usage-stats",
    ]
    subprocess.run(start, check=True, env=env, capture_output=True, timeout=180)
    try:
        # the tasks run in the cluster's workers, which import this test module by path
        results = run_tasks(square_and_pid, list(range(5)), ray_address=f"127.0.0.1:{port}", progress=False)
        assert [r[0] for r in results] == [0, 1, 4, 9, 16]
        assert os.getpid() not in {r[1] for r in results}
        from agents.rl.config import load_train_config
        from agents.rl.train import train_seeds

        config = load_train_config("ppo_candidate_sets", {
            "total_timesteps": 64, "n_envs": 2, "vec_env": "dummy", "crowd_sizes": [3], "ppo.n_steps": 32,
            "ppo.batch_size": 32, "ppo.n_epochs": 1, "ppo.net_arch": [16]})  # fmt: skip
        models = train_seeds(config, tmp_path, [0, 1], ray_address=f"127.0.0.1:{port}", progress=False)
        assert [m.parent.name for m in models] == ["seed_0", "seed_1"] and all(m.is_file() for m in models)
        # crowdloc benchmark --ray-address: the same numbers as local processes
        from agents.cli import main

        bench = ["benchmark", "--quick", "--worlds", "crowdloc/RoboCupStatic-v0", "--seeds", "1", "--no-progress",
                 "--localizers", "dead_reckoning", "kalman", "--policies", "random_walk"]  # fmt: skip
        assert main([*bench, "--ray-address", f"127.0.0.1:{port}", "--out", str(tmp_path / "ray")]) == 0
        assert main([*bench, "--workers", "2", "--out", str(tmp_path / "local")]) == 0
        rows = [[{k: v for k, v in r.items() if k != "update_ms"} for r in json.loads((tmp_path / d / "results.json").read_text())["rows"]]
                for d in ("ray", "local")]  # fmt: skip
        assert rows[0] == rows[1] and len(rows[0]) == 8
    finally:
        import ray

        ray.shutdown()
        subprocess.run([ray_cli, "stop", "--force"], env=env, capture_output=True, timeout=120)
        shutil.rmtree(temp, ignore_errors=True)
