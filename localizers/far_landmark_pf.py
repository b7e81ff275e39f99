"""``far_landmark_pf``: the far-landmark paper's particle filter (paper D, docs/papers.md section D).

People and cars are near the robot, building walls and poles far: the filter weighs each
particle by the far landmarks first. Per update (sec. 2.4 of the paper, numbered as there):

1. the map's landmarks near the estimate: those of the ``scenes`` scenes recorded nearest the
   estimate (within ``scene_radius_m``; :class:`localizers.scene_map.SceneMap`), in the world
   frame, grouped by edge type;
2. eqs. (6)-(10): a detection ``(1/r, theta)`` of a landmark at ``(1/r*, theta*)`` has the
   likelihood ``N(1/r; 1/r*, sigma_inv_r) N(theta; theta*, sigma_theta)`` (normalized
   Gaussians), ``(r*, theta*)`` from the particle's pose and the landmark (eqs. (11)-(12),
   the bearing counter-clockwise from the heading, crowdloc's convention);
3. eq. (13): a detection is associated, per particle, with the same-type map landmark of the
   largest likelihood; below the threshold it is a mismatch. The threshold is given as the
   likelihood's fall from its peak in standard deviations, ``match_gate`` (ours: the paper
   thresholds the likelihood without a value): a detection matches when
   ``((1/r - 1/r*) / sigma_inv_r)^2 + ((theta - theta*) / sigma_theta)^2 <= match_gate^2``;
4. far emphasis (sec. 2.4.2, eq. (14)): the detections' bearings are cut into sectors of
   ``sector_rad`` (30 deg); in each, the farthest detection that matches is used (if the
   farthest fails, the next farthest; if none, nothing from that sector); nothing nearer than
   ``min_range_m`` (3 m) is used. The particle's weight is the product of the likelihoods used.
   ``selection``: ``"farthest"`` (the paper's), ``"nearest"`` (nearest first, the comparison
   the paper's argument implies), ``"all"`` (every matching detection: the baseline without
   far emphasis);
5. the estimate is the weighted mean of the particles (500, spread around the initial pose);
   the motion model is Probabilistic Robotics' odometry model (:mod:`localizers.particles`).

A particle matching nothing keeps its weight (an empty product), so a frame without detections
changes nothing; resampling (systematic) happens when the effective sample size falls below
``resample_ess_fraction`` of the set. While only coasting on odometry the set spreads with the
motion noise, and no pose is claimed once the position spread exceeds ``max_spread_m`` (ours).

The reported covariance is the particles' plus the map's own error (``map_error``, ours): the
scenes' poses are the mapping drive's estimates, and every landmark of a scene shares its
error, which the particles' weights cannot know. Measured on the campus route at crowd 30
(``route_follower``, seeds 0-4, ``tests/localizers/test_consistency_promises.py``'s protocol):
70-95 % of the steps inside the 95 % region, NEES medians 1.4-3.8; without it 35-68 % and
5.0-18.8. The estimate is the same either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numba
import numpy as np
from numpy.typing import NDArray

from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    ConsistencyPromise,
    EdgeMeasurement,
    LandmarkMap,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    checked_dt,
    checked_odometry,
    require_reset,
    within_spread,
)
from localizers.particles import (
    MAX_PARTICLES,
    PARTICLE_MEMORY,
    gaussian_poses,
    prior_covariance,
    propagate_particles,
    systematic_resample,
    weighted_pose_covariance,
    weighted_pose_mean,
)
from localizers.scene_map import SceneMap
from localizers.schema import ConfigError, check, check_at_most, check_ranges

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
SELECTIONS = ("farthest", "nearest", "all")
_FARTHEST, _NEAREST, _ALL = 0, 1, 2


@dataclass(frozen=True)
class FarLandmarkParams:
    """Parameters of :class:`FarLandmarkPF` (defaults: ``configs/localizers/far_landmark_pf.yaml``).

    Attributes:
        scene_map: the scene map's file (``.npz``, :class:`~localizers.scene_map.SceneMap`);
            empty: the world's default map, which ``gym.make(..., localizer="far_landmark_pf")``
            builds and caches on first use (:mod:`agents.scene_maps`).
        n_particles: set size (paper: 500).
        alphas: odometry motion-model alpha1..alpha4 (ours).
        min_translation_std_m, min_rotation_std_rad: per-step motion-noise floors (ours).
        initial_position_std_m, initial_heading_std_rad: the spread around the initial pose.
        sigma_inv_r: sd of the inverse range, 1/m (eq. (8); the paper leaves it open).
        sigma_theta_rad: sd of the bearing (eq. (9); likewise).
        match_gate: the threshold of eq. (13) as a distance in standard deviations.
        sector_rad: the width of far emphasis's sectors (paper: 30 deg).
        min_range_m: detections nearer are never used (paper: 3 m).
        selection: ``"farthest"`` (the paper's), ``"nearest"`` or ``"all"`` (module docstring).
        scenes: how many scenes near the estimate give landmarks; ``scene_radius_m``: how near.
        resample_ess_fraction: resample when the effective sample size falls below this share.
        max_spread_m: no pose is claimed while the position spread exceeds this (ours).
        map_error: add the map's own uncertainty to the reported covariance (ours; the paper
            reports none): the mean pose covariance of the scenes the last update matched
            against (:meth:`~localizers.scene_map.SceneMap.pose_covariance`). The filter's
            particles know the camera's noise only, but every landmark of a scene carries that
            scene's pose error, so a pose fixed on them is off by it too. The estimate itself
            is the same either way.
    """

    scene_map: str = ""
    n_particles: int = 500
    alphas: tuple[float, float, float, float] = (0.05, 0.02, 0.02, 0.02)
    min_translation_std_m: float = 0.002
    min_rotation_std_rad: float = 0.002
    initial_position_std_m: float = 0.3
    initial_heading_std_rad: float = 0.05
    sigma_inv_r: float = 0.005
    sigma_theta_rad: float = 0.01
    match_gate: float = 3.0
    sector_rad: float = math.radians(30.0)
    min_range_m: float = 3.0
    selection: Literal["farthest", "nearest", "all"] = "farthest"
    scenes: int = 3
    scene_radius_m: float = 10.0
    resample_ess_fraction: float = 0.5
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    map_error: bool = True

    def __post_init__(self) -> None:
        name = "FarLandmarkParams"
        check(self.n_particles >= 2, f"{name}.n_particles must be >= 2, got {self.n_particles!r}")
        check_at_most(self, name, {"n_particles": MAX_PARTICLES}, PARTICLE_MEMORY)
        check(
            len(self.alphas) == 4 and all(math.isfinite(a) and a >= 0.0 for a in self.alphas),
            f"{name}.alphas must be four finite values >= 0, got {self.alphas!r}",
        )
        check_ranges(
            self,
            name,
            positive=("sigma_inv_r", "sigma_theta_rad", "match_gate", "sector_rad", "scene_radius_m"),
            non_negative=(
                "min_translation_std_m",
                "min_rotation_std_rad",
                "initial_position_std_m",
                "initial_heading_std_rad",
                "min_range_m",
            ),
        )
        check(self.selection in SELECTIONS, f"{name}.selection must be one of {SELECTIONS}, got {self.selection!r}")
        check(self.sector_rad <= 2.0 * math.pi, f"{name}.sector_rad must be at most a turn, got {self.sector_rad!r}")
        check(self.scenes >= 1, f"{name}.scenes must be >= 1, got {self.scenes!r}")
        check(
            0.0 < self.resample_ess_fraction <= 1.0,
            f"{name}.resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction!r}",
        )
        check_max_spread(name, self.max_spread_m)


def order_detections(
    inverse_range: Array, bearings: Array, sector_rad: float, min_range_m: float, selection: str
) -> tuple[IntArray, IntArray]:
    """The detections far emphasis weighs, grouped by sector and ordered within each.

    Detections nearer than ``min_range_m`` are dropped (eq. (14)); the rest are cut into sectors
    of their bearing (``floor((theta + pi) / sector_rad)``) and ordered farthest first
    (``"farthest"``), nearest first (``"nearest"``) or kept in one group (``"all"``: every one
    is weighed).

    Returns:
        ``order`` ``(K,)``: detection indices, sector by sector; ``starts`` ``(G + 1,)``: group
        ``g`` is ``order[starts[g]:starts[g + 1]]``.
    """
    keep = np.flatnonzero(1.0 / inverse_range >= min_range_m)
    if selection == "all":
        return keep.astype(np.int64), np.array([0, keep.size], dtype=np.int64)
    sector = np.floor((bearings[keep] + math.pi) / sector_rad).astype(np.int64)
    rank = inverse_range[keep] if selection == "farthest" else -inverse_range[keep]  # farthest: smallest 1/r first
    order = np.lexsort((rank, sector))
    sector = sector[order]
    bounds = np.flatnonzero(np.diff(sector)) + 1
    starts = np.concatenate([[0], bounds, [keep.size]]).astype(np.int64)
    return keep[order].astype(np.int64), starts


@numba.njit(cache=True)
def detection_log_likelihood(
    px: float, py: float, pth: float, det_type: int, det_inv_r: float, det_bearing: float,
    lm_xy: Array, type_start: IntArray, inv_sigma_r: float, inv_sigma_t: float,
) -> float:  # fmt: skip
    """Eq. (13): the largest log-likelihood ``-0.5 d^2`` (without the normalizing constant) over
    the same-type map landmarks of a detection seen from pose ``(px, py, pth)``, ``d`` the
    Mahalanobis distance in ``(1/r, theta)``; ``-inf`` without such a landmark."""
    best = -math.inf
    for m in range(type_start[det_type], type_start[det_type + 1]):
        dx = lm_xy[m, 0] - px
        dy = lm_xy[m, 1] - py
        r = math.sqrt(dx * dx + dy * dy)
        if r <= 0.0:
            continue
        e_r = (det_inv_r - 1.0 / r) * inv_sigma_r
        e_t = det_bearing - (math.atan2(dy, dx) - pth)  # eq. (12), counter-clockwise from the heading
        e_t = ((e_t + math.pi) % (2.0 * math.pi) - math.pi) * inv_sigma_t
        ll = -0.5 * (e_r * e_r + e_t * e_t)
        if ll > best:
            best = ll
    return best


@numba.njit(cache=True)
def particle_log_weights(
    particles: Array, det_type: IntArray, det_inv_r: Array, det_bearing: Array, order: IntArray, starts: IntArray,
    first_only: bool, lm_xy: Array, type_start: IntArray, inv_sigma_r: float, inv_sigma_t: float, log_gate: float,
    log_norm: float, chosen: IntArray,
) -> Array:  # fmt: skip
    """``(N,)`` each particle's log-weight change: the sum, over the groups (sectors), of the
    log-likelihoods of the detections used (eq. (14)): with ``first_only`` the first in each
    group's order that matches (its log-likelihood at least ``log_gate``), else every one that
    matches. ``log_norm``: the Gaussians' log normalizing constant, added per detection used.
    ``chosen`` ``(G,)``, for the last particle: the detection each group used (-1: none)."""
    n = particles.shape[1]
    out = np.zeros(n)
    groups = starts.shape[0] - 1
    for i in range(n):
        px = particles[0, i]
        py = particles[1, i]
        pth = particles[2, i]
        total = 0.0
        for g in range(groups):
            if i == n - 1:
                chosen[g] = -1
            for q in range(starts[g], starts[g + 1]):
                k = order[q]
                ll = detection_log_likelihood(px, py, pth, det_type[k], det_inv_r[k], det_bearing[k], lm_xy, type_start,
                                              inv_sigma_r, inv_sigma_t)  # fmt: skip
                if ll >= log_gate:
                    total += ll + log_norm
                    if i == n - 1:
                        chosen[g] = k
                    if first_only:
                        break
        out[i] = total
    return out


class FarLandmarkPF:
    """The far-landmark particle filter (module docstring)."""

    name: ClassVar[str] = "far_landmark_pf"
    #: measured on this run: share 0.738, NEES median 2.48 (without ``map_error``: 0.447 and 9.2, the filter
    #: knowing only the camera's noise while the scenes' poses, the LIDAR reference's estimates, are off by
    #: 0.1-0.2 m) (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/StereoCampus-v0", "route_follower", 1200, 0.7)

    def __init__(self, landmarks: LandmarkMap, params: FarLandmarkParams, *, dt_s: float, scenes: SceneMap | None = None) -> None:
        self._dt = checked_dt(type(self).__name__, dt_s)
        self._map = landmarks
        self._params = params
        if scenes is None:
            if not params.scene_map:
                raise ConfigError(
                    "far_landmark_pf needs a scene map: give localizer_params={'scene_map': PATH} (`crowdloc map WORLD` makes one), "
                    "or make it with gym.make(..., localizer='far_landmark_pf'), which builds the world's default map"
                )
            scenes = SceneMap.load(params.scene_map)
        scenes.check_world(landmarks)
        self.scenes = scenes
        self._alphas = np.asarray(params.alphas, dtype=np.float64)
        self._inv_sr = 1.0 / params.sigma_inv_r
        self._inv_st = 1.0 / params.sigma_theta_rad
        self._log_gate = -0.5 * params.match_gate**2
        self._log_norm = -math.log(2.0 * math.pi * params.sigma_inv_r * params.sigma_theta_rad)
        self._rng: np.random.Generator | None = None
        self._particles = np.zeros((3, 0))
        self._log_w = np.zeros(0)
        self._weights: Array | None = None
        self._cache: tuple[Array, Array] | None = None
        # the nearest scenes, their landmarks (types, xy, type_start) and their mean pose covariance
        self._near: tuple[tuple[int, ...], IntArray, Array, IntArray, Array] | None = None
        #: the detections the estimate's pose used at the last update, in the world frame (for drawing)
        self.used_xy = np.zeros((0, 2))

    # ------------------------------------------------------------------ the protocol
    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """500 particles around ``prior`` (needed: the paper spreads them around the initial pose)."""
        if prior is None or not prior.valid or not np.isfinite(prior.as_array()).all():
            raise ValueError(
                f"{self.name}.reset needs a valid initial pose (prior), got {prior!r}: the paper spreads its particles "
                "around the initial pose (gym.make(..., prior='start'))"
            )
        p = self._params
        self._rng = rng
        cov = prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
        self._particles = gaussian_poses(prior.as_array(), cov, p.n_particles, rng)
        self._log_w = np.full(p.n_particles, -math.log(p.n_particles))
        self._weights = None
        self._cache = None
        self._near = None
        self.used_xy = np.zeros((0, 2))

    def predict(self, odometry: OdometryDelta) -> None:
        """Move every particle by the odometry motion model."""
        rng = self._generator()
        d = checked_odometry(self.name, odometry, self._map.step_limit_m)
        p = self._params
        propagate_particles(self._particles, d, self._alphas, rng,
                            min_translation_std_m=p.min_translation_std_m, min_rotation_std_rad=p.min_rotation_std_rad)  # fmt: skip
        self._cache = None

    def update(self, measurement: EdgeMeasurement) -> None:
        """Weigh the particles by the far landmarks (steps 1-4), resample when needed."""
        rng = self._generator()
        meas = measurement.validated(self.name)
        p = self._params
        self.used_xy = np.zeros((0, 2))  # nothing used until this frame's detections are weighed
        order, starts = order_detections(meas.inverse_range_m, meas.bearings_rad, p.sector_rad, p.min_range_m, p.selection)
        if order.size == 0:
            return
        mean, _ = self._mean_cov()
        types, lm_xy, type_start = self._landmarks_near(mean)
        if types.size == 0:
            return
        chosen = np.full(starts.size - 1, -1, dtype=np.int64)
        # the estimate's pose rides along as a last column: what it used is what the overlay draws
        poses = np.concatenate([self._particles, mean[:, None]], axis=1)
        ll = particle_log_weights(poses, meas.types, meas.inverse_range_m, meas.bearings_rad, order, starts,
                                  p.selection != "all", lm_xy, type_start, self._inv_sr, self._inv_st, self._log_gate,
                                  self._log_norm, chosen)  # fmt: skip
        used = chosen[chosen >= 0]
        r, b = 1.0 / meas.inverse_range_m[used], meas.bearings_rad[used] + mean[2]
        self.used_xy = np.stack([mean[0] + r * np.cos(b), mean[1] + r * np.sin(b)], axis=1)
        log_w = self._log_w + ll[:-1]
        log_w -= log_w.max()
        w = np.exp(log_w)
        w /= w.sum()
        self._weights = w
        self._log_w = np.log(np.maximum(w, 1e-300))
        self._cache = None
        if 1.0 / float(np.sum(w * w)) < p.resample_ess_fraction * w.size:
            idx = systematic_resample(w, w.size, rng)
            self._particles = np.ascontiguousarray(self._particles[:, idx])
            self._log_w = np.full(w.size, -math.log(w.size))
            self._weights = None

    @property
    def estimate(self) -> PoseEstimate:
        if self._rng is None:
            return PoseEstimate.invalid()
        mean, cov = self._mean_cov()
        if self._params.map_error and self._near is not None:
            cov = cov + self._near[4]
        return PoseEstimate(
            float(mean[0]), float(mean[1]), float(mean[2]), cov.copy(), within_spread(cov, self._params.max_spread_m)
        )

    def overlay(self) -> Overlay:
        n = self._particles.shape[1]
        w = np.ones(n) if self._weights is None else self._weights / self._weights.max()
        out = self._particles.T.copy()
        out[:, 2] = (out[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        return Overlay(
            poses=out, weights=w, points_xy=self.used_xy, label=f"{self.name}: {n} particles, {len(self.used_xy)} far landmarks"
        )

    # ------------------------------------------------------------------ internals
    def _generator(self) -> np.random.Generator:
        require_reset(type(self).__name__, self._rng is not None)
        assert self._rng is not None
        return self._rng

    def _mean_cov(self) -> tuple[Array, Array]:
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        return self._cache

    def _landmarks_near(self, pose: Array) -> tuple[IntArray, Array, IntArray]:
        """Step 1, reused while the same scenes are the nearest."""
        p = self._params
        nearest = self.scenes.nearest_scenes(pose, p.scenes, p.scene_radius_m)
        scenes = tuple(int(s) for s in nearest)
        if self._near is None or self._near[0] != scenes:
            self._near = (scenes, *self.scenes.landmarks_of(nearest), self.scenes.pose_covariance(nearest))
        return self._near[1], self._near[2], self._near[3]
