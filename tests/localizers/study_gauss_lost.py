"""Measure the stress cases of issue 19 for dead_reckoning, resection, kalman and candidate_sets
(run: ``python -m tests.localizers.study_gauss_lost [seeds]``; prints one line per figure).

- coast: 10 s with every bearing, then 333 s with none (circle): spread, error, share > 3 sd.
- one landmark: 10 s with every bearing, then 60 s with only one (circle): share > 3 sd.
- kidnap: kidnapped (>= 2 m) at t = 10 s, circle or random walk, 40 s; recovered = error < 0.2 m for 1 s
  within 30 s; the longest stretch of valid estimates more than 1 m off.
- odometry jump: 10 m added to one increment at t = 10 s (circle), error after 30 s.
"""

from __future__ import annotations

import sys

import numpy as np

from tests.localizers.stress import no_landmarks, one_landmark, stress_run

NAMES = ("dead_reckoning", "resection", "kalman", "candidate_sets")
#: (env id, policy, env kwargs); the random walk drives into the static field's walls, where the
#: odometry goes on counting (a kidnap of its own before the one at 10 s), so it gets the circle too
KIDNAP_WORLDS = (
    ("crowdloc/RoboCupStatic-v0", "circle", {}),
    ("crowdloc/RoboCupStatic-v0", "random_walk", {}),
    ("crowdloc/RoboCupCrowded-v0", "circle", {"crowd_size": 3}),
    ("crowdloc/RoboCupCrowded-v0", "random_walk", {"crowd_size": 3}),
)


def main(seeds: int = 10) -> None:
    for name in ("kalman", "candidate_sets"):
        r = stress_run(name, policy="circle", duration_s=343.0, frames=no_landmarks(300))
        w = r.window(10.0)
        last = np.flatnonzero(w)[-1]
        print(
            f"coast 333 s  {name:15s} valid {r.valid[w].mean():.2f}  spread_end {r.spread_m[last]:.3f} m  "
            f"error_end {r.error_m[last]:.3f} m  >3sd {r.outside_3sd(w):.2f}  nees_median {np.nanmedian(r.nees[w]):.1f}"
        )
    for name in ("kalman", "candidate_sets"):
        r = stress_run(name, policy="circle", duration_s=70.0, frames=one_landmark(300))
        w = r.window(10.0)
        print(
            f"one landmark {name:15s} valid {r.valid[w].mean():.2f}  >3sd {r.outside_3sd(w):.2f}  "
            f"nees_median {np.nanmedian(r.nees[w]):.1f}  error_end {r.error_m[-1]:.3f} m  spread_end {r.spread_m[-1]:.3f} m"
        )
    for env_id, policy, kwargs in KIDNAP_WORLDS:
        for name in NAMES:
            runs = [stress_run(name, env_id, seed=s, policy=policy, kidnap_at_s=10.0, **kwargs) for s in range(seeds)]
            rec = np.array([r.recovery_s() for r in runs])
            wrong = np.array([r.longest_wrong_s() for r in runs])
            after = [r.window(10.0) for r in runs]
            valid = np.mean([r.valid[a].mean() for r, a in zip(runs, after, strict=True)])
            ok = rec <= 30.0
            print(
                f"kidnap {env_id.split('/')[1]:18s} {policy:11s} {name:15s} recovered {int(ok.sum())}/{seeds}  "
                f"median_time {np.median(rec[ok]) if ok.any() else np.inf:.1f} s  longest_wrong max {wrong.max():.1f} s "
                f"median {np.median(wrong):.1f} s  valid_after {valid:.2f}  "
                f"error_end median {np.median(np.nan_to_num([r.error_m[-1] for r in runs], nan=np.inf)):.2f} m (inf: invalid)"
            )
    for name in ("kalman", "candidate_sets", "dead_reckoning"):
        r = stress_run(name, policy="circle", duration_s=40.0, odometry_jump_m=10.0)
        print(
            f"odometry jump 10 m {name:15s} error_end {r.error_m[-1]:.3f} m  valid_end {r.valid[-1]}  "
            f"recovered {r.recovery_s():.1f} s  longest_wrong {r.longest_wrong_s():.1f} s"
        )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
