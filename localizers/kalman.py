"""Baseline (3) of the two-landmark bearings paper (docs/papers.md section A, appendix A).

Dead reckoning (baseline (1)) and Cassini resection (baseline (2), here over every triple of
the visible landmarks with the robust median-gated combination of
:func:`localizers.resection.resect_all_triples`) fused by a Kalman filter: each of x, y and
heading is an independent constant-acceleration state ``(p, p', p'')`` (eqs. A.1, A.3);
dead reckoning observes the velocity (eq. A.4), vision observes the position (eq. A.5);
the two arrive asynchronously, so each is its own measurement update. (The OCR of eq. A.4
reads ``C = (0 1 1)``, ``Y = (0 x' x'')``, which may mean odometry also observes the
acceleration; we observe the velocity only, as docs/papers.md states: a finite difference of
30 Hz increments is too noisy to be an acceleration measurement.)

The linear filter itself is two pure functions in the style of filterpy, :func:`kf_predict`
and :func:`kf_update`; they broadcast over leading axes, which lets the localizer run the
three axes as one batch.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import (
    BearingMeasurement,
    LandmarkMap,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    checked_bearings,
    checked_dt,
    checked_odometry,
    finite_covariance,
    require_reset,
)
from localizers.geometry import wrap_angle
from localizers.resection import DEFAULT_MIN_CONDITIONING, resect_all_triples
from localizers.schema import check

Array = NDArray[np.float64]


# --------------------------------------------------------------------------------------
# Linear Kalman filter core (pure functions)


def kf_predict(x: ArrayLike, P: ArrayLike, F: ArrayLike, Q: ArrayLike) -> tuple[Array, Array]:
    """Time update ``x <- F x``, ``P <- F P F^T + Q``.

    Args:
        x: ``(..., n)`` state means.
        P: ``(..., n, n)`` state covariances.
        F: ``(..., n, n)`` transition matrices (broadcast against ``x``).
        Q: ``(..., n, n)`` process noise covariances.

    Returns:
        ``(x, P)`` new arrays of shapes ``(..., n)`` and ``(..., n, n)``.
    """
    x = np.asarray(x, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    F = np.asarray(F, dtype=np.float64)
    x_new = np.einsum("...ij,...j->...i", F, x)
    P_new = F @ P @ np.swapaxes(F, -1, -2) + np.asarray(Q, dtype=np.float64)
    return x_new, 0.5 * (P_new + np.swapaxes(P_new, -1, -2))


def kf_update(
    x: ArrayLike,
    P: ArrayLike,
    z: ArrayLike,
    H: ArrayLike,
    R: ArrayLike,
    residual: Callable[[Array, Array], Array] | None = None,
) -> tuple[Array, Array]:
    """Measurement update with a linear observation ``z = H x + v``, ``v ~ N(0, R)``.

    The covariance uses the Joseph form ``(I - K H) P (I - K H)^T + K R K^T``, which equals
    the textbook ``(I - K H) P`` for the optimal gain but stays symmetric positive definite.

    Args:
        x: ``(..., n)`` prior means.
        P: ``(..., n, n)`` prior covariances.
        z: ``(..., m)`` measurements.
        H: ``(..., m, n)`` observation matrices.
        R: ``(..., m, m)`` measurement noise covariances.
        residual: ``residual(z, H x) -> (..., m)`` innovation; ``z - H x`` when ``None``
            (pass one that wraps angles for heading measurements).

    Returns:
        ``(x, P)`` posterior, new arrays of shapes ``(..., n)`` and ``(..., n, n)``.
    """
    x = np.asarray(x, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    H = np.asarray(H, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    Hx = np.einsum("...ij,...j->...i", H, x)
    y = z - Hx if residual is None else np.asarray(residual(z, Hx), dtype=np.float64)
    HP = H @ P
    S = HP @ np.swapaxes(H, -1, -2) + R
    K = np.swapaxes(np.linalg.solve(S, HP), -1, -2)  # K = P H^T S^-1 (S, P symmetric)
    x_new = x + np.einsum("...ij,...j->...i", K, y)
    n = x.shape[-1]
    IKH = np.eye(n) - K @ H
    P_new = IKH @ P @ np.swapaxes(IKH, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
    return x_new, 0.5 * (P_new + np.swapaxes(P_new, -1, -2))


def constant_acceleration_model(dt_s: float, jerk_psd: ArrayLike) -> tuple[Array, Array]:
    """Transition and process noise of a constant-acceleration axis driven by white jerk.

    Args:
        dt_s: time step.
        jerk_psd: ``(...)`` power spectral density ``q`` of the jerk per axis (unit^2 / s^5).

    Returns:
        ``F`` ``(3, 3)`` (eq. A.3 of the paper) and ``Q`` ``(..., 3, 3)``: the exact
        discretization ``q * [[t^5/20, t^4/8, t^3/6], [t^4/8, t^3/3, t^2/2], [t^3/6, t^2/2, t]]``.
    """
    t = float(dt_s)
    F = np.array([[1.0, t, 0.5 * t * t], [0.0, 1.0, t], [0.0, 0.0, 1.0]])
    unit = np.array(
        [
            [t**5 / 20.0, t**4 / 8.0, t**3 / 6.0],
            [t**4 / 8.0, t**3 / 3.0, t**2 / 2.0],
            [t**3 / 6.0, t**2 / 2.0, t],
        ]
    )
    q = np.asarray(jerk_psd, dtype=np.float64)
    return F, q[..., None, None] * unit


# --------------------------------------------------------------------------------------
# The localizer


@dataclass(frozen=True)
class KalmanParams:
    """Parameters of the appendix-A Kalman filter (defaults: ``configs/localizers/kalman.yaml``).

    The defaults trust dead reckoning (paper sec. 5 (3)): the odometry velocity noise is
    small, the vision position noise is large (1 m), so a single false detection moves the
    estimate by a few millimetres instead of dragging it away until the next good fix. The
    paper publishes no values; all are ours.

    Attributes:
        jerk_psd_xy_m2_per_s5, jerk_psd_heading_rad2_per_s5: white-jerk spectral densities
            of the constant-acceleration model (process noise ``Q``).
        odometry_velocity_std_m_per_s, odometry_yaw_rate_std_rad_per_s: noise of the
            dead-reckoning velocity observation (eq. A.4).
        vision_position_std_m, vision_heading_std_rad: noise of the resection fix (eq. A.5).
        resection_inlier_radius_m, resection_min_conditioning: passed to
            :func:`localizers.resection.resect_all_triples`.
        initial_position_std_m, initial_heading_std_rad: prior stds when the prior has no
            finite covariance.
        initial_velocity_std_m_per_s, initial_yaw_rate_std_rad_per_s,
        initial_acceleration_std_m_per_s2, initial_yaw_acceleration_std_rad_per_s2: initial
            stds of the derivative states.
    """

    jerk_psd_xy_m2_per_s5: float = 10.0
    jerk_psd_heading_rad2_per_s5: float = 30.0
    odometry_velocity_std_m_per_s: float = 0.05
    odometry_yaw_rate_std_rad_per_s: float = 0.05
    vision_position_std_m: float = 1.0
    vision_heading_std_rad: float = 0.5
    resection_inlier_radius_m: float = 0.3
    resection_min_conditioning: float = DEFAULT_MIN_CONDITIONING
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    initial_velocity_std_m_per_s: float = 0.5
    initial_yaw_rate_std_rad_per_s: float = 1.0
    initial_acceleration_std_m_per_s2: float = 1.0
    initial_yaw_acceleration_std_rad_per_s2: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "jerk_psd_xy_m2_per_s5",
            "jerk_psd_heading_rad2_per_s5",
            "odometry_velocity_std_m_per_s",
            "odometry_yaw_rate_std_rad_per_s",
            "vision_position_std_m",
            "vision_heading_std_rad",
            "resection_inlier_radius_m",
            "resection_min_conditioning",
            "initial_velocity_std_m_per_s",
            "initial_yaw_rate_std_rad_per_s",
            "initial_acceleration_std_m_per_s2",
            "initial_yaw_acceleration_std_rad_per_s2",
        ):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0.0, f"KalmanParams.{name} must be > 0, got {value!r}")
        for name in ("initial_position_std_m", "initial_heading_std_rad"):
            value = getattr(self, name)
            check(math.isfinite(value) and value >= 0.0, f"KalmanParams.{name} must be >= 0, got {value!r}")


_H_POSITION = np.array([[1.0, 0.0, 0.0]])  # eq. (A.5): vision observes p
_H_VELOCITY = np.array([[0.0, 1.0, 0.0]])  # eq. (A.4): dead reckoning observes p'


def _wrap_heading_row(z: Array, hx: Array) -> Array:
    """Innovation for the stacked (x, y, heading) axes: row 2 is an angle."""
    y = z - hx
    y[2] = wrap_angle(y[2])
    return y


class KalmanLocalizer:
    """Dead reckoning + resection fused by per-axis constant-acceleration Kalman filters.

    The state is ``x`` ``(3, 3)`` (rows: x, y, heading; columns: p, p', p'') with one
    ``(3, 3)`` covariance per axis. ``predict`` runs the time update over ``dt_s`` and then
    the odometry velocity update (the increment divided by ``dt_s``, rotated into the world
    by the heading estimate at mid-step); ``update`` applies a resection fix when >= 3
    bearings are seen. Without a prior the filter stays invalid (and ignores odometry)
    until the first fix.
    """

    name: ClassVar[str] = "kalman"

    def __init__(self, landmarks: LandmarkMap, params: KalmanParams, *, dt_s: float) -> None:
        self._dt = checked_dt("KalmanLocalizer", dt_s)
        self._map = landmarks
        self._step_limit_m = landmarks.step_limit_m
        self._params = params
        self._F, self._Q = constant_acceleration_model(
            self._dt,
            [params.jerk_psd_xy_m2_per_s5, params.jerk_psd_xy_m2_per_s5, params.jerk_psd_heading_rad2_per_s5],
        )
        pv, hv = params.odometry_velocity_std_m_per_s, params.odometry_yaw_rate_std_rad_per_s
        self._R_velocity = np.array([pv * pv, pv * pv, hv * hv]).reshape(3, 1, 1)
        pp, hp = params.vision_position_std_m, params.vision_heading_std_rad
        self._R_position = np.array([pp * pp, pp * pp, hp * hp]).reshape(3, 1, 1)
        self._x: Array | None = None
        self._P: Array | None = None
        self._ready = False  # reset() called

    def _initial_covariance(self, position_var: Array) -> Array:
        """``(3, 3, 3)`` block covariances with the given ``(3,)`` variances of p."""
        p = self._params
        P = np.zeros((3, 3, 3))
        P[:, 0, 0] = position_var
        P[:, 1, 1] = [p.initial_velocity_std_m_per_s**2] * 2 + [p.initial_yaw_rate_std_rad_per_s**2]
        P[:, 2, 2] = [p.initial_acceleration_std_m_per_s2**2] * 2 + [p.initial_yaw_acceleration_std_rad_per_s2**2]
        return P

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Start a new episode; ``prior`` (optional) initializes the position states.

        The prior's covariance diagonal is used when finite, else the params' initial stds.
        ``rng`` is accepted for the protocol (the filter is deterministic).
        """
        del rng
        self._ready = True
        self._x = None
        self._P = None
        if prior is None or not prior.valid:
            return
        x = np.zeros((3, 3))
        x[:, 0] = [prior.x_m, prior.y_m, wrap_angle(prior.theta_rad)]
        cov = finite_covariance(prior)
        var = np.diag(cov).copy() if cov is not None else np.full(3, np.nan)
        if not np.isfinite(var).all() or (var < 0).any():
            p = self._params
            var = np.array([p.initial_position_std_m**2] * 2 + [p.initial_heading_std_rad**2])
        self._x, self._P = x, self._initial_covariance(var)

    def _require_reset(self) -> None:
        require_reset("KalmanLocalizer", self._ready)

    def predict(self, odometry: OdometryDelta) -> None:
        """Time update by ``dt_s``, then the dead-reckoning velocity update (eq. A.4)."""
        self._require_reset()
        d = checked_odometry(self.name, odometry, self._step_limit_m)
        if self._x is None or self._P is None:
            return
        heading = self._x[2, 0] + 0.5 * d[2]  # mid-step heading, rotates the increment into the world
        c, s = math.cos(heading), math.sin(heading)
        z = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]) / self._dt
        x, P = kf_predict(self._x, self._P, self._F, self._Q)
        x, P = kf_update(x, P, z[:, None], _H_VELOCITY, self._R_velocity)
        x[2, 0] = wrap_angle(x[2, 0])
        self._x, self._P = x, P

    def update(self, measurement: BearingMeasurement) -> None:
        """Vision update (eq. A.5) with the robust all-triples resection when >= 3 bearings are seen."""
        self._require_reset()
        meas = checked_bearings(self.name, measurement, self._map.count)
        if meas.landmark_ids.size < 3:
            return
        res = resect_all_triples(
            self._map.positions_xy_m,
            meas.landmark_ids,
            meas.bearings_rad,
            min_conditioning=self._params.resection_min_conditioning,
            inlier_radius_m=self._params.resection_inlier_radius_m,
        )
        if not res.valid:
            return
        fix = np.asarray(res.pose, dtype=np.float64)
        if self._x is None or self._P is None:  # the first fix initializes the filter
            x = np.zeros((3, 3))
            x[:, 0] = fix
            self._x, self._P = x, self._initial_covariance(self._R_position[:, 0, 0])
            return
        x, P = kf_update(self._x, self._P, fix[:, None], _H_POSITION, self._R_position, residual=_wrap_heading_row)
        x[2, 0] = wrap_angle(x[2, 0])
        self._x, self._P = x, P

    @property
    def estimate(self) -> PoseEstimate:
        """Position states and the diagonal of their covariance (the axes are independent)."""
        if self._x is None or self._P is None:
            return PoseEstimate.invalid()
        cov = np.diag(self._P[:, 0, 0])
        return PoseEstimate(float(self._x[0, 0]), float(self._x[1, 0]), float(wrap_angle(self._x[2, 0])), cov, True)

    @property
    def state(self) -> Array | None:
        """``(3, 3)`` copy of the state (rows x, y, heading; columns p, p', p''), or ``None``."""
        return None if self._x is None else self._x.copy()

    def overlay(self) -> Overlay:
        est = self.estimate
        if not est.valid:
            return Overlay(label="kalman: no fix yet")
        return Overlay(poses=est.as_array()[None, :], weights=np.ones(1), label="kalman")
