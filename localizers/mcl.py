"""Monte Carlo localization from landmark bearings: one particle core, two filters.

- :class:`PaperBearingMCL` (``mcl_bearing_paper``) is baseline (4) of the two-landmark
  bearings paper (docs/papers.md section A, sec. 5 (4) of the original): 1000 unweighted
  particles; at each observation the particles whose bearing to any observed landmark is
  off by more than pi/9 are deleted and as many are re-seeded from the observation.
- :class:`BearingMCL` (``mcl_bearing``) is a modern reference: Gaussian bearing likelihood
  in log-weights, systematic resampling on low effective sample size and augmented-MCL
  random injection (Probabilistic Robotics, Table 8.3) to recover from pose jumps.

Both share the particle core of :mod:`localizers.particles` (re-exported here). Particles
are stored *struct-of-arrays*: an array of shape ``(3, N)`` whose rows are x, y and
heading, so every vector operation runs over one contiguous row of N values. The motion
model is the alpha model of :mod:`core.motion` (Probabilistic Robotics,
sample_motion_model_odometry), applied to the odometry increment.

Consistency (measured, ``crowdloc reproduce bearing-candidates``, 20 seeds, NEES of the pose
against the truth over the steps with a pose): ``mcl_bearing_paper`` is cautious (median 1.00 in
Exp 1, 0.091 in Exp 2; 90 % and 100 % of steps inside the 95 % region): its unweighted set,
re-seeded from arcs, is wider than its error. ``mcl_bearing`` is consistent in Exp 2 (0.65, 96 %)
and overconfident in Exp 1 (2790, 28 %): where the small pole L5 is out of range its distractor
fits a wrong pose, and with two landmarks in view a wrong pose on the circle through them fits
the bearings exactly; the set collapses there with a small spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import compose, wrap_angle
from core.schema import check, check_at_most, check_ranges
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    BearingMeasurement,
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    OdometryDelta,
    Overlay,
    ParamsT,
    PoseEstimate,
    check_max_spread,
    checked_bearings,
    require_reset,
    within_spread,
)
from localizers.contradiction import Contradiction
from localizers.particles import (
    MAX_PARTICLES,
    PARTICLE_MEMORY,
    LikelihoodAverages,
    gaussian_poses,
    motion_covariance,
    propagate_particles,
    systematic_resample,
    uniform_poses,
    weighted_pose_covariance,
    weighted_pose_mean,
)
from localizers.particles import prior_covariance as _prior_covariance
from localizers.resection import inscribed_arc_poses, resect_all_triples

Array = NDArray[np.float64]
_TWO_PI = 2.0 * math.pi
_INV_TWO_PI = 1.0 / _TWO_PI

# --------------------------------------------------------------------------------------
# Bearing-specific parts of the particle core (the rest is in localizers.particles)


def bearing_residuals(particles: Array, landmarks_xy: Array, bearings_rad: Array, out: Array | None = None) -> Array:
    """Measured minus predicted bearing for every particle and observed landmark.

    The predicted direction ``atan2`` runs in float32 on float64 differences (3x faster;
    error below 1e-6 rad, against bearing noise of ~1e-2 rad); all else is float64.

    Args:
        particles: ``(3, N)`` poses.
        landmarks_xy: ``(n, 2)`` positions of the observed landmarks.
        bearings_rad: ``(n,)`` measured bearings (robot frame).
        out: optional ``(n, N)`` float64 array for the result, reused to avoid allocations.

    Returns:
        ``(n, N)`` residuals, wrapped to ``[-pi, pi]`` (the sign convention does not matter
        to the callers, which use ``|e|`` or ``e^2``).
    """
    n, N = bearings_rad.shape[0], particles.shape[1]
    e = np.empty((n, N)) if out is None else out
    dx = np.empty((n, N), dtype=np.float32)
    dy = np.empty((n, N), dtype=np.float32)
    np.subtract(landmarks_xy[:, 0, None], particles[0], out=dx, casting="same_kind")
    np.subtract(landmarks_xy[:, 1, None], particles[1], out=dy, casting="same_kind")
    np.arctan2(dy, dx, out=dx)  # predicted world direction to each landmark
    np.subtract(dx, particles[2], out=e)
    e -= bearings_rad[:, None]
    # Wrap by the nearest multiple of 2 pi (cheaper than a modulo over n * N values).
    turns = np.multiply(e, _INV_TWO_PI)
    np.rint(turns, out=turns)
    turns *= _TWO_PI
    e -= turns
    return e


def resection_poses(landmarks_xy: Array, measurement: BearingMeasurement) -> Array:
    """``(M, 3)`` Cassini solutions of the inlier triples of a frame (``(0, 3)`` if none).

    Uses :func:`localizers.resection.resect_all_triples` over every triple of the observed
    landmarks, so one false detection does not seed particles far from the truth.
    """
    if measurement.landmark_ids.size < 3:
        return np.zeros((0, 3))
    res = resect_all_triples(landmarks_xy, measurement.landmark_ids, measurement.bearings_rad)
    return np.asarray(res.poses, dtype=np.float64)[res.inliers]


def _jitter(centers: Array, position_std_m: float, heading_std_rad: float, rng: np.random.Generator) -> Array:
    """``(3, k)`` copies of ``(3, k)`` centers with isotropic position and heading noise."""
    noise = rng.standard_normal(centers.shape)
    noise[:2] *= position_std_m
    noise[2] *= heading_std_rad
    noise += centers
    noise[2] = wrap_angle(noise[2])
    return noise


def _check_alphas(owner: str, alphas: tuple[float, float, float, float]) -> None:
    check(
        len(alphas) == 4 and all(math.isfinite(a) and a >= 0.0 for a in alphas),
        f"{owner}.alphas must be four finite values >= 0, got {alphas!r}",
    )


class _ParticleLocalizer(LocalizerBase[ParamsT]):
    """What both filters share: the map, the rng, particle propagation, estimate, overlay."""

    name: ClassVar[str] = ""

    def __init__(
        self, landmarks: LandmarkMap, params: ParamsT, *, dt_s: float, alphas: ArrayLike, floors: tuple[float, float]
    ) -> None:
        super().__init__(landmarks, params, dt_s=dt_s)
        self._alphas = np.asarray(alphas, dtype=np.float64)
        self._floor_m, self._floor_rad = floors
        self._rng: np.random.Generator | None = None
        self._particles = np.zeros((3, 0))
        self._weights: Array | None = None  # None: uniform
        self._cache: tuple[Array, Array] | None = None

    def _generator(self) -> np.random.Generator:
        rng = self._rng
        require_reset(type(self).__name__, rng is not None)
        assert rng is not None  # for mypy: require_reset raised otherwise
        return rng

    def _validated(self, measurement: BearingMeasurement) -> BearingMeasurement:
        self._generator()
        return checked_bearings(self.name, measurement, self._map.count)

    def _propagate(self, d: Array) -> None:
        rng = self._generator()
        if self._particles.shape[1]:
            propagate_particles(
                self._particles,
                d,
                self._alphas,
                rng,
                min_translation_std_m=self._floor_m,
                min_rotation_std_rad=self._floor_rad,
            )
        self._cache = None

    def _mean_cov(self) -> tuple[Array, Array]:
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        return self._cache

    @property
    def particles(self) -> Array:
        """``(N, 3)`` copy of the particle poses (heading wrapped)."""
        out = self._particles.T.copy()
        out[:, 2] = wrap_angle(out[:, 2])
        return out

    def overlay(self) -> Overlay:
        n = self._particles.shape[1]
        if n == 0:
            return Overlay(label=f"{self.name}: no particles")
        w = np.ones(n) if self._weights is None else self._weights / self._weights.max()
        return Overlay(poses=self.particles, weights=w, label=f"{self.name}: {n} particles")


# --------------------------------------------------------------------------------------
# Baseline (4): the paper's delete-and-reseed MCL


@dataclass(frozen=True)
class PaperMCLParams:
    """Baseline (4) of the two-landmark paper (defaults: ``configs/localizers/mcl_bearing_paper.yaml``).

    Attributes:
        n_particles: set size (paper: 1000).
        gate_rad: delete a particle when any observed bearing is off by more (paper: pi/9).
        one_landmark_heading_std_rad: heading spread of seeds from one bearing (paper: pi/9).
        two_landmark_position_std_m, two_landmark_heading_std_rad: seeds around the
            inscribed-angle arc (paper: 200 mm, pi/12.6).
        three_landmark_position_std_m, three_landmark_heading_std_rad: seeds around the
            Cassini solution (paper: 200 mm, pi/15.3).
        alphas: odometry motion-model alpha1..alpha4 (ours).
        min_translation_std_m, min_rotation_std_rad: per-step motion-noise floors (ours).
        initial_position_std_m, initial_heading_std_rad: spread around a prior without a
            finite covariance (ours).
        max_spread_m: no pose is claimed while the position spread exceeds this (ours).
        min_survival_fraction: lost detection (ours): no pose is claimed while fewer than this
            fraction of the particles survived the gate of the latest observation (a set the
            observations keep contradicting, as after a kidnapping or with misidentified
            landmarks, is no fix; the paper's deletion and re-seeding are unchanged). Not applied
            to the dead-reckoned pose of an emptied set (the paper's fallback).
    """

    n_particles: int = 1000
    gate_rad: float = math.pi / 9.0
    one_landmark_heading_std_rad: float = math.pi / 9.0
    two_landmark_position_std_m: float = 0.2
    two_landmark_heading_std_rad: float = math.pi / 12.6
    three_landmark_position_std_m: float = 0.2
    three_landmark_heading_std_rad: float = math.pi / 15.3
    alphas: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 0.01)
    min_translation_std_m: float = 0.0005
    min_rotation_std_rad: float = 0.0005
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    min_survival_fraction: float = 0.5

    def __post_init__(self) -> None:
        check_max_spread("PaperMCLParams", self.max_spread_m)
        check(
            0.0 <= self.min_survival_fraction <= 1.0,
            f"PaperMCLParams.min_survival_fraction must be in [0, 1], got {self.min_survival_fraction!r}",
        )
        check(self.n_particles >= 1, f"PaperMCLParams.n_particles must be >= 1, got {self.n_particles!r}")
        check_at_most(self, "PaperMCLParams", {"n_particles": MAX_PARTICLES}, PARTICLE_MEMORY)
        check(
            math.isfinite(self.gate_rad) and 0.0 < self.gate_rad <= math.pi,
            f"PaperMCLParams.gate_rad must be in (0, pi], got {self.gate_rad!r}",
        )
        check_ranges(
            self,
            "PaperMCLParams",
            positive=(
                "one_landmark_heading_std_rad",
                "two_landmark_position_std_m",
                "two_landmark_heading_std_rad",
                "three_landmark_position_std_m",
                "three_landmark_heading_std_rad",
            ),
            non_negative=("min_translation_std_m", "min_rotation_std_rad", "initial_position_std_m", "initial_heading_std_rad"),
        )
        _check_alphas("PaperMCLParams", self.alphas)


class PaperBearingMCL(_ParticleLocalizer[PaperMCLParams]):
    """The paper's MCL: gate-and-delete, re-seed from the observation, mean of the set.

    Re-seeding (paper sec. 5 (4)), by the number ``n`` of landmarks seen now:

    - ``n >= 3``: around Cassini solutions (one per inlier triple of
      :func:`resect_all_triples`, drawn at random per seed);
    - ``n == 2``: around poses on the inscribed-angle arc (:func:`inscribed_arc_poses`);
    - ``n == 1``: position uniform over the field, heading from that bearing plus noise.

    Degenerate geometry (all triples near their danger circle, a robot collinear with the
    two landmarks) re-seeds nothing, so the set shrinks. The estimate is the unweighted mean
    of the set once an observation has left it non-empty. Before the first observation, and
    whenever every particle is deleted with nothing to re-seed from, MCL "yields no pose"
    and the filter dead-reckons from its last pose (the prior at the start; paper sec. 5
    (4)), keeping that pose's covariance; it is invalid if it never had a pose. A prior
    also seeds the set (Gaussian), so the first observation gates real particles.
    """

    name: ClassVar[str] = "mcl_bearing_paper"
    #: measured on this run: share 1.000, NEES median 0.22: cautious (module docstring)
    #: (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.95)

    def __init__(self, landmarks: LandmarkMap, params: PaperMCLParams, *, dt_s: float) -> None:
        super().__init__(
            landmarks,
            params,
            dt_s=dt_s,
            alphas=params.alphas,
            floors=(params.min_translation_std_m, params.min_rotation_std_rad),
        )
        self._has_pose = False  # MCL has yielded a pose (an observation left a non-empty set)
        self._fallback: tuple[Array, Array] | None = None  # (pose, covariance) dead-reckoned
        self._survival = 1.0  # fraction of the set that survived the latest observation's gate

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Seed the set around ``prior`` (and dead-reckon it until the first observation),
        or leave the set empty until the first observation."""
        self._rng = rng
        self._cache = None
        self._weights = None
        self._has_pose = False
        self._fallback = None
        self._survival = 1.0
        if prior is None or not prior.valid:
            self._particles = np.zeros((3, 0))
            return
        p = self._params
        cov = _prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
        self._particles = gaussian_poses(prior.as_array(), cov, p.n_particles, rng)
        self._fallback = (np.array([prior.x_m, prior.y_m, wrap_angle(prior.theta_rad)]), cov)

    def predict(self, odometry: OdometryDelta) -> None:
        """Move every particle, and the dead-reckoned pose while MCL yields none."""
        self._generator()
        d = self._checked_odometry(odometry)
        if not self._has_pose and self._fallback is not None:
            pose, cov = self._fallback
            p = self._params
            floors = {"min_translation_std_m": p.min_translation_std_m, "min_rotation_std_rad": p.min_rotation_std_rad}
            self._fallback = (compose(pose, d), motion_covariance(pose, cov, d, self._alphas, **floors))
        self._propagate(d)

    def update(self, measurement: BearingMeasurement) -> None:
        """Delete particles outside the bearing gate and re-seed as many (paper sec. 5 (4))."""
        meas = self._validated(measurement)
        if meas.landmark_ids.size == 0:
            return
        rng = self._generator()
        lm = self._map.positions_xy_m[meas.landmark_ids]
        before = self._particles
        if before.shape[1]:
            e = bearing_residuals(before, lm, meas.bearings_rad)
            keep = (np.abs(e) <= self._params.gate_rad).all(axis=0)
            kept = before[:, keep]
            self._survival = kept.shape[1] / before.shape[1]
        else:
            kept = before
        seeds = self._reseed(self._params.n_particles - kept.shape[1], meas, lm, rng)
        after = np.concatenate([kept, seeds], axis=1)
        if after.shape[1]:
            self._has_pose = True
        elif self._has_pose:  # the set just emptied: "no pose", dead-reckon from the last one
            self._fallback = self._mean_cov()
            self._has_pose = False
        self._particles = after
        self._cache = None

    def _reseed(self, count: int, meas: BearingMeasurement, lm: Array, rng: np.random.Generator) -> Array:
        """``(3, count)`` new particles consistent with the observation, or ``(3, 0)`` when the
        geometry is degenerate (every triple near its danger circle, or the two landmarks
        collinear with the robot)."""
        none = np.zeros((3, 0))
        if count <= 0:
            return none
        p = self._params
        n = meas.landmark_ids.size
        if n >= 3:
            poses = resection_poses(self._map.positions_xy_m, meas)
            if poses.shape[0] == 0:
                return none
            centers = poses[rng.integers(poses.shape[0], size=count)].T
            return _jitter(centers, p.three_landmark_position_std_m, p.three_landmark_heading_std_rad, rng)
        if n == 2:
            arc = np.asarray(
                inscribed_arc_poses(lm[0], lm[1], meas.bearings_rad[0], meas.bearings_rad[1], count),
                dtype=np.float64,
            ).reshape(-1, 3)
            arc = arc[np.isfinite(arc).all(axis=1)]
            if arc.shape[0] == 0:
                return none
            centers = arc.T if arc.shape[0] == count else arc[rng.integers(arc.shape[0], size=count)].T
            return _jitter(centers, p.two_landmark_position_std_m, p.two_landmark_heading_std_rad, rng)
        # one landmark: position uniform over the field, heading from the bearing plus noise
        seeds = uniform_poses(self._map.bounds_m, count, rng)
        direction = np.arctan2(lm[0, 1] - seeds[1], lm[0, 0] - seeds[0])
        seeds[2] = wrap_angle(direction - meas.bearings_rad[0] + rng.standard_normal(count) * p.one_landmark_heading_std_rad)
        return seeds

    @property
    def survival_fraction(self) -> float:
        """The fraction of the set that survived the latest observation's gate (1 before any)."""
        return self._survival

    @property
    def estimate(self) -> PoseEstimate:
        """Mean of the set, else the dead-reckoned last pose (its covariance grown by the
        motion model), else invalid; not valid past ``max_spread_m`` or while lost."""
        if self._has_pose:
            mean, cov = self._mean_cov()
        elif self._fallback is not None:
            mean, cov = self._fallback
        else:
            return PoseEstimate.invalid()
        p = self._params
        consistent = not self._has_pose or self._survival >= p.min_survival_fraction  # dead reckoning: the paper's
        valid = within_spread(cov, p.max_spread_m) and consistent
        return PoseEstimate(float(mean[0]), float(mean[1]), float(mean[2]), cov.copy(), valid)


# --------------------------------------------------------------------------------------
# The reference MCL


@dataclass(frozen=True)
class BearingMCLParams:
    """Reference bearing MCL (defaults: ``configs/localizers/mcl_bearing.yaml``, all ours).

    Attributes:
        n_particles: set size.
        alphas: odometry motion-model alpha1..alpha4.
        min_translation_std_m, min_rotation_std_rad: per-step motion-noise floors.
        bearing_std_rad: bearing sensor standard deviation.
        likelihood_inflation: the likelihood uses ``bearing_std_rad * likelihood_inflation``
            (bearings of one frame are not independent in practice, and a 1000-particle set
            under-samples a sharp likelihood; Probabilistic Robotics sec. 6.3).
        resample_ess_fraction: resample when the effective sample size drops below this
            fraction of ``n_particles``.
        alpha_slow, alpha_fast: smoothing rates of the long/short-term likelihood averages
            of augmented MCL (Probabilistic Robotics, Table 8.3; 0 < slow << fast <= 1).
        injection_ratio: inject with probability ``max(0, 1 - w_fast / (injection_ratio *
            w_slow))``; 1.0 is the book's rule, below 1 ignores the few-percent frame-to-frame
            jitter of the ratio.
        injection_position_std_m, injection_heading_std_rad: spread of injected particles
            around resection solutions.
        initial_position_std_m, initial_heading_std_rad: spread around a prior without a
            finite covariance.
        max_spread_m: the estimate is valid only while the particles' position spread
            (sqrt of the trace of their position covariance) is at most this: a set still
            spread over the field is no fix.
        min_fix_landmarks, fix_memory_s: the estimate is valid only while bearings to at
            least ``min_fix_landmarks`` distinct landmarks arrived within the last
            ``fix_memory_s`` (a prior counts as a fix at the reset): a set weighed by one
            landmark only narrows by resampling, not by information, and would claim a
            confident wrong pose.
        lost_residual_rad, lost_after_s: lost detection (:mod:`localizers.contradiction`):
            no pose is claimed while the bearings have contradicted the estimate (median
            absolute residual above ``lost_residual_rad``) on every frame with two or more
            of them for ``lost_after_s``. (Augmented MCL's ``w_fast < injection_ratio w_slow``
            drives the injection only: in a crowd it holds on about half the frames of a
            well-localized filter, as occlusions change which landmarks are seen.)
    """

    n_particles: int = 1000
    alphas: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 0.01)
    min_translation_std_m: float = 0.0005
    min_rotation_std_rad: float = 0.0005
    bearing_std_rad: float = math.radians(1.0)
    likelihood_inflation: float = 2.0
    resample_ess_fraction: float = 0.5
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    injection_ratio: float = 0.9
    injection_position_std_m: float = 0.1
    injection_heading_std_rad: float = 0.05
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    max_spread_m: float = 0.5  # the former fix_spread_m
    min_fix_landmarks: int = 3
    fix_memory_s: float = 10.0
    lost_residual_rad: float = 0.35
    lost_after_s: float = 0.5

    def __post_init__(self) -> None:
        check(self.n_particles >= 2, f"BearingMCLParams.n_particles must be >= 2, got {self.n_particles!r}")
        check_at_most(self, "BearingMCLParams", {"n_particles": MAX_PARTICLES}, PARTICLE_MEMORY)
        check(
            math.isfinite(self.lost_residual_rad) and 0.0 < self.lost_residual_rad <= math.pi,
            f"BearingMCLParams.lost_residual_rad must be in (0, pi] rad, got {self.lost_residual_rad!r}",
        )
        check(
            self.lost_after_s >= 0.0,  # false for NaN
            f"BearingMCLParams.lost_after_s must be a number of seconds >= 0 (inf: never), got {self.lost_after_s!r}",
        )
        check_max_spread("BearingMCLParams", self.max_spread_m)
        check(self.min_fix_landmarks >= 1, f"BearingMCLParams.min_fix_landmarks must be >= 1, got {self.min_fix_landmarks!r}")
        check(
            not math.isnan(self.fix_memory_s) and self.fix_memory_s > 0.0,
            f"BearingMCLParams.fix_memory_s must be > 0 s, got {self.fix_memory_s!r}",
        )
        _check_alphas("BearingMCLParams", self.alphas)
        check_ranges(
            self,
            "BearingMCLParams",
            positive=("bearing_std_rad", "injection_position_std_m", "injection_heading_std_rad"),
            non_negative=("min_translation_std_m", "min_rotation_std_rad", "initial_position_std_m", "initial_heading_std_rad"),
        )
        check(
            math.isfinite(self.likelihood_inflation) and self.likelihood_inflation >= 1.0,
            f"BearingMCLParams.likelihood_inflation must be >= 1, got {self.likelihood_inflation!r}",
        )
        check(
            0.0 < self.resample_ess_fraction <= 1.0,
            f"BearingMCLParams.resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction!r}",
        )
        check(
            0.0 < self.alpha_slow < self.alpha_fast <= 1.0,
            f"BearingMCLParams needs 0 < alpha_slow < alpha_fast <= 1, got {self.alpha_slow!r}, {self.alpha_fast!r}",
        )
        check(
            0.0 < self.injection_ratio <= 1.0,
            f"BearingMCLParams.injection_ratio must be in (0, 1], got {self.injection_ratio!r}",
        )


class BearingMCL(_ParticleLocalizer[BearingMCLParams]):
    """Weighted MCL with a Gaussian bearing likelihood and augmented-MCL recovery.

    Per update with ``n >= 1`` bearings: ``log w += -sum_l e_l^2 / (2 s^2)`` with ``e_l`` the
    wrapped bearing residual and ``s = bearing_std_rad * likelihood_inflation``; then the
    short- and long-term averages of the per-bearing likelihood ``w_avg = (sum_i w_i
    p(z | x_i))^(1/n)`` are updated (the ``1/n`` power, ours, keeps frames with different
    numbers of visible landmarks comparable). Both averages start at the value expected of
    a localized filter, ``(1 + 1/inflation^2)^(-1/2)``, so a filter that starts or becomes
    lost injects at once. Injected particles come from the triple resections when >= 3
    bearings are seen, else uniformly from the field.
    """

    name: ClassVar[str] = "mcl_bearing"
    #: measured on this run: share 0.962, NEES median 0.28 (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.9)

    def __init__(self, landmarks: LandmarkMap, params: BearingMCLParams, *, dt_s: float) -> None:
        super().__init__(
            landmarks,
            params,
            dt_s=dt_s,
            alphas=params.alphas,
            floors=(params.min_translation_std_m, params.min_rotation_std_rad),
        )
        sigma = params.bearing_std_rad * params.likelihood_inflation
        self._neg_half_inv_var = -0.5 / (sigma * sigma)
        self._w_reference = 1.0 / math.sqrt(1.0 + 1.0 / params.likelihood_inflation**2)
        N = params.n_particles
        self._log_w = np.full(N, -math.log(N))
        self._scratch = np.empty(landmarks.count * N)
        self._averages = LikelihoodAverages(params.alpha_slow, params.alpha_fast, self._w_reference)
        self._valid = False
        self._t_s = 0.0
        self._last_seen_s = np.full(landmarks.count, -math.inf)  # per landmark, when last seen
        self._contradiction = Contradiction(landmarks.positions_xy_m, params.lost_residual_rad, params.lost_after_s, dt_s)

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Gaussian around ``prior`` (its covariance when finite), else uniform over the field."""
        self._rng = rng
        self._cache = None
        p = self._params
        N = p.n_particles
        if prior is None or not prior.valid:
            self._particles = uniform_poses(self._map.bounds_m, N, rng)
            self._valid = False
        else:
            cov = _prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
            self._particles = gaussian_poses(prior.as_array(), cov, N, rng)
            self._valid = True
        self._log_w.fill(-math.log(N))
        self._weights = np.full(N, 1.0 / N)
        self._averages.reset()
        self._contradiction.reset()
        self._t_s = 0.0
        self._last_seen_s.fill(0.0 if self._valid else -math.inf)  # a prior counts as a fix now

    def predict(self, odometry: OdometryDelta) -> None:
        """Sample the odometry motion model for every particle."""
        self._propagate(self._checked_odometry(odometry))
        self._t_s += self._dt_s

    def update(self, measurement: BearingMeasurement) -> None:
        """Weight by the bearing likelihood; resample (with injection) when needed."""
        meas = self._validated(measurement)
        n = meas.landmark_ids.size
        if n == 0:
            return
        rng = self._generator()
        if self._valid:  # the bearings against the estimate before this frame (lost detection)
            mean, _ = self._mean_cov()
            self._contradiction.observe((float(mean[0]), float(mean[1]), float(mean[2])), meas.landmark_ids, meas.bearings_rad)
        N = self._params.n_particles
        lm = self._map.positions_xy_m[meas.landmark_ids]
        e = bearing_residuals(self._particles, lm, meas.bearings_rad, out=self._scratch[: n * N].reshape(n, N))
        e *= e
        log_w = self._log_w
        log_w += self._neg_half_inv_var * np.add.reduce(e, axis=0)
        peak = log_w.max()
        log_w -= peak
        w = np.exp(log_w)
        total = w.sum()
        w /= total
        log_w -= math.log(total)  # normalized: logsumexp(log_w) == 0
        self._weights = w
        self._cache = None
        self._valid = True
        self._last_seen_s[meas.landmark_ids] = self._t_s
        # Augmented MCL (Probabilistic Robotics Table 8.3); w_avg = sum_i w_i p(z | x_i).
        p = self._params
        self._averages.update(math.exp((peak + math.log(total)) / n))
        p_inject = self._averages.injection_probability(p.injection_ratio)
        n_inject = int(rng.binomial(N, p_inject)) if p_inject > 0.0 else 0
        if n_inject == 0 and 1.0 / float(w @ w) >= p.resample_ess_fraction * N:
            return
        idx = systematic_resample(w, N - n_inject, rng)
        particles = np.empty((3, N))
        np.take(self._particles, idx, axis=1, out=particles[:, : N - n_inject])
        if n_inject:
            particles[:, N - n_inject :] = self._injected(n_inject, meas, rng)
        self._particles = particles
        log_w.fill(-math.log(N))
        self._weights = np.full(N, 1.0 / N)

    def _injected(self, count: int, meas: BearingMeasurement, rng: np.random.Generator) -> Array:
        """``(3, count)`` random particles: around triple resections, else uniform."""
        p = self._params
        if meas.landmark_ids.size >= 3:
            poses = resection_poses(self._map.positions_xy_m, meas)
            if poses.shape[0]:
                centers = poses[rng.integers(poses.shape[0], size=count)].T
                return _jitter(centers, p.injection_position_std_m, p.injection_heading_std_rad, rng)
        return uniform_poses(self._map.bounds_m, count, rng)

    @property
    def likelihood_averages(self) -> tuple[float, float]:
        """``(w_slow, w_fast)`` of augmented MCL."""
        slow, fast = self._averages.slow, self._averages.fast
        assert slow is not None and fast is not None  # they start at the localized value
        return slow, fast

    @property
    def lost(self) -> bool:
        """Whether the bearings have contradicted the estimate for ``lost_after_s`` (:mod:`localizers.contradiction`)."""
        return self._contradiction.lost

    @property
    def estimate(self) -> PoseEstimate:
        """Weighted mean and covariance; invalid before reset and without a prior until a
        bearing arrives. It claims no pose (``valid`` false, the mean and covariance kept) while
        the position spread exceeds ``max_spread_m``, while lost (:attr:`lost`: contradicted by the bearings), and while fewer
        than ``min_fix_landmarks`` distinct landmarks were seen in the last ``fix_memory_s``."""
        if self._rng is None or not self._valid:
            return PoseEstimate.invalid()
        mean, cov = self._mean_cov()
        p = self._params
        seen = int(np.count_nonzero(self._last_seen_s >= self._t_s - p.fix_memory_s))
        valid = within_spread(cov, p.max_spread_m) and not self.lost and seen >= p.min_fix_landmarks
        return PoseEstimate(float(mean[0]), float(mean[1]), float(mean[2]), cov.copy(), valid)
