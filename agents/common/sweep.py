"""Run many independent tasks: a local process pool by default, a Ray cluster on request.

Evaluation grids, multi-seed training and tuning workers all go through :func:`run_tasks`,
so moving a sweep from a laptop to a cluster is one flag (``--ray-address``). Ray is an
optional extra (``pip install crowdloc[distributed]``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, TypeVar

from tqdm import tqdm

T = TypeVar("T")
R = TypeVar("R")


def default_workers() -> int:
    """All cores but none more (the tasks are CPU-bound)."""
    return max(1, os.cpu_count() or 1)


def run_tasks(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    desc: str = "tasks",
    progress: bool = True,
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]:
    """Apply ``fn`` to every task and return the results in task order.

    Args:
        fn: a picklable module-level function.
        tasks: picklable arguments, one per call.
        workers: local processes (default: the core count); 1 runs in this process.
        ray_address: a Ray cluster address (``"auto"``, ``"ray://host:10001"``, ``"127.0.0.1:6379"``);
            the tasks then run as Ray remote functions there instead of locally.
        desc: progress-bar label.
        progress: show a progress bar.
        on_result: called in this process with ``(index, result)`` as each task finishes (in
            the order they finish), e.g. to save each result before the others are done.

    Raises:
        ImportError: with the install hint, when Ray is asked for but not installed.
        ValueError: for ``workers < 1``.
    """
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if ray_address is not None:
        return _run_on_ray(fn, tasks, ray_address, desc, progress, on_result)
    n = min(workers or default_workers(), max(len(tasks), 1))
    bar = tqdm(total=len(tasks), desc=desc, unit="task", disable=not progress)
    try:
        if n == 1:
            results = []
            for i, task in enumerate(tasks):
                results.append(fn(task))
                if on_result is not None:
                    on_result(i, results[-1])
                bar.update()
            return results
        with ProcessPoolExecutor(max_workers=n) as pool:
            futures = {pool.submit(fn, task): i for i, task in enumerate(tasks)}
            for future in as_completed(futures):
                if on_result is not None:
                    on_result(futures[future], future.result())
                bar.update()
            return [f.result() for f in futures]
    finally:
        bar.close()


def _run_on_ray(
    fn: Callable[[T], R],
    tasks: Sequence[T],
    address: str,
    desc: str,
    progress: bool,
    on_result: Callable[[int, R], None] | None = None,
) -> list[R]:
    try:
        import ray
    except ImportError as exc:
        raise ImportError("--ray-address needs Ray: pip install 'crowdloc[distributed]'") from exc
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False)
    remote = ray.remote(fn)
    refs: list[Any] = [remote.remote(task) for task in tasks]
    index = {ref: i for i, ref in enumerate(refs)}
    results: dict[Any, R] = {}
    pending = list(refs)
    with tqdm(total=len(refs), desc=f"{desc} (ray)", unit="task", disable=not progress) as bar:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                results[ref] = ray.get(ref)
                if on_result is not None:
                    on_result(index[ref], results[ref])
                bar.update()
    return [results[ref] for ref in refs]
