"""Lost and found: drive a localizer through a crowdloc env while a scenario tampers
with the world or with what the localizer is fed (a kidnapping, an odometry jump, blank, thinned,
swapped or zeroed frames), and measure how wrong it is while it claims a pose, how consistent its
spread is and how soon it is right again. The one harness of the recovery tests
(test_mcl_recovery.py, test_gauss_recovery.py), the coasting runs (coasting.py) and the figures
(``python -m tests.localizers.lost_figures``).

Steps are numbered from 1 (step ``n`` gives the frame at ``t = n dt``); the reset frame is fed as
the env feeds it, untouched by any filter."""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import envs  # noqa: F401
from agents.evaluate.metrics import chi2_quantile, pose_nees
from agents.experiments.scenarios import kidnap
from agents.policies import make_policy
from localizers.base import BearingMeasurement, OdometryDelta, PoseEstimate, ScanMeasurement

#: a gentle circle: forward at 40 % of top speed, turning at 20 % of the top turn rate
CIRCLE = np.array([0.4, 0.2], dtype=np.float32)
#: the faster circle the particle filters' recovery tests were measured on: 60 % forward, 20 % turn
FAST_CIRCLE = np.array([0.6, 0.2], dtype=np.float32)

STATIC, CROWDED, ROOM = "crowdloc/RoboCupStatic-v0", "crowdloc/RoboCupCrowded-v0", "crowdloc/CrowdedRoom-v0"
ROOM_KW: dict[str, Any] = {"crowd_size": 4}
EVENT_S = 10.0

#: the random streams the kidnapper draws from (``[seed, stream]``): the gauss localizers' tests
#: were measured with the first, the particle filters' with the second
KIDNAP_STREAM, MCL_KIDNAP_STREAM = 19, 0xC0FFEE
#: how the particle filters' runs were measured: the faster circle, the kidnapper's second stream
MCL_RUN: dict[str, Any] = {"action": FAST_CIRCLE, "kidnap_stream": MCL_KIDNAP_STREAM}
#: the gauss localizers' kidnapping: before step 300 (30 Hz), the recovery counted from t = 10 s
GAUSS_KIDNAP: dict[str, Any] = {"kidnap_at": 300, "event_s": EVENT_S}

Frame = Callable[[int, Any], Any]
Odometry = Callable[[int, NDArray[np.float64]], NDArray[np.float64]]


@dataclass
class Run:
    """One drive, per step (after the reset frame).

    Attributes:
        t_s: ``(T,)`` time since the reset.
        error_m: ``(T,)`` position error of the estimate (NaN where it is not valid).
        valid: ``(T,)`` whether it claimed a pose.
        spread_m: ``(T,)`` its position spread (NaN where not valid).
        nees: ``(T,)`` its position NEES (2 dof; NaN where not valid).
        estimates: the estimate after each step.
        odometry: ``(T, 3)`` the odometry increments fed to the localizer.
        sensor_metadata: the env's sensor metadata (the odometry's alphas, ...).
        event_s: the time of the kidnap or the odometry jump (NaN: none); recovery counts from it.
    """

    t_s: NDArray[np.float64]
    error_m: NDArray[np.float64]
    valid: NDArray[np.bool_]
    spread_m: NDArray[np.float64]
    nees: NDArray[np.float64]
    estimates: list[PoseEstimate] = field(default_factory=list, repr=False)
    odometry: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)), repr=False)
    sensor_metadata: dict[str, Any] = field(default_factory=dict, repr=False)
    event_s: float = math.nan

    def window(self, start_s: float, end_s: float = math.inf) -> NDArray[np.bool_]:
        return (self.t_s >= start_s) & (self.t_s < end_s)

    def outside_3sd(self, mask: NDArray[np.bool_]) -> float:
        """Share of the valid steps in ``mask`` whose error lies outside the 3-sd region
        (position NEES above the chi-square 2-dof quantile of the 3-sd 1-D mass, 0.9973)."""
        v = self.nees[mask & self.valid]
        return float(np.mean(v > chi2_quantile(0.9973, 2))) if v.size else math.nan

    def recovery_s(self, threshold_m: float = 0.2, hold_s: float = 0.0) -> float:
        """Seconds from the event to the first valid estimate after it within ``threshold_m``
        that stays within it for ``hold_s`` (0: the first such estimate; inf: never)."""
        ok = self.valid & (self.error_m < threshold_m)
        start = None
        for i in np.flatnonzero(self.t_s > self.event_s):
            if ok[i]:
                start = i if start is None else start
                if self.t_s[i] - self.t_s[start] >= hold_s - 1e-9:
                    return float(self.t_s[start] - self.event_s)
            else:
                start = None
        return math.inf

    def _wrong(self, threshold_m: float) -> NDArray[np.bool_]:
        return self.valid & (np.nan_to_num(self.error_m, nan=0.0) > threshold_m)

    def wrong_claims(self, threshold_m: float = 1.0, since_s: float = 0.0) -> int:
        """Valid estimates more than ``threshold_m`` off, from ``since_s`` on."""
        return int(np.count_nonzero(self._wrong(threshold_m) & (self.t_s >= since_s)))

    def longest_wrong_s(self, threshold_m: float = 1.0) -> float:
        """The longest stretch (s) of consecutive valid estimates more than ``threshold_m`` off."""
        best = run = 0
        for w in self._wrong(threshold_m).tolist():
            run = run + 1 if w else 0
            best = max(best, run)
        dt = float(self.t_s[1] - self.t_s[0]) if self.t_s.size > 1 else 0.0
        return best * dt

    def spread_of_wrong_claims(self, threshold_m: float = 1.0) -> float:
        """Median reported spread (m) of the valid estimates more than ``threshold_m`` off (nan: none)."""
        wrong = self._wrong(threshold_m)
        return float(np.median(self.spread_m[wrong])) if wrong.any() else math.nan


def drive(
    localizer: str,
    env_id: str,
    steps: int,
    seed: int = 0,
    *,
    policy: str | None = None,
    action: NDArray[np.float32] = CIRCLE,
    localizer_params: dict[str, Any] | None = None,
    kidnap_at: int | None = None,
    kidnap_stream: int = KIDNAP_STREAM,
    event_s: float | None = None,
    frame: Frame | None = None,
    odometry: Odometry | None = None,
    **env_kwargs: Any,
) -> Run:
    """Drive ``steps`` steps of the fixed policy ``policy`` (seeded with ``seed``) or, without
    one, the fixed ``action``, feeding the localizer the odometry and frames of each step ``n``
    (through ``odometry(n, d)`` and ``frame(n, f)`` when given), and kidnapping the robot
    (:func:`agents.experiments.scenarios.kidnap`, at least 2 m, drawn from ``[seed, kidnap_stream]``)
    before step ``kidnap_at``. ``event_s`` (default: the time of the kidnap) is where the
    recovery time counts from."""
    env = gym.make(
        env_id, localizer=localizer, localizer_params=localizer_params or {}, max_episode_steps=steps + 1, **env_kwargs
    )
    wrapper = env
    while not hasattr(wrapper, "localizer"):
        wrapper = wrapper.env
    obs, _ = env.reset(seed=seed)
    base = wrapper.env
    loc = wrapper.localizer
    act = make_policy(policy, env, seed=seed) if policy is not None else None
    world_rng = np.random.default_rng([seed, kidnap_stream])
    dt = float(base.unwrapped.config.dt_s)
    estimates, truth, increments = [], np.empty((steps, 3)), np.empty((steps, 3))
    for n in range(1, steps + 1):
        if n == kidnap_at:
            kidnap(base.unwrapped.world, world_rng, min_distance_m=2.0)
        obs, _, _, _, info = base.step(action if act is None else act.predict(obs)[0])
        d = np.asarray(obs[wrapper._odometry_key], dtype=np.float64)
        if odometry is not None:
            d = odometry(n, d)
        increments[n - 1] = d
        loc.predict(OdometryDelta(float(d[0]), float(d[1]), float(d[2])))
        f = wrapper._decode(obs[wrapper._sensor_key], wrapper._sensor_meta)
        loc.update(frame(n, f) if frame is not None else f)
        estimates.append(loc.estimate)
        truth[n - 1] = np.asarray(info["true_pose"], dtype=np.float64)
    metadata = base.unwrapped.sensor_metadata
    env.close()
    valid = np.array([e.valid for e in estimates], dtype=bool)
    est = np.array([e.as_array() for e in estimates]).reshape(-1, 3)
    est[~valid] = np.nan
    cov = np.array([np.asarray(e.covariance, dtype=np.float64) for e in estimates]).reshape(-1, 3, 3)
    error = np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1])
    spread = np.sqrt(cov[:, 0, 0] + cov[:, 1, 1])
    spread[~valid] = np.nan
    if event_s is None:
        event_s = math.nan if kidnap_at is None else (kidnap_at - 1) * dt
    return Run(
        np.arange(1, steps + 1) * dt,
        error,
        valid,
        spread,
        pose_nees(est, truth, cov, dof=2),
        estimates,
        increments,
        metadata,
        float(event_s),
    )


def during(change: Callable[[Any], Any], start: int = 1, stop: int | None = None) -> Frame:
    """A frame filter: ``change`` applied to the frames of steps ``start`` to ``stop`` (excluded; None: the end)."""
    return lambda n, f: change(f) if start <= n and (stop is None or n < stop) else f


def blank(measurement: Any) -> Any:
    """The frame a sensor gives when it sees nothing: no bearings; every beam at its maximum range."""
    if isinstance(measurement, BearingMeasurement):
        return BearingMeasurement.empty()
    if isinstance(measurement, ScanMeasurement):
        return ScanMeasurement(
            np.full_like(measurement.ranges_m, measurement.max_range_m), measurement.angles_rad, measurement.max_range_m
        )
    raise TypeError(f"no blank frame for {type(measurement).__name__}")


def lowest_landmark(f: BearingMeasurement) -> BearingMeasurement:
    """Only the bearing to the lowest landmark id in view."""
    if f.landmark_ids.size <= 1:
        return f
    i = int(np.argmin(f.landmark_ids))
    return BearingMeasurement(f.landmark_ids[i : i + 1].copy(), f.bearings_rad[i : i + 1].copy())


def swap_ids(f: BearingMeasurement) -> BearingMeasurement:
    """Landmarks 0 and 1 swap ids (a consistent misidentification)."""
    ids = f.landmark_ids.copy()
    ids[f.landmark_ids == 0], ids[f.landmark_ids == 1] = 1, 0
    return BearingMeasurement(ids, f.bearings_rad)


def zero_ranges(f: ScanMeasurement) -> ScanMeasurement:
    """An all-zero scan (a blocked sensor)."""
    return ScanMeasurement(np.zeros_like(f.ranges_m), f.angles_rad, f.max_range_m)


def no_landmarks(start: int = 1, stop: int | None = None) -> Frame:
    """Every bearing removed from step ``start`` on (to ``stop``)."""
    return during(lambda f: BearingMeasurement.empty(), start, stop)


def one_landmark(start: int = 1, stop: int | None = None) -> Frame:
    """From step ``start`` on (to ``stop``), only the bearing to the lowest landmark id in view."""
    return during(lowest_landmark, start, stop)


def swapped(start: int = 1, stop: int | None = None) -> Frame:
    """From step ``start`` on (to ``stop``), landmarks 0 and 1 swap ids."""
    return during(swap_ids, start, stop)


def zero_scans(start: int = 1, stop: int | None = None) -> Frame:
    """All-zero scans from step ``start`` on (to ``stop``)."""
    return during(zero_ranges, start, stop)


def odometry_jump(forward_m: float, steps: Collection[int]) -> Odometry:
    """``forward_m`` added to the forward odometry increment of each of ``steps`` (motion the robot does not make)."""

    def jumped(n: int, d: NDArray[np.float64]) -> NDArray[np.float64]:
        if n not in steps:
            return d
        d = d.copy()
        d[0] += forward_m
        return d

    return jumped
