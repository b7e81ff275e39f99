"""The odometry motion model of Probabilistic Robotics (Thrun et al., sec. 5.4), a leaf module.

One implementation serves both sides: the worlds use it to corrupt the commanded motion
into what the odometry reports, and particle filters use it to sample their motion model.
An increment ``(dx, dy, dtheta)`` in the start frame is decomposed into a first rotation,
a translation and a second rotation; each part gets zero-mean Gaussian noise whose
variance is

    rot1:  alpha1 rot1^2 + alpha2 trans^2
    trans: alpha3 trans^2 + alpha4 (rot1^2 + rot2^2)
    rot2:  alpha1 rot2^2 + alpha2 trans^2

Backward motion is decomposed with a negative translation, so driving in reverse does
not turn into a half-turn, a straight drive and another half-turn.

The kernels are compiled with numba: the env corrupts one increment per step and a
particle filter a thousand, and both must be cheap.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

_PI = math.pi
_TWO_PI = 2.0 * math.pi


@numba.njit(cache=True, inline="always")
def wrap_scalar(a: float) -> float:
    """One angle wrapped to ``[-pi, pi)`` inside compiled code (``geometry.wrap_angle`` for arrays)."""
    return (a + _PI) % _TWO_PI - _PI


@numba.njit(cache=True)
def _decompose(delta: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n, 3)`` increments -> ``(n, 3)`` rows of ``(rot1, trans, rot2)``."""
    out = np.empty_like(delta)
    for i in range(delta.shape[0]):
        dx, dy, dth = delta[i, 0], delta[i, 1], delta[i, 2]
        trans = math.sqrt(dx * dx + dy * dy)
        rot1 = math.atan2(dy, dx) if trans > 1e-12 else 0.0
        if abs(rot1) > _PI / 2:
            rot1 = wrap_scalar(rot1 - _PI)
            trans = -trans
        out[i, 0] = rot1
        out[i, 1] = trans
        out[i, 2] = wrap_scalar(dth - rot1)
    return out


@numba.njit(cache=True)
def _compose(rtr: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n, 3)`` rows of ``(rot1, trans, rot2)`` -> ``(n, 3)`` increments."""
    out = np.empty_like(rtr)
    for i in range(rtr.shape[0]):
        out[i, 0] = rtr[i, 1] * math.cos(rtr[i, 0])
        out[i, 1] = rtr[i, 1] * math.sin(rtr[i, 0])
        out[i, 2] = wrap_scalar(rtr[i, 0] + rtr[i, 2])
    return out


@numba.njit(cache=True)
def _noise_std(rtr: NDArray[np.float64], alphas: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.empty_like(rtr)
    a1, a2, a3, a4 = alphas[0], alphas[1], alphas[2], alphas[3]
    for i in range(rtr.shape[0]):
        r1 = rtr[i, 0] * rtr[i, 0]
        t = rtr[i, 1] * rtr[i, 1]
        r2 = rtr[i, 2] * rtr[i, 2]
        out[i, 0] = math.sqrt(a1 * r1 + a2 * t)
        out[i, 1] = math.sqrt(a3 * t + a4 * (r1 + r2))
        out[i, 2] = math.sqrt(a1 * r2 + a2 * t)
    return out


@numba.njit(cache=True)
def _perturb(delta: NDArray[np.float64], z: NDArray[np.float64], alphas: NDArray[np.float64]) -> NDArray[np.float64]:
    rtr = _decompose(delta)
    std = _noise_std(rtr, alphas)
    return _compose(rtr + z * std)


def _rows(delta: ArrayLike) -> NDArray[np.float64]:
    return np.ascontiguousarray(np.asarray(delta, dtype=np.float64).reshape(-1, 3))


def to_rot_trans_rot(delta: ArrayLike) -> NDArray[np.float64]:
    """Decompose increments ``(..., 3)`` into ``(..., 3)`` rows of ``(rot1, trans, rot2)``."""
    d = np.asarray(delta, dtype=np.float64)
    return _decompose(_rows(d)).reshape(d.shape)


def from_rot_trans_rot(rtr: ArrayLike) -> NDArray[np.float64]:
    """Compose ``(..., 3)`` rows of ``(rot1, trans, rot2)`` back into increments ``(..., 3)``."""
    r = np.asarray(rtr, dtype=np.float64)
    return _compose(_rows(r)).reshape(r.shape)


def odometry_noise_std(delta: ArrayLike, alphas: ArrayLike) -> NDArray[np.float64]:
    """Standard deviations ``(..., 3)`` of the noise on ``(rot1, trans, rot2)`` of increments ``(..., 3)``."""
    d = np.asarray(delta, dtype=np.float64)
    return _noise_std(_decompose(_rows(d)), np.asarray(alphas, dtype=np.float64)).reshape(d.shape)


def sample_odometry(
    rng: np.random.Generator, delta: ArrayLike, alphas: ArrayLike, size: int | None = None
) -> NDArray[np.float64]:
    """Draw noisy versions of increments under the alpha model.

    Args:
        rng: the only source of randomness.
        delta: ``(3,)`` one increment, or ``(n, 3)`` one per sample.
        alphas: ``(4,)`` alpha1..alpha4.
        size: number of samples of a single increment (``None``: one sample, shape ``(3,)``).

    Returns:
        ``(3,)`` or ``(size or n, 3)`` noisy increments.
    """
    d = np.asarray(delta, dtype=np.float64)
    rows = np.ascontiguousarray(d.reshape(-1, 3))  # (_rows without converting d again: the env calls this every step)
    if size is not None:
        if d.ndim != 1:
            raise ValueError(f"sample_odometry: size={size} needs a single (3,) increment, got shape {d.shape}")
        rows = np.ascontiguousarray(np.broadcast_to(rows, (size, 3)))
    z = rng.standard_normal(rows.shape)
    out = _perturb(rows, z, np.asarray(alphas, dtype=np.float64))
    return out[0] if (size is None and d.ndim == 1) else out
