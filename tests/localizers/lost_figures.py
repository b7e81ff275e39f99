"""The lost-and-found stress cases, measured: how wrong the localizers are while they claim a pose, how
consistent their spread is, and how soon they are right again (tests/localizers/lost.py drives them).

    python -m tests.localizers.lost_figures [case ...] [--seeds N]

The particle filters' cases: one_landmark, swapped_ids, kidnap_bearing, odometry_jump, zero_scans,
kidnap_lidar. Those of dead_reckoning, resection, kalman and candidate_sets (gauss_*):

- gauss_coast: 10 s with every bearing, then 333 s with none (circle): spread, error, share > 3 sd.
- gauss_one_landmark: 10 s with every bearing, then 60 s with only one (circle): share > 3 sd.
- gauss_kidnap: kidnapped (>= 2 m) at t = 10 s, circle or random walk, 40 s; recovered = error
  < 0.2 m for 1 s within 30 s; the longest stretch of valid estimates more than 1 m off.
- gauss_odometry_jump: 10 m added to one increment at t = 10 s (circle), error after 30 s.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

from tests.localizers.lost import (
    CROWDED,
    EVENT_S,
    GAUSS_KIDNAP,
    MCL_RUN,
    ROOM,
    ROOM_KW,
    STATIC,
    Run,
    drive,
    no_landmarks,
    odometry_jump,
    one_landmark,
    swapped,
    zero_scans,
)


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
        line(f"seed {seed}", drive("mcl_bearing", STATIC, 10_000, seed, policy="random_walk", frame=one_landmark()))


def case_swapped_ids(seeds: int) -> None:
    print("swapped_ids: landmarks 0 and 1 swap ids, random walk, 1800 steps (60 s)")
    for name in ("mcl_bearing_paper", "mcl_bearing"):
        for seed in range(min(seeds, 2)):
            line(f"{name} seed {seed}", drive(name, STATIC, 1800, seed, policy="random_walk", frame=swapped()))


def case_kidnap_bearing(seeds: int) -> None:
    print(f"kidnap_bearing: kidnapped >= 2 m at t = 10 s, random walk to 40 s, {seeds} seeds; recovered: < 0.2 m within 30 s")
    for name in ("mcl_bearing", "mcl_bearing_paper"):
        times, wrong, longest = [], 0, 0.0
        for seed in range(seeds):
            run = drive(name, STATIC, 1200, seed, policy="random_walk", kidnap_at=301, **MCL_RUN)
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
    jump = odometry_jump(5.0, (401, 402))
    for name, params in lidar_variants():
        for seed in range(min(seeds, 2)):
            run = drive(name, ROOM, 1600, seed, localizer_params=params, odometry=jump, event_s=EVENT_S, **MCL_RUN, **ROOM_KW)
            end = run.error_m[-40:]
            line(f"{name} {params} s{seed}", run, f" end err {np.nanmedian(end) if run.valid[-40:].any() else math.nan:.2f} m")


def case_zero_scans(seeds: int) -> None:
    print("zero_scans: all-zero scans from 10 s to 20 s, then good scans to 50 s, circle")
    zeros = zero_scans(401, 801)
    for name, params in lidar_variants():
        for seed in range(min(seeds, 2)):
            run = drive(name, ROOM, 2000, seed, localizer_params=params, frame=zeros, **MCL_RUN, **ROOM_KW)
            end = run.error_m[-40:]
            line(f"{name} {params} s{seed}", run, f" end err {np.nanmedian(end) if run.valid[-40:].any() else math.nan:.2f} m")


def case_kidnap_lidar(seeds: int) -> None:
    print(f"kidnap_lidar: kidnapped >= 2 m at t = 10 s, circle to 40 s, crowd of 4, {seeds} seeds")
    for name, params in lidar_variants():
        times, wrong, longest, ends = [], 0, 0.0, []
        for seed in range(seeds):
            run = drive(name, ROOM, 1600, seed, localizer_params=params, kidnap_at=401, **MCL_RUN, **ROOM_KW)
            times.append(run.recovery_s(0.3))
            wrong += run.wrong_claims(since_s=EVENT_S)
            longest = max(longest, run.longest_wrong_s())
            ends.append(float(np.nanmedian(run.error_m[-40:])) if run.valid[-40:].any() else math.nan)
        ok = [t for t in times if t <= 30.0]
        print(
            f"  {name} {params}: recovered (< 0.3 m) {len(ok)}/{seeds}  >1m-off claims {wrong}  longest {longest:.1f} s"
            f"  times {[round(t, 2) for t in times]}  end errors {[round(e, 2) for e in ends]}"
        )


GAUSS = ("dead_reckoning", "resection", "kalman", "candidate_sets")
#: (env id, policy, env kwargs); the random walk drives into the static field's walls, where the
#: odometry goes on counting (a kidnap of its own before the one at 10 s), so it gets the circle too
GAUSS_KIDNAP_WORLDS: tuple[tuple[str, str | None, dict[str, Any]], ...] = (
    (STATIC, None, {}),
    (STATIC, "random_walk", {}),
    (CROWDED, None, {"crowd_size": 3}),
    (CROWDED, "random_walk", {"crowd_size": 3}),
)


def case_gauss_coast(seeds: int) -> None:
    for name in ("kalman", "candidate_sets"):
        r = drive(name, STATIC, 10290, frame=no_landmarks(300))
        w = r.window(10.0)
        last = np.flatnonzero(w)[-1]
        print(
            f"coast 333 s  {name:15s} valid {r.valid[w].mean():.2f}  spread_end {r.spread_m[last]:.3f} m  "
            f"error_end {r.error_m[last]:.3f} m  >3sd {r.outside_3sd(w):.2f}  nees_median {np.nanmedian(r.nees[w]):.1f}"
        )


def case_gauss_one_landmark(seeds: int) -> None:
    for name in ("kalman", "candidate_sets"):
        r = drive(name, STATIC, 2100, frame=one_landmark(300))
        w = r.window(10.0)
        print(
            f"one landmark {name:15s} valid {r.valid[w].mean():.2f}  >3sd {r.outside_3sd(w):.2f}  "
            f"nees_median {np.nanmedian(r.nees[w]):.1f}  error_end {r.error_m[-1]:.3f} m  spread_end {r.spread_m[-1]:.3f} m"
        )


def case_gauss_kidnap(seeds: int) -> None:
    for env_id, policy, kwargs in GAUSS_KIDNAP_WORLDS:
        for name in GAUSS:
            runs = [drive(name, env_id, 1200, s, policy=policy, **GAUSS_KIDNAP, **kwargs) for s in range(seeds)]
            rec = np.array([r.recovery_s(hold_s=1.0) for r in runs])
            wrong = np.array([r.longest_wrong_s() for r in runs])
            after = [r.window(10.0) for r in runs]
            valid = np.mean([r.valid[a].mean() for r, a in zip(runs, after, strict=True)])
            ok = rec <= 30.0
            print(
                f"kidnap {env_id.split('/')[1]:18s} {policy or 'circle':11s} {name:15s} recovered {int(ok.sum())}/{seeds}  "
                f"median_time {np.median(rec[ok]) if ok.any() else np.inf:.1f} s  longest_wrong max {wrong.max():.1f} s "
                f"median {np.median(wrong):.1f} s  valid_after {valid:.2f}  "
                f"error_end median {np.median(np.nan_to_num([r.error_m[-1] for r in runs], nan=np.inf)):.2f} m (inf: invalid)"
            )


def case_gauss_odometry_jump(seeds: int) -> None:
    for name in ("kalman", "candidate_sets", "dead_reckoning"):
        r = drive(name, STATIC, 1200, odometry=odometry_jump(10.0, (300,)), event_s=EVENT_S)
        print(
            f"odometry jump 10 m {name:15s} error_end {r.error_m[-1]:.3f} m  valid_end {r.valid[-1]}  "
            f"recovered {r.recovery_s(hold_s=1.0):.1f} s  longest_wrong {r.longest_wrong_s():.1f} s"
        )


CASES = {
    "one_landmark": case_one_landmark,
    "swapped_ids": case_swapped_ids,
    "kidnap_bearing": case_kidnap_bearing,
    "odometry_jump": case_odometry_jump,
    "zero_scans": case_zero_scans,
    "kidnap_lidar": case_kidnap_lidar,
    "gauss_coast": case_gauss_coast,
    "gauss_one_landmark": case_gauss_one_landmark,
    "gauss_kidnap": case_gauss_kidnap,
    "gauss_odometry_jump": case_gauss_odometry_jump,
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
