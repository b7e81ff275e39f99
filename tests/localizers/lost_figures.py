"""Issue 19's stress cases for the particle filters, measured: how wrong they are while they
claim a pose, and how soon they are right again (tests/localizers/lost.py drives them).

    python -m tests.localizers.lost_figures [case ...] [--seeds N]

Cases: one_landmark, swapped_ids, kidnap_bearing, odometry_jump, zero_scans, kidnap_lidar.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

from localizers.base import ScanMeasurement
from tests.localizers.lost import EVENT_S, ROOM, ROOM_KW, STATIC, Run, drive, one_landmark, swapped


def line(name: str, run: Run, extra: str = "") -> None:
    v = run.valid
    err = run.error_m[v]
    print(
        f"  {name:<34} valid {int(v.sum()):>5}/{v.size}  >1m-off claims {run.wrong_claims():>5}"
        f"  longest {run.longest_wrong_s():5.1f} s  median err {np.median(err) if err.size else math.nan:6.2f} m"
        f"  median spread of wrong {run.spread_of_wrong_claims():5.2f} m {extra}"
    )


def case_one_landmark(seeds: int) -> None:
    print("one_landmark: mcl_bearing fed only the lowest-id landmark of each frame, random walk, 10000 steps")
    for seed in range(min(seeds, 2)):
        line(f"seed {seed}", drive("mcl_bearing", STATIC, 10_000, seed, policy="random_walk", frame=one_landmark))


def case_swapped_ids(seeds: int) -> None:
    print("swapped_ids: landmarks 0 and 1 swap ids, random walk, 1800 steps (60 s)")
    for name in ("mcl_bearing_paper", "mcl_bearing"):
        for seed in range(min(seeds, 2)):
            line(f"{name} seed {seed}", drive(name, STATIC, 1800, seed, policy="random_walk", frame=swapped))


def case_kidnap_bearing(seeds: int) -> None:
    print(f"kidnap_bearing: kidnapped >= 2 m at t = 10 s, random walk to 40 s, {seeds} seeds; recovered: < 0.2 m within 30 s")
    for name in ("mcl_bearing", "mcl_bearing_paper"):
        times, wrong, longest = [], 0, 0.0
        for seed in range(seeds):
            run = drive(name, STATIC, 1200, seed, policy="random_walk", kidnap_at=300)
            times.append(run.recovery_s())
            wrong += run.wrong_claims(since_s=EVENT_S)
            longest = max(longest, run.longest_wrong_s())
        ok = [t for t in times if t <= 30.0]
        print(
            f"  {name:<20} recovered {len(ok)}/{seeds}  median time {np.median(ok) if ok else math.nan:5.2f} s"
            f"  >1m-off claims after the kidnap {wrong}  longest {longest:.1f} s  times {[round(t, 2) for t in times]}"
        )


def lidar_variants() -> list[tuple[str, dict[str, Any]]]:
    return [
        ("mcl_lidar", {}),
        ("mcl_lidar", {"recovery": True}),
        ("far_point_mcl", {}),
        ("far_point_mcl", {"mcl": {"recovery": True}}),
    ]


def case_odometry_jump(seeds: int) -> None:
    print("odometry_jump: two 5 m forward odometry increments at t = 10 s (the robot does not move), circle to 40 s")

    def jump(k: int, d: np.ndarray) -> np.ndarray:
        return d + np.array([5.0, 0.0, 0.0]) if k in (400, 401) else d

    for name, params in lidar_variants():
        for seed in range(min(seeds, 2)):
            run = drive(name, ROOM, 1600, seed, localizer_params=params, odometry=jump, **ROOM_KW)
            run.event_s = EVENT_S
            end = run.error_m[-40:]
            line(f"{name} {params} s{seed}", run, f" end err {np.nanmedian(end) if run.valid[-40:].any() else math.nan:.2f} m")


def case_zero_scans(seeds: int) -> None:
    print("zero_scans: all-zero scans from 10 s to 20 s, then good scans to 50 s, circle")

    def zeros(k: int, f: ScanMeasurement) -> ScanMeasurement:
        return ScanMeasurement(np.zeros_like(f.ranges_m), f.angles_rad, f.max_range_m) if 400 <= k < 800 else f

    for name, params in lidar_variants():
        for seed in range(min(seeds, 2)):
            run = drive(name, ROOM, 2000, seed, localizer_params=params, frame=zeros, **ROOM_KW)
            end = run.error_m[-40:]
            line(f"{name} {params} s{seed}", run, f" end err {np.nanmedian(end) if run.valid[-40:].any() else math.nan:.2f} m")


def case_kidnap_lidar(seeds: int) -> None:
    print(f"kidnap_lidar: kidnapped >= 2 m at t = 10 s, circle to 40 s, crowd of 4, {seeds} seeds")
    for name, params in lidar_variants():
        times, wrong, longest, ends = [], 0, 0.0, []
        for seed in range(seeds):
            run = drive(name, ROOM, 1600, seed, localizer_params=params, kidnap_at=400, **ROOM_KW)
            times.append(run.recovery_s(0.3))
            wrong += run.wrong_claims(since_s=EVENT_S)
            longest = max(longest, run.longest_wrong_s())
            ends.append(float(np.nanmedian(run.error_m[-40:])) if run.valid[-40:].any() else math.nan)
        ok = [t for t in times if t <= 30.0]
        print(
            f"  {name} {params}: recovered (< 0.3 m) {len(ok)}/{seeds}  >1m-off claims {wrong}  longest {longest:.1f} s"
            f"  times {[round(t, 2) for t in times]}  end errors {[round(e, 2) for e in ends]}"
        )


CASES = {
    "one_landmark": case_one_landmark,
    "swapped_ids": case_swapped_ids,
    "kidnap_bearing": case_kidnap_bearing,
    "odometry_jump": case_odometry_jump,
    "zero_scans": case_zero_scans,
    "kidnap_lidar": case_kidnap_lidar,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*", help=", ".join(CASES))
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    for case in args.cases or list(CASES):
        t0 = time.perf_counter()
        CASES[case](args.seeds)
        print(f"  ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
