"""Run many independent tasks: a local process pool by default, a Ray cluster on request.

Evaluation grids, multi-seed training and tuning workers all go through :func:`run_tasks`,
so moving a sweep from a laptop to a cluster is one flag (``--ray-address``). Ray is an
optional extra (``pip install crowdloc[distributed]``).

Local workers never start as a fork of the calling process (:func:`worker_context`): a fork copies
whatever that process had started, and some of it cannot live in a child. numba's ``parallel=True``
kernels run on an OpenMP thread pool (its ``omp`` layer, where TBB is not installed); once GNU
OpenMP has run in a process, a forked child that runs a parallel kernel (a LIDAR range table built
on a cold cache, say) is killed at once (``fork() called from a process already using GNU
OpenMP``). The workers start from a fork server instead, a clean process started for the purpose,
and each exits when the process that started the pool is gone (:func:`_exit_with_parent`), even
when it was killed with no time to stop them.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, TypeVar

from tqdm import tqdm

T = TypeVar("T")
R = TypeVar("R")


def default_workers() -> int:
    """All cores but none more (the tasks are CPU-bound)."""
    return max(1, os.cpu_count() or 1)


def worker_context() -> multiprocessing.context.BaseContext:
    """How local worker processes start: from the fork server where the platform has one
    (Linux, macOS), else as fresh interpreters (spawn); never as a fork of this process."""
    method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    return multiprocessing.get_context(method)


def _exit_with_parent() -> None:
    """Exit this worker as soon as the process that started its pool is gone, however it ended.

    A worker's parent in the fork server's sense is the server, which lives on while workers
    hold its descriptors; what tells of the pool's owner is the pipe it keeps open to each
    worker (multiprocessing's parent sentinel), which reads as closed once the owner exits. A
    daemon thread waits on it (the wait holds no lock) and ends the process."""
    parent = multiprocessing.parent_process()
    if parent is None:  # not a worker: nothing to watch
        return

    def watch() -> None:
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


def _start_worker(environment: dict[str, str]) -> None:
    """A pool worker's initializer: it exits with its parent and sees the environment of the
    process that started the pool as it was then (a fork server keeps the one it started with;
    ``CROWDLOC_CACHE`` set later must still reach the workers)."""
    _exit_with_parent()
    os.environ.clear()
    os.environ.update(environment)


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
        context = worker_context()
        if isinstance(context, multiprocessing.context.ForkServerContext):
            # the fork server imports the task's module once; every worker forks from it ready to run
            context.set_forkserver_preload(["__main__", fn.__module__])
        with ProcessPoolExecutor(
            max_workers=n, mp_context=context, initializer=_start_worker, initargs=(dict(os.environ),)
        ) as pool:
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
