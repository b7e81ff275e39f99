"""agents.evaluate.consistency: the reports' NEES respects the registry's covariance flag, pools runs, and says so in words."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.evaluate import consistency, metrics
from localizers import registry


def test_run_nees_is_the_pose_nees_of_a_localizer_with_a_covariance() -> None:
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(50, 3))
    est = truth + rng.normal(scale=0.1, size=(50, 3))
    cov = np.broadcast_to(0.01 * np.eye(3), (50, 3, 3))
    assert registry.LOCALIZERS["kalman"].covariance
    got = consistency.run_nees("kalman", est, truth, cov)
    np.testing.assert_array_equal(got, metrics.pose_nees(est, truth, cov, dof=3))
    assert np.isfinite(got).all()


def test_a_localizer_without_a_covariance_gets_no_nees(monkeypatch: pytest.MonkeyPatch) -> None:
    spec = dataclasses.replace(registry.LOCALIZERS["kalman"], covariance=False)
    monkeypatch.setitem(registry.LOCALIZERS, "kalman", spec)
    got = consistency.run_nees("kalman", np.zeros((4, 3)), np.zeros((4, 3)), np.broadcast_to(np.eye(3), (4, 3, 3)))
    assert got.shape == (4,) and np.isnan(got).all()
    assert consistency.cells(consistency.reports_covariance("kalman"), 2.0, 0.9) == ("no covariance",) * 2


def test_pooled_counts_the_masked_steps_of_every_run() -> None:
    q95 = metrics.chi2_quantile(0.95, 3)
    a, b = np.array([1.0, 2.0, np.nan, 100.0]), np.array([3.0, q95 + 1.0])
    fit = consistency.pooled([a, b], [np.array([True, True, True, False]), np.array([True, True])])
    assert (fit.steps, fit.excluded) == (4, 1)  # the NaN step is asked for but has no NEES; 100 is masked out
    assert fit.nees_median == pytest.approx(2.5) and fit.inside_95 == pytest.approx(0.75)
    with pytest.raises(ValueError, match="masks"):
        consistency.pooled([a], [])
    assert np.isnan(consistency.pooled([], []).nees_median)


def test_cells_and_legend() -> None:
    assert consistency.cells(True, 2.3712, 0.951) == ("2.37", "95 %")
    assert consistency.cells(True, float("nan"), float("nan")) == ("n/a", "n/a")
    texts = [consistency.nees_text(v) for v in (0.0388, 0.971, 6.0, 65.33, 523.4, 2410.0)]
    assert texts == ["0.039", "0.97", "6.00", "65.3", "523", "2410"]
    legend = consistency.legend()
    assert "2.37" in legend and "7.81" in legend and "overconfident" in legend and "no covariance" in legend
    assert consistency.consistent_median() == pytest.approx(2.366, abs=1e-3)


def test_missing_share_is_the_share_of_steps_left_out() -> None:
    fit = metrics.consistency(np.array([1.0, np.nan, np.nan, 2.0]))
    assert consistency.missing_share(fit) == pytest.approx(0.5)
    assert np.isnan(consistency.missing_share(metrics.consistency(np.zeros(0))))
