"""Tests of localizers.kalman: the linear filter core against a textbook filter, the
constant-acceleration model against a numerical discretization, the resection fix, and the
appendix-A localizer's behaviour and error handling."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from core.geometry import bearings_to, compose, wrap_angle
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, MeasurementError, OdometryDelta, PoseEstimate
from localizers.kalman import (
    KalmanLocalizer,
    KalmanParams,
    constant_acceleration_model,
    kf_predict,
    kf_update,
)

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "localizers" / "kalman.yaml"
DT = 1.0 / 30.0
LANDMARKS = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0], [3.0, 0.0], [3.0, 4.0], [0.0, 2.0], [6.0, 2.0]])


def make_map() -> LandmarkMap:
    return LandmarkMap(LANDMARKS, tuple(f"L{i + 1}" for i in range(len(LANDMARKS))), (0.0, 0.0, 6.0, 4.0))


def seen(pose: np.ndarray, ids: list[int]) -> BearingMeasurement:
    ids_arr = np.asarray(ids, dtype=np.int64)
    return BearingMeasurement(ids_arr, np.asarray(bearings_to(pose, LANDMARKS[ids_arr])))


# --- kf_predict / kf_update against an independent textbook filter --------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("q, r", [(0.1, 0.5), (2.0, 0.01), (1e-4, 4.0)])
def test_kf_matches_textbook_constant_velocity(seed: int, q: float, r: float) -> None:
    dt = 0.1
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    H = np.array([[1.0, 0.0]])
    R = np.array([[r]])
    rng = np.random.default_rng(seed)
    truth = np.array([0.0, 1.0])
    x_ref, P_ref = np.array([0.5, 0.0]), np.diag([1.0, 4.0])
    x, P = x_ref.copy(), P_ref.copy()
    for _ in range(50):
        truth = F @ truth + rng.multivariate_normal(np.zeros(2), Q)
        z = H @ truth + rng.normal(0.0, math.sqrt(r), 1)
        # textbook (Kalman 1960 / Welch & Bishop), written out
        x_ref = F @ x_ref
        P_ref = F @ P_ref @ F.T + Q
        S = H @ P_ref @ H.T + R
        K = P_ref @ H.T @ np.linalg.inv(S)
        x_ref = x_ref + K @ (z - H @ x_ref)
        P_ref = (np.eye(2) - K @ H) @ P_ref
        x, P = kf_predict(x, P, F, Q)
        x, P = kf_update(x, P, z, H, R)
        np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-10)
        np.testing.assert_allclose(P, P_ref, rtol=0, atol=1e-10)


def test_kf_batched_equals_per_axis() -> None:
    F, Q = constant_acceleration_model(DT, [1.0, 2.0, 3.0])
    rng = np.random.default_rng(3)
    x = rng.normal(size=(3, 3))
    A = rng.normal(size=(3, 3, 3))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(3)
    H = np.array([[0.0, 1.0, 0.0]])
    R = np.array([0.1, 0.2, 0.3]).reshape(3, 1, 1)
    z = rng.normal(size=(3, 1))
    xb, Pb = kf_update(*kf_predict(x, P, F, Q), z, H, R)
    for i in range(3):
        xi, Pi = kf_update(*kf_predict(x[i], P[i], F, Q[i]), z[i], H, R[i])
        np.testing.assert_allclose(xb[i], xi, atol=1e-12)
        np.testing.assert_allclose(Pb[i], Pi, atol=1e-12)


def test_kf_update_residual_wraps_angles() -> None:
    x, P = np.array([3.1]), np.array([[1.0]])
    z = np.array([-3.1])
    x_plain, _ = kf_update(x, P, z, np.eye(1), np.eye(1))
    x_wrapped, _ = kf_update(x, P, z, np.eye(1), np.eye(1), residual=lambda a, b: wrap_angle(a - b))
    assert x_plain[0] == pytest.approx(0.0)  # naive: averages through zero
    assert x_wrapped[0] == pytest.approx(3.1 + 0.5 * (2 * math.pi - 6.2))  # halfway across +-pi


@pytest.mark.parametrize("dt", [1.0 / 30.0, 0.003, 0.5])
def test_constant_acceleration_q_matches_van_loan(dt: float) -> None:
    q = 7.0
    F, Q = constant_acceleration_model(dt, q)
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    G = np.array([[0.0], [0.0], [1.0]])
    M = np.zeros((6, 6))  # Van Loan (1978): expm of [[-A, G q G^T], [0, A^T]] dt
    M[:3, :3] = -A
    M[:3, 3:] = G @ G.T * q
    M[3:, 3:] = A.T
    E = expm(M * dt)
    Phi = E[3:, 3:].T
    np.testing.assert_allclose(F, Phi, atol=1e-12)
    np.testing.assert_allclose(Q, Phi @ E[:3, 3:], rtol=1e-9, atol=1e-18)


# --- the localizer ----------------------------------------------------------------------


def make() -> KalmanLocalizer:
    return KalmanLocalizer(make_map(), KalmanParams(), dt_s=DT)


def test_is_a_localizer() -> None:
    assert isinstance(make(), Localizer)


def test_invalid_until_first_fix_without_prior() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0))
    assert not loc.estimate.valid
    loc.predict(OdometryDelta(0.01, 0.0, 0.0))  # ignored: nothing to rotate it with
    loc.update(seen(np.array([2.0, 2.0, 0.5]), [0, 1]))  # two bearings: no fix
    assert not loc.estimate.valid
    loc.update(seen(np.array([2.0, 2.0, 0.5]), [0, 1, 2, 3]))
    est = loc.estimate
    assert est.valid
    np.testing.assert_allclose(est.as_array(), [2.0, 2.0, 0.5], atol=1e-6)


@pytest.mark.parametrize("turn_rad", [0.0, 0.02, -0.03])
def test_odometry_alone_follows_dead_reckoning(turn_rad: float) -> None:
    loc = make()
    truth = np.array([1.0, 1.0, 0.2])
    loc.reset(np.random.default_rng(0), PoseEstimate(*truth, np.diag([1e-6, 1e-6, 1e-6])))
    step = np.array([0.01, 0.0, turn_rad])  # 0.3 m/s
    for _ in range(90):
        loc.predict(OdometryDelta(*step))
        truth = compose(truth, step)
    est = loc.estimate
    assert np.hypot(est.x_m - truth[0], est.y_m - truth[1]) < 0.01
    assert abs(wrap_angle(est.theta_rad - truth[2])) < 0.01
    assert loc.state is not None and np.hypot(*loc.state[:2, 1]) == pytest.approx(0.3, rel=0.02)


def test_first_fix_ignores_a_false_detection() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0))
    pose = np.array([2.2, 1.7, 0.4])
    meas = seen(pose, list(range(8)))
    bad = meas.bearings_rad.copy()
    bad[5] = wrap_angle(bad[5] + 0.4)  # a blue object outside the field taken for L6
    loc.update(BearingMeasurement(meas.landmark_ids, bad))
    est = loc.estimate
    assert est.valid
    assert np.hypot(est.x_m - pose[0], est.y_m - pose[1]) < 1e-6


@pytest.mark.parametrize("gate", [math.inf, KalmanParams().innovation_gate])
def test_trusts_dead_reckoning_over_one_false_fix(gate: float) -> None:
    # the paper's filter (no gate) moves a little; the innovation gate (ours) refuses the fix
    loc = KalmanLocalizer(make_map(), KalmanParams(innovation_gate=gate), dt_s=DT)
    truth = np.array([3.0, 2.0, 0.0])
    loc.reset(np.random.default_rng(0), PoseEstimate(*truth, np.diag([1e-4, 1e-4, 1e-4])))
    for _ in range(30):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
    loc.update(seen(np.array([5.0, 2.0, 0.0]), list(range(8))))  # a fix 2 m away
    moved = np.hypot(loc.estimate.x_m - truth[0], loc.estimate.y_m - truth[1])
    assert (0.0 < moved < 0.05) if math.isinf(gate) else moved == 0.0


def test_consecutive_rejected_fixes_restart_the_filter() -> None:
    params = KalmanParams()
    loc = KalmanLocalizer(make_map(), params, dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 2.0, 0.0, np.diag([1e-4, 1e-4, 1e-4])))
    moved = np.array([5.0, 3.0, 1.0])  # kidnapped: every fix is 2.2 m away
    for k in range(params.reset_after_rejections):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
        assert loc.estimate.x_m == pytest.approx(3.0, abs=1e-9), k
        loc.update(seen(moved, list(range(8))))
    np.testing.assert_allclose(loc.estimate.as_array(), moved, atol=1e-6)


def test_repeated_fixes_pull_the_estimate() -> None:
    params = KalmanParams(vision_position_std_m=0.1, vision_heading_std_rad=0.05)
    loc = KalmanLocalizer(make_map(), params, dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 2.0, 0.0, np.diag([0.01, 0.01, 0.01])))
    target = np.array([3.5, 2.0, 0.2])
    fix = seen(target, [0, 1, 2, 3])
    for _ in range(150):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
        loc.update(fix)
    np.testing.assert_allclose(loc.estimate.as_array(), target, atol=0.01)


def test_default_tuning_pulls_slowly() -> None:
    # Appendix A's tuning trusts dead reckoning: 10 s of consistent fixes 0.5 m away move the
    # estimate most of the way, but not all of it.
    # (without the innovation gate, ours: 0.5 m from a 0.1 m prior is a 5-sd fix, which it refuses)
    loc = KalmanLocalizer(make_map(), KalmanParams(innovation_gate=math.inf), dt_s=DT)
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 2.0, 0.0, np.diag([0.01, 0.01, 0.01])))
    fix = seen(np.array([3.5, 2.0, 0.0]), [0, 1, 2, 3])
    for _ in range(300):
        loc.predict(OdometryDelta(0.0, 0.0, 0.0))
        loc.update(fix)
    assert 0.5 < (loc.estimate.x_m - 3.0) / 0.5 < 0.95


def test_heading_fix_wraps_across_pi() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(3.0, 2.0, 3.1, np.diag([0.01, 0.01, 0.3])))
    loc.update(seen(np.array([3.0, 2.0, -3.1]), list(range(8))))
    theta = loc.estimate.theta_rad
    assert abs(theta) > 3.0  # moved through +-pi, not through zero


# --- the shared localizer contract --------------------------------------------------------


def test_empty_measurement_is_legal() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    before = loc.estimate
    loc.update(BearingMeasurement.empty())
    after = loc.estimate
    np.testing.assert_array_equal(before.as_array(), after.as_array())
    np.testing.assert_array_equal(before.covariance, after.covariance)


def test_reset_clears_state() -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    for _ in range(20):
        loc.predict(OdometryDelta(0.02, 0.0, 0.05))
        loc.update(seen(np.array([4.0, 3.0, 1.0]), [0, 2, 4, 6]))
    loc.reset(np.random.default_rng(0))
    assert not loc.estimate.valid
    prior = PoseEstimate(2.0, 2.0, 1.0, np.diag([0.01, 0.02, 0.03]))
    loc.reset(np.random.default_rng(0), prior)
    fresh = make()
    fresh.reset(np.random.default_rng(0), prior)
    np.testing.assert_array_equal(loc.estimate.as_array(), fresh.estimate.as_array())
    np.testing.assert_array_equal(loc.estimate.covariance, fresh.estimate.covariance)


@pytest.mark.parametrize("bad, text", [(float("nan"), "nan"), (4.0, "4.0")])
def test_bad_bearing_raises_naming_the_value(bad: float, text: str) -> None:
    loc = make()
    loc.reset(np.random.default_rng(0), PoseEstimate(1.0, 1.0, 0.0))
    with pytest.raises(MeasurementError, match=text):
        loc.update(BearingMeasurement(np.array([0, 1, 2]), np.array([0.1, bad, -0.2])))


def test_deterministic() -> None:
    def run() -> np.ndarray:
        loc = make()
        loc.reset(np.random.default_rng(5), PoseEstimate(1.0, 1.0, 0.0))
        out = []
        for k in range(40):
            loc.predict(OdometryDelta(0.01, 0.0, 0.01))
            if k % 3 == 0:
                loc.update(seen(np.array([1.0 + 0.01 * k, 1.0, 0.01 * k]), [0, 2, 5, 7]))
            out.append(loc.estimate.as_array())
        return np.array(out)

    np.testing.assert_array_equal(run(), run())


def test_predict_before_reset_raises() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        make().predict(OdometryDelta(0.0, 0.0, 0.0))


@pytest.mark.parametrize("dt", [0.0, -1.0, float("nan")])
def test_bad_dt_raises(dt: float) -> None:
    with pytest.raises(ValueError, match="dt_s"):
        KalmanLocalizer(make_map(), KalmanParams(), dt_s=dt)


# --- config -------------------------------------------------------------------------------


def test_yaml_holds_every_default() -> None:
    data = load_yaml(CONFIG)
    assert set(data) == set(KalmanParams.__dataclass_fields__)
    assert from_mapping(KalmanParams, data, str(CONFIG)) == KalmanParams()


def test_reset_after_rejections_is_a_whole_number_never_a_bool() -> None:
    assert KalmanParams(reset_after_rejections=np.int64(3)).reset_after_rejections == 3
    for value in (True, 2.5, -1):
        with pytest.raises(ConfigError, match=rf"reset_after_rejections must be an integer >= 0 .*got {value!r}$"):
            KalmanParams(reset_after_rejections=value)


@pytest.mark.parametrize("key, value", [("vision_position_std_m", 0.0), ("jerk_psd_xy_m2_per_s5", -1.0)])
def test_params_reject_out_of_range(key: str, value: float) -> None:
    with pytest.raises(ConfigError, match=key):
        from_mapping(KalmanParams, {key: value}, "test")
