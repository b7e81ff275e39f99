"""The ceiling-target paper's localizer (Fukaya et al.): a pose fix from every colour target in view.

Each image goes through the paper's pipeline (:mod:`localizers.ceiling_target.vision`): HSV, the
learned thresholds, the line C fitted by least squares, the end squares A and B found with a
5 x 5 mask, and the map positions of A and B. A target is identified by its colour code; a
code that several targets share (or a reading with one end in view that fits several) is
resolved by the current estimate, and left unused without one.

Between fixes the pose is dead-reckoned from the last fix (:func:`localizers.dead_reckoning.dead_reckon`)
with a covariance that grows with travel. ``fusion: reset`` is the paper's correction (the
fix replaces the pose); ``fusion: ekf`` fuses each fix with the dead-reckoned pose in an
extended Kalman filter (the paper's future work), the fix's covariance being
``diag(position_sd_m^2, position_sd_m^2, heading_sd_rad^2)``.

**Lost** (ours; the paper has none). Three tests contradict the estimate. (1) The ceiling plan: the map
also holds the ceiling as built (a ceiling feature's ``plan``: the light panels, the exit signs'
lettering), and each image, averaged over cells of ``plan_cell_px``, shows its white light panels
by their HSV saturation (the ceiling's off-white has 0.04-0.07, a panel under 0.03, whatever the
illumination's gain and the vignetting; :func:`localizers.ceiling_target.vision.plan_evidence`). White
seen more than ``plan_margin_out_m`` from every white the plan puts in view from the estimate, or
a panel it puts in view (``plan_expected_m2``) showing plain ceiling, contradicts the estimate;
dark cells (a person's head under the camera) count neither way, and white where the plan has it
agrees. Contradicted on every frame that says anything for ``plan_after_s``: lost. A jump of a
multiple of the panels' 2.4 m pitch (within ``plan_margin_out_m``) looks the same and is left to
the targets. (2) Every target reading of a frame lies more than ``lost_offset_m`` from the estimate.
(3) A target the estimate puts wholly in view goes unseen for ``lost_after_s``. While lost no
pose is claimed (:attr:`lost`); a reading whose colour code only one target has is a full fix
whatever the estimate predicted (it replaces the pose, with ``fusion: ekf`` too), and
``corridor_follower`` searches along the corridor by its sonar until it comes under one. Measured
on 10 seeds with ``corridor_follower``, carried 2-5 m by a pure translation 10 s in (a kidnap
the odometry does not see)::

    crowdloc eval --env-id crowdloc/CeilingCorridor-v0 --policies corridor_follower --localizers ceiling_target \
        --crowd-sizes 20 --seeds 10 --episode-steps 800 --workers 1 \
        --kidnap-at-s 10 --kidnap-m 2 --kidnap-max-m 5 --kidnap-keep-heading

confident wrong pose in the 30 s after the jump 1.56 s on average (9.08 s with the target tests
alone), at most 0.5 s in 9 runs, 12.6 s in one whose jump was close to a multiple of the panels'
2.4 m pitch; recovered to 0.2 m 7 of 10 (8), no pose 10.2 s (4.3); at the world's default crowd
(``--crowd-sizes 0``) 0.57 s, at most 2.85 s in any run, recovered 9 of 10. Of the runs not
recovered, the robot searched without passing under a target its colours identify in 30 s (a
target seen by one end only fits two targets). Carried anywhere with a random heading (``--kidnap-at-s 10`` alone):
0.39 s (20.9 s), 9 of 10 (3) at crowd 20; 0.81 s, 10 of 10 at crowd 0. (A kidnap lands on the
floor the robot can reach, :mod:`envs.floor`.) Without a
kidnap the mean error is 0.091 m at crowd 20 (0.132 m with the target tests alone) with availability 0.950 (0.999:
people pushing the robot make its odometry slip, and the panels show it), and 0.048 m,
availability 1.000, at crowd 0 (the same with the target tests alone).

Parameters: ``configs/localizers/ceiling_target.yaml``; the colour thresholds there are
learned by ``crowdloc fit ceiling_target`` from rendered, labelled images and record the data
they were learned from.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from core.geometry import wrap_angle
from core.schema import ConfigError, check, check_ranges
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    finite_covariance,
    require_reset,
    within_spread,
)
from localizers.ceiling_target.vision import (
    CameraIntrinsics,
    CeilingPlan,
    ColourRange,
    PipelineSettings,
    PlanEvidence,
    PlanSettings,
    Sighting,
    TargetMap,
    cell_points,
    cell_tint,
    check_image,
    colour_ranges,
    plan_evidence,
    sight_targets,
)
from localizers.contradiction import ContradictionClock
from localizers.dead_reckoning import dead_reckon


@dataclass(frozen=True)
class CeilingImage:
    """One upward camera frame and the camera it came from.

    Attributes:
        image: ``uint8 (H, W, 3)`` RGB.
        camera: the camera's intrinsics and mounting (:class:`CameraIntrinsics`).
        feature: the name of the world feature (ceiling) it looks at.
    """

    image: NDArray[np.uint8]
    camera: CameraIntrinsics
    feature: str = "ceiling"


def ceiling_image(observation: NDArray[Any], metadata: Mapping[str, Any]) -> CeilingImage:
    """Decode a ceiling camera's observation (the image) with its metadata."""
    return CeilingImage(
        np.asarray(observation), CameraIntrinsics.from_metadata(metadata), str(metadata.get("feature", "ceiling"))
    )


@dataclass(frozen=True)
class CeilingTargetParams:
    """Parameters of :class:`CeilingTargetLocalizer` (defaults: ``configs/localizers/ceiling_target.yaml``).

    Attributes:
        thresholds: colour name -> learned :class:`~localizers.ceiling_target.vision.ColourRange`.
        fitted_on: a record of the data the thresholds were learned from (written by ``fit``).
        colour_space: ``"hsv"`` (the paper's) or ``"rgb"`` (plain RGB boxes, for comparison).
        mask_px, mask_fill: the square mask of the end squares and the share of it that must
            be of the end's colour.
        min_line_fraction: a line blob needs this share of a whole line's expected pixel count.
        undistort: remove the lens distortion (from the camera's metadata) before converting.
        metres_per_px: > 0: the paper's single calibration constant instead of the intrinsics.
        fusion: ``"reset"`` (the paper's correction) or ``"ekf"``.
        fixes: ``"every"`` target in view corrects the pose; ``"first"``: only the first fix
            counts (the start target), then dead reckoning alone (the paper's Table 5 drive).
        position_sd_m, heading_sd_rad: the uncertainty of one fix.
        position_var_m2_per_m, heading_var_rad2_per_m, heading_var_rad2_per_rad: dead-reckoning
            drift between fixes (as :mod:`localizers.dead_reckoning`).
        max_gate: with an estimate, a fix farther than this many sds (Mahalanobis) is refused
            as a misreading (0: never refused).
        max_spread_m: past this position spread (m) of the dead reckoning between targets the
            pose is not claimed (ours). With the default drift (2e-4 m^2 per m per axis)
            the spread grows by 0.02 m over the 6.9 m between the corridor's targets and
            reaches 1 m only after 2.5 km without a target, so the reproduction never meets it.
        lost_offset_m: lost detection (ours): a frame whose every target reading lies
            farther than this (m) from the estimate contradicts it. One target fits the colours
            seen: the reading is a full pose fix and replaces the pose whatever ``fusion``; several
            fit: the localizer is lost (claims no pose) until a reading that only one target fits.
            inf: never (the paper's behaviour: the reading nearest the estimate is taken).
        lost_after_s: a target the estimate puts wholly in view (both ends ``view_margin_m``
            inside the camera's footprint) while no target is seen on any frame for this long
            contradicts the estimate: lost (inf: never).
        view_margin_m: how far inside the footprint's edge a target's ends must be predicted for
            its absence to count (m; blur, heads at the edges and the estimate's drift).
        plan_after_s: lost test by the ceiling plan (ours; module docstring): the light
            panels seen contradicting the estimate on every frame that says anything for this
            long (s): lost (inf: never).
        plan_cell_px: the image is averaged over cells of this many pixels a side (noise).
        plan_white_saturation: a cell of at most this HSV saturation (and ``plan_min_value``) is
            white, a light panel (the ceiling's off-white has 0.04-0.07).
        plan_plain_saturation, plan_plain_saturation_max: a cell in this saturation range shows
            the plain ceiling (above: a target or a sign's colour).
        plan_min_value: cells darker than this (0-255) count neither way (a head under the camera).
        plan_margin_out_m: white seen farther than this (m) from every white of the plan, seen
            from the estimate, is unexplained (the dead reckoning drifts 15 cm between targets).
        plan_margin_in_m: the plan's white this far (m) inside its edges is expected to be seen.
        plan_min_area_m2: a frame contradicts the estimate with this much ceiling (m^2) of
            unexplained white, and agrees with it with this much white matched.
        plan_expected_m2, plan_missing_share: a frame also contradicts the estimate with this
            much expected white in view (m^2; half a panel's inside) of which this share shows
            plain ceiling (a panel where there is none: the drift moves a panel's edge by less).
    """

    thresholds: Mapping[str, ColourRange] = field(default_factory=dict)
    fitted_on: Mapping[str, Any] = field(default_factory=dict)
    colour_space: Literal["hsv", "rgb"] = "hsv"
    mask_px: int = 5
    mask_fill: float = 0.5
    min_line_fraction: float = 0.4
    undistort: bool = False
    metres_per_px: float = 0.0
    fusion: Literal["reset", "ekf"] = "reset"
    fixes: Literal["every", "first"] = "every"
    position_sd_m: float = 0.02
    heading_sd_rad: float = 0.05
    position_var_m2_per_m: float = 2e-4
    heading_var_rad2_per_m: float = 2e-4
    heading_var_rad2_per_rad: float = 1e-3
    max_gate: float = 0.0
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    lost_offset_m: float = 1.0
    lost_after_s: float = 1.0
    view_margin_m: float = 0.1
    plan_after_s: float = 0.5
    plan_cell_px: int = 4
    plan_white_saturation: float = 0.03
    plan_plain_saturation: float = 0.035
    plan_plain_saturation_max: float = 0.15
    plan_min_value: float = 90.0
    plan_margin_out_m: float = 0.2
    plan_margin_in_m: float = 0.08
    plan_min_area_m2: float = 0.01
    plan_expected_m2: float = 0.03
    plan_missing_share: float = 0.6

    def __post_init__(self) -> None:
        check_max_spread("ceiling_target", self.max_spread_m)
        check(1 <= self.plan_cell_px <= 16, f"ceiling_target.plan_cell_px must be in 1..16, got {self.plan_cell_px}")
        check(
            0 <= self.plan_white_saturation < self.plan_plain_saturation < self.plan_plain_saturation_max <= 1,
            "ceiling_target: plan_white_saturation < plan_plain_saturation < plan_plain_saturation_max must lie in "
            f"[0, 1], got {self.plan_white_saturation}, {self.plan_plain_saturation}, {self.plan_plain_saturation_max}",
        )
        check(
            0 < self.plan_missing_share <= 1,
            f"ceiling_target.plan_missing_share must be in (0, 1], got {self.plan_missing_share}",
        )
        check(0 <= self.plan_min_value <= 255, f"ceiling_target.plan_min_value must be in [0, 255], got {self.plan_min_value}")
        check_ranges(
            self,
            "ceiling_target",
            positive_or_inf=("lost_offset_m", "lost_after_s", "plan_after_s", "plan_min_area_m2", "plan_expected_m2"),
        )
        check(
            self.mask_px >= 3 and self.mask_px % 2 == 1, f"ceiling_target.mask_px must be an odd number >= 3, got {self.mask_px}"
        )
        check(0 < self.mask_fill <= 1, f"ceiling_target.mask_fill must be in (0, 1], got {self.mask_fill}")
        check(
            0 < self.min_line_fraction <= 1, f"ceiling_target.min_line_fraction must be in (0, 1], got {self.min_line_fraction}"
        )
        check_ranges(
            self,
            "ceiling_target",
            positive=("position_sd_m", "heading_sd_rad"),
            non_negative=(
                "metres_per_px",
                "position_var_m2_per_m",
                "heading_var_rad2_per_m",
                "heading_var_rad2_per_rad",
                "max_gate",
                "view_margin_m",
                "plan_margin_out_m",
                "plan_margin_in_m",
            ),
        )

    @property
    def settings(self) -> PipelineSettings:
        return PipelineSettings(
            self.colour_space, self.mask_px, self.mask_fill, self.min_line_fraction, self.undistort, self.metres_per_px
        )

    @property
    def plan_settings(self) -> PlanSettings:
        return PlanSettings(
            self.plan_cell_px,
            self.plan_white_saturation,
            (self.plan_plain_saturation, self.plan_plain_saturation_max),
            self.plan_min_value,
            self.plan_margin_out_m,
            self.plan_margin_in_m,
        )


class CeilingTargetLocalizer(LocalizerBase[CeilingTargetParams]):
    """Pose fixes from ceiling colour targets, dead reckoning in between (module docstring)."""

    name: ClassVar[str] = "ceiling_target"
    #: measured on this run: share 0.823, NEES median 0.50 (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/CeilingCorridor-v0", "corridor_follower", 600, 0.8)
    measurement: ClassVar[str] = "ceiling_image"

    def __init__(self, landmarks: LandmarkMap, params: CeilingTargetParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s, owner="CeilingTargetLocalizer")
        ceilings = {name: data for name, data in landmarks.features.items() if data.get("type") == "ceiling"}
        if not ceilings:
            raise ConfigError(
                f"localizer 'ceiling_target' needs a world with a ceiling feature (features: {', '.join(landmarks.features) or 'none'})"
            )
        self._targets = {name: TargetMap.from_map_data(data) for name, data in ceilings.items()}
        self._plans = {name: CeilingPlan.from_map_data(data) for name, data in ceilings.items()}
        self._plan_settings = params.plan_settings
        self._cells: dict[CameraIntrinsics, NDArray[np.float64]] = {}  # cell_points per camera
        for name, targets in self._targets.items():
            try:
                colour_ranges(params.thresholds, targets.colours, f"ceiling_target on feature {name!r}")
            except ValueError as exc:
                raise ConfigError(str(exc)) from None
        self._settings = params.settings
        self._fix_cov = np.diag([params.position_sd_m**2, params.position_sd_m**2, params.heading_sd_rad**2])
        self._pose: NDArray[np.float64] | None = None
        self._cov = np.full((3, 3), np.nan)
        self._ready = False
        #: the sightings of the last image (every reading of every blob), and the one used
        self.last_sightings: list[list[Sighting]] = []
        self.last_fix: Sighting | None = None
        self.fixes = 0
        self._lost = False
        #: how long a target predicted wholly in view has not been seen (``lost_after_s``)
        self._unseen = ContradictionClock(params.lost_after_s, self._dt_s)
        #: how long the ceiling plan has contradicted the estimate (``plan_after_s``)
        self._plan_clock = ContradictionClock(params.plan_after_s, self._dt_s)
        #: what the last image said of the estimate against the ceiling plan (None: not compared)
        self.last_plan: PlanEvidence | None = None

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Start lost, or from ``prior`` (the paper starts under a target that fixes the pose)."""
        del rng  # deterministic
        self._ready = True
        self.last_sightings, self.last_fix, self.fixes = [], None, 0
        self._lost, self.last_plan = False, None
        self._unseen.reset()
        self._plan_clock.reset()
        if prior is not None and prior.valid and np.isfinite(prior.as_array()).all():
            self._pose = np.array([prior.x_m, prior.y_m, wrap_angle(prior.theta_rad)])
            cov = finite_covariance(prior)
            self._cov = self._fix_cov.copy() if cov is None else 0.5 * (cov + cov.T)
        else:
            self._pose = None
            self._cov = np.full((3, 3), np.nan)

    def predict(self, odometry: OdometryDelta) -> None:
        require_reset("CeilingTargetLocalizer", self._ready)
        d = self._checked_odometry(odometry)
        if self._pose is None:
            return
        p = self._params
        self._pose, self._cov = dead_reckon(
            self._pose, self._cov, d, p.position_var_m2_per_m, p.heading_var_rad2_per_m, p.heading_var_rad2_per_rad
        )

    def update(self, measurement: CeilingImage) -> None:
        """Run the pipeline on the image and correct the pose with the best target reading."""
        require_reset("CeilingTargetLocalizer", self._ready)
        if not isinstance(measurement, CeilingImage):
            raise MeasurementError(f"{self.name}: expected a CeilingImage, got {type(measurement).__name__}")
        targets = self._targets.get(measurement.feature)
        if targets is None:
            raise MeasurementError(
                f"{self.name}: the camera looks at feature {measurement.feature!r}, not one of {', '.join(self._targets)}"
            )
        image = check_image(measurement.image, measurement.camera, self.name)
        if self._params.fixes == "first" and self.fixes:
            return  # dead reckoning from the start fix on
        self.last_sightings = sight_targets(image, measurement.camera, targets, self._params.thresholds, self._settings)
        self._watch(targets, measurement.camera)
        fix, contradicted = self._choose(self.last_sightings)
        if fix is None:
            plan_lost = self._check_plan(image, measurement.camera, self._plans.get(measurement.feature))
            self._lost = self._lost or contradicted or plan_lost or self._unseen.lost
            return
        self.last_fix, self.last_plan = fix, None
        self.fixes += 1
        was_lost = self._lost
        self._lost = False
        self._unseen.reset()
        self._plan_clock.reset()
        if self._pose is None or self._params.fusion == "reset" or contradicted or was_lost:
            self._pose = fix.pose.copy()
            self._cov = self._fix_cov.copy()
            return
        # EKF: the fix measures the pose directly (H = I)
        innovation = fix.pose - self._pose
        innovation[2] = wrap_angle(innovation[2])
        gain = self._cov @ np.linalg.inv(self._cov + self._fix_cov)
        self._pose = self._pose + gain @ innovation
        self._pose[2] = wrap_angle(self._pose[2])
        cov = (np.eye(3) - gain) @ self._cov
        self._cov = 0.5 * (cov + cov.T)

    def _check_plan(self, image: NDArray[np.uint8], camera: CameraIntrinsics, plan: CeilingPlan | None) -> bool:
        """Fold one image's :class:`PlanEvidence` into the time the ceiling plan has contradicted the
        estimate (module docstring, **Lost**); returns whether that reached ``plan_after_s``."""
        p = self._params
        self.last_plan = None
        if (
            plan is None
            or self._pose is None
            or self._lost
            or not math.isfinite(p.plan_after_s)
            or not within_spread(self._cov, p.max_spread_m)
        ):
            self._plan_clock.reset()
            return False
        points = self._cells.get(camera)
        if points is None:
            points = self._cells[camera] = cell_points(camera, p.plan_cell_px)
        cell_m2 = (p.plan_cell_px * camera.depth_m) ** 2 / (camera.fx_px * camera.fy_px)
        tint = cell_tint(image, p.plan_cell_px)
        evidence = self.last_plan = plan_evidence(plan, self._pose, points, tint, cell_m2, self._plan_settings)
        area = p.plan_min_area_m2
        against = evidence.unexplained_m2 >= area or (
            evidence.expected_m2 >= p.plan_expected_m2 and evidence.missing_m2 >= p.plan_missing_share * evidence.expected_m2
        )
        # white where the plan has it agrees; a frame with neither (people hiding the ceiling) says nothing
        return self._plan_clock.tick(True if against else False if evidence.matched_m2 >= area else None)

    def _watch(self, targets: TargetMap, camera: CameraIntrinsics) -> None:
        """Count the time a target that the estimate puts wholly in view goes unseen (``lost_after_s``)."""
        if self._pose is None or self._lost or self.last_sightings or not math.isfinite(self._params.lost_after_s):
            self._unseen.reset()
            return
        self._unseen.tick(self._target_in_view(targets, camera))

    def _target_in_view(self, targets: TargetMap, camera: CameraIntrinsics) -> bool:
        """Whether the estimate puts both ends of some target ``view_margin_m`` inside the camera's footprint."""
        assert self._pose is not None
        x, y, th = self._pose
        c, s = math.cos(th), math.sin(th)
        ends = np.concatenate([targets.a_xy, targets.b_xy]) - (x, y)
        forward = c * ends[:, 0] + s * ends[:, 1] - camera.offset_m[0]
        left = -s * ends[:, 0] + c * ends[:, 1] - camera.offset_m[1]
        # the pinhole footprint (a barrel lens sees a little more) less the margin
        half_forward = camera.cy_px * camera.depth_m / camera.fy_px - self._params.view_margin_m
        half_left = camera.cx_px * camera.depth_m / camera.fx_px - self._params.view_margin_m
        inside = (np.abs(forward) <= half_forward) & (np.abs(left) <= half_left)
        n = targets.a_xy.shape[0]
        return bool(np.any(inside[:n] & inside[n:]))

    def _choose(self, sightings: list[list[Sighting]]) -> tuple[Sighting | None, bool]:
        """The reading to use, and whether the frame contradicts the estimate.

        Per blob the reading nearest the estimate (the only one without an estimate, past
        ``max_spread_m`` or while lost, else none); of the blobs, the one with the most line
        pixels. When every reading of every blob lies farther than ``lost_offset_m`` from the
        estimate the frame contradicts it, and only a reading that one target alone fits (its
        colours identify it) is used: a full fix, whatever the estimate predicted.
        """
        lost = self._pose is None or self._lost or not within_spread(self._cov, self._params.max_spread_m)
        contradicted = (
            not lost
            and bool(sightings)
            and all(self._offset_m(r) > self._params.lost_offset_m for readings in sightings for r in readings)
        )
        chosen: list[Sighting] = []
        for readings in sightings:
            if lost or contradicted:
                if len(readings) == 1:  # without a trusted estimate only an unambiguous reading counts
                    chosen.append(readings[0])
                continue
            distance, best = min(((self._distance(r), r) for r in readings), key=lambda pair: pair[0])
            gate = self._params.max_gate
            if gate == 0 or distance <= gate * gate:
                chosen.append(best)
        if not chosen:
            return None, contradicted
        return max(chosen, key=lambda r: (len(r.ends), r.line_px)), contradicted

    def _offset_m(self, reading: Sighting) -> float:
        """How far (m) a reading's position lies from the estimate's."""
        assert self._pose is not None
        return float(math.hypot(reading.pose[0] - self._pose[0], reading.pose[1] - self._pose[1]))

    def _distance(self, reading: Sighting) -> float:
        """Squared Mahalanobis distance of a reading from the estimate (with the fix's own covariance)."""
        assert self._pose is not None
        diff = reading.pose - self._pose
        diff[2] = wrap_angle(diff[2])
        cov = self._cov + self._fix_cov
        return float(diff @ np.linalg.solve(cov, diff))

    @property
    def estimate(self) -> PoseEstimate:
        if self._pose is None or self._lost:
            return PoseEstimate.invalid()
        x, y, th = self._pose
        return PoseEstimate(float(x), float(y), float(th), self._cov.copy(), within_spread(self._cov, self._params.max_spread_m))

    @property
    def lost(self) -> bool:
        """Whether the images contradict the dead-reckoned pose (``lost_offset_m``, ``lost_after_s``):
        no pose is claimed until a target that its colours identify is seen."""
        return self._lost

    def overlay(self) -> Overlay:
        if self._pose is None:
            return Overlay(label="ceiling target: no fix yet")
        fixes = [r.pose for readings in self.last_sightings for r in readings]
        poses = np.array(fixes).reshape(-1, 3) if fixes else self._pose[None, :].copy()
        return Overlay(poses=poses, weights=np.ones(poses.shape[0]), label=f"ceiling target: {self.fixes} fixes")
