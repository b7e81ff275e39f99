"""Shared timing helpers for the benchmarks."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Result:
    """One measured figure: ``value`` in ``unit`` (median of repeats), with the target if any."""

    group: str
    name: str
    value: float
    unit: str
    spread: str
    target: str = ""
    passed: bool | None = None


def rate(run: Callable[[int], None], steps: int, repeats: int = 5) -> tuple[float, float, float]:
    """Median, min and max of ``steps / seconds`` over ``repeats`` calls of ``run(steps)``."""
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        run(steps)
        rates.append(steps / (time.perf_counter() - start))
    return float(np.median(rates)), float(np.min(rates)), float(np.max(rates))


def per_call_ms(call: Callable[[], None], calls: int) -> tuple[float, float]:
    """Median and 99th percentile of one call's wall time, in milliseconds."""
    times = np.empty(calls)
    for i in range(calls):
        start = time.perf_counter()
        call()
        times[i] = time.perf_counter() - start
    return float(np.median(times) * 1e3), float(np.percentile(times, 99) * 1e3)
