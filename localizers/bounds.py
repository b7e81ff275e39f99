"""Posterior Cramer-Rao bound (PCRB) for bearing-only localization along a known trajectory.

Tichavsky, Muravchik and Nehorai (1998) give the Fisher information ``J_k`` of the pose
at step ``k`` for a nonlinear filtering problem; for additive process noise ``w_k ~ N(0,
Q_k)`` on the motion ``x_{k+1} = f(x_k, u_k) + w_k`` (linearized along the true
trajectory, ``F_k = df/dx``) and bearing measurements,

    D11 = F^T Q^-1 F,   D12 = D21^T = -F^T Q^-1,   D22 = Q^-1 + J_z,k+1
    J_{k+1} = D22 - D21 (J_k + D11)^-1 D12                                   (eq. 21)

and the bound is ``E[(x_hat - x)(x_hat - x)^T] >= J_k^-1``. ``J_z`` sums
``H_l^T H_l / sigma_b^2`` over the landmarks ``l`` visible at that step, with ``H_l`` the
gradient of the bearing ``atan2(l_y - y, l_x - x) - theta``.

The process noise is the odometry alpha model of :mod:`core.motion`, mapped from
``(rot1, trans, rot2)`` to the pose through the linearized motion ``G_k``:
``Q_k = G_k diag(std^2) G_k^T``. Standing still gives ``Q_k = 0`` and a pure rotation a
rank-deficient ``Q_k``, so ``Q^-1`` does not exist; we regularize with
``Q_k + process_noise_floor * I`` (default ``1e-12``: a 1 micrometre / 1 microradian
standard deviation, far below any physical noise) and evaluate eq. (21) in the equivalent
form given by the matrix inversion lemma,

    J_{k+1} = (Q_k + F_k J_k^-1 F_k^T)^-1 + J_z,k+1,

which never inverts ``Q_k`` and so is exact in the limit of a zero floor and free of the
cancellation between the two large terms of eq. (21). ``F_k`` is invertible (unit
determinant), so ``J_k`` stays positive definite from a positive-definite
``initial_cov``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.motion import odometry_noise_std, to_rot_trans_rot

Array = NDArray[np.float64]


def bearing_jacobians(pose: ArrayLike, landmarks_xy: ArrayLike) -> Array:
    """Gradients of the bearings to landmarks w.r.t. ``(x, y, theta)``.

    Args:
        pose: ``(3,)`` robot pose.
        landmarks_xy: ``(L, 2)`` landmark positions.

    Returns:
        ``(L, 3)`` rows ``[(l_y - y) / r^2, -(l_x - x) / r^2, -1]``.
    """
    p = np.asarray(pose, dtype=np.float64)
    lm = np.asarray(landmarks_xy, dtype=np.float64).reshape(-1, 2)
    dx = lm[:, 0] - p[0]
    dy = lm[:, 1] - p[1]
    r2 = dx * dx + dy * dy
    return np.column_stack([dy / r2, -dx / r2, -np.ones(lm.shape[0])])


def bearing_information(pose: ArrayLike, landmarks_xy: ArrayLike, bearing_std_rad: float) -> Array:
    """``(3, 3)`` Fisher information ``sum_l H_l^T H_l / sigma_b^2`` of one frame of bearings."""
    H = bearing_jacobians(pose, landmarks_xy)
    return (H.T @ H) / (bearing_std_rad * bearing_std_rad)


def odometry_process_noise(
    pose: ArrayLike,
    increment: ArrayLike,
    alphas: ArrayLike,
    *,
    min_translation_std_m: float = 0.0,
    min_rotation_std_rad: float = 0.0,
) -> Array:
    """``(3, 3)`` pose covariance added by one odometry increment under the alpha model.

    Args:
        pose: ``(3,)`` pose at the start of the increment (its heading orients the noise).
        increment: ``(3,)`` odometry increment ``(dx, dy, dtheta)`` in that pose's frame.
        alphas: ``(4,)`` alpha1..alpha4.
        min_translation_std_m, min_rotation_std_rad: noise floors added in quadrature to the
            translation's and each rotation's sd (as a particle filter's motion model has them).

    Returns:
        ``G diag(std^2) G^T`` with ``G`` the Jacobian of the pose after the motion with
        respect to ``(rot1, trans, rot2)``.
    """
    rot1, trans, _ = np.asarray(to_rot_trans_rot(increment), dtype=np.float64)
    std = np.asarray(odometry_noise_std(increment, alphas), dtype=np.float64)
    var = std * std + np.array([min_rotation_std_rad**2, min_translation_std_m**2, min_rotation_std_rad**2])
    phi = float(np.asarray(pose, dtype=np.float64)[2]) + rot1
    c, s = np.cos(phi), np.sin(phi)
    G = np.array([[-trans * s, c, 0.0], [trans * c, s, 0.0], [1.0, 0.0, 1.0]])
    return (G * var) @ G.T


def _visibility(visible: ArrayLike | Sequence[Sequence[int]], T: int, L: int) -> NDArray[np.bool_]:
    """Normalize a ``(T, L)`` bool mask or a length-``T`` list of id lists to a mask."""
    if isinstance(visible, np.ndarray) and visible.dtype == np.bool_:
        mask = visible
    else:
        seq = list(visible)  # type: ignore[arg-type]
        if len(seq) != T:
            raise ValueError(f"posterior_crb: visible_ids has {len(seq)} entries for {T} poses")
        if all(np.asarray(v).dtype == np.bool_ and np.asarray(v).shape == (L,) for v in seq) and T:
            mask = np.asarray(seq, dtype=bool)
        else:
            mask = np.zeros((T, L), dtype=bool)
            for k, ids in enumerate(seq):
                idx = np.asarray(ids, dtype=np.int64).reshape(-1)
                if idx.size and (idx.min() < 0 or idx.max() >= L):
                    raise ValueError(f"posterior_crb: landmark id out of range 0..{L - 1} at step {k}: {idx.tolist()}")
                mask[k, idx] = True
    if mask.shape != (T, L):
        raise ValueError(f"posterior_crb: visibility mask must have shape ({T}, {L}), got {mask.shape}")
    return mask


def posterior_crb(
    true_poses: ArrayLike,
    odometry_increments: ArrayLike,
    visible_ids: ArrayLike | Sequence[Sequence[int]],
    landmarks_xy: ArrayLike,
    bearing_std_rad: float,
    alphas: ArrayLike,
    initial_cov: ArrayLike,
    *,
    process_noise_floor: float = 1e-12,
) -> Array:
    """Posterior Cramer-Rao bound on the pose covariance at every step of a run.

    Step 0 combines ``initial_cov`` with the bearings seen at step 0; step ``k + 1``
    follows from step ``k`` by the increment ``k`` and the bearings at ``k + 1``.

    Args:
        true_poses: ``(T, 3)`` true poses.
        odometry_increments: ``(T - 1, 3)`` odometry increments (set the alpha-model noise).
        visible_ids: ``(T, L)`` bool mask, or ``T`` sequences of visible landmark ids.
        landmarks_xy: ``(L, 2)`` landmark positions.
        bearing_std_rad: bearing noise standard deviation (> 0).
        alphas: ``(4,)`` odometry alpha1..alpha4.
        initial_cov: ``(3, 3)`` positive-definite prior covariance.
        process_noise_floor: added to the diagonal of every ``Q_k`` (see the module doc).

    Returns:
        ``(T, 3, 3)`` bound covariances ``J_k^-1``.
    """
    poses = np.asarray(true_poses, dtype=np.float64)
    incs = np.asarray(odometry_increments, dtype=np.float64)
    lm = np.asarray(landmarks_xy, dtype=np.float64)
    P0 = np.asarray(initial_cov, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or poses.shape[0] < 1:
        raise ValueError(f"posterior_crb: true_poses must have shape (T, 3) with T >= 1, got {poses.shape}")
    T = poses.shape[0]
    if incs.shape != (T - 1, 3):
        raise ValueError(f"posterior_crb: odometry_increments must have shape ({T - 1}, 3), got {incs.shape}")
    if lm.ndim != 2 or lm.shape[1] != 2:
        raise ValueError(f"posterior_crb: landmarks_xy must have shape (L, 2), got {lm.shape}")
    if not (np.isfinite(bearing_std_rad) and bearing_std_rad > 0.0):
        raise ValueError(f"posterior_crb: bearing_std_rad must be > 0, got {bearing_std_rad!r}")
    if P0.shape != (3, 3) or not np.isfinite(P0).all() or np.linalg.eigvalsh(0.5 * (P0 + P0.T)).min() <= 0.0:
        raise ValueError(f"posterior_crb: initial_cov must be a finite positive-definite (3, 3) matrix, got {P0!r}")
    if not (np.isfinite(process_noise_floor) and process_noise_floor >= 0.0):
        raise ValueError(f"posterior_crb: process_noise_floor must be >= 0, got {process_noise_floor!r}")
    mask = _visibility(visible_ids, T, lm.shape[0])

    eye = np.eye(3)
    bounds = np.empty((T, 3, 3))
    J = np.linalg.inv(P0) + bearing_information(poses[0], lm[mask[0]], bearing_std_rad)
    bounds[0] = np.linalg.inv(J)
    for k in range(T - 1):
        # F: Jacobian of x_{k+1} = compose(x_k, u_k) w.r.t. x_k along the true trajectory.
        F = eye.copy()
        F[0, 2] = -(poses[k + 1, 1] - poses[k, 1])
        F[1, 2] = poses[k + 1, 0] - poses[k, 0]
        Q = odometry_process_noise(poses[k], incs[k], alphas) + process_noise_floor * eye
        prior_cov = Q + F @ bounds[k] @ F.T  # (Q + F J^-1 F^T), eq. (21) via the inversion lemma
        J = np.linalg.inv(0.5 * (prior_cov + prior_cov.T))
        J += bearing_information(poses[k + 1], lm[mask[k + 1]], bearing_std_rad)
        inv = np.linalg.inv(0.5 * (J + J.T))
        bounds[k + 1] = 0.5 * (inv + inv.T)
    return bounds


def bound_position_rmse(bounds: ArrayLike) -> Array:
    """``(T,)`` position RMSE bound ``sqrt(trace)`` of the ``(T, 3, 3)`` bounds' position blocks."""
    b = np.asarray(bounds, dtype=np.float64)
    return np.sqrt(b[..., 0, 0] + b[..., 1, 1])
