"""``LocalizationObservation``: run a localizer inside the env loop and show its estimate to the policy.

The wrapper feeds the localizer what the robot senses (the observation), never the truth,
and adds to the observation:

- ``estimate`` ``(4,)``: ``(x, y)`` normalized to ``[-1, 1]`` over the field (clipped: a wild
  estimate outside the field shows at the border) and ``(cos theta, sin theta)``; zeros
  when there is no valid estimate;
- ``estimate_valid`` ``(1,)``: 1 when the localizer claims a pose;
- ``estimate_spread`` ``(2,)``: position spread over the field diagonal and heading spread
  over pi, both clipped to ``[0, 1]`` (1 when unknown);
- with ``belief_spread=True`` only, ``belief_spread`` ``(2,)``: the same two spreads of the
  localizer's hypotheses (candidates, particles; :func:`hypothesis_spread`), whether or not it
  claims a pose. Before a first fix it shows how far the localizer still is from one (an arc
  of candidates being pruned, particles gathering); localizers without hypotheses give their
  estimate's spread. A localizer may compute it itself with a ``hypothesis_spread()`` method
  (the candidate sets do, in one pass); it must equal :func:`hypothesis_spread` of its overlay.

``info["estimate"]`` holds the :class:`PoseEstimate` in world units for metrics. The
localizer draws from its own generator, seeded from the env seed, so filtering never
changes the world's random stream. The measurements come from the sensor that the
localizer's measurement kind reads (:mod:`localizers.measurements`), found through the base
env's ``sensor_metadata``; odometry from the ``odometry`` sensor. The wrapper composes a
localizer into the env loop, so it lives with the envs, above :mod:`localizers`, and reads the
env only through its ``landmark_map``, ``sensor_metadata`` and ``config``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.geometry import circular_std
from core.schema import ConfigError
from localizers.base import LandmarkMap, Localizer, Overlay, PoseEstimate
from localizers.measurements import (
    bearing_measurement,
    find_sensor,
    measurement_kind,
    odometry_delta,
    readable_kinds,
    sensor_map,
)
from localizers.registry import make_localizer, measurement_in, prepared_params, spec

__all__ = ["LocalizationObservation", "bearing_measurement", "decode_estimate", "encode_estimate", "hypothesis_spread"]

ESTIMATE_COLOR = (220, 30, 200)
_SEED_SALT = 0x10CA112E  # separates the localizer's stream from the env's for the same seed


def encode_estimate(estimate: PoseEstimate, bounds_m: tuple[float, float, float, float]) -> NDArray[np.float32]:
    """The ``estimate`` observation ``(4,)``: position normalized to ``[-1, 1]`` over the field
    (clipped), then ``cos`` and ``sin`` of the heading; zeros for an invalid estimate."""
    out = np.zeros(4, dtype=np.float32)
    if estimate.valid:
        xmin, ymin, xmax, ymax = bounds_m
        x = (estimate.x_m - (xmin + xmax) / 2) / ((xmax - xmin) / 2)
        y = (estimate.y_m - (ymin + ymax) / 2) / ((ymax - ymin) / 2)
        out[:] = (min(max(x, -1.0), 1.0), min(max(y, -1.0), 1.0), np.cos(estimate.theta_rad), np.sin(estimate.theta_rad))
    return out


def hypothesis_spread(overlay: Overlay) -> tuple[float, float]:
    """``(position_m, heading_rad)`` spread of a localizer's hypotheses, weighted by the overlay's
    weights: sqrt of the trace of the position covariance and the circular standard deviation
    ``sqrt(-2 ln R)`` of the headings (inf when they cancel out); ``(nan, nan)`` without any
    hypothesis or weight."""
    poses = np.asarray(overlay.poses, dtype=np.float64)
    w = np.asarray(overlay.weights, dtype=np.float64)
    if poses.shape[0] == 0 or w.shape != (poses.shape[0],) or not w.sum() > 0.0:
        return math.nan, math.nan
    w = w / w.sum()
    mean = w @ poses[:, :2]
    position = math.sqrt(float(w @ np.sum((poses[:, :2] - mean) ** 2, axis=1)))
    return position, circular_std(math.hypot(float(w @ np.cos(poses[:, 2])), float(w @ np.sin(poses[:, 2]))))


def decode_estimate(encoded: NDArray[np.float32], bounds_m: tuple[float, float, float, float]) -> NDArray[np.float64]:
    """Invert :func:`encode_estimate`: ``(3,)`` pose ``(x, y, theta)`` in world units."""
    xmin, ymin, xmax, ymax = bounds_m
    e = np.asarray(encoded, dtype=np.float64)
    return np.array(
        [(xmin + xmax) / 2 + e[0] * (xmax - xmin) / 2, (ymin + ymax) / 2 + e[1] * (ymax - ymin) / 2, np.arctan2(e[3], e[2])]
    )


def _first_kind(sensors: Mapping[str, Mapping[str, Any]], name: str) -> str:
    """The first registered measurement kind whose sensor the world has."""
    kinds = readable_kinds(sensors)
    if not kinds:
        types = ", ".join(str(meta.get("type")) for meta in sensors.values())
        raise ConfigError(f"localizer {name!r}: this world has no sensor that a measurement kind reads ({types})")
    return kinds[0]


class LocalizationObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Adds a localizer's pose estimate to a crowdloc env's observation.

    Args:
        env: a crowdloc env (its ``unwrapped`` has ``landmark_map``, ``sensor_metadata`` and ``config.dt_s``).
        localizer: a registered name (``"candidate_sets"``) or a ready :class:`Localizer`.
        localizer_params: overrides of the localizer's YAML parameters (names only).
        prior: ``"start"`` to give the localizer the true start pose (what the paper's dead
            reckoning and Kalman filter assume), ``"none"``; default: what the localizer needs.
        belief_spread: also observe the spread of the localizer's hypotheses (module docstring).
        sensor: the name of the sensor it reads, where the world has several of its kind (a
            second LIDAR); default: the world's one sensor of that kind.

    Raises:
        ConfigError: unknown localizer or parameter, a world without the sensor it needs, or
            an env whose observation already has a key the wrapper adds.
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        localizer: str | Localizer = "candidate_sets",
        localizer_params: Mapping[str, Any] | None = None,
        prior: str | None = None,
        belief_spread: bool = False,
        sensor: str | None = None,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, localizer=localizer, localizer_params=localizer_params, prior=prior, belief_spread=belief_spread, sensor=sensor
        )
        if not isinstance(belief_spread, bool):
            raise ConfigError(f"belief_spread must be true or false, got {belief_spread!r}")
        self.belief_spread = belief_spread
        gym.ObservationWrapper.__init__(self, env)
        base = env.unwrapped
        if not isinstance(env.observation_space, spaces.Dict):
            raise ConfigError(f"LocalizationObservation needs a Dict observation space, got {env.observation_space!r}")
        sensed = env.observation_space.spaces
        added = {
            "estimate": spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32),
            "estimate_valid": spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32),
            "estimate_spread": spaces.Box(0.0, 1.0, shape=(2,), dtype=np.float32),
            **({"belief_spread": spaces.Box(0.0, 1.0, shape=(2,), dtype=np.float32)} if belief_spread else {}),
        }
        for key in added:
            if key in sensed:
                raise ConfigError(
                    f"LocalizationObservation adds the observation key {key!r}, which the env already has "
                    f"(keys: {', '.join(sensed)}); wrap an env without it"
                )
        for needed in ("landmark_map", "sensor_metadata", "config"):
            if not hasattr(base, needed):
                raise ConfigError(f"LocalizationObservation needs a crowdloc env (its unwrapped env has no {needed!r})")
        self.landmark_map: LandmarkMap = base.landmark_map  # type: ignore[attr-defined]
        dt_s = float(base.config.dt_s)  # type: ignore[attr-defined]
        sensors: dict[str, dict[str, Any]] = base.sensor_metadata  # type: ignore[attr-defined]
        if isinstance(localizer, str):
            entry = spec(localizer)
            self.measurement = measurement_in(localizer, sensors) if sensor is None else entry.measurement
            self.localizer_name = localizer
            self._sensor = find_sensor(self.measurement, sensors, f"localizer {localizer!r}", sensor)
            self.landmark_map = sensor_map(self.landmark_map, sensors[self._sensor])
            localizer_params = prepared_params(localizer, base, self._sensor, localizer_params)
            self.localizer: Localizer = make_localizer(localizer, self.landmark_map, dt_s=dt_s, params=localizer_params)
            default_prior = "start" if entry.needs_prior else "none"
        else:
            if not isinstance(localizer, Localizer):
                raise ConfigError(
                    f"localizer must be a registered name or an object with the Localizer interface "
                    f"(reset, predict, update, estimate, overlay), got {type(localizer).__name__} {localizer!r}"
                )
            if localizer_params:
                raise ConfigError("localizer_params only apply to a localizer given by name")
            self.localizer_name = type(localizer).__name__
            # a ready localizer names its kind (a ``measurement`` attribute) or gets the first the world offers
            self.measurement = getattr(localizer, "measurement", None) or _first_kind(sensors, self.localizer_name)
            self._sensor = find_sensor(self.measurement, sensors, f"localizer {self.localizer_name!r}", sensor)
            self.localizer = localizer
            default_prior = "none"
        self._decode = measurement_kind(self.measurement).decode
        self._sensor_key = str(sensors[self._sensor]["key"])
        self._sensor_meta = sensors[self._sensor]
        odometry = [meta["key"] for meta in sensors.values() if meta.get("type") == "odometry"]
        if len(odometry) != 1:
            raise ConfigError(
                f"localizer {self.localizer_name!r} needs exactly one odometry sensor; this world has {len(odometry)}"
            )
        self._odometry_key = str(odometry[0])
        self._odometry_meta = next(meta for meta in sensors.values() if meta.get("type") == "odometry")
        self.prior = prior or default_prior
        if self.prior not in ("start", "none"):
            raise ConfigError(f"prior must be 'start' or 'none', got {self.prior!r}")
        xmin, ymin, xmax, ymax = self.landmark_map.bounds_m
        self._diag = float(np.hypot(xmax - xmin, ymax - ymin))
        self.observation_space = spaces.Dict({**sensed, **added})
        own_spread = getattr(self.localizer, "hypothesis_spread", None)  # a faster route to the same numbers
        self._hypothesis_spread = own_spread if callable(own_spread) else lambda: hypothesis_spread(self.localizer.overlay())
        self._rng = np.random.default_rng()
        self._estimate = PoseEstimate.invalid()
        #: wall time (s) spent in the localizer's predict and update since the last reset, and how many
        #: steps that was: what a step of this localizer costs on this machine (never in an observation)
        self.update_seconds, self.updates = 0.0, 0
        if hasattr(base, "add_overlay"):
            base.add_overlay(self.draw)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        if seed is not None:
            self._rng = np.random.default_rng([seed, _SEED_SALT])
        prior = None
        if self.prior == "start":
            x, y, theta = np.asarray(info["true_pose"], dtype=np.float64)
            prior = PoseEstimate(float(x), float(y), float(theta), np.diag([1e-6, 1e-6, 1e-6]), True)
        self.localizer.reset(self._rng, prior)
        self.update_seconds, self.updates = 0.0, 0
        self._update(obs, first=True)
        info["estimate"] = self._estimate
        return self.observation(obs), info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._update(obs, first=False)
        info["estimate"] = self._estimate
        return self.observation(obs), float(reward), terminated, truncated, info

    def _update(self, obs: Mapping[str, NDArray[np.float32]], first: bool) -> None:
        start = time.perf_counter()
        if not first:
            self.localizer.predict(odometry_delta(obs[self._odometry_key], self._odometry_meta))
        self.localizer.update(self._decode(obs[self._sensor_key], self._sensor_meta))
        self._estimate = self.localizer.estimate
        self.update_seconds += time.perf_counter() - start
        self.updates += 1

    def observation(self, observation: dict[str, NDArray[np.float32]]) -> dict[str, NDArray[np.float32]]:
        est = self._estimate
        estimate = encode_estimate(est, self.landmark_map.bounds_m)
        valid = np.array([1.0 if est.valid else 0.0], dtype=np.float32)
        own = (est.position_spread_m, est.heading_spread_rad) if est.valid else (math.nan, math.nan)
        out = {**observation, "estimate": estimate, "estimate_valid": valid, "estimate_spread": self._encode_spread(*own)}
        if self.belief_spread:
            position, heading = self._hypothesis_spread()
            out["belief_spread"] = self._encode_spread(position, heading) if math.isfinite(position) else out["estimate_spread"]
        return out

    def _encode_spread(self, position_m: float, heading_rad: float) -> NDArray[np.float32]:
        """Position spread over the field diagonal, heading spread over pi, clipped to ``[0, 1]``;
        1 for an unknown (non-finite) spread."""
        return np.array(
            [
                min(position_m / self._diag, 1.0) if math.isfinite(position_m) else 1.0,
                min(heading_rad / math.pi, 1.0) if math.isfinite(heading_rad) else 1.0,
            ],
            dtype=np.float32,
        )

    @property
    def estimate(self) -> PoseEstimate:
        return self._estimate

    def draw(self, canvas: Any) -> None:
        """Overlay for the env's renderer: the localizer's hypotheses and its estimate."""
        canvas.overlay(self.localizer.overlay(), ESTIMATE_COLOR)
        est = self._estimate
        if est.valid:
            canvas.pose(est.x_m, est.y_m, est.theta_rad, ESTIMATE_COLOR)
        canvas.text(f"{self.localizer_name}: {'fix' if est.valid else 'no fix'}", ESTIMATE_COLOR)
