"""Lost and found: drive a localizer through an env while a scenario tampers with the world or
with what the localizer is fed (a kidnapping, an odometry jump, blank or swapped frames), and
measure how wrong it is while it claims a pose and how soon it is right again. Shared by the
recovery tests (test_mcl_recovery.py) and the before/after figures
(``python -m tests.localizers.lost_figures``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import envs  # noqa: F401
from agents.policies import make_policy
from agents.scenarios import kidnap
from localizers.base import BearingMeasurement, OdometryDelta

#: a gentle circle: forward at 60 % of top speed, turning at 20 % of the top turn rate
CIRCLE = np.array([0.6, 0.2], dtype=np.float32)

Frame = Callable[[int, Any], Any]
Odometry = Callable[[int, NDArray[np.float64]], NDArray[np.float64]]


@dataclass
class Run:
    """One drive: per step the time, the position error (nan where not valid), the claim and the spread."""

    t_s: NDArray[np.float64]
    error_m: NDArray[np.float64]
    valid: NDArray[np.bool_]
    spread_m: NDArray[np.float64]
    event_s: float = math.nan

    def recovery_s(self, threshold_m: float = 0.2) -> float:
        """Seconds from the event to the first valid estimate within ``threshold_m`` (inf: never)."""
        after = (self.t_s > self.event_s) & self.valid & (self.error_m < threshold_m)
        return float(self.t_s[np.argmax(after)] - self.event_s) if after.any() else math.inf

    def wrong_claims(self, threshold_m: float = 1.0, since_s: float = 0.0) -> int:
        """Valid estimates more than ``threshold_m`` off, from ``since_s`` on."""
        keep = self.t_s >= since_s
        return int(np.count_nonzero(self.valid[keep] & (self.error_m[keep] > threshold_m)))

    def longest_wrong_s(self, threshold_m: float = 1.0) -> float:
        """The longest stretch (s) of consecutive valid estimates more than ``threshold_m`` off."""
        bad = self.valid & (self.error_m > threshold_m)
        best = run = 0
        for b in bad.tolist():
            run = run + 1 if b else 0
            best = max(best, run)
        dt = float(self.t_s[1] - self.t_s[0]) if self.t_s.size > 1 else 0.0
        return best * dt

    def spread_of_wrong_claims(self, threshold_m: float = 1.0) -> float:
        """Median reported spread (m) of the valid estimates more than ``threshold_m`` off (nan: none)."""
        bad = self.valid & (self.error_m > threshold_m)
        return float(np.median(self.spread_m[bad])) if bad.any() else math.nan


def drive(
    localizer: str,
    env_id: str,
    steps: int,
    seed: int = 0,
    *,
    policy: str = "circle",
    localizer_params: dict[str, Any] | None = None,
    kidnap_at: int | None = None,
    frame: Frame | None = None,
    odometry: Odometry | None = None,
    **env_kwargs: Any,
) -> Run:
    """Drive ``steps`` steps (``policy``: ``"circle"`` for :data:`CIRCLE`, else a fixed policy's
    name), feeding the localizer the odometry and frames (through ``odometry(k, d)`` and
    ``frame(k, f)`` when given), and kidnapping the robot (:func:`agents.scenarios.kidnap`, at
    least 2 m) before step ``kidnap_at``."""
    env = gym.make(
        env_id, localizer=localizer, localizer_params=localizer_params or {}, max_episode_steps=steps + 1, **env_kwargs
    )
    wrapper = env
    while not hasattr(wrapper, "localizer"):
        wrapper = wrapper.env
    obs, _ = env.reset(seed=seed)
    base = wrapper.env
    loc = wrapper.localizer
    act = make_policy(policy, env, seed=seed) if policy != "circle" else None
    world_rng = np.random.default_rng([seed, 0xC0FFEE])
    dt = float(base.unwrapped.config.dt_s)
    errors, valid, spreads = np.full(steps, math.nan), np.zeros(steps, bool), np.full(steps, math.nan)
    for k in range(steps):
        if k == kidnap_at:
            kidnap(base.unwrapped.world, world_rng, min_distance_m=2.0)
        action = CIRCLE if act is None else act.predict(obs)[0]
        obs, _, terminated, truncated, info = base.step(action)
        d = np.asarray(obs[wrapper._odometry_key], dtype=np.float64)
        if odometry is not None:
            d = odometry(k, d)
        loc.predict(OdometryDelta(float(d[0]), float(d[1]), float(d[2])))
        f = wrapper._decode(obs[wrapper._sensor_key], wrapper._sensor_meta)
        loc.update(frame(k, f) if frame is not None else f)
        est = loc.estimate
        truth = np.asarray(info["true_pose"], dtype=np.float64)
        valid[k] = est.valid
        if est.valid:
            errors[k] = math.hypot(est.x_m - truth[0], est.y_m - truth[1])
            spreads[k] = est.position_spread_m
    env.close()
    return Run(np.arange(1, steps + 1) * dt, errors, valid, spreads, math.nan if kidnap_at is None else kidnap_at * dt)


STATIC, ROOM = "crowdloc/RoboCupStatic-v0", "crowdloc/CrowdedRoom-v0"
ROOM_KW: dict[str, Any] = {"crowd_size": 4}
EVENT_S = 10.0


def one_landmark(k: int, f: BearingMeasurement) -> BearingMeasurement:
    """Only the lowest-id landmark of the frame."""
    if f.landmark_ids.size <= 1:
        return f
    i = int(np.argmin(f.landmark_ids))
    return BearingMeasurement(f.landmark_ids[i : i + 1], f.bearings_rad[i : i + 1])


def swapped(k: int, f: BearingMeasurement) -> BearingMeasurement:
    """Landmarks 0 and 1 swap ids (a consistent misidentification)."""
    ids = f.landmark_ids.copy()
    ids[f.landmark_ids == 0], ids[f.landmark_ids == 1] = 1, 0
    return BearingMeasurement(ids, f.bearings_rad)
