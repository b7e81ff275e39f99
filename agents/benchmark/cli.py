"""``crowdloc benchmark`` from parsed options (the parser lives in :mod:`agents.cli`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from agents.benchmark.protocol import load_protocol
from agents.benchmark.results import BENCHMARK_OUTPUTS, write_results
from agents.benchmark.run import BenchmarkPlan, load_plugins, plan_benchmark, score_task
from agents.common.sweep import run_tasks
from agents.common.util import prepare_out_dir


def run_cli(args: Any) -> BenchmarkPlan:
    """Import the plug-ins, read the protocol, plan, check ``--out``, run every episode, write.

    Raises:
        ConfigError: an unimportable plug-in, a bad protocol, an unknown world, localizer or
            policy, a bad seed count, or an ``--out`` that is not empty (without ``--overwrite``),
            all before any episode runs.
    """
    plugins = tuple(args.plugins or ())
    load_plugins(plugins)
    protocol = load_protocol(args.protocol)
    plan = plan_benchmark(protocol, worlds=args.worlds, localizers=args.localizers, policies=args.policies,
                          seeds=args.seeds, quick=args.quick, plugins=plugins)  # fmt: skip
    out = Path(args.out)
    prepare_out_dir(out, BENCHMARK_OUTPUTS, command="crowdloc benchmark", overwrite=args.overwrite)
    for line in plan.left_out:
        print(line)
    tasks = plan.tasks()
    start = time.perf_counter()
    scores = run_tasks(score_task, tasks, workers=args.workers, desc="benchmark", progress=not args.no_progress)
    wall_s = time.perf_counter() - start
    written = write_results(out, plan, scores, wall_s)
    quick = " (quick: not comparable with a full run)" if plan.quick else ""
    print(f"{protocol.name}{quick}: {len(tasks)} episodes in {wall_s:.0f} s; wrote {out}/ "
          f"({', '.join(p.name for p in written.values())})")  # fmt: skip
    return plan
