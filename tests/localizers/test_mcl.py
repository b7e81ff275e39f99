"""Tests of localizers.mcl: the particle core (motion model, resampling, moments), the
paper's delete-and-reseed MCL, the reference MCL, and both against the posterior
Cramer-Rao bound on a well-conditioned seeded run."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from core.geometry import bearings_to, between, compose, wrap_angle
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, MeasurementError, OdometryDelta, PoseEstimate
from localizers.bounds import bound_position_rmse, posterior_crb
from localizers.mcl import (
    BearingMCL,
    BearingMCLParams,
    PaperBearingMCL,
    PaperMCLParams,
    propagate_particles,
    systematic_resample,
    weighted_pose_covariance,
    weighted_pose_mean,
)

CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "localizers"
DT = 1.0 / 30.0
ALPHAS = np.array([0.1, 0.1, 0.1, 0.01])
BEARING_STD = math.radians(1.0)
# A 6 m x 4 m field with six landmarks (corners and the middle of the long sides).
LANDMARKS = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0], [3.0, 0.0], [3.0, 4.0]])
BOUNDS = (0.0, 0.0, 6.0, 4.0)


def make_map(landmarks: np.ndarray = LANDMARKS) -> LandmarkMap:
    return LandmarkMap(landmarks, tuple(f"L{i + 1}" for i in range(len(landmarks))), BOUNDS)


def seen(pose: np.ndarray, ids: list[int], landmarks: np.ndarray = LANDMARKS) -> BearingMeasurement:
    ids_arr = np.asarray(ids, dtype=np.int64)
    return BearingMeasurement(ids_arr, np.asarray(bearings_to(pose, landmarks[ids_arr])))


def alpha_model_std(rot1: float, trans: float, rot2: float, alphas: np.ndarray = ALPHAS) -> np.ndarray:
    """Probabilistic Robotics Table 5.6, written out independently of core.motion."""
    a1, a2, a3, a4 = alphas
    return np.sqrt(
        [
            a1 * rot1**2 + a2 * trans**2,
            a3 * trans**2 + a4 * (rot1**2 + rot2**2),
            a1 * rot2**2 + a2 * trans**2,
        ]
    )


# --- particle core ------------------------------------------------------------------------


# Distinct, small alphas: a swapped alpha shows, and the sampled translation never changes
# sign (which would make the decomposition of a sample ambiguous).
TEST_ALPHAS = np.array([0.02, 0.05, 0.01, 0.0005])


@pytest.mark.parametrize(
    "delta",
    [
        (0.05, 0.0, 0.0),  # straight
        (0.04, 0.01, 0.1),  # arc with a lateral component
        (0.06, -0.01, -0.3),
        (-0.05, 0.005, 0.05),  # reversing: negative translation, small rot1
    ],
)
def test_motion_model_matches_alpha_model(delta: tuple[float, float, float]) -> None:
    n = 10_000
    start = np.array([1.0, 2.0, 0.7])
    particles = np.repeat(start[:, None], n, axis=1)
    propagate_particles(particles, np.array(delta), TEST_ALPHAS, np.random.default_rng(42))
    inc = between(start, particles.T)  # (n, 3) sampled increments in the start frame
    sign = 1.0 if delta[0] >= 0 else -1.0  # reversing is decomposed with negative translation
    rot1 = np.arctan2(sign * inc[:, 1], sign * inc[:, 0])
    trans = sign * np.hypot(inc[:, 0], inc[:, 1])
    rot2 = wrap_angle(inc[:, 2] - rot1)
    r1 = math.atan2(sign * delta[1], sign * delta[0])
    t = sign * math.hypot(delta[0], delta[1])
    r2 = wrap_angle(delta[2] - r1)
    std = alpha_model_std(r1, t, r2, TEST_ALPHAS)
    samples = np.column_stack([rot1, trans, rot2])
    mean_tol = 5.0 * std / math.sqrt(n)
    np.testing.assert_array_less(np.abs(samples.mean(axis=0) - [r1, t, r2]), mean_tol)
    var_ratio = samples.var(axis=0, ddof=1) / std**2
    np.testing.assert_allclose(var_ratio, 1.0, atol=5.0 * math.sqrt(2.0 / (n - 1)))
    # the three noises are independent
    corr = np.corrcoef(samples.T)[np.triu_indices(3, 1)]
    np.testing.assert_array_less(np.abs(corr), 5.0 / math.sqrt(n))


def test_motion_model_pure_rotation() -> None:
    n = 10_000
    start = np.array([0.0, 0.0, -1.0])
    particles = np.repeat(start[:, None], n, axis=1)
    propagate_particles(particles, np.array([0.0, 0.0, 0.3]), ALPHAS, np.random.default_rng(1))
    inc = between(start, particles.T)
    # rot1 = 0 and trans = 0: the position moves along the heading only, by N(0, alpha4 rot2^2).
    np.testing.assert_allclose(inc[:, 1], 0.0, atol=1e-8)  # float32 direction: ~1e-7 relative
    _, sd_t, sd_r2 = alpha_model_std(0.0, 0.0, 0.3)
    assert inc[:, 0].std() == pytest.approx(sd_t, rel=0.05)
    assert inc[:, 2].mean() == pytest.approx(0.3, abs=5 * sd_r2 / math.sqrt(n))
    assert inc[:, 2].std() == pytest.approx(sd_r2, rel=0.05)


def test_motion_floor_keeps_diversity_at_rest() -> None:
    particles = np.zeros((3, 5000))
    propagate_particles(
        particles, np.zeros(3), ALPHAS, np.random.default_rng(0), min_translation_std_m=0.001, min_rotation_std_rad=0.002
    )
    assert particles[2].std() == pytest.approx(0.002 * math.sqrt(2.0), rel=0.05)  # rot1 and rot2 both floored
    assert particles[0].std() == pytest.approx(0.001, rel=0.05)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_systematic_resample_counts(seed: int) -> None:
    rng = np.random.default_rng(seed)
    w = rng.random(200) ** 4
    w /= w.sum()
    idx = systematic_resample(w, 200, rng)
    counts = np.bincount(idx, minlength=200)
    expected = 200 * w
    assert counts.sum() == 200
    assert np.all(counts >= np.floor(expected) - 1e-9) and np.all(counts <= np.ceil(expected) + 1e-9)


def test_weighted_moments_use_circular_heading() -> None:
    particles = np.array([[1.0, 3.0, 2.0], [0.0, 0.0, 3.0], [math.pi - 0.1, -math.pi + 0.1, math.pi]])
    w = np.array([0.25, 0.25, 0.5])
    mean = weighted_pose_mean(particles, w)
    np.testing.assert_allclose(mean[:2], [2.0, 1.5])
    assert abs(wrap_angle(mean[2] - math.pi)) < 1e-12
    cov = weighted_pose_covariance(particles, mean, w)
    assert cov[2, 2] == pytest.approx(0.5 * 0.01)
    assert cov[0, 0] == pytest.approx(0.25 + 0.25)


# --- the paper's MCL ----------------------------------------------------------------------


def tight_paper_params() -> PaperMCLParams:
    """Seeding noise ~0 so that the seed centres themselves can be checked."""
    return PaperMCLParams(
        two_landmark_position_std_m=1e-9,
        two_landmark_heading_std_rad=1e-9,
        three_landmark_position_std_m=1e-9,
        three_landmark_heading_std_rad=1e-9,
    )


def test_paper_one_landmark_seeds_uniform_positions_and_bearing_headings() -> None:
    loc = PaperBearingMCL(make_map(), PaperMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    loc.update(seen(np.array([2.0, 1.0, 0.3]), [2]))
    p = loc.particles
    assert p.shape == (1000, 3)
    assert p[:, 0].min() >= 0.0 and p[:, 0].max() <= 6.0 and p[:, 0].std() > 1.5
    assert p[:, 1].min() >= 0.0 and p[:, 1].max() <= 4.0 and p[:, 1].std() > 1.0
    residual = wrap_angle(bearings_to(p, LANDMARKS[[2]])[:, 0] - seen(np.array([2.0, 1.0, 0.3]), [2]).bearings_rad[0])
    assert residual.std() == pytest.approx(math.pi / 9.0, rel=0.1)


def test_paper_two_landmarks_seed_on_the_inscribed_arc() -> None:
    pose = np.array([2.0, 1.0, 0.3])
    loc = PaperBearingMCL(make_map(), tight_paper_params(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    meas = seen(pose, [1, 2])
    loc.update(meas)
    p = loc.particles
    assert p.shape == (1000, 3)
    np.testing.assert_allclose(wrap_angle(bearings_to(p, LANDMARKS[[1, 2]]) - meas.bearings_rad), 0.0, atol=1e-6)
    assert np.hypot(*p[:, :2].std(axis=0)) > 0.5  # spread along the arc, not one point


@pytest.mark.parametrize("ids", [[0, 1, 2], [0, 1, 2, 3, 4, 5]])
def test_paper_three_landmarks_seed_at_cassini(ids: list[int]) -> None:
    pose = np.array([2.0, 1.0, 0.3])
    loc = PaperBearingMCL(make_map(), tight_paper_params(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    loc.update(seen(pose, ids))
    np.testing.assert_allclose(loc.particles - pose, 0.0, atol=1e-6)


def test_paper_seed_spread_follows_params() -> None:
    pose = np.array([2.0, 1.5, -0.4])
    loc = PaperBearingMCL(make_map(), PaperMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(3))
    loc.update(seen(pose, [0, 1, 2, 3]))
    p = loc.particles
    np.testing.assert_allclose(p[:, :2].std(axis=0), 0.2, rtol=0.1)
    assert wrap_angle(p[:, 2] - pose[2]).std() == pytest.approx(math.pi / 15.3, rel=0.1)


def test_paper_gate_deletes_inconsistent_particles() -> None:
    truth = np.array([2.0, 1.5, 0.0])
    loc = PaperBearingMCL(make_map(), PaperMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(4.5, 3.0, 1.0, np.diag([0.01, 0.01, 0.01])))  # 1.8 m off
    meas = seen(truth, [0, 1, 2, 3])
    loc.update(meas)
    est = loc.estimate
    assert np.hypot(est.x_m - truth[0], est.y_m - truth[1]) < 0.05  # all re-seeded around Cassini
    # A second look: exactly the particles within pi/9 on every bearing survive, in order,
    # and as many new ones are seeded.
    before = loc.particles
    inside = (np.abs(wrap_angle(bearings_to(before, LANDMARKS[[0, 1, 2, 3]]) - meas.bearings_rad)) <= math.pi / 9).all(1)
    assert 0 < inside.sum() < 1000
    loc.update(meas)
    after = loc.particles
    assert after.shape == (1000, 3)
    np.testing.assert_allclose(after[: inside.sum()], before[inside], atol=1e-12)


def test_paper_dead_reckons_when_no_pose() -> None:
    loc = PaperBearingMCL(make_map(), PaperMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    assert not loc.estimate.valid  # no prior and no observation: no pose at all
    loc.predict(OdometryDelta(0.1, 0.0, 0.0))
    assert not loc.estimate.valid
    # With a prior and no observation yet: exact dead reckoning from the prior.
    prior = PoseEstimate(1.0, 1.0, 0.5, np.diag([1e-4, 1e-4, 1e-4]))
    loc.reset(np.random.default_rng(0), prior)
    for _ in range(5):
        loc.predict(OdometryDelta(0.1, 0.0, 0.2))
    expected = prior.as_array()
    for _ in range(5):
        expected = compose(expected, [0.1, 0.0, 0.2])
    np.testing.assert_allclose(loc.estimate.as_array(), expected, atol=1e-12)
    # An observation gives MCL a pose; then a view from the line through L1 and L2
    # (|sin psi| = 0) deletes every particle and the degenerate arc seeds nothing.
    loc.reset(np.random.default_rng(0), PoseEstimate(4.5, 3.0, 1.0, np.diag([1e-4, 1e-4, 1e-4])))
    loc.update(seen(np.array([4.5, 3.0, 1.0]), [0, 2, 3]))
    last = loc.estimate
    loc.update(seen(np.array([3.0, 0.0, 1.2]), [0, 1]))
    est = loc.estimate
    assert est.valid and loc.particles.shape == (0, 3)
    np.testing.assert_array_equal(est.as_array(), last.as_array())
    loc.predict(OdometryDelta(0.1, 0.0, 0.0))
    np.testing.assert_allclose(loc.estimate.as_array(), compose(last.as_array(), [0.1, 0.0, 0.0]), atol=1e-12)
    loc.update(seen(np.array([2.0, 1.5, 0.0]), [0, 1, 2]))  # seeds again
    assert loc.particles.shape == (1000, 3)
    np.testing.assert_allclose(loc.estimate.as_array()[:2], [2.0, 1.5], atol=0.05)


# --- the reference MCL --------------------------------------------------------------------


def test_reference_init_uniform_without_prior() -> None:
    loc = BearingMCL(make_map(), BearingMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    assert not loc.estimate.valid
    p = loc.particles
    assert p.shape == (1000, 3)
    for k, (lo, hi) in enumerate([(0.0, 6.0), (0.0, 4.0), (-math.pi, math.pi)]):
        assert lo <= p[:, k].min() and p[:, k].max() <= hi
        assert p[:, k].std() == pytest.approx((hi - lo) / math.sqrt(12.0), rel=0.1)


def test_reference_init_gaussian_around_prior() -> None:
    cov = np.diag([0.04, 0.01, 0.0025])
    loc = BearingMCL(make_map(), BearingMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(2.0, 1.0, 3.1, cov))
    est = loc.estimate
    assert est.valid
    assert np.hypot(est.x_m - 2.0, est.y_m - 1.0) < 0.02 and abs(wrap_angle(est.theta_rad - 3.1)) < 0.01
    np.testing.assert_allclose(np.diag(est.covariance), np.diag(cov), rtol=0.15)


def test_reference_update_concentrates_on_the_truth() -> None:
    truth = np.array([2.0, 1.5, 0.5])
    loc = BearingMCL(make_map(), BearingMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(2.1, 1.4, 0.45, np.diag([0.01, 0.01, 0.01])))
    spread = loc.estimate.position_spread_m
    loc.update(seen(truth, [0, 1, 2, 3, 4, 5]))
    est = loc.estimate
    assert est.position_spread_m < 0.5 * spread
    assert np.hypot(est.x_m - truth[0], est.y_m - truth[1]) < 0.05


def kidnap_run(params: BearingMCLParams, seed: int = 0) -> float:
    """Track, then move the robot 1 m without odometry seeing it; return the final error."""
    rng = np.random.default_rng(seed)
    loc = BearingMCL(make_map(), params, dt_s=DT)
    truth = np.array([2.0, 1.5, 0.0])
    loc.reset(np.random.default_rng(100 + seed), PoseEstimate(*truth, np.diag([1e-4, 1e-4, 1e-4])))
    step = np.array([0.005, 0.0, 0.005])
    for k in range(150):
        if k == 60:
            truth = compose(truth, [0.0, 1.0, 0.3])  # pushed by another robot
        truth = compose(truth, step)
        loc.predict(OdometryDelta(*step))
        meas = seen(truth, list(range(6)))
        noisy = wrap_angle(meas.bearings_rad + rng.normal(0.0, BEARING_STD, 6))
        loc.update(BearingMeasurement(meas.landmark_ids, noisy))
    est = loc.estimate
    return float(np.hypot(est.x_m - truth[0], est.y_m - truth[1]))


def test_reference_recovers_from_a_pose_jump() -> None:
    assert kidnap_run(BearingMCLParams()) < 0.05


def test_reference_without_injection_stays_lost() -> None:
    # Control for the test above: with injection effectively off the filter cannot recover.
    assert kidnap_run(BearingMCLParams(injection_ratio=1e-9)) > 0.3


def test_reference_global_localization_without_prior() -> None:
    rng = np.random.default_rng(7)
    loc = BearingMCL(make_map(), BearingMCLParams(), dt_s=DT)
    loc.reset(np.random.default_rng(8))
    truth = np.array([4.0, 2.5, -2.0])
    for _ in range(60):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
        meas = seen(truth, list(range(6)))
        loc.update(BearingMeasurement(meas.landmark_ids, wrap_angle(meas.bearings_rad + rng.normal(0, BEARING_STD, 6))))
    est = loc.estimate
    assert est.valid and np.hypot(est.x_m - truth[0], est.y_m - truth[1]) < 0.05


# --- statistical accuracy against the posterior Cramer-Rao bound --------------------------


def simulate(seed: int, steps: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A slow circle (0.15 m/s) inside the field; all six landmarks always visible.

    The true motion draws (rot1, trans, rot2) noise from the alpha model around the
    commanded increment, which is what the odometry reports (Probabilistic Robotics 5.4).

    Returns:
        true poses (T, 3), odometry increments (T - 1, 3), noisy bearings (T, 6), prior (3,).
    """
    rng = np.random.default_rng(seed)
    u = np.array([0.005, 0.0, 0.00625])
    r1, t, r2 = 0.0, 0.005, 0.00625
    std = alpha_model_std(r1, t, r2)
    poses = [np.array([3.0, 1.2, 0.0])]
    for _ in range(steps - 1):
        n1, nt, n2 = np.array([r1, t, r2]) + std * rng.standard_normal(3)
        x, y, th = poses[-1]
        poses.append(np.array([x + nt * math.cos(th + n1), y + nt * math.sin(th + n1), wrap_angle(th + n1 + n2)]))
    true = np.array(poses)
    bearings = wrap_angle(bearings_to(true, LANDMARKS) + rng.normal(0.0, BEARING_STD, (steps, len(LANDMARKS))))
    prior = true[0] + rng.normal(0.0, 0.05, 3)
    return true, np.tile(u, (steps - 1, 1)), np.asarray(bearings), prior


def mse_and_bound(make: type, params: object, seed: int, use_prior: bool) -> tuple[float, float]:
    true, odo, bearings, prior = simulate(seed)
    P0 = np.diag([0.05**2, 0.05**2, 0.05**2]) if use_prior else np.diag([1.0, 1.0, 1.0])
    loc = make(make_map(), params, dt_s=DT)
    loc.reset(np.random.default_rng(1000 + seed), PoseEstimate(*prior, P0) if use_prior else None)
    ids = np.arange(len(LANDMARKS))
    sq = []
    for k in range(true.shape[0]):
        if k:
            loc.predict(OdometryDelta(*odo[k - 1]))
        loc.update(BearingMeasurement(ids, bearings[k]))
        est = loc.estimate
        sq.append((est.x_m - true[k, 0]) ** 2 + (est.y_m - true[k, 1]) ** 2)
    visible = np.ones((true.shape[0], len(LANDMARKS)), dtype=bool)
    bound = posterior_crb(true, odo, visible, LANDMARKS, BEARING_STD, ALPHAS, P0)
    return float(np.mean(sq)), float(np.mean(bound_position_rmse(bound) ** 2))


def test_reference_mcl_within_3x_of_the_bound() -> None:
    runs = np.array([mse_and_bound(BearingMCL, BearingMCLParams(), seed, True) for seed in range(4)])
    ratio = math.sqrt(runs[:, 0].mean() / runs[:, 1].mean())
    # 1000 particles and a likelihood inflated 2x cost efficiency, but not a factor 3
    # (measured ~1.2-1.3 on these seeds).
    assert ratio < 3.0, ratio


def test_paper_mcl_within_10x_of_the_bound() -> None:
    runs = np.array([mse_and_bound(PaperBearingMCL, PaperMCLParams(), seed, False) for seed in range(4)])
    ratio = math.sqrt(runs[:, 0].mean() / runs[:, 1].mean())
    # Looser: the paper's MCL never weights particles. Its set only shrinks at the pi/9 gate,
    # which is 20 bearing standard deviations wide, so after the first Cassini-centred seeding
    # its mean is carried by odometry alone, i.e. it dead-reckons until the gate bites; over
    # this 10 s run that gives 2-6x the bound (measured ~3.7 pooled on these seeds).
    assert ratio < 10.0, ratio


# --- the shared localizer contract --------------------------------------------------------

CLASSES = [(PaperBearingMCL, PaperMCLParams), (BearingMCL, BearingMCLParams)]


@pytest.mark.parametrize("cls, params_cls", CLASSES)
def test_is_a_localizer(cls: type, params_cls: type) -> None:
    assert isinstance(cls(make_map(), params_cls(), dt_s=DT), Localizer)


@pytest.mark.parametrize("cls, params_cls", CLASSES)
def test_empty_measurement_is_legal(cls: type, params_cls: type) -> None:
    loc = cls(make_map(), params_cls(), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    before, particles = loc.estimate, loc.particles
    loc.update(BearingMeasurement.empty())
    np.testing.assert_array_equal(loc.estimate.as_array(), before.as_array())
    np.testing.assert_array_equal(loc.particles, particles)


@pytest.mark.parametrize("cls, params_cls", CLASSES)
def test_reset_clears_state(cls: type, params_cls: type) -> None:
    prior = PoseEstimate(2.0, 1.0, 0.5, np.diag([0.01, 0.01, 0.01]))
    loc = cls(make_map(), params_cls(), dt_s=DT)
    loc.reset(np.random.default_rng(1), prior)
    for k in range(10):
        loc.predict(OdometryDelta(0.02, 0.0, 0.1))
        loc.update(seen(np.array([3.0 + 0.02 * k, 2.0, 0.1 * k]), [0, 2, 4]))
    loc.reset(np.random.default_rng(9), prior)
    fresh = cls(make_map(), params_cls(), dt_s=DT)
    fresh.reset(np.random.default_rng(9), prior)
    np.testing.assert_array_equal(loc.particles, fresh.particles)
    np.testing.assert_array_equal(loc.estimate.as_array(), fresh.estimate.as_array())
    if isinstance(loc, BearingMCL):
        assert loc.likelihood_averages == fresh.likelihood_averages


@pytest.mark.parametrize("cls, params_cls", CLASSES)
@pytest.mark.parametrize("bad, text", [(float("nan"), "nan"), (4.0, "4.0")])
def test_bad_bearing_raises_naming_the_value(cls: type, params_cls: type, bad: float, text: str) -> None:
    loc = cls(make_map(), params_cls(), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    with pytest.raises(MeasurementError, match=text):
        loc.update(BearingMeasurement(np.array([0, 1]), np.array([0.1, bad])))


@pytest.mark.parametrize("cls, params_cls", CLASSES)
def test_deterministic(cls: type, params_cls: type) -> None:
    def run() -> np.ndarray:
        loc = cls(make_map(), params_cls(), dt_s=DT)
        loc.reset(np.random.default_rng(5))
        truth = np.array([2.0, 1.0, 0.0])
        out = []
        for k in range(30):
            truth = compose(truth, [0.01, 0.0, 0.02])
            loc.predict(OdometryDelta(0.01, 0.0, 0.02))
            loc.update(seen(truth, [[0], [1, 2], [0, 2, 3, 5]][k % 3]))
            out.append(loc.estimate.as_array())
        return np.array(out)

    np.testing.assert_array_equal(run(), run())


@pytest.mark.parametrize("cls, params_cls", CLASSES)
def test_predict_before_reset_raises(cls: type, params_cls: type) -> None:
    with pytest.raises(RuntimeError, match="reset"):
        cls(make_map(), params_cls(), dt_s=DT).predict(OdometryDelta(0.0, 0.0, 0.0))


# --- configs ------------------------------------------------------------------------------


@pytest.mark.parametrize("name, params_cls", [("mcl_bearing_paper", PaperMCLParams), ("mcl_bearing", BearingMCLParams)])
def test_yaml_holds_every_default(name: str, params_cls: type) -> None:
    path = CONFIGS / f"{name}.yaml"
    data = load_yaml(path)
    assert set(data) == set(params_cls.__dataclass_fields__)
    assert from_mapping(params_cls, data, str(path)) == params_cls()


def test_paper_defaults_are_the_papers() -> None:
    p = PaperMCLParams()
    assert p.n_particles == 1000
    assert p.gate_rad == pytest.approx(math.pi / 9) and p.one_landmark_heading_std_rad == pytest.approx(math.pi / 9)
    assert p.two_landmark_position_std_m == 0.2 and p.two_landmark_heading_std_rad == pytest.approx(math.pi / 12.6)
    assert p.three_landmark_position_std_m == 0.2 and p.three_landmark_heading_std_rad == pytest.approx(math.pi / 15.3)


@pytest.mark.parametrize(
    "params_cls, key, value",
    [
        (PaperMCLParams, "gate_rad", 0.0),
        (PaperMCLParams, "alphas", [0.1, -0.1, 0.1, 0.1]),
        (BearingMCLParams, "alpha_slow", 0.5),
        (BearingMCLParams, "likelihood_inflation", 0.5),
        (BearingMCLParams, "n_particles", 1),
    ],
)
def test_params_reject_out_of_range(params_cls: type, key: str, value: object) -> None:
    with pytest.raises(ConfigError, match=key):
        from_mapping(params_cls, {key: value}, "test")
