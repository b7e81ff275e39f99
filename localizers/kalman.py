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
and :func:`kf_update`; they broadcast over leading axes.

What is ours (for a localizer that knows when it is lost; the paper says nothing
of it), each a parameter of :class:`KalmanParams`:

* *Coupled covariance.* The per-axis models are the paper's, but the covariance is one
  ``9 x 9`` matrix over all three axes and the odometry observation is linearized as what it
  is, a robot-frame velocity ``R(theta)^T (x', y')`` (an EKF step): the heading's uncertainty
  then reaches the position (a heading error turns every later step). With three independent
  axes and the increment rotated by the estimated heading, the filter ignored that and, with
  one landmark in view (no fix: pure coasting), was more than 3 sd off on most steps.
* *Odometry drift as process noise.* Every increment adds the random-walk drift of
  :func:`localizers.dead_reckoning.drift_covariance` to the pose states: the odometry's error
  enters the position directly, it is not a measurement noise the constant-acceleration
  prior can average away (without it the spread grew by 0.041 m over 300 coasting steps
  where the odometry's own noise gives 0.098 m).
* *Innovation gate and reset.* A resection fix whose normalized innovation squared, against
  the filter's pose covariance plus the fix's own covariance
  (:func:`localizers.resection.fix_covariance`), exceeds ``innovation_gate`` (chi-square,
  3 dof) is rejected; after ``reset_after_rejections`` consecutive rejections the filter is
  re-initialized on the current fix (velocity and acceleration states from their initial
  stds). A kidnapped robot (>= 2 m) is found again about 0.5 s after the next frame with a
  valid fix (measured: python -m tests.localizers.lost_figures gauss_kidnap).
* ``max_spread_m``: past this position spread the estimate is not claimed.

Consistency (measured, ``crowdloc reproduce bearing-candidates``, 20 seeds, run with the gate
and without the restart): Exp 1 NEES median 1.25, 92 % of steps inside the 95 % region;
Exp 2 5.48 and 58 %: among the crowd's contacts and fast turns the constant-acceleration
model's prediction is too sure between fixes. With independent axes and the odometry as
velocity noise instead, the medians are 641 and 84.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import wrap_angle
from core.schema import check, check_ranges, is_int
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    BearingMeasurement,
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    checked_bearings,
    finite_covariance,
    require_reset,
    within_spread,
)
from localizers.dead_reckoning import drift_covariance
from localizers.resection import DEFAULT_MIN_CONDITIONING, fix_covariance, resect_all_triples

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
        position_var_m2_per_m, heading_var_rad2_per_m, heading_var_rad2_per_rad: odometry
            drift added to the pose states per increment (as
            :mod:`localizers.dead_reckoning`; ours, module docstring).
        fix_bearing_std_rad: bearing noise behind a fix's own covariance
            (:func:`localizers.resection.fix_covariance`), used by the innovation gate and
            the reset (rad; ours).
        innovation_gate: a fix whose normalized innovation squared exceeds this is rejected
            (chi-square with 3 dof; 16.27 = the 0.999 quantile; ``inf``: no gate; ours, the
            paper says nothing of outlying fixes).
        reset_after_rejections: after this many consecutive rejected fixes the filter restarts
            on the current fix (count; 0: never, the gate only rejects; ours).
        max_spread_m: past this position spread (m) the estimate is not claimed (ours).
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
    position_var_m2_per_m: float = 1e-3
    heading_var_rad2_per_m: float = 1e-3
    heading_var_rad2_per_rad: float = 1e-3
    fix_bearing_std_rad: float = 0.0175
    innovation_gate: float = 16.27
    reset_after_rejections: int = 15
    max_spread_m: float = DEFAULT_MAX_SPREAD_M

    def __post_init__(self) -> None:
        check_ranges(
            self,
            "KalmanParams",
            positive=(
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
                "fix_bearing_std_rad",
            ),
            non_negative=(
                "initial_position_std_m",
                "initial_heading_std_rad",
                "position_var_m2_per_m",
                "heading_var_rad2_per_m",
                "heading_var_rad2_per_rad",
            ),
        )
        check(
            self.innovation_gate > 0.0, f"KalmanParams.innovation_gate must be > 0 (inf: no gate), got {self.innovation_gate!r}"
        )
        check(
            is_int(self.reset_after_rejections) and self.reset_after_rejections >= 0,
            f"KalmanParams.reset_after_rejections must be an integer >= 0 (0: never restart), got {self.reset_after_rejections!r}",
        )
        check_max_spread("KalmanParams", self.max_spread_m)


#: index of (axis, order) in the 9-state vector: axis-major (x, x', x'', y, y', y'', theta, ...)
_POSE = np.array([0, 3, 6])  # p of x, y, heading
_VEL = np.array([1, 4, 7])  # p' of x, y, heading


def _wrap_heading_row(z: Array, hx: Array) -> Array:
    """Innovation of an (x, y, heading) observation: row 2 is an angle."""
    y = z - hx
    y[2] = wrap_angle(y[2])
    return y


class KalmanLocalizer(LocalizerBase[KalmanParams]):
    """Dead reckoning + resection fused by constant-acceleration Kalman filters per axis.

    The state is ``x`` ``(3, 3)`` (rows: x, y, heading; columns: p, p', p''), its covariance
    one ``(9, 9)`` matrix (axis-major; module docstring). ``predict`` runs the time update
    over ``dt_s``, adds the odometry drift and applies the odometry velocity observation (the
    increment divided by ``dt_s``, in the robot frame at mid-step); ``update`` applies a
    resection fix when >= 3 bearings are seen and it passes the innovation gate. Without a
    prior the filter stays invalid (and ignores odometry) until the first fix.
    """

    name: ClassVar[str] = "kalman"
    #: measured on this run: share 0.690, NEES median 4.4: the robot's true motion differs from its commands by
    #: 4.7 m over its 10.8 m path, 4.6 m of it on the 290 steps where the random walk drives it against the
    #: field's edge: more than the odometry drift and the constant-acceleration prediction allow between fixes
    #: (module docstring)
    #: (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.65)

    def __init__(self, landmarks: LandmarkMap, params: KalmanParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s, owner="KalmanLocalizer")
        F, Q = constant_acceleration_model(
            self._dt_s,
            [params.jerk_psd_xy_m2_per_s5, params.jerk_psd_xy_m2_per_s5, params.jerk_psd_heading_rad2_per_s5],
        )
        self._F = np.kron(np.eye(3), F)
        self._Q = np.zeros((9, 9))
        for a in range(3):
            self._Q[3 * a : 3 * a + 3, 3 * a : 3 * a + 3] = Q[a]
        pv, hv = params.odometry_velocity_std_m_per_s, params.odometry_yaw_rate_std_rad_per_s
        self._R_velocity = np.diag([pv * pv, pv * pv, hv * hv])
        pp, hp = params.vision_position_std_m, params.vision_heading_std_rad
        self._R_position = np.diag([pp * pp, pp * pp, hp * hp])
        self._H_position = np.zeros((3, 9))  # eq. (A.5): vision observes p
        self._H_position[[0, 1, 2], _POSE] = 1.0
        self._x: Array | None = None  # (9,)
        self._P: Array | None = None  # (9, 9)
        self._rejected = 0  # consecutive fixes refused by the innovation gate
        self._ready = False  # reset() called

    def _initial_covariance(self, pose_cov: Array) -> Array:
        """``(9, 9)`` covariance with the given ``(3, 3)`` pose block and the initial derivative stds."""
        p = self._params
        P = np.zeros((9, 9))
        P[np.ix_(_POSE, _POSE)] = pose_cov
        P[_VEL, _VEL] = [p.initial_velocity_std_m_per_s**2] * 2 + [p.initial_yaw_rate_std_rad_per_s**2]
        P[_VEL + 1, _VEL + 1] = [p.initial_acceleration_std_m_per_s2**2] * 2 + [p.initial_yaw_acceleration_std_rad_per_s2**2]
        return P

    def _start(self, pose: Array, pose_cov: Array) -> None:
        x = np.zeros(9)
        x[_POSE] = [pose[0], pose[1], wrap_angle(pose[2])]
        self._x, self._P = x, self._initial_covariance(pose_cov)
        self._rejected = 0

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Start a new episode; ``prior`` (optional) initializes the position states.

        The prior's covariance diagonal is used when finite, else the params' initial stds.
        ``rng`` is accepted for the protocol (the filter is deterministic).
        """
        del rng
        self._ready = True
        self._x = None
        self._P = None
        self._rejected = 0
        if prior is None or not prior.valid:
            return
        cov = finite_covariance(prior)
        var = np.diag(cov).copy() if cov is not None else np.full(3, np.nan)
        if not np.isfinite(var).all() or (var < 0).any():
            p = self._params
            var = np.array([p.initial_position_std_m**2] * 2 + [p.initial_heading_std_rad**2])
        self._start(np.array([prior.x_m, prior.y_m, prior.theta_rad]), np.diag(var))

    def _require_reset(self) -> None:
        require_reset("KalmanLocalizer", self._ready)

    def predict(self, odometry: OdometryDelta) -> None:
        """Time update by ``dt_s`` with the odometry drift, then the dead-reckoning velocity
        observation (eq. A.4) linearized in the heading."""
        self._require_reset()
        d = self._checked_odometry(odometry)
        if self._x is None or self._P is None:
            return
        p = self._params
        x, P = kf_predict(self._x, self._P, self._F, self._Q)
        heading = float(self._x[6]) + 0.5 * d[2]  # mid-step heading: the increment is in that frame
        P[np.ix_(_POSE, _POSE)] += drift_covariance(
            heading, d, p.position_var_m2_per_m, p.heading_var_rad2_per_m, p.heading_var_rad2_per_rad
        )
        c, s = math.cos(heading), math.sin(heading)
        vx, vy = float(x[1]), float(x[4])
        # h(x) = (R(theta)^T (x', y'), theta'): the robot-frame velocity the increment measures
        h = np.array([c * vx + s * vy, -s * vx + c * vy, float(x[7])])
        H = np.zeros((3, 9))
        H[0, [1, 4, 6]] = [c, s, -s * vx + c * vy]
        H[1, [1, 4, 6]] = [-s, c, -c * vx - s * vy]
        H[2, 7] = 1.0
        z = d / self._dt_s - h + H @ x  # so that kf_update's z - H x is the EKF innovation
        x, P = kf_update(x, P, z, H, self._R_velocity)
        x[6] = wrap_angle(x[6])
        self._x, self._P = x, P

    def update(self, measurement: BearingMeasurement) -> None:
        """Vision update (eq. A.5) with the robust all-triples resection when >= 3 bearings are
        seen, through the innovation gate (ours; module docstring)."""
        self._require_reset()
        meas = checked_bearings(self.name, measurement, self._map.count)
        if meas.landmark_ids.size < 3:
            return
        p = self._params
        res = resect_all_triples(
            self._map.positions_xy_m,
            meas.landmark_ids,
            meas.bearings_rad,
            min_conditioning=p.resection_min_conditioning,
            inlier_radius_m=p.resection_inlier_radius_m,
        )
        if not res.valid:
            return
        fix = np.asarray(res.pose, dtype=np.float64)
        own = fix_covariance(res, p.fix_bearing_std_rad)
        if self._x is None or self._P is None:  # the first fix initializes the filter
            self._start(fix, np.diag(np.diag(own)))
            return
        innovation = _wrap_heading_row(fix, self._x[_POSE])
        S = self._P[np.ix_(_POSE, _POSE)] + own
        if float(innovation @ np.linalg.solve(S, innovation)) > p.innovation_gate:
            self._rejected += 1
            if p.reset_after_rejections and self._rejected >= p.reset_after_rejections:
                self._start(fix, np.diag(np.diag(own)))
            return
        self._rejected = 0
        x, P = kf_update(self._x, self._P, fix, self._H_position, self._R_position, residual=_wrap_heading_row)
        x[6] = wrap_angle(x[6])
        self._x, self._P = x, P

    @property
    def estimate(self) -> PoseEstimate:
        """Position states and their ``(3, 3)`` covariance; valid up to ``max_spread_m``."""
        if self._x is None or self._P is None:
            return PoseEstimate.invalid()
        cov = self._P[np.ix_(_POSE, _POSE)].copy()
        x, y, th = self._x[_POSE].tolist()
        return PoseEstimate(x, y, float(wrap_angle(th)), cov, within_spread(cov, self._params.max_spread_m))

    @property
    def state(self) -> Array | None:
        """``(3, 3)`` copy of the state (rows x, y, heading; columns p, p', p''), or ``None``."""
        return None if self._x is None else self._x.reshape(3, 3).copy()

    def overlay(self) -> Overlay:
        est = self.estimate
        if self._x is None:
            return Overlay(label="kalman: no fix yet")
        return Overlay(poses=est.as_array()[None, :], weights=np.ones(1), label="kalman")
