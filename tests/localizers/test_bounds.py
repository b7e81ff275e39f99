"""Tests of localizers.bounds: the posterior Cramer-Rao bound against direct computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.geometry import bearings_to, compose, wrap_angle
from core.motion import sample_odometry
from localizers.bounds import (
    bearing_information,
    bearing_jacobians,
    bound_position_rmse,
    odometry_process_noise,
    posterior_crb,
)

LANDMARKS = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0], [3.0, 0.0], [3.0, 4.0]])
ALPHAS = np.array([0.1, 0.1, 0.1, 0.01])
SIGMA = math.radians(1.0)
P0 = np.diag([0.1, 0.2, 0.05])


def trajectory(steps: int, increment: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    incs = np.tile(np.asarray(increment, dtype=np.float64), (steps - 1, 1))
    poses = [np.array([2.0, 1.5, 0.3])]
    for d in incs:
        poses.append(compose(poses[-1], d))
    return np.array(poses), incs


def information(pose: np.ndarray, ids: list[int]) -> np.ndarray:
    """Fisher information of one frame, written out from the bearing gradient."""
    J = np.zeros((3, 3))
    for j in ids:
        dx, dy = LANDMARKS[j] - pose[:2]
        r2 = dx * dx + dy * dy
        h = np.array([dy / r2, -dx / r2, -1.0])
        J += np.outer(h, h) / SIGMA**2
    return J


@pytest.mark.parametrize("ids", [[0, 1, 2], [0, 1, 2, 3, 4, 5], [1, 3, 5]])
@pytest.mark.parametrize("floor, rtol", [(0.0, 1e-9), (1e-12, 1e-4)])  # exact, and with the default floor
def test_static_robot_accumulates_fisher_information(ids: list[int], floor: float, rtol: float) -> None:
    steps = 50
    poses, incs = trajectory(steps, (0.0, 0.0, 0.0))
    visible = np.zeros((steps, len(LANDMARKS)), dtype=bool)
    visible[:, ids] = True
    bounds = posterior_crb(poses, incs, visible, LANDMARKS, SIGMA, ALPHAS, P0, process_noise_floor=floor)
    J1 = information(poses[0], ids)
    for k in [0, 1, 9, 49]:
        direct = np.linalg.inv(np.linalg.inv(P0) + (k + 1) * J1)
        np.testing.assert_allclose(bounds[k], direct, rtol=rtol, atol=1e-18)


def test_more_landmarks_give_a_smaller_bound() -> None:
    steps = 120
    poses, incs = trajectory(steps, (0.01, 0.0, 0.01))
    few = np.zeros((steps, len(LANDMARKS)), dtype=bool)
    few[:, [0, 2]] = True
    few[::7, 4] = True
    many = few.copy()
    many[:, [1, 3]] = True
    b_few = posterior_crb(poses, incs, few, LANDMARKS, SIGMA, ALPHAS, P0)
    b_many = posterior_crb(poses, incs, many, LANDMARKS, SIGMA, ALPHAS, P0)
    for k in range(steps):  # Loewner order: b_few - b_many is positive semi-definite
        assert np.linalg.eigvalsh(b_few[k] - b_many[k]).min() > -1e-12 * np.trace(b_few[k])
    assert np.all(bound_position_rmse(b_many)[1:] < bound_position_rmse(b_few)[1:])


def explicit_tichavsky(poses: np.ndarray, incs: np.ndarray, ids: list[int], floor: float) -> np.ndarray:
    """Eq. (21) with the D terms written out (needs an invertible Q)."""
    J = np.linalg.inv(P0) + information(poses[0], ids)
    out = [np.linalg.inv(J)]
    for k in range(len(incs)):
        F = np.eye(3)
        F[0, 2] = -(poses[k + 1, 1] - poses[k, 1])
        F[1, 2] = poses[k + 1, 0] - poses[k, 0]
        Qi = np.linalg.inv(odometry_process_noise(poses[k], incs[k], ALPHAS) + floor * np.eye(3))
        D11 = F.T @ Qi @ F
        D12 = -F.T @ Qi
        D22 = Qi + information(poses[k + 1], ids)
        J = D22 - D12.T @ np.linalg.inv(J + D11) @ D12
        out.append(np.linalg.inv(J))
    return np.array(out)


@pytest.mark.parametrize("increment", [(0.02, 0.0, 0.02), (0.03, 0.01, -0.05), (-0.02, 0.0, 0.1)])
def test_matches_the_explicit_recursion(increment: tuple[float, float, float]) -> None:
    poses, incs = trajectory(40, increment)
    ids = [0, 2, 5]
    floor = 1e-8  # large enough for the explicit form's Q^-1 to be well conditioned
    visible = [ids] * len(poses)
    bounds = posterior_crb(poses, incs, visible, LANDMARKS, SIGMA, ALPHAS, P0, process_noise_floor=floor)
    np.testing.assert_allclose(bounds, explicit_tichavsky(poses, incs, ids, floor), rtol=1e-6, atol=1e-14)


@pytest.mark.parametrize("increment", [(0.0, 0.0, 0.0), (0.0, 0.0, 0.2)])  # Q = 0; Q of rank 2
@pytest.mark.parametrize("floor", [0.0, 1e-12])
def test_degenerate_process_noise_stays_finite(increment: tuple[float, float, float], floor: float) -> None:
    poses, incs = trajectory(100, increment)
    bounds = posterior_crb(poses, incs, [[0, 1]] * 100, LANDMARKS, SIGMA, ALPHAS, P0, process_noise_floor=floor)
    assert np.isfinite(bounds).all()
    assert all(np.linalg.eigvalsh(b).min() > 0.0 for b in bounds)
    if increment == (0.0, 0.0, 0.0):  # no motion noise: the bound only shrinks
        assert np.all(np.diff(bound_position_rmse(bounds)) <= 1e-15)


def test_no_landmarks_grows_like_the_motion_noise() -> None:
    poses, incs = trajectory(30, (0.02, 0.0, 0.0))
    bounds = posterior_crb(poses, incs, np.zeros((30, 6), dtype=bool), LANDMARKS, SIGMA, ALPHAS, P0)
    cov = P0.copy()
    for k in range(29):  # linear covariance propagation, what the bound must equal here
        F = np.array([[1.0, 0.0, -(poses[k + 1, 1] - poses[k, 1])], [0.0, 1.0, poses[k + 1, 0] - poses[k, 0]], [0, 0, 1]])
        cov = F @ cov @ F.T + odometry_process_noise(poses[k], incs[k], ALPHAS)
    np.testing.assert_allclose(bounds[-1], cov, rtol=1e-6)


def test_ragged_ids_equal_mask() -> None:
    poses, incs = trajectory(5, (0.02, 0.0, 0.01))
    ids = [[0], [], [1, 2], [5, 0, 3], [4]]
    mask = np.zeros((5, 6), dtype=bool)
    for k, row in enumerate(ids):
        mask[k, row] = True
    np.testing.assert_array_equal(
        posterior_crb(poses, incs, ids, LANDMARKS, SIGMA, ALPHAS, P0),
        posterior_crb(poses, incs, mask, LANDMARKS, SIGMA, ALPHAS, P0),
    )


def test_bearing_jacobian_matches_finite_differences() -> None:
    pose = np.array([2.0, 1.0, 0.4])
    H = bearing_jacobians(pose, LANDMARKS)
    eps = 1e-6
    for i in range(3):
        step = np.zeros(3)
        step[i] = eps
        fd = wrap_angle(bearings_to(pose + step, LANDMARKS) - bearings_to(pose - step, LANDMARKS)) / (2 * eps)
        np.testing.assert_allclose(H[:, i], fd, rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(bearing_information(pose, LANDMARKS, SIGMA), information(pose, list(range(6))))


@pytest.mark.parametrize("increment", [(0.05, 0.0, 0.0), (0.04, 0.01, 0.1), (0.0, 0.0, 0.3)])
def test_process_noise_matches_monte_carlo(increment: tuple[float, float, float]) -> None:
    alphas = np.array([0.002, 0.004, 0.001, 0.0005])  # small noise: the linearization is accurate
    pose = np.array([1.0, 2.0, 0.9])
    noisy = sample_odometry(np.random.default_rng(0), np.array(increment), alphas, size=200_000)
    ends = compose(pose, noisy)
    ends[:, 2] = wrap_angle(ends[:, 2] - compose(pose, increment)[2])
    Q = odometry_process_noise(pose, increment, alphas)
    mc = np.cov(ends.T)
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q))) + 1e-20
    np.testing.assert_allclose(mc / scale, Q / scale, atol=0.02)


def test_position_rmse_is_sqrt_trace_of_position_block() -> None:
    b = np.array([np.diag([1.0, 4.0, 100.0]), np.diag([0.25, 0.0, 9.0])])
    np.testing.assert_allclose(bound_position_rmse(b), [math.sqrt(5.0), 0.5])


@pytest.mark.parametrize(
    "kwargs, text",
    [
        ({"initial_cov": np.diag([1.0, 1.0, 0.0])}, "initial_cov"),
        ({"visible_ids": [[0]] * 4}, "visible_ids"),
        ({"visible_ids": [[0], [1], [9], [2], [3]]}, "out of range"),
        ({"odometry_increments": np.zeros((5, 3))}, "odometry_increments"),
        ({"bearing_std_rad": 0.0}, "bearing_std_rad"),
    ],
)
def test_bad_input_raises(kwargs: dict, text: str) -> None:
    poses, incs = trajectory(5, (0.01, 0.0, 0.0))
    args = {
        "true_poses": poses,
        "odometry_increments": incs,
        "visible_ids": [[0, 1]] * 5,
        "landmarks_xy": LANDMARKS,
        "bearing_std_rad": SIGMA,
        "alphas": ALPHAS,
        "initial_cov": P0,
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=text):
        posterior_crb(**args)
