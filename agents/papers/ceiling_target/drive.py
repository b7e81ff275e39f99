"""Tables 5-6 of the ceiling-target paper and the drives beyond it.

The corridor_follower drives the corridor from the start target to the last one on the
``ceiling_target`` localizer: with correction at every target (Table 6) and with the start fix
only, dead reckoning and the sonar after it (Table 5). Where the robot really stood at each
stop is read from the ground truth (``info["true_pose"]``), which neither the policy nor the
localizer sees. One episode is one seed; nothing but the pipeline's output is kept (no
images: a 2,000-frame drive would be about 460 MB of them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the ids)
from agents.evaluate import consistency, metrics
from agents.policies import make_policy
from agents.policies.navigation import CorridorFollower
from envs.localization_env import LocalizationEnv

ENV_ID = "crowdloc/CeilingCorridor-v0"


@dataclass(frozen=True)
class DriveTask:
    """One drive: a seed, a crowd size, the localizer's parameters, the policy's and the camera's overrides."""

    seed: int
    crowd: int = 0
    localizer: Mapping[str, Any] = field(default_factory=dict)
    policy: Mapping[str, Any] = field(default_factory=dict)
    camera: Mapping[str, Any] = field(default_factory=dict)
    label: str = ""


@dataclass(frozen=True)
class DriveResult:
    """What one drive did: per target stop the true error; the time, contacts and the policy's counts."""

    task: DriveTask
    stops: list[dict[str, Any]]
    time_s: float
    reached_goal: bool
    remeasures: int
    missed: int
    contacts: int
    fixes: int
    max_error_between_m: float  # the largest true-vs-estimate position error along the drive
    errors_m: list[float]  # true-vs-estimate position error per step (for the spacing study)
    travelled_m: list[float]  # the true distance driven since the last fix, per step
    nees_median: float  # of the pose against the reported covariance, over the steps with an estimate
    inside_95: float  # share of those steps inside the reported 95 % region


#: the paper's robot dead-reckons between targets for as long as it drives: crowdloc's claim limit
#: (ours: ``max_spread_m``) is off, so Table 5's drive without correction has an estimate
#: at every target as the paper's had
AS_IN_PAPER: dict[str, Any] = {"max_spread_m": math.inf}


def drive(task: DriveTask) -> DriveResult:
    """Run one drive (module docstring)."""
    kwargs: dict[str, Any] = {"localizer": "ceiling_target", "localizer_params": {**AS_IN_PAPER, **dict(task.localizer)}}
    if task.camera:
        kwargs["camera"] = dict(task.camera)
    env = gym.make(ENV_ID, crowd_size=task.crowd, **kwargs)
    policy = make_policy("corridor_follower", env, seed=task.seed, **dict(task.policy))
    assert isinstance(policy, CorridorFollower)
    obs, info = env.reset(seed=task.seed)
    base = env.unwrapped
    assert isinstance(base, LocalizationEnv)
    localizer = env.get_wrapper_attr("localizer")
    truths = [np.asarray(info["true_pose"], dtype=np.float64)]
    errors, travelled = [], []
    estimates, covariances = [], []
    since_fix, fixes_seen, contacts = 0.0, localizer.fixes, 0
    terminated = truncated = False
    steps = 0
    while not (terminated or truncated):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
        truth = np.asarray(info["true_pose"], dtype=np.float64)
        since_fix += float(np.hypot(*(truth[:2] - truths[-1][:2])))
        truths.append(truth)
        contacts += len(info["contacts"])
        if localizer.fixes != fixes_seen:
            fixes_seen, since_fix = localizer.fixes, 0.0
        est = info["estimate"]
        errors.append(float(math.hypot(est.x_m - truth[0], est.y_m - truth[1])) if est.valid else math.nan)
        estimates.append(est.as_array() if est.valid else np.full(3, np.nan))
        covariances.append(np.asarray(est.covariance, dtype=np.float64))
        travelled.append(since_fix)
    targets = {t["name"]: t for t in base.landmark_map.features["ceiling"]["targets"]}
    stops = []
    for stop in policy.stops:
        truth = truths[min(stop.step, len(truths) - 1)]
        target = targets[stop.target]
        stops.append({"target": stop.target, "target_y_m": target["y_m"], "fixed": stop.fixed, "measurements": stop.measurements,
                      "x_cm": 100 * (truth[0] - target["x_m"]), "y_cm": 100 * (truth[1] - target["y_m"])})  # fmt: skip
    env.close()
    finite = [e for e in errors if math.isfinite(e)]
    nees = consistency.run_nees(
        "ceiling_target", np.array(estimates).reshape(-1, 3), np.array(truths[1:]).reshape(-1, 3), np.array(covariances)
    )
    fit = metrics.consistency(nees, consistency.POSE_DOF)  # over the steps with an estimate and a covariance
    return DriveResult(
        task, stops, steps * base.config.dt_s, bool(terminated), policy.remeasures, policy.missed, contacts,
        localizer.fixes, max(finite) if finite else math.nan, errors, travelled,
        fit.nees_median, fit.inside_95,
    )  # fmt: skip


def summarize(results: list[DriveResult], targets_m: tuple[float, ...]) -> dict[float, dict[str, Any]]:
    """Per target: mean and sd of the true (X, Y) error [cm] at its stop over the drives that stopped there."""
    out = {}
    for y in targets_m:
        xs = [s["x_cm"] for r in results for s in r.stops if abs(s["target_y_m"] - y) < 1e-6]
        ys = [s["y_cm"] for r in results for s in r.stops if abs(s["target_y_m"] - y) < 1e-6]
        out[y] = {"n": len(xs), "x_mean": _mean(xs), "x_sd": _sd(xs), "y_mean": _mean(ys), "y_sd": _sd(ys)}
    return out


def _mean(v: list[float]) -> float:
    return float(np.mean(v)) if v else math.nan


def _sd(v: list[float]) -> float:
    return float(np.std(v, ddof=1)) if len(v) > 1 else math.nan
