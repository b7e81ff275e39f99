"""Stress runs for the localizers that must know when they are lost (issue 19): a localizer
inside a crowdloc env with its frames thinned (no landmark, one landmark), the robot kidnapped
(moved without the odometry seeing it) or the odometry jumping. Shared by the recovery tests
and the measurement script :mod:`tests.localizers.study_gauss_lost`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import envs  # noqa: F401
from agents.metrics import chi2_quantile, pose_nees
from agents.policies import make_policy
from agents.scenarios import kidnap
from localizers.base import BearingMeasurement, OdometryDelta

#: a gentle circle: forward at 40 % of top speed, turning at 20 % of the top turn rate
CIRCLE = np.array([0.4, 0.2], dtype=np.float32)

Frames = Callable[[int, BearingMeasurement], BearingMeasurement]


def no_landmarks(after_step: int) -> Frames:
    """Frames with every bearing removed from step ``after_step`` on."""
    return lambda k, m: BearingMeasurement.empty() if k >= after_step else m


def one_landmark(after_step: int) -> Frames:
    """From step ``after_step`` on, only the bearing to the lowest landmark id in view."""

    def thin(k: int, m: BearingMeasurement) -> BearingMeasurement:
        if k < after_step or m.landmark_ids.size <= 1:
            return m
        i = int(np.argmin(m.landmark_ids))
        return BearingMeasurement(m.landmark_ids[i : i + 1].copy(), m.bearings_rad[i : i + 1].copy())

    return thin


@dataclass
class Run:
    """One stress run, per step (after the reset frame).

    Attributes:
        time_s: ``(T,)`` time since the reset.
        error_m: ``(T,)`` position error of the estimate (NaN where it is not valid).
        valid: ``(T,)`` whether it claimed a pose.
        spread_m: ``(T,)`` its position spread (NaN where not valid).
        nees: ``(T,)`` its position NEES (2 dof; NaN where not valid).
        event_s: the time of the kidnap or the odometry jump (NaN: none).
    """

    time_s: NDArray[np.float64]
    error_m: NDArray[np.float64]
    valid: NDArray[np.bool_]
    spread_m: NDArray[np.float64]
    nees: NDArray[np.float64]
    event_s: float = math.nan

    def window(self, start_s: float, end_s: float = math.inf) -> NDArray[np.bool_]:
        return (self.time_s >= start_s) & (self.time_s < end_s)

    def outside_3sd(self, mask: NDArray[np.bool_]) -> float:
        """Share of the valid steps in ``mask`` whose error lies outside the 3-sd region
        (position NEES above the chi-square 2-dof quantile of the 3-sd 1-D mass, 0.9973)."""
        v = self.nees[mask & self.valid]
        return float(np.mean(v > chi2_quantile(0.9973, 2))) if v.size else math.nan

    def recovery_s(self, threshold_m: float = 0.2, hold_s: float = 1.0) -> float:
        """Seconds after the event until the error stays below ``threshold_m`` for ``hold_s`` (inf: never)."""
        ok = np.isfinite(self.error_m) & (self.error_m < threshold_m)
        start = None
        for i in np.flatnonzero(self.time_s >= self.event_s):
            if ok[i]:
                start = i if start is None else start
                if self.time_s[i] - self.time_s[start] >= hold_s - 1e-9:
                    return float(self.time_s[start] - self.event_s)
            else:
                start = None
        return math.inf

    def longest_wrong_s(self, threshold_m: float = 1.0) -> float:
        """Longest stretch (s) of consecutive valid estimates more than ``threshold_m`` off."""
        wrong = self.valid & (np.nan_to_num(self.error_m, nan=0.0) > threshold_m)
        best = run = 0
        for w in wrong.tolist():
            run = run + 1 if w else 0
            best = max(best, run)
        dt = float(self.time_s[1] - self.time_s[0]) if self.time_s.size > 1 else 0.0
        return best * dt


def stress_run(
    localizer: str,
    env_id: str = "crowdloc/RoboCupStatic-v0",
    *,
    seed: int = 0,
    duration_s: float = 40.0,
    policy: str = "random_walk",
    kidnap_at_s: float | None = None,
    frames: Frames | None = None,
    odometry_jump_m: float = 0.0,
    jump_at_s: float = 10.0,
    localizer_params: dict[str, Any] | None = None,
    **env_kwargs: Any,
) -> Run:
    """Drive ``policy`` (``"random_walk"`` seeded with ``seed``, or ``"circle"``: :data:`CIRCLE`)
    for ``duration_s`` with ``localizer`` in the loop; optionally kidnap the robot
    (:func:`agents.scenarios.kidnap`, >= 2 m) at ``kidnap_at_s``, thin the frames, or add
    ``odometry_jump_m`` to one odometry increment's forward motion at ``jump_at_s``."""
    env = gym.make(env_id, localizer=localizer, localizer_params=localizer_params or {}, max_episode_steps=10**7, **env_kwargs)
    wrapper = env
    while not hasattr(wrapper, "localizer"):
        wrapper = wrapper.env
    dt = float(env.unwrapped.config.dt_s)
    steps = round(duration_s / dt)
    step = 0
    if frames is not None:
        decode = wrapper._decode
        wrapper._decode = lambda obs, meta: frames(step, decode(obs, meta))
    loc = wrapper.localizer
    jump_step = round(jump_at_s / dt)
    if odometry_jump_m:
        predict = loc.predict

        def jumped(d: OdometryDelta) -> None:
            if step == jump_step:
                d = OdometryDelta(d.dx_m + odometry_jump_m, d.dy_m, d.dtheta_rad)
            predict(d)

        loc.predict = jumped
    obs, info = env.reset(seed=seed)
    act = make_policy("random_walk", env, seed=seed) if policy == "random_walk" else None
    rng = np.random.default_rng([seed, 19])
    kidnap_step = None if kidnap_at_s is None else round(kidnap_at_s / dt)
    est_rows, truth_rows, covs, valid = [], [], [], []
    for step in range(1, steps + 1):
        if step == kidnap_step:
            kidnap(env.unwrapped.world, rng, min_distance_m=2.0)
        action = act.predict(obs)[0] if act is not None else CIRCLE
        obs, _, _, _, info = env.step(action)
        e = info["estimate"]
        est_rows.append(e.as_array())
        truth_rows.append(np.asarray(info["true_pose"], dtype=np.float64))
        covs.append(np.asarray(e.covariance, dtype=np.float64))
        valid.append(bool(e.valid))
    env.close()
    est, truth, cov, ok = np.array(est_rows), np.array(truth_rows), np.array(covs), np.array(valid)
    est[~ok] = np.nan
    error = np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1])
    spread = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    spread[~ok] = np.nan
    event = kidnap_at_s if kidnap_at_s is not None else (jump_at_s if odometry_jump_m else math.nan)
    return Run(np.arange(1, steps + 1) * dt, error, ok, spread, pose_nees(est, truth, cov, dof=2), float(event))
