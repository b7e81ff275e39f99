"""Worker pools are safe whatever ran in the process that starts them, and die with it.

numba's parallel kernels run on GNU OpenMP here (numba's ``omp`` layer, TBB not installed): once
OpenMP has run in a process, a forked child that runs a parallel kernel is killed (``fork() called
from a process already using GNU OpenMP``). The script below starts OpenMP in the parent the way a
newcomer's first ``make demo`` did, by building a range table on an empty cache, then runs pools
whose workers build range tables of their own on another empty cache: ``evaluate(..., workers=2)``
and ``crowdloc benchmark --quick``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

PARENT_THEN_POOLS = textwrap.dedent(
    """
    import os, sys
    from pathlib import Path
    import numpy as np
    import numba
    from localizers.base import LandmarkMap
    from localizers.range_table import build_range_table

    root = Path(sys.argv[1])
    os.environ["CROWDLOC_CACHE"] = str(root / "cache_parent")
    box = np.array([[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 3.0], [4.0, 3.0, 0.0, 3.0], [0.0, 3.0, 0.0, 0.0]])
    table = build_range_table(LandmarkMap(np.zeros((0, 2)), (), (0.0, 0.0, 4.0, 3.0), box), resolution_m=0.1, directions=36, max_range_m=5.0)
    assert not table.loaded, "the parent's table must be built here, on the parallel kernel"
    print("parent threading layer:", numba.threading_layer(), flush=True)

    from agents.evaluate import evaluate
    from agents.evaluate.spec import EvalSpec
    from agents.cli import main

    os.environ["CROWDLOC_CACHE"] = str(root / "cache_eval")  # empty: each worker builds the room's table
    spec = EvalSpec(policies=("spin",), localizers=("mcl_lidar",), crowd_sizes=(0,), seeds=2, episode_steps=3,
                    env_id="crowdloc/CrowdedRoom-v0", bootstrap_resamples=10)
    result = evaluate(spec, workers=2, progress=False)
    assert len(result.episodes) == 2
    assert any((root / "cache_eval").glob("range_table_*.npy")), "the workers built no range table"
    print("evaluate ok", flush=True)

    os.environ["CROWDLOC_CACHE"] = str(root / "cache_benchmark")
    code = main(["benchmark", "--quick", "--worlds", "crowdloc/CrowdedRoom-v0", "--seeds", "1", "--workers", "2",
                 "--no-progress", "--out", str(root / "benchmark")])
    assert code == 0
    assert any((root / "cache_benchmark").glob("range_table_*.npy")), "the benchmark's workers built no range table"
    print("benchmark ok", flush=True)
    """
)


def test_pools_run_parallel_kernels_after_the_parent_ran_one(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-c", PARENT_THEN_POOLS, str(tmp_path)], capture_output=True, text=True,
                          timeout=600, env={**os.environ, "PYTHONWARNINGS": "ignore"})  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "parent threading layer:" in done.stdout
    assert "evaluate ok" in done.stdout and "benchmark ok" in done.stdout


SLEEPING_POOL = textwrap.dedent(
    """
    import os, sys, time
    from agents.common.sweep import run_tasks

    def nap(path):
        with open(path, "w") as f:
            f.write(str(os.getpid()))
        time.sleep(120)

    if __name__ == "__main__":
        run_tasks(nap, [sys.argv[1] + "/a", sys.argv[1] + "/b"], workers=2, progress=False)
    """
)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie still answers kill 0; it has exited
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.is_file() and stat.read_text().split(")")[-1].split()[0] == "Z")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_exit_when_the_main_process_is_killed(tmp_path: Path) -> None:
    script = tmp_path / "pool.py"
    script.write_text(SLEEPING_POOL)
    main = subprocess.Popen([sys.executable, str(script), str(tmp_path)], cwd=Path(__file__).parents[2])
    try:
        deadline = time.monotonic() + 60
        while not ((tmp_path / "a").is_file() and (tmp_path / "b").is_file()):
            assert main.poll() is None, "the pool script ended early"
            assert time.monotonic() < deadline, "the workers never started"
            time.sleep(0.1)
        time.sleep(0.2)  # the files are written before each worker's text is flushed
        workers = [int((tmp_path / name).read_text()) for name in ("a", "b")]
        assert all(_alive(pid) for pid in workers)
    finally:
        main.send_signal(signal.SIGKILL)
        main.wait()
    deadline = time.monotonic() + 15
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [pid for pid in workers if _alive(pid)]
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert not left, f"workers {left} outlived the killed main process"
