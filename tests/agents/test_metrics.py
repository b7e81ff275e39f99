"""agents.evaluate.metrics on hand-made trajectories with known errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.evaluate import metrics


def straight_line(T: int = 11, step: float = 0.1) -> np.ndarray:
    """``(T, 3)`` poses along +x, ``step`` apart, heading 0."""
    return np.column_stack([np.arange(T) * step, np.zeros(T), np.zeros(T)])


def test_position_and_heading_errors_are_exact_and_wrap() -> None:
    truth = np.array([[0.0, 0.0, math.radians(179.0)], [1.0, 1.0, 0.0], [2.0, 0.0, math.radians(-90.0)]])
    est = np.array([[3.0, 4.0, math.radians(-179.0)], [1.0, 1.0, math.radians(359.0)], [np.nan, np.nan, np.nan]])
    np.testing.assert_allclose(metrics.position_errors(est, truth)[:2], [5.0, 0.0])
    # 179 deg vs -179 deg is 2 deg apart, 359 deg vs 0 is 1 deg, not 358
    np.testing.assert_allclose(np.degrees(metrics.heading_errors(est, truth)[:2]), [2.0, 1.0], atol=1e-9)
    assert np.isnan(metrics.position_errors(est, truth)[2]) and np.isnan(metrics.heading_errors(est, truth)[2])


def test_first_fix_and_availability() -> None:
    valid = np.array([False, False, True, False, True, True, True, True])
    assert metrics.first_fix(valid) == 2
    assert metrics.first_fix(np.zeros(5, dtype=bool)) is None
    assert metrics.availability(valid) == pytest.approx(5 / 8)
    assert metrics.availability(valid, start=2) == pytest.approx(5 / 6)


def test_distinct_landmarks_count_from_their_first_sighting() -> None:
    visible = np.zeros((6, 5), dtype=bool)
    visible[1, 0] = True
    visible[2, [0, 3]] = True  # 0 again: still two distinct landmarks
    visible[3, 0] = True
    visible[4, 4] = True  # the third, with the others out of view
    assert metrics.distinct_seen(visible, 1) == 1
    assert metrics.distinct_seen(visible, 2) == 2
    assert metrics.distinct_seen(visible, 3) == 4
    assert metrics.distinct_seen(visible, 4) is None
    with pytest.raises(ValueError, match="count must be >= 1, got 0"):
        metrics.distinct_seen(visible, 0)


def test_statistics_start_at_the_first_fix_and_skip_invalid_steps() -> None:
    truth = straight_line()
    est = truth.copy()
    est[:3] = np.nan  # no pose yet
    est[3:, 1] = [0.5, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.3]  # a known cross-track error
    est[6] = np.nan  # a dropout after the first fix
    err = metrics.position_errors(est, truth)
    start = metrics.first_fix(np.isfinite(est[:, 0]))
    assert start == 3
    expected = np.array([0.5, 0.1, 0.1, 0.1, 0.1, 0.1, 0.3])
    mean, sd = metrics.mean_sd(err, start)
    assert mean == pytest.approx(expected.mean())
    assert sd == pytest.approx(expected.std())
    # statistics from another method's first fix (later) see fewer steps
    assert metrics.mean_sd(err, 4)[0] == pytest.approx(expected[1:].mean())
    assert metrics.failure_rate(err, start, threshold=0.3) == pytest.approx(2 / 7)
    assert math.isnan(metrics.mean_sd(err, None)[0])


def test_distance_and_time_to_first_fix() -> None:
    truth = straight_line(T=11, step=0.1)
    truth[6:, 2] = 1.0  # turning in place does not add distance
    truth[6:, 0] = truth[5, 0]
    travelled = metrics.travelled(truth)
    np.testing.assert_allclose(travelled, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5], atol=1e-12)
    valid = np.zeros(11, dtype=bool)
    valid[4:] = True
    ff = metrics.first_fix(valid)
    assert ff is not None and travelled[ff] == pytest.approx(0.4)
    np.testing.assert_allclose(metrics.speeds(truth, 0.05)[:5], 2.0)


def test_rms_and_error_bound_ratio() -> None:
    err = np.array([np.nan, 3.0, 4.0, np.nan, 0.0])
    bound = np.array([9.0, 1.0, 1.0, 9.0, 1.0])
    assert metrics.rms(err, 0) == pytest.approx(math.sqrt(25.0 / 3.0))
    # the bound is averaged over the steps where the error exists only
    assert metrics.error_bound_ratio(err, bound, 0) == pytest.approx(math.sqrt(25.0 / 3.0))
    assert metrics.error_bound_ratio(err, bound, 2) == pytest.approx(math.sqrt(8.0))
    assert math.isnan(metrics.error_bound_ratio(np.full(3, np.nan), np.ones(3), 0))


def test_time_to_recover_needs_the_error_to_stay_low() -> None:
    t = np.arange(0.0, 10.0, 0.5)
    err = np.full(t.size, 0.05)
    err[(t >= 2.0) & (t < 4.0)] = 0.6  # pushed at 2 s
    err[t == 5.0] = 0.6  # a relapse: the run starting at 4.0 does not count
    err[t == 6.5] = np.nan  # no pose counts as not recovered
    # runs below 0.2 m: [4.0, 4.5], [5.5, 6.0], [7.0, ...]: the first lasting 1 s starts at 7.0
    assert metrics.time_to_recover(t, err, 2.0, 0.2, hold_s=1.0) == pytest.approx(5.0)
    assert metrics.time_to_recover(t, err, 2.0, 0.2, hold_s=0.5) == pytest.approx(2.0)
    assert metrics.time_to_recover(t, np.full(t.size, 1.0), 2.0, 0.2) == math.inf


def test_over_seeds_ignores_missing_values() -> None:
    s = metrics.over_seeds([1.0, np.nan, 3.0])
    assert (s.mean, s.n) == (2.0, 2)
    assert s.sd == pytest.approx(math.sqrt(2.0))
    empty = metrics.over_seeds([np.nan])
    assert empty.n == 0 and math.isnan(empty.mean)


# --------------------------------------------------------------------------- consistency (NEES)
def test_chi2_quantiles_equal_scipys() -> None:
    from scipy import stats

    for dof in (1, 2, 3):
        for p in (0.05, 0.5, 0.95, 0.99):
            assert metrics.chi2_quantile(p, dof) == pytest.approx(stats.chi2.ppf(p, dof), rel=1e-11)
            assert metrics.chi2_cdf(stats.chi2.ppf(p, dof), dof) == pytest.approx(p, abs=1e-12)
    assert metrics.chi2_quantile(0.95, 3) == pytest.approx(7.815, abs=5e-4)
    with pytest.raises(ValueError, match="dof must be 1, 2 or 3"):
        metrics.chi2_quantile(0.95, 4)
    with pytest.raises(ValueError, match=r"p must be in \(0, 1\)"):
        metrics.chi2_quantile(1.0, 3)


def test_nees_of_hand_made_errors() -> None:
    cov = np.diag([0.04, 0.09, 0.01])  # sd 0.2 m, 0.3 m, 0.1 rad
    truth = np.array([[1.0, 2.0, 3.1], [1.0, 2.0, 0.0], [1.0, 2.0, 3.1], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    est = np.array([[1.0, 2.0, 3.1], [1.2, 1.7, 0.1], [1.0, 2.0, 3.1 + 0.1 - 2 * np.pi], [0.1, 0.0, 0.0], [np.nan] * 3])
    covs = np.stack([cov, cov, cov, np.full((3, 3), np.nan), cov])
    nees = metrics.pose_nees(est, truth, covs)
    assert nees[0] == 0.0  # no error
    assert nees[1] == pytest.approx(3.0)  # one sd on each axis
    assert nees[2] == pytest.approx(1.0)  # the heading error wraps to 0.1 rad
    assert np.isnan(nees[3]) and np.isnan(nees[4])  # no covariance; no estimate
    assert metrics.pose_nees(est, truth, covs, dof=2)[1] == pytest.approx(2.0)  # position only
    # a singular covariance claims certainty: an error makes it infinitely off, none leaves it at 0
    singular = np.diag([0.04, 0.0, 0.01])
    assert metrics.pose_nees(est[:2], truth[:2], np.stack([singular, singular]))[1] == np.inf
    assert metrics.pose_nees(est[:1], truth[:1], singular[None])[0] == 0.0
    assert metrics.pose_nees(est[1:2], truth[1:2], np.zeros((1, 3, 3)))[0] == np.inf  # a collapsed particle set
    broken = np.diag([0.04, -0.01, 0.01])  # a negative variance: no covariance at all
    assert np.isnan(metrics.pose_nees(est[1:2], truth[1:2], broken[None])[0])
    counted = metrics.consistency([1.0, np.inf, np.nan])
    assert (counted.steps, counted.excluded, counted.inside_95, counted.nees_mean) == (2, 1, 0.5, np.inf)
    assert (counted.singular, counted.singular_share, counted.nees_median) == (1, 0.5, np.inf)  # what reports show
    correlated = np.array([[1.0, 0.8, 0.0], [0.8, 1.0, 0.0], [0.0, 0.0, 1.0]])
    e = np.array([0.3, -0.2, 0.1])
    assert metrics.pose_nees(e[None], np.zeros((1, 3)), correlated[None])[0] == pytest.approx(e @ np.linalg.solve(correlated, e))
    fit = metrics.consistency(nees, mask=[True, True, True, True, False])
    assert (fit.steps, fit.excluded) == (3, 1)
    assert fit.nees_mean == pytest.approx(4.0 / 3) and fit.inside_95 == 1.0
    assert (fit.singular, fit.singular_share) == (0, 0.0)
    nothing = metrics.consistency([np.nan, np.nan])
    assert math.isnan(nothing.nees_mean) and nothing.singular == 0 and math.isnan(nothing.singular_share)
    with pytest.raises(ValueError, match=r"\(T, 3, 3\) covariances"):
        metrics.pose_nees(est, truth, cov)


def _synthetic_filter(scale: float, n: int = 20_000) -> metrics.Consistency:
    """Errors drawn from N(0, P), a different P per step; the filter reports ``scale * P``."""
    rng = np.random.default_rng(19)
    a = rng.normal(size=(n, 3, 3)) * np.array([0.3, 0.3, 0.05])[:, None]
    cov = a @ np.swapaxes(a, 1, 2) + np.diag([1e-3, 1e-3, 1e-4])
    err = np.einsum("nij,nj->ni", np.linalg.cholesky(cov), rng.normal(size=(n, 3)))
    truth = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    est = truth + err
    est[:, 2] = np.mod(est[:, 2] + np.pi, 2 * np.pi) - np.pi  # reported headings are wrapped
    return metrics.consistency(metrics.pose_nees(est, truth, scale * cov))


def test_a_consistent_filter_is_inside_its_95_region_on_95_percent_of_steps() -> None:
    fit = _synthetic_filter(1.0)
    assert fit.inside_95 == pytest.approx(0.95, abs=0.02)
    assert fit.nees_mean == pytest.approx(3.0, abs=0.1)
    overconfident = _synthetic_filter(0.25)  # covariance 4x too small
    assert overconfident.inside_95 < 0.6 and overconfident.nees_mean == pytest.approx(12.0, rel=0.05)
