"""The particle-filter core shared by the Monte Carlo localizers (bearing and LIDAR MCL).

Pure functions on particle sets stored *struct-of-arrays*: an array of shape ``(3, N)``
whose rows are x, y and heading, so every vector operation runs over one contiguous row of
N values. The motion model is the alpha model of :mod:`core.motion` (Probabilistic
Robotics sec. 5.4, sample_motion_model_odometry), applied to the odometry increment.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import circular_mean, wrap_angle
from core.motion import odometry_noise_std, to_rot_trans_rot
from localizers.base import PoseEstimate, finite_covariance
from localizers.bounds import odometry_process_noise

Array = NDArray[np.float64]
_HEADING_REWRAP_RAD = 32.0  # particle headings are re-wrapped once they exceed this magnitude

#: the most particles (or candidate poses) a localizer's parameters may ask for: each is a pose and
#: its weights, about 50 bytes, weighed at every update; 10**6 is a thousand times the papers' sets
#: and about 50 MB (10**9 would need about 50 GB). Checked with :func:`core.schema.check_at_most`.
MAX_PARTICLES = 1_000_000
#: why :data:`MAX_PARTICLES` (the reason the parameter errors give)
PARTICLE_MEMORY = "memory: each particle is a pose and its weights, about 50 bytes, weighed at every update"


def propagate_particles(
    particles: Array,
    delta: ArrayLike,
    alphas: ArrayLike,
    rng: np.random.Generator,
    *,
    min_translation_std_m: float = 0.0,
    min_rotation_std_rad: float = 0.0,
) -> Array:
    """Sample the odometry motion model for every particle, in place.

    Each particle draws its own ``(rot1, trans, rot2)`` around the decomposed increment
    with the alpha-model standard deviations (:func:`core.motion.odometry_noise_std`);
    the optional floors are added in quadrature to those deviations so that a robot at rest
    keeps a little particle diversity (ours, a form of roughening).

    Speed: the direction of travel goes through ``cos``/``sin`` in float32 (SIMD, ~8x faster
    than float64 here). Headings are kept in ``(-_HEADING_REWRAP_RAD, _HEADING_REWRAP_RAD)``
    so the float32 rounding of the angle stays below 4e-6 rad, i.e. below 1e-7 m of position
    per step, far under any motion noise.

    Args:
        particles: ``(3, N)`` poses (rows x, y, heading); overwritten. Headings come out
            unwrapped (bounded, see above); wrap them where a canonical angle is needed.
        delta: ``(3,)`` odometry increment in the previous odometry frame.
        alphas: ``(4,)`` alpha1..alpha4.
        rng: the random generator.
        min_translation_std_m: floor on the translation noise std.
        min_rotation_std_rad: floor on each rotation noise std.

    Returns:
        ``particles`` (the same array).
    """
    rot1, trans, rot2 = (float(v) for v in to_rot_trans_rot(delta))
    std = odometry_noise_std(delta, alphas)
    sd_r1 = math.hypot(float(std[0]), min_rotation_std_rad)
    sd_t = math.hypot(float(std[1]), min_translation_std_m)
    sd_r2 = math.hypot(float(std[2]), min_rotation_std_rad)
    noise = rng.standard_normal((3, particles.shape[1]))
    phi, t, turn = noise[0], noise[1], noise[2]
    phi *= sd_r1
    phi += rot1
    phi += particles[2]  # direction of travel: heading + noisy rot1
    t *= sd_t
    t += trans
    phi32 = phi.astype(np.float32)
    particles[0] += t * np.cos(phi32)
    particles[1] += t * np.sin(phi32)
    turn *= sd_r2
    turn += rot2
    heading = particles[2]
    np.add(phi, turn, out=heading)  # left unwrapped: every consumer wraps (saves a pass per step)
    if max(heading.max(), -heading.min()) > _HEADING_REWRAP_RAD:
        heading[:] = wrap_angle(heading)
    return particles


def weighted_pose_mean(particles: Array, weights: Array | None = None) -> Array:
    """``(3,)`` weighted mean pose of ``(3, N)`` particles, heading by circular mean.

    ``weights`` ``(N,)`` must sum to one; ``None`` means uniform.
    """
    if weights is None:
        x, y = particles[0].mean(), particles[1].mean()
    else:
        x, y = weights @ particles[0], weights @ particles[1]
    return np.array([x, y, circular_mean(particles[2], weights)], dtype=np.float64)


def weighted_pose_covariance(particles: Array, mean: Array, weights: Array | None = None) -> Array:
    """``(3, 3)`` weighted covariance of ``(3, N)`` particles about ``mean`` (heading wrapped)."""
    d = particles - mean[:, None]
    d[2] = wrap_angle(d[2])
    if weights is None:
        return (d @ d.T) / max(particles.shape[1], 1)
    return (d * weights) @ d.T


def systematic_resample(weights: Array, count: int, rng: np.random.Generator) -> NDArray[np.intp]:
    """Low-variance (systematic) resampling, Probabilistic Robotics Table 4.4.

    Args:
        weights: ``(N,)`` normalized weights.
        count: number of indices to draw.
        rng: one uniform draw per call.

    Returns:
        ``(count,)`` ancestor indices in ``[0, N)``, non-decreasing.
    """
    if count <= 0:
        return np.zeros(0, dtype=np.intp)
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against round-off
    positions = (rng.random() + np.arange(count)) / count
    idx = np.searchsorted(cumulative, positions, side="right")
    return np.minimum(idx, weights.shape[0] - 1)


def uniform_poses(bounds_m: tuple[float, float, float, float], count: int, rng: np.random.Generator) -> Array:
    """``(3, count)`` poses uniform over the field ``(xmin, ymin, xmax, ymax)`` and heading."""
    xmin, ymin, xmax, ymax = bounds_m
    out = rng.random((3, count))
    out[0] = xmin + (xmax - xmin) * out[0]
    out[1] = ymin + (ymax - ymin) * out[1]
    out[2] = math.pi * (2.0 * out[2] - 1.0)
    return out


def gaussian_poses(center: ArrayLike, cov: ArrayLike, count: int, rng: np.random.Generator) -> Array:
    """``(3, count)`` poses drawn from ``N(center, cov)`` (heading wrapped).

    ``cov`` ``(3, 3)`` must be symmetric positive semi-definite.
    """
    c = np.asarray(center, dtype=np.float64)
    w, v = np.linalg.eigh(np.asarray(cov, dtype=np.float64))
    root = v * np.sqrt(np.clip(w, 0.0, None))
    out = root @ rng.standard_normal((3, count)) + c[:, None]
    out[2] = wrap_angle(out[2])
    return out


def prior_covariance(prior: PoseEstimate, position_std_m: float, heading_std_rad: float) -> Array:
    """The prior's covariance when it is a finite PSD ``(3, 3)``, else the params' diagonal."""
    cov = finite_covariance(prior)
    if cov is not None:
        cov = 0.5 * (cov + cov.T)
        if np.linalg.eigvalsh(cov).min() >= -1e-12:
            return cov
    return np.diag([position_std_m**2, position_std_m**2, heading_std_rad**2])


def motion_covariance(
    pose: ArrayLike,
    cov: ArrayLike,
    delta: ArrayLike,
    alphas: ArrayLike,
    *,
    min_translation_std_m: float = 0.0,
    min_rotation_std_rad: float = 0.0,
) -> Array:
    """``(3, 3)`` covariance of ``compose(pose, delta)`` with the increment drawn from the alpha model.

    First-order propagation (the EKF prediction of Probabilistic Robotics Table 7.1 with the
    odometry model of sec. 5.4): ``F cov F^T`` plus the increment's own noise
    (:func:`localizers.bounds.odometry_process_noise`, floors added in quadrature as
    :func:`propagate_particles` does), ``F`` the Jacobian of the composition in the pose. A particle filter reports it for motion
    it has not yet applied to its particles, a dead-reckoned pose for every increment.
    """
    p = np.asarray(pose, dtype=np.float64)
    rot1, trans, _ = (float(v) for v in to_rot_trans_rot(delta))
    phi = float(p[2]) + rot1
    F = np.array([[1.0, 0.0, -trans * math.sin(phi)], [0.0, 1.0, trans * math.cos(phi)], [0.0, 0.0, 1.0]])
    noise = odometry_process_noise(
        p, delta, alphas, min_translation_std_m=min_translation_std_m, min_rotation_std_rad=min_rotation_std_rad
    )
    return F @ np.asarray(cov, dtype=np.float64) @ F.T + noise


class LikelihoodAverages:
    """The short- and long-term averages of the measurement likelihood of augmented MCL
    (Probabilistic Robotics Table 8.3): ``w_slow += alpha_slow (w_avg - w_slow)``, likewise
    ``w_fast``. ``w_fast`` falling below ``w_slow`` means the measurements have just become
    unlikely under the particles: the filter is lost (kidnapped, or its odometry jumped).

    Args:
        alpha_slow, alpha_fast: the rates, ``0 < alpha_slow < alpha_fast <= 1``.
        start: the value both averages start at; ``None``: the first ``w_avg``.
    """

    def __init__(self, alpha_slow: float, alpha_fast: float, start: float | None = None) -> None:
        self.alpha_slow, self.alpha_fast = alpha_slow, alpha_fast
        self._start = start
        self.slow: float | None = start
        self.fast: float | None = start

    def reset(self) -> None:
        self.slow = self.fast = self._start

    def update(self, w_avg: float) -> None:
        """Fold one update's average likelihood in."""
        if self.slow is None or self.fast is None:
            self.slow = self.fast = w_avg
            return
        self.slow += self.alpha_slow * (w_avg - self.slow)
        self.fast += self.alpha_fast * (w_avg - self.fast)

    def injection_probability(self, ratio: float = 1.0) -> float:
        """``max(0, 1 - w_fast / (ratio w_slow))`` (``ratio`` 1: the book's rule; 0 before any update)."""
        if self.slow is None or self.fast is None or not self.slow > 0.0:
            return 0.0
        return max(0.0, 1.0 - self.fast / (ratio * self.slow))

    def lost(self, ratio: float) -> bool:
        """Whether ``w_fast < ratio w_slow``: the recent measurements are this much less likely than usual (``ratio`` 0: never)."""
        return ratio > 0.0 and self.injection_probability(ratio) > 0.0
