"""Tests of localizers.dead_reckoning: exact SE(2) integration, the documented drift model
against its closed form, and the shared localizer contract."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from core.geometry import compose, wrap_angle
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, MeasurementError, OdometryDelta, PoseEstimate
from localizers.dead_reckoning import DeadReckoningLocalizer, DeadReckoningParams

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "localizers" / "dead_reckoning.yaml"
DT = 1.0 / 30.0


def make_map() -> LandmarkMap:
    return LandmarkMap(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 5.0]]), ("a", "b", "c"), (0.0, 0.0, 10.0, 5.0))


def make(params: DeadReckoningParams | None = None) -> DeadReckoningLocalizer:
    return DeadReckoningLocalizer(make_map(), params or DeadReckoningParams(), dt_s=DT)


ZERO_COV = np.zeros((3, 3))


def test_is_a_localizer() -> None:
    assert isinstance(make(), Localizer)


@pytest.mark.parametrize("prior", [None, PoseEstimate.invalid()])
def test_reset_without_prior_raises(prior: PoseEstimate | None) -> None:
    with pytest.raises(ValueError, match="prior"):
        make().reset(np.random.default_rng(0), prior)


@pytest.mark.parametrize("seed", [0, 1])
def test_integrates_increments_exactly(seed: int) -> None:
    rng = np.random.default_rng(seed)
    loc = make()
    pose = np.array([1.0, 2.0, -3.0])
    loc.reset(np.random.default_rng(0), PoseEstimate(*pose, ZERO_COV))
    for _ in range(200):
        d = rng.normal([0.02, 0.0, 0.0], [0.01, 0.005, 0.1])
        loc.predict(OdometryDelta(*d))
        pose = compose(pose, d)
    np.testing.assert_allclose(loc.estimate.as_array(), pose, atol=1e-12)


def test_square_path_closes() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(2.0, 2.0, 0.0, ZERO_COV))
    for _ in range(4):
        for _ in range(100):
            loc.predict(OdometryDelta(0.01, 0.0, 0.0))
        for _ in range(10):
            loc.predict(OdometryDelta(0.0, 0.0, math.pi / 20))
    est = loc.estimate.as_array()
    np.testing.assert_allclose(est[:2], [2.0, 2.0], atol=1e-9)
    assert abs(wrap_angle(est[2])) < 1e-9


@pytest.mark.parametrize("step_m", [0.01, 0.05])
def test_straight_drift_matches_closed_form(step_m: float) -> None:
    """Along x for D metres: var x = p D, var theta = h D, var y = p D + h D^3 / 3 (continuum)."""
    p = DeadReckoningParams(position_var_m2_per_m=2e-3, heading_var_rad2_per_m=1e-3, heading_var_rad2_per_rad=5e-3)
    loc = make(p)
    loc.reset(np.random.default_rng(0), PoseEstimate(0.0, 0.0, 0.0, ZERO_COV))
    distance = 10.0
    for _ in range(round(distance / step_m)):
        loc.predict(OdometryDelta(step_m, 0.0, 0.0))
    cov = loc.estimate.covariance
    assert cov[0, 0] == pytest.approx(2e-3 * distance, rel=1e-9)  # step-size independent
    assert cov[2, 2] == pytest.approx(1e-3 * distance, rel=1e-9)
    # the discrete sum h s^3 (N-1) N (2N-1) / 6 tends to h D^3 / 3 as the step shrinks
    assert cov[1, 1] == pytest.approx(2e-3 * distance + 1e-3 * distance**3 / 3.0, rel=3 * step_m / distance)


def test_turning_in_place_grows_heading_only() -> None:
    p = DeadReckoningParams(position_var_m2_per_m=2e-3, heading_var_rad2_per_m=1e-3, heading_var_rad2_per_rad=5e-3)
    loc = make(p)
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0, ZERO_COV))
    for _ in range(60):
        loc.predict(OdometryDelta(0.0, 0.0, -0.1))
    cov = loc.estimate.covariance
    assert cov[2, 2] == pytest.approx(5e-3 * 6.0)
    np.testing.assert_allclose(cov[:2, :], 0.0, atol=1e-15)


def test_prior_covariance_or_params() -> None:
    loc = make(DeadReckoningParams(initial_position_std_m=0.1, initial_heading_std_rad=0.2))
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))  # covariance NaN
    np.testing.assert_allclose(loc.estimate.covariance, np.diag([0.01, 0.01, 0.04]))
    given = np.diag([0.5, 0.6, 0.7])
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0, given))
    np.testing.assert_allclose(loc.estimate.covariance, given)


# --- the shared localizer contract --------------------------------------------------------


def test_empty_measurement_is_legal() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0, ZERO_COV))
    loc.update(BearingMeasurement.empty())
    np.testing.assert_array_equal(loc.estimate.as_array(), [1.0, 1.0, 0.0])


def test_reset_clears_state() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0, ZERO_COV))
    for _ in range(10):
        loc.predict(OdometryDelta(0.1, 0.0, 0.1))
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 2.0, 1.0, ZERO_COV))
    np.testing.assert_array_equal(loc.estimate.as_array(), [3.0, 2.0, 1.0])
    np.testing.assert_array_equal(loc.estimate.covariance, ZERO_COV)


@pytest.mark.parametrize("bad, text", [(float("nan"), "nan"), (4.0, "4.0")])
def test_bad_bearing_raises_naming_the_value(bad: float, text: str) -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    with pytest.raises(MeasurementError, match=text):
        loc.update(BearingMeasurement(np.array([0, 2]), np.array([bad, 0.3])))


def test_nan_odometry_raises() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    with pytest.raises(MeasurementError, match="nan"):
        loc.predict(OdometryDelta(float("nan"), 0.0, 0.0))


def test_deterministic() -> None:
    def run(seed: int) -> np.ndarray:
        loc = make()
        loc.reset(np.random.default_rng(seed), PoseEstimate(1.0, 1.0, 0.0, ZERO_COV))
        out = []
        for k in range(20):
            loc.predict(OdometryDelta(0.01 * k, 0.001, 0.02))
            out.append(np.concatenate([loc.estimate.as_array(), loc.estimate.covariance.ravel()]))
        return np.array(out)

    np.testing.assert_array_equal(run(3), run(3))


def test_predict_before_reset_raises() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        make().predict(OdometryDelta(0.0, 0.0, 0.0))


# --- config -------------------------------------------------------------------------------


def test_yaml_holds_every_default() -> None:
    data = load_yaml(CONFIG)
    assert set(data) == set(DeadReckoningParams.__dataclass_fields__)
    assert from_mapping(DeadReckoningParams, data, str(CONFIG)) == DeadReckoningParams()


def test_params_reject_negative_drift() -> None:
    with pytest.raises(ConfigError, match="position_var_m2_per_m"):
        from_mapping(DeadReckoningParams, {"position_var_m2_per_m": -1.0}, "test")
