"""``belief_greedy``: drive where the localizer's own belief is expected to narrow most.

The baseline of active localization that reads the whole belief, not its mean: at each step the
policy draws ``hypotheses`` poses from the localizer's particles or candidates
(``Localizer.overlay()``, the belief a trained policy sees as its ``belief_map``) and, for each
candidate motion (forward speed x turn rate, held ``horizon_s``), moves every hypothesis by it
and predicts what the sensor would read from there. Taking each hypothesis in turn as the truth,
the readings it predicts reweigh all of them (a Gaussian of the predicted differences, and a
fixed penalty where one hypothesis would see a landmark or a wall the other would not); the
score of the motion is the mean entropy of those reweighed beliefs. The motion with the least
expected entropy wins; ties go to the faster one. A motion whose direction the sonar ring finds
obstructed, or whose end lies off the map (by the belief's mean), is not taken. It plans every
``REPLAN_S`` (0.2 s) and holds the motion between, sooner when the sonar blocks a held drive.

What is predicted is the localizer's sensor: a bearing camera's landmark bearings (in its field of
view and range), a LIDAR's ranges to the map's walls at ``beams`` directions over its scan, or a
stereo pair's bearings to the far landmarks of the scene map (``far_landmark_pf``'s: the landmarks
of the scenes it would match, those recorded nearest the hypotheses' mean, in the cameras' field of
view between the localizer's ``min_range_m`` and the sensor's ``max_range_m``; the buildings'
occlusion and the edges' types are not predicted).
The policy never reads the true pose: only the localizer's belief, the sonar and the map.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agents.policies.base import FixedPolicy, Observation, arc_end_poses, sonar_blocked
from core.geometry import in_field_of_view, wrap_angle
from core.raycast import cast_rays
from core.schema import ConfigError, check

if TYPE_CHECKING:
    from envs.config import WorldConfig
    from localizers.far_landmark_pf.scene_map import SceneMap

#: a hypothesis seeing a landmark (or a wall within range) where another sees none: this log-likelihood
MISMATCH_LOGLIK = math.log(0.1)

#: how often it plans anew, s (the motion is held between; planning every step costs 8-13 ms)
REPLAN_S = 0.2

Predict = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def bearings_seen(
    landmarks_xy: NDArray[np.float64], poses: NDArray[np.float64], fov_rad: float, max_range_m: float, min_range_m: float = 0.0
) -> NDArray[np.float64]:
    """``(K, L)``: each landmark's bearing from each of ``poses`` (K, 3), NaN out of view or of
    ``[min_range_m, max_range_m]``."""
    lm = np.asarray(landmarks_xy, dtype=np.float64).reshape(-1, 2)
    offsets = lm[None, :, :] - poses[:, None, :2]
    bearing = wrap_angle(np.arctan2(offsets[..., 1], offsets[..., 0]) - poses[:, 2:3])
    distance = np.linalg.norm(offsets, axis=-1)
    seen = (distance <= max_range_m) & (distance >= min_range_m)
    if fov_rad < 2 * math.pi:
        seen &= in_field_of_view(poses[:, None, :2], poses[:, 2:3], lm[None], fov_rad)
    return np.where(seen, bearing, np.nan)


def bearing_predictor(landmarks_xy: NDArray[np.float64], fov_rad: float, max_range_m: float) -> Predict:
    """``predict(poses (K, 3)) -> (K, L)``: each landmark's bearing from each pose, NaN out of view or range."""
    lm = np.asarray(landmarks_xy, dtype=np.float64)
    return lambda poses: bearings_seen(lm, poses, fov_rad, max_range_m)


def scene_bearing_predictor(
    scenes: SceneMap, count: int, radius_m: float, fov_rad: float, min_range_m: float, max_range_m: float
) -> Predict:
    """``predict(poses (K, 3)) -> (K, M)``: each pose's bearing to the landmarks of the ``count``
    scenes recorded nearest the poses' mean (within ``radius_m``), NaN out of view or of
    ``[min_range_m, max_range_m]``. Only the landmarks some pose sees are kept (of the ~300 the
    scenes hold, most lie outside the cameras' 60 deg); ``(K, 0)`` where none is seen."""

    def predict(poses: NDArray[np.float64]) -> NDArray[np.float64]:
        _, xy, _ = scenes.landmarks_near(poses[:, :2].mean(axis=0), count, radius_m)
        bearings = bearings_seen(xy, poses, fov_rad, max_range_m, min_range_m)
        return bearings[:, np.isfinite(bearings).any(axis=0)]

    return predict


def range_predictor(walls_m: NDArray[np.float64], beam_angles_rad: NDArray[np.float64], max_range_m: float) -> Predict:
    """``predict(poses (K, 3)) -> (K, B)``: the map's range along each beam from each pose, NaN at the maximum range."""
    walls = np.asarray(walls_m, dtype=np.float64).reshape(-1, 4)
    seg_a, seg_b = np.ascontiguousarray(walls[:, :2]), np.ascontiguousarray(walls[:, 2:])
    angles = np.sort(np.asarray(beam_angles_rad, dtype=np.float64))
    none_c, none_r = np.zeros((0, 2)), np.zeros(0)

    def predict(poses: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.empty((poses.shape[0], angles.size))
        for k, pose in enumerate(poses):
            out[k] = cast_rays(np.ascontiguousarray(pose[:2]), pose[2] + angles, max_range_m, seg_a, seg_b, none_c, none_r)
        return np.where(out < max_range_m - 1e-9, out, np.nan)

    return predict


def expected_entropy(readings: NDArray[np.float64], std: float, circular: bool) -> float:
    """The mean, over hypotheses taken as the truth, of the entropy of the equal-weight hypotheses reweighed by the
    readings ``(K, M)`` that truth predicts (NaN: nothing read)."""
    truth, other = readings[:, None, :], readings[None, :, :]
    diff = truth - other
    if circular:
        diff = np.asarray(wrap_angle(diff))
    both = np.isfinite(truth) & np.isfinite(other)
    one = np.isfinite(truth) ^ np.isfinite(other)
    loglik = -0.5 * np.where(both, diff / std, 0.0) ** 2
    loglik = loglik.sum(axis=-1) + MISMATCH_LOGLIK * one.sum(axis=-1)
    loglik -= loglik.max(axis=1, keepdims=True)
    w = np.exp(loglik)
    w /= w.sum(axis=1, keepdims=True)
    return float(np.mean(-np.sum(np.where(w > 0, w * np.log(np.where(w > 0, w, 1.0)), 0.0), axis=1)))


class BeliefGreedy(FixedPolicy):
    """The motion after which the localizer's belief is expected to hold the least entropy (module docstring).

    Args:
        action_space: the env's action space.
        belief: returns the belief now as ``(poses (N, 3), weights (N,))`` (a localizer's overlay).
        predict: the sensor's readings from poses (:func:`bearing_predictor`, :func:`range_predictor`).
        std: the readings' noise (radians for bearings, metres for ranges).
        circular: whether readings are angles.
        bounds_m: the map's bounds; an end pose must lie ``margin_m`` inside them.
    """

    @classmethod
    def unmet_need(cls, world: WorldConfig) -> tuple[str, str] | None:
        """A world without a bearing camera, a LIDAR or a stereo pair (the sensors it predicts) lacks what it needs."""
        if all(world.sensor_of_type(kind) is None for kind in ("bearing_camera", "lidar", "stereo_camera")):
            return "a bearing_camera, lidar or stereo_camera sensor", f"its sensors: {', '.join(world.sensors) or 'none'}"
        return None

    def __init__(
        self,
        action_space: spaces.Box,
        belief: Callable[[], tuple[NDArray[np.float64], NDArray[np.float64]]],
        predict: Predict,
        std: float,
        circular: bool,
        bounds_m: tuple[float, float, float, float],
        seed: int | None = None,
        *,
        hypotheses: int = 48,
        horizon_s: float = 1.0,
        speeds: Sequence[float] = (0.0, 0.5, 1.0),
        turns: Sequence[float] = (-1.0, -0.5, 0.0, 0.5, 1.0),
        max_speed_mps: float = 1.0,
        max_turn_rate_rps: float = 1.0,
        clearance_m: float = 0.7,
        margin_m: float = 0.4,
        replan_steps: int = 1,
    ) -> None:
        super().__init__(action_space, seed)
        check(hypotheses >= 2, f"belief_greedy hypotheses must be >= 2, got {hypotheses!r}")
        check(std > 0, f"belief_greedy std must be > 0, got {std!r}")
        self.belief, self.predict_readings, self.std, self.circular = belief, predict, float(std), circular
        self.bounds_m, self.hypotheses, self.horizon_s = bounds_m, int(hypotheses), float(horizon_s)
        self.candidates = np.array([(v, w) for v in speeds for w in turns], dtype=np.float64)
        self.max_speed_mps, self.max_turn_rate_rps = max_speed_mps, max_turn_rate_rps
        self.clearance_m, self.margin_m = clearance_m, margin_m
        check(
            isinstance(replan_steps, int) and replan_steps >= 1,
            f"belief_greedy replan_steps must be an integer >= 1, got {replan_steps!r}",
        )
        self.replan_steps = replan_steps
        self._held: NDArray[np.float64] | None = None
        self._since = 0

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._held, self._since = None, 0

    def _draw(self) -> NDArray[np.float64] | None:
        poses, weights = self.belief()
        if len(poses) == 0 or not np.any(weights > 0):
            return None
        w = np.asarray(weights, dtype=np.float64) / float(np.sum(weights))
        return np.asarray(poses, dtype=np.float64)[self.rng.choice(len(w), size=self.hypotheses, p=w)]

    def scores(self, hypotheses: NDArray[np.float64], observation: Observation) -> NDArray[np.float64]:
        """Each candidate motion's expected entropy after it (inf: not taken)."""
        v = self.candidates[:, 0] * self.max_speed_mps
        w = self.candidates[:, 1] * self.max_turn_rate_rps
        ends = arc_end_poses(hypotheses, v, w, self.horizon_s)  # (C, K, 3)
        xmin, ymin, xmax, ymax = self.bounds_m
        m = self.margin_m
        mean_end = ends[..., :2].mean(axis=1)
        inside = (
            (mean_end[:, 0] > xmin + m) & (mean_end[:, 0] < xmax - m) & (mean_end[:, 1] > ymin + m) & (mean_end[:, 1] < ymax - m)
        )
        obstructed = (self.candidates[:, 0] > 0) & sonar_blocked(observation, 0.5 * w * self.horizon_s, self.clearance_m)
        out = np.full(len(self.candidates), np.inf)
        for i in np.flatnonzero(inside & ~obstructed):
            out[i] = expected_entropy(self.predict_readings(ends[i]), self.std, self.circular) - 1e-3 * self.candidates[i, 0]
        return out

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        """A new plan every ``replan_steps`` steps (and whenever the sonar blocks the held one); the held motion between."""
        held = self._held
        if (
            held is not None
            and self._since < self.replan_steps
            and not (held[0] > 0 and sonar_blocked(observation, np.array([0.0]), self.clearance_m)[0])
        ):
            self._since += 1
            return held.copy()
        self._held, self._since = self._plan(observation), 1
        return self._held.copy()

    def _plan(self, observation: Observation) -> NDArray[np.float64]:
        hypotheses = self._draw()
        if hypotheses is None:
            return np.array([0.0, 0.5])  # no belief yet: look around
        scores = self.scores(hypotheses, observation)
        if not np.isfinite(scores).any():
            return np.array([0.0, 0.5])  # every way is blocked or off the map: turn on the spot
        return self.candidates[int(np.argmin(scores))].copy()


def make_belief_greedy(env: Any, seed: int | None = None, **kwargs: Any) -> BeliefGreedy:
    """:class:`BeliefGreedy` on ``env``'s localizer and its sensor (a bearing camera, a LIDAR or a stereo pair).

    Raises:
        ConfigError: an env without a localizer, or whose localizer reads neither sensor.
    """
    try:
        localizer = env.get_wrapper_attr("localizer")
    except AttributeError:
        raise ConfigError("belief_greedy reads the localizer's belief: make the env with a localizer") from None
    base = env.unwrapped
    config, lmap, meta = base.config, base.landmark_map, base.sensor_metadata

    def belief() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        overlay = localizer.overlay()
        return np.asarray(overlay.poses).reshape(-1, 3), np.asarray(overlay.weights).reshape(-1)

    from localizers.registry import measurement_in

    kind = measurement_in(localizer.name, meta)
    camera = config.sensor_of_type("bearing_camera")
    stereo = config.sensor_of_type("stereo_camera")
    lidar = next(((n, m) for n, m in meta.items() if m["type"] == "lidar"), None)
    if kind == "bearings" and camera is not None:
        predict = bearing_predictor(lmap.positions_xy_m, camera.fov_rad, camera.max_range_m)
        std, circular = max(camera.noise_std_rad, 0.02), True
    elif kind == "scan" and lidar is not None:
        from localizers.measurements import sensor_map

        angles = np.asarray(lidar[1]["beam_angles_rad"], dtype=np.float64)
        beams = int(kwargs.pop("beams", 24))
        picked = angles[np.linspace(0, len(angles) - 1, beams).round().astype(int)]
        walls = sensor_map(lmap, lidar[1]).walls_m
        predict, std, circular = range_predictor(walls, picked, float(lidar[1]["max_range_m"])), 0.2, False
    elif kind == "stereo_edges" and stereo is not None and getattr(localizer, "scenes", None) is not None:
        p = localizer.params
        fov = 2.0 * math.atan(0.5 * stereo.width_px / stereo.focal_px)
        predict = scene_bearing_predictor(localizer.scenes, p.scenes, p.scene_radius_m, fov, p.min_range_m, stereo.max_range_m)
        std, circular = max(p.sigma_theta_rad, 0.02), True
    else:
        raise ConfigError(f"belief_greedy predicts a bearing camera's, a LIDAR's or a stereo pair's readings; localizer {localizer.name!r} "
                          f"reads {kind!r} in world {config.name!r}")  # fmt: skip
    kwargs.setdefault("max_speed_mps", config.robot.max_speed_mps)
    kwargs.setdefault("max_turn_rate_rps", config.robot.max_turn_rate_rps)
    kwargs.setdefault("replan_steps", max(1, round(REPLAN_S / config.dt_s)))
    return BeliefGreedy(env.action_space, belief, predict, std, circular, lmap.bounds_m, seed, **kwargs)
