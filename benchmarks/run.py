"""Run every benchmark and write the results as markdown (``make bench`` -> BENCHMARKS.md)."""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import sys
from pathlib import Path

from benchmarks import bench_benchmark, bench_ceiling, bench_envs, bench_lidar, bench_localizers, bench_stereo, bench_train
from benchmarks.common import Result

SUITES = {
    "envs": bench_envs.run_all,
    "localizers": bench_localizers.run_all,
    "lidar": bench_lidar.run_all,
    "ceiling": bench_ceiling.run_all,
    "stereo": bench_stereo.run_all,
    "training": bench_train.run_all,
    "benchmark": bench_benchmark.run_all,
}

HEADER = """# Benchmarks

Measured by `make bench` (`python -m benchmarks.run --output BENCHMARKS.md`), which rewrites this
file. Rates (steps/s) are the median of 5 repeats with the min-max beside them; per-call
times (ms) are the median over every call with the 99th percentile beside it; wall clock, one
process unless stated. Targets come from the issues; they are measured here, never asserted
in tests, and a missed one is marked **no**.
"""


def to_markdown(results: list[Result], load: tuple[float, float]) -> str:
    lines = [
        HEADER,
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"{platform.system()} {platform.release()}; measured {datetime.date.today().isoformat()}. "
        f"1-minute load average {load[0]:.1f} at the start and {load[1]:.1f} at the end "
        "(above 0 means other work shared the cores and the figures are lower bounds).",
        "",
    ]
    for group in dict.fromkeys(r.group for r in results):
        lines += [f"## {group}", "", "| what | median | range | target | met |", "|---|---:|---:|---:|:---:|"]
        for r in (r for r in results if r.group == group):
            met = "" if r.passed is None else ("yes" if r.passed else "**no**")
            lines.append(f"| {r.name} | {_fmt(r.value)} {r.unit} | {r.spread} | {r.target} | {met} |")
        lines.append("")
    return "\n".join(lines)


def _fmt(value: float) -> str:
    return f"{value:,.0f}" if value >= 100 else f"{value:.3g}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--output", type=Path, help="write the markdown here (default: print only)")
    parser.add_argument("--quick", action="store_true", help="fewer steps (a smoke run, figures are noisier)")
    parser.add_argument("--only", choices=sorted(SUITES), action="append", help="run only these suites")
    args = parser.parse_args(argv)
    results: list[Result] = []
    load_start = os.getloadavg()[0]
    for name in args.only or SUITES:
        print(f"running {name} benchmarks ...", file=sys.stderr)
        results += SUITES[name](quick=args.quick)
    for r in results:
        print(f"{r.group:10s} {r.name:62s} {_fmt(r.value):>10s} {r.unit:8s} {r.target}")
    text = to_markdown(results, (load_start, os.getloadavg()[0]))
    if args.output:
        args.output.write_text(text)
        print(f"wrote {args.output}", file=sys.stderr)
    missed = [r.name for r in results if r.passed is False]
    if missed:
        print("targets missed: " + "; ".join(missed), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
