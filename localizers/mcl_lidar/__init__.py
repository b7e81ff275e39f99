"""Monte Carlo localization with a 2-D LIDAR against the static map (``mcl_lidar``).

The MCL of the far-point paper (docs/papers.md section B, Fujii et al.): Probabilistic Robotics
MCL (Table 8.2) with 1000 particles, the odometry motion model whose alpha1..alpha4 are
scaled by one *sampling parameter*, and the beam range-finder model (Table 6.1). Options
beyond the paper: the likelihood-field model (Table 6.3), KLD-sampling (Fox 2003; Table
8.4) and augmented-MCL recovery (Table 8.3).

What depends only on the map is precomputed once per map:

- beam model: a *ray-cast table* of the expected range ``z*`` for every cell of a grid over
  the map bounds and every one of ``table_directions`` world directions, computed with
  :func:`core.raycast.cast_rays` and cached on disk
  (:func:`localizers.range_table.build_range_table`);
- likelihood field: ``log(z_hit N(d; 0, sigma^2) + z_rand / z_max)`` per cell, ``d`` the
  distance from the cell centre to the nearest wall.

The measurement models and their numba kernels are in :mod:`localizers.mcl_lidar.beam_model`, the
table and its cache in :mod:`localizers.range_table`; this module re-exports their public
names.

The parameters (:class:`LidarMCLParams`) and their choice in a world too large for the beam
model's table (:data:`LARGE_MAP_PARAMS`, :func:`large_map_params`) are in
:mod:`localizers.mcl_lidar.params`, the scan's checks in :func:`localizers.base.validated_scan`;
this module re-exports them too, so that ``localizers.mcl_lidar`` stays the one place a user imports.

Motion is integrated lazily, as ROS amcl does: :meth:`LidarMCL.predict` composes the
odometry increments, and the particles are moved once, by the composed increment, when an
update is due (after ``update_min_travel_m`` of travel or ``update_min_rotation_rad`` of
turning; the paper localizes every 0.5 m). The alpha model's noise therefore refers to the
motion between two updates, not to the simulation step.

Consistency (measured, ``crowdloc reproduce lidar-far-point``, 10 seeds, NEES against the
truth at the updates): with the paper's beam model on all 1081 beams, each beam counted as
independent, the weights after an update are so peaked that resampling leaves copies of one
particle: the covariance is singular (NEES inf) on most updates at sampling >= 0.2 and the
NEES median is in the millions at 0.1, with errors of 8-9 cm. This is the beam model's
independence assumption, not a bug: ROS amcl's defaults (likelihood field, 30 beams) are
consistent in the same runs (NEES median 1.97, 84 % of updates inside the 95 % region); the
reference (these defaults on the LIDAR at 1.9 m, which sees over the crowd) has a NEES median
of 20-24. Between updates the covariance grows with the odometry not yet applied
(:func:`localizers.particles.motion_covariance`).
"""

from __future__ import annotations

import math
import statistics
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import compose, deskewed_scan, wrap_angle
from localizers.base import (
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    ScanMeasurement,
    require_reset,
    validated_scan,
    within_spread,
)
from localizers.mcl_lidar.beam_model import BeamModel, LikelihoodFieldModel, beam_likelihood, p_hit, p_max, p_rand, p_short
from localizers.mcl_lidar.params import (
    LARGE_MAP_PARAMS,
    MAX_TABLE_DIRECTIONS,
    LidarMCLParams,
    large_map_mcl,
    large_map_params,
)
from localizers.particles import (
    LikelihoodAverages,
    gaussian_poses,
    motion_covariance,
    prior_covariance,
    propagate_particles,
    systematic_resample,
    uniform_poses,
    weighted_pose_covariance,
    weighted_pose_mean,
)
from localizers.range_table import (
    CACHE_ENV,
    RangeTable,
    build_range_table,
    cache_dir,
    check_range_table_size,
    range_table_key,
    wall_distance_field,
)

__all__ = [
    "CACHE_ENV",
    "LARGE_MAP_PARAMS",
    "MAX_TABLE_DIRECTIONS",
    "BeamModel",
    "LidarMCL",
    "LidarMCLParams",
    "LikelihoodFieldModel",
    "RangeTable",
    "beam_likelihood",
    "build_range_table",
    "cache_dir",
    "chi_square_sample_count",
    "deskewed",
    "informative",
    "kld_resample",
    "large_map_mcl",
    "large_map_params",
    "p_hit",
    "p_max",
    "p_rand",
    "p_short",
    "range_table_key",
    "validated_scan",
    "wall_distance_field",
]

Array = NDArray[np.float64]


def informative(ranges: Array, max_range: float, params: LidarMCLParams) -> bool:
    """Whether a scan carries information on the pose: at least ``min_informative_fraction`` of
    its beams read a range in ``(min_range_m, max_range)`` (not blank, not blocked)."""
    hits = int(np.count_nonzero((ranges > params.min_range_m) & (ranges < max_range)))
    return hits > 0 and hits >= params.min_informative_fraction * ranges.size


# --------------------------------------------------------------------------------------
# The filter


def deskewed(
    ranges: Array, angles: Array, max_range: float, lags_s: ArrayLike | None, increment: Array, dt_s: float, source: str
) -> tuple[Array, Array]:
    """The ``deskew`` option of the LIDAR localizers: ``(ranges, angles)`` of a swept scan whose beams
    were taken ``lags_s`` before its end, moved to the end pose by the step's odometry ``increment``
    over ``dt_s`` (:func:`core.geometry.deskewed_scan`); unchanged without lags, with all lags 0
    or without motion.

    Raises:
        MeasurementError: lags of another length than the beams, or not finite and >= 0.
    """
    if lags_s is None:
        return ranges, angles
    lags = np.asarray(lags_s, dtype=np.float64)
    if lags.shape != ranges.shape:
        raise MeasurementError(f"{source}: beam_lags_s must have one lag per beam {ranges.shape}, got shape {lags.shape}")
    bad = ~(np.isfinite(lags) & (lags >= 0.0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeasurementError(f"{source}: beam lag {float(lags[i])!r} s at index {i} is not a finite value >= 0")
    if not (lags.any() and increment.any()):
        return ranges, angles
    return deskewed_scan(ranges, angles, max_range, increment, lags / dt_s)


def chi_square_sample_count(k: ArrayLike, epsilon: float, delta: float) -> Array:
    """KLD-sampling bound (Fox 2003; Probabilistic Robotics Table 8.4, line 17).

    ``M_chi = (k - 1) / (2 eps) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z_{1-delta})^3``
    samples keep the KL divergence between the sample-based and the true posterior below
    ``eps`` with probability ``1 - delta`` when the samples occupy ``k`` bins (0 for k <= 1).
    """
    kk = np.asarray(k, dtype=np.float64)
    z = statistics.NormalDist().inv_cdf(1.0 - delta)
    km1 = np.maximum(kk - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    out = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(kk > 1.0, out, 0.0)


def kld_resample(particles: Array, weights: Array, rng: np.random.Generator, params: LidarMCLParams) -> NDArray[np.intp]:
    """Ancestor indices of a KLD-sized resample (Fox 2003; Probabilistic Robotics Table 8.4).

    Up to ``max_particles`` ancestors are drawn by low-variance resampling and put in random
    order; the sample is cut at the first size ``M >= max(min_particles, M_chi(k(M)))``,
    ``k(M)`` the number of histogram bins (x, y, heading) occupied by the first ``M``.
    """
    cap = params.max_particles
    idx = systematic_resample(weights, cap, rng)
    idx = idx[rng.permutation(cap)]
    x = np.floor(particles[0, idx] / params.kld_bin_xy_m).astype(np.int64)
    y = np.floor(particles[1, idx] / params.kld_bin_xy_m).astype(np.int64)
    t = np.floor((np.asarray(wrap_angle(particles[2, idx])) + math.pi) / params.kld_bin_theta_rad).astype(np.int64)
    keys = (x * 1_000_003 + y) * 100_003 + t
    _, first = np.unique(keys, return_index=True)
    new_bin = np.zeros(cap, dtype=np.int64)
    new_bin[first] = 1
    k = np.cumsum(new_bin)
    m = np.arange(1, cap + 1)
    ok = (m >= params.min_particles) & (m >= chi_square_sample_count(k, params.kld_epsilon, params.kld_delta))
    count = int(np.argmax(ok)) + 1 if ok.any() else cap
    return idx[:count]


class LidarMCL(LocalizerBase[LidarMCLParams]):
    """MCL on LIDAR scans against the map's walls (Probabilistic Robotics Table 8.2).

    Per due update: move every particle by the odometry composed since the last update
    (alpha model, ``sampling * alphas_base``); add each particle's scan log-likelihood to its
    log-weight; with ``recovery``, update the averages of augmented MCL (of the per-beam
    geometric-mean likelihood, so scans of different lengths compare); resample (low
    variance, or KLD-sized) when the effective sample size is low, injecting uniform random
    particles with probability ``max(0, 1 - w_fast / w_slow)``.

    The estimate is the weighted mean (circular in heading) composed with the odometry not
    yet applied, and the weighted covariance. It is valid after a prior, or once a scan has
    been weighed.
    """

    name: ClassVar[str] = "mcl_lidar"
    #: measured on this run (tests/localizers/test_consistency_promises.py), in the room with people who see the
    #: robot and the 25 ms sweep: share 0.390, NEES median 11.6: the beam model counts every beam as independent, so
    #: the cloud is narrower than the error (module docstring). The crowd's paths do it, not the sweep: 0.622 with
    #: nobody seeing the robot, 0.292 with the sweep off, 0.378 with deskew; so the promise is 0.35
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/CrowdedRoom-v0", "random_walk", 500, 0.35)

    def __init__(self, landmarks: LandmarkMap, params: LidarMCLParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s)
        self._alphas = np.asarray(params.alphas, dtype=np.float64)
        if params.model == "beam":  # refused here, not at the first scan: the table's size depends on the map only
            check_range_table_size(landmarks.bounds_m, params.table_resolution_m, params.table_directions, params.max_table_mb)
        self._beam_models: dict[float, BeamModel] = {}
        self._field: LikelihoodFieldModel | None = None
        self._rng: np.random.Generator | None = None
        self._particles = np.zeros((3, 0))
        self._log_w = np.zeros(0)
        self._weights = np.zeros(0)
        self._loglik = np.zeros(0)
        self._pending = np.zeros(3)
        self._increment = np.zeros(3)  # the last step's odometry (deskew)
        self._travel_m = 0.0
        self._turn_rad = 0.0
        self._updates = 0
        self._valid = False
        self._averages = LikelihoodAverages(params.alpha_slow, params.alpha_fast)
        self._global = False  # set by reset: a start without a prior
        self._cache: tuple[Array, Array] | None = None

    # ------------------------------------------------------------------ map models
    def beam_model(self, max_range_m: float) -> BeamModel:
        """The beam model (and its ray-cast table) for a sensor of this maximum range."""
        model = self._beam_models.get(max_range_m)
        if model is None:
            p = self._params
            table = build_range_table(
                self._map,
                resolution_m=p.table_resolution_m,
                directions=p.table_directions,
                max_range_m=max_range_m,
                max_mb=p.max_table_mb,
            )
            model = self._beam_models[max_range_m] = BeamModel(table, p)
        return model

    def likelihood_field(self) -> LikelihoodFieldModel:
        if self._field is None:
            self._field = LikelihoodFieldModel(self._map, self._params)
        return self._field

    # ------------------------------------------------------------------ localizer API
    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Gaussian around ``prior`` (its covariance when finite), else uniform over the bounds."""
        self._rng = rng
        p = self._params
        n = p.n_particles
        self._global = prior is None or not prior.valid  # global localization: no prior (global_candidates)
        if prior is None or not prior.valid:
            self._particles = uniform_poses(self._map.bounds_m, n, rng)
            self._valid = False
        else:
            cov = prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
            self._particles = gaussian_poses(prior.as_array(), cov, n, rng)
            self._valid = True
        self._set_uniform_weights(n)
        self._pending = np.zeros(3)
        self._increment = np.zeros(3)
        self._travel_m = self._turn_rad = 0.0
        self._updates = 0
        self._averages.reset()
        self._cache = None

    def predict(self, odometry: OdometryDelta) -> None:
        """Compose the increment into the motion not yet applied to the particles."""
        self._generator()
        d = self._checked_odometry(odometry)
        self._increment = d
        self._pending = compose(self._pending, d)
        self._travel_m += math.hypot(d[0], d[1])
        self._turn_rad += abs(d[2])

    def update(self, measurement: ScanMeasurement) -> None:
        """Weigh the particles by the scan when an update is due; resample when needed."""
        rng = self._generator()
        ranges, angles, max_range = validated_scan(measurement, self.name)
        p = self._params
        if not self.update_due:
            return
        stride = p.beam_stride
        if p.deskew:
            lags = None if measurement.beam_lags_s is None else np.asarray(measurement.beam_lags_s)
            ranges, angles = deskewed(ranges, angles, max_range, lags, self._increment, self._dt_s, self.name)
        ranges = np.ascontiguousarray(ranges[::stride])
        angles = np.ascontiguousarray(angles[::stride])
        used = ranges.size if p.model == "beam" else int(np.count_nonzero(ranges < max_range))
        if not informative(ranges, max_range, p):  # (no beam short of max_range is never informative)
            # nothing observed: the particles only move (once motion is due), nothing is weighed
            if self._travel_m >= p.update_min_travel_m or self._turn_rad >= p.update_min_rotation_rad:
                self._apply_motion(rng)
            return
        self._apply_motion(rng)
        n = self._particles.shape[1]
        if self._loglik.shape[0] != n:
            self._loglik = np.empty(n)
        ll = self._loglik
        drawn_ll = None
        if self._global and p.global_candidates:  # the first scan proposes the particles (params)
            self._particles, drawn_ll = self._drawn_by_scan(n, p.global_candidates, (ranges, angles, max_range), rng)
            self._set_uniform_weights(n)
        self._global = False
        self._log_likelihood(self._particles, ranges, angles, max_range, ll)
        self._updates += 1
        self._valid = True
        self._cache = None
        log_w = self._log_w
        log_w += ll
        if drawn_ll is not None:  # importance weight: the scan over what proposed them
            log_w -= drawn_ll
        peak = float(log_w.max())
        w = self._weights
        np.subtract(log_w, peak, out=w)
        np.exp(w, out=w)
        total = float(w.sum())
        w /= total
        log_w -= peak + math.log(total)  # normalized: logsumexp(log_w) == 0
        # Table 8.3 with w_avg = mean_i p(z | x_i), as a per-beam geometric mean
        ll_peak = float(ll.max())
        self._averages.update(math.exp((ll_peak + math.log(float(np.exp(ll - ll_peak).sum()) / n)) / used))
        n_inject = 0
        if p.recovery:
            p_inject = self._averages.injection_probability()
            n_inject = int(rng.binomial(n, p_inject)) if p_inject > 0.0 else 0
        if n_inject == 0 and 1.0 / float(w @ w) >= p.resample_ess_fraction * n:
            return
        self._resample(rng, n_inject, (ranges, angles, max_range))

    @property
    def estimate(self) -> PoseEstimate:
        """Weighted mean and covariance, both carried through the pending odometry (the
        covariance by :func:`localizers.particles.motion_covariance`: the noise the particles
        will get when it is applied). No pose is claimed past ``max_spread_m`` or while lost."""
        if self._rng is None or not self._valid:
            return PoseEstimate.invalid()
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        mean, cov = self._cache
        pose = compose(mean, self._pending)
        p = self._params
        if self._pending.any():
            floors = {"min_translation_std_m": p.min_translation_std_m, "min_rotation_std_rad": p.min_rotation_std_rad}
            cov = motion_covariance(mean, cov, self._pending, self._alphas, **floors)
        valid = within_spread(cov, p.max_spread_m) and not self.lost
        return PoseEstimate(float(pose[0]), float(pose[1]), float(pose[2]), cov.copy(), valid)

    @property
    def lost(self) -> bool:
        """Whether the short-term average likelihood is below ``lost_ratio`` times the long-term one."""
        return self._averages.lost(self._params.lost_ratio)

    def overlay(self) -> Overlay:
        """The particles (moved by the pending odometry), shaded by weight."""
        n = self._particles.shape[1]
        if n == 0:
            return Overlay(label=f"{self.name}: no particles")
        w = self._weights / self._weights.max()
        return Overlay(poses=self.particles, weights=w, label=f"{self.name}: {n} particles")

    # ------------------------------------------------------------------ extras
    @property
    def particles(self) -> Array:
        """``(N, 3)`` particle poses with the pending odometry applied (heading wrapped)."""
        return compose(self._particles.T, self._pending)

    @property
    def weights(self) -> Array:
        """``(N,)`` normalized particle weights."""
        return self._weights.copy()

    @property
    def update_due(self) -> bool:
        """Whether the next scan will be weighed: the first after a reset, then after
        ``update_min_travel_m`` of travel or ``update_min_rotation_rad`` of turning."""
        p = self._params
        return self._updates == 0 or self._travel_m >= p.update_min_travel_m or self._turn_rad >= p.update_min_rotation_rad

    @property
    def likelihood_averages(self) -> tuple[float | None, float | None]:
        """``(w_slow, w_fast)`` of augmented MCL (None before the first weighed scan)."""
        return self._averages.slow, self._averages.fast

    @property
    def updates(self) -> int:
        """Number of scans weighed since the last reset."""
        return self._updates

    @property
    def increment(self) -> Array:
        """``(3,)`` the last odometry increment :meth:`predict` got (zeros since the reset): the step's motion ``deskew`` undoes."""
        return self._increment.copy()

    @property
    def dt_s(self) -> float:
        """The env's step, s."""
        return self._dt_s

    # ------------------------------------------------------------------ internals
    def _generator(self) -> np.random.Generator:
        rng = self._rng
        require_reset(type(self).__name__, rng is not None)
        assert rng is not None  # for mypy: require_reset raised otherwise
        return rng

    def _set_uniform_weights(self, n: int) -> None:
        self._log_w = np.full(n, -math.log(n))
        self._weights = np.full(n, 1.0 / n)

    def _apply_motion(self, rng: np.random.Generator) -> None:
        p = self._params
        if self._particles.shape[1]:
            propagate_particles(
                self._particles,
                self._pending,
                self._alphas,
                rng,
                min_translation_std_m=p.min_translation_std_m,
                min_rotation_std_rad=p.min_rotation_std_rad,
            )
        self._pending = np.zeros(3)
        self._travel_m = self._turn_rad = 0.0
        self._cache = None

    def _log_likelihood(self, particles: Array, ranges: Array, angles: Array, max_range: float, out: Array) -> None:
        p = self._params
        if p.model == "beam":
            self.beam_model(max_range).log_likelihood(particles, ranges, angles, out, parallel=p.parallel)
        else:
            self.likelihood_field().log_likelihood(particles, ranges, angles, max_range, out, parallel=p.parallel)

    def _drawn_by_scan(
        self, count: int, candidates: int, scan: tuple[Array, Array, float], rng: np.random.Generator
    ) -> tuple[Array, Array]:
        """``(3, count)`` particles drawn from ``candidates`` uniform poses in proportion to their
        likelihood under the scan (every ``recovery_beam_stride``-th beam), and that log-likelihood of each."""
        p = self._params
        pool = uniform_poses(self._map.bounds_m, candidates, rng)
        ranges, angles, max_range = scan
        stride = p.recovery_beam_stride
        ll = np.empty(pool.shape[1])
        self._log_likelihood(pool, np.ascontiguousarray(ranges[::stride]), np.ascontiguousarray(angles[::stride]), max_range, ll)
        w = np.exp(ll - ll.max())
        w /= w.sum()
        idx = systematic_resample(w, count, rng)
        return pool[:, idx], ll[idx]

    def _injected(self, count: int, scan: tuple[Array, Array, float], rng: np.random.Generator) -> Array:
        """``(3, count)`` particles drawn from ``recovery_candidates`` poses by the scan (:meth:`_drawn_by_scan`)."""
        return self._drawn_by_scan(count, self._params.recovery_candidates, scan, rng)[0]

    def _resample(self, rng: np.random.Generator, n_inject: int, scan: tuple[Array, Array, float]) -> None:
        p = self._params
        w = self._weights
        if p.kld:
            idx = kld_resample(self._particles, w, rng, p)
            n = idx.shape[0]
            n_inject = min(n_inject, n)
            idx = idx[: n - n_inject]
        else:
            n = self._particles.shape[1]
            idx = systematic_resample(w, n - n_inject, rng)
        particles = np.empty((3, n))
        np.take(self._particles, idx, axis=1, out=particles[:, : n - n_inject])
        if n_inject:
            particles[:, n - n_inject :] = self._injected(n_inject, scan, rng)
        self._particles = particles
        self._set_uniform_weights(n)
        self._cache = None
