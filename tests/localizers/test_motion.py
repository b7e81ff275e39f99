"""``core.motion``: the alpha odometry model's decomposition and noise statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.motion import from_rot_trans_rot, odometry_noise_std, sample_odometry, to_rot_trans_rot

N = 10_000
SIGMAS = 5.0  # tolerance in standard errors of the estimate


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def expected_variances(rot1: float, trans: float, rot2: float, alphas: tuple[float, float, float, float]) -> np.ndarray:
    """Variances of the (rot1, trans, rot2) noise, Probabilistic Robotics table 5.6."""
    a1, a2, a3, a4 = alphas
    return np.array(
        [
            a1 * rot1**2 + a2 * trans**2,
            a3 * trans**2 + a4 * (rot1**2 + rot2**2),
            a1 * rot2**2 + a2 * trans**2,
        ]
    )


def assert_noise_matches(noise: np.ndarray, variances: np.ndarray) -> None:
    """Zero mean and the given per-column variances, within SIGMAS standard errors.

    Standard error of the mean of n normal draws: sqrt(var / n); of the unbiased sample
    variance: var * sqrt(2 / (n - 1)).
    """
    n = noise.shape[0]
    mean = noise.mean(axis=0)
    var = noise.var(axis=0, ddof=1)
    assert np.all(np.abs(mean) <= SIGMAS * np.sqrt(variances / n)), (mean, variances)
    assert np.all(np.abs(var - variances) <= SIGMAS * variances * math.sqrt(2.0 / (n - 1))), (var, variances)


CASES = [
    # (increment (dx, dy, dtheta), alphas)
    ((0.3, 0.1, 0.4), (0.05, 0.02, 0.03, 0.01)),
    ((0.05, -0.01, -0.2), (0.02, 0.005, 0.005, 0.005)),
    ((-0.2, 0.05, 0.1), (0.1, 0.0, 0.02, 0.0)),  # reverse drive: negative translation
    ((0.029, 0.0007, 0.05), (0.02, 0.005, 0.005, 0.005)),  # one env step of robocup_static
]


@pytest.mark.parametrize(("delta", "alphas"), CASES)
def test_sample_odometry_noise_statistics_follow_the_alpha_model(delta: tuple, alphas: tuple) -> None:
    rng = np.random.default_rng(12345)
    samples = sample_odometry(rng, delta, alphas, size=N)
    assert samples.shape == (N, 3)
    clean = to_rot_trans_rot(delta)
    noisy = to_rot_trans_rot(samples)
    noise = noisy - clean
    noise[:, [0, 2]] = wrap(noise[:, [0, 2]])
    assert_noise_matches(noise, expected_variances(*clean, alphas))


@pytest.mark.parametrize(("delta", "alphas"), CASES)
def test_odometry_noise_std_is_the_square_root_of_the_model_variances(delta: tuple, alphas: tuple) -> None:
    rot1, trans, rot2 = to_rot_trans_rot(delta)
    expected = np.sqrt(expected_variances(rot1, trans, rot2, alphas))
    np.testing.assert_allclose(odometry_noise_std(delta, alphas), expected, rtol=1e-12)


@pytest.mark.parametrize(
    ("delta", "expected"),
    [
        ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
        ((0.0, 1.0, math.pi / 2), (math.pi / 2, 1.0, 0.0)),
        ((1.0, 1.0, 0.0), (math.pi / 4, math.sqrt(2), -math.pi / 4)),
        ((-1.0, 0.0, 0.0), (0.0, -1.0, 0.0)),  # backward: no half-turns
        ((-1.0, -1.0, 0.3), (math.pi / 4, -math.sqrt(2), 0.3 - math.pi / 4)),
        ((0.0, 0.0, 0.7), (0.0, 0.0, 0.7)),  # turn on the spot
    ],
)
def test_to_rot_trans_rot_closed_form(delta: tuple, expected: tuple) -> None:
    np.testing.assert_allclose(to_rot_trans_rot(delta), expected, atol=1e-12)


def test_rot_trans_rot_round_trip() -> None:
    rng = np.random.default_rng(7)
    deltas = np.column_stack([rng.uniform(-1, 1, 500), rng.uniform(-1, 1, 500), rng.uniform(-3, 3, 500)])
    rtr = to_rot_trans_rot(deltas)
    assert rtr.shape == deltas.shape
    assert np.all(np.abs(rtr[:, 0]) <= math.pi / 2 + 1e-12)
    np.testing.assert_allclose(from_rot_trans_rot(rtr), deltas, atol=1e-12)


@pytest.mark.parametrize("delta", [(0.3, 0.1, 0.4), (-0.2, 0.0, -1.0), (0.0, 0.0, 0.0)])
def test_zero_alphas_return_the_increment(delta: tuple) -> None:
    rng = np.random.default_rng(0)
    out = sample_odometry(rng, delta, (0.0, 0.0, 0.0, 0.0))
    assert out.shape == (3,)
    np.testing.assert_allclose(out, delta, atol=1e-15)


def test_sample_odometry_per_row_increments_and_reproducibility() -> None:
    deltas = np.array([[0.3, 0.1, 0.4], [0.0, 0.0, 0.0], [-0.1, 0.02, 0.05]])
    alphas = (0.05, 0.02, 0.03, 0.01)
    a = sample_odometry(np.random.default_rng(3), deltas, alphas)
    b = sample_odometry(np.random.default_rng(3), deltas, alphas)
    assert a.shape == (3, 3)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a[1], 0.0)  # no motion, no noise
    assert not np.array_equal(a, sample_odometry(np.random.default_rng(4), deltas, alphas))


def test_sample_odometry_size_needs_a_single_increment() -> None:
    with pytest.raises(ValueError, match=r"size=5 needs a single \(3,\) increment, got shape \(2, 3\)"):
        sample_odometry(np.random.default_rng(0), np.zeros((2, 3)), (0.1, 0.1, 0.1, 0.1), size=5)
