"""``far_landmark_pf``: the far-landmark paper's particle filter (paper D, docs/papers.md section D).

People and cars are near the robot, building walls and poles far: the filter weighs each
particle by the far landmarks first. Per update (sec. 2.4 of the paper, numbered as there):

1. the map's landmarks near the estimate: those of the ``scenes`` scenes recorded nearest the
   estimate (within ``scene_radius_m``; :class:`localizers.far_landmark_pf.scene_map.SceneMap`), in the world
   frame, grouped by edge type;
2. eqs. (6)-(10): a detection ``(1/r, theta)`` of a landmark at ``(1/r*, theta*)`` has the
   likelihood ``N(1/r; 1/r*, sigma_inv_r) N(theta; theta*, sigma_theta)`` (normalized
   Gaussians), ``(r*, theta*)`` from the particle's pose and the landmark (eqs. (11)-(12),
   the bearing counter-clockwise from the heading, crowdloc's convention);
3. eq. (13): a detection is associated, per particle, with the same-type map landmark of the
   largest likelihood; below the threshold it is a mismatch. The threshold is given as the
   likelihood's fall from its peak in standard deviations, ``match_gate`` (ours: the paper
   thresholds the likelihood without a value): a detection matches when
   ``((1/r - 1/r*) / sigma_inv_r)^2 + ((theta - theta*) / sigma_theta)^2 <= match_gate^2``;
4. far emphasis (sec. 2.4.2, eq. (14)): the detections' bearings are cut into sectors of
   ``sector_rad`` (30 deg); in each, the farthest detection that matches is used (if the
   farthest fails, the next farthest; if none, nothing from that sector); nothing nearer than
   ``min_range_m`` (3 m) is used. The particle's weight is the product of the likelihoods used.
   ``selection``: ``"farthest"`` (the paper's), ``"nearest"`` (nearest first, the comparison
   the paper's argument implies), ``"all"`` (every matching detection: the baseline without
   far emphasis);
5. the estimate is the weighted mean of the particles (500, spread around the initial pose);
   the motion model is Probabilistic Robotics' odometry model (:mod:`localizers.particles`).

A particle matching nothing keeps its weight (an empty product), so a frame without detections
changes nothing; resampling (systematic) happens when the effective sample size falls below
``resample_ess_fraction`` of the set. While only coasting on odometry the set spreads with the
motion noise, and no pose is claimed once the position spread exceeds ``max_spread_m`` (ours).

The reported covariance is the particles' plus the map's own error (``map_error``, ours): the
scenes' poses are the mapping drive's estimates, and every landmark of a scene shares its
error, which the particles' weights cannot know. Measured on the campus route at crowd 30
(``route_follower``, seeds 0-4, ``tests/localizers/test_consistency_promises.py``'s protocol):
70-95 % of the steps inside the 95 % region, NEES medians 1.4-3.8; without it 35-68 % and
5.0-18.8. The estimate is the same either way.

Lost and found (ours; the paper has no recovery). Each frame, before it is weighed, the
usable detections are compared with the landmarks of the scenes near the estimate: the median
distance (:func:`detection_distances`, in standard deviations of ``(1/r, theta)``, to the nearest
same-type landmark; detections toward which the map holds no landmark say nothing) above
``lost_gate`` contradicts it (:class:`localizers.contradiction.ContradictionClock`, the bearing
localizers' test on another residual). Those standard deviations are the paper's widened by what
the last step's turn can shift between the rig's frames (``frame_gap_s``, ``baseline_m``;
the paper's webcams take their frames up to 1/30 s apart, and a turn of 0.4 rad/s then moves the
outer pair's disparity by up to 7 sds of the inverse range although the pose is right). Contradicted on
every frame for ``lost_after_s``, the filter is lost: it claims no pose (``valid`` false) and
searches the scene map (sensor resetting): every usable detection votes, at headings around the
estimate's, for the positions within ``search_radius_m`` where a same-type landmark of the scenes
recorded there would put the robot (:func:`position_votes`); the three best cells are refined by
every detection's likelihood, and when the best pose agrees with the frame (median distance within
``lost_gate`` at the paper's sds, directions where the map holds nothing counted against it) the set
is drawn around it. A search that lands within two cells and two heading steps of the estimate
confirms it (crowds hiding the landmarks; one that finds the position with another heading redraws
the set: confirming it would keep a heading 5-20 deg off and lose it again every 0.5 s). Until a
frame agrees or a search fits, no pose is claimed: a robot that drives on the estimate
(``route_follower``) stops, and one kidnapped off the route that turns toward views the mapping drive
never had may stay there, honestly lost.

Measured on the campus route at crowd 30, seeds 0-9, 50 s, kidnapped at 20 s (``crowdloc eval --env-id
crowdloc/StereoCampus-v0 --localizers far_landmark_pf --policies route_follower --crowd-sizes 30 --seeds 10
--episode-steps 500 --kidnap-at-s 20``, on the default map): by 2-5 m (pure translation, heading kept, unseen by
odometry; ``--kidnap-m 2 --kidnap-max-m 5 --kidnap-keep-heading``) it recovers in 9 of 10 runs, in 7.7 s on average, with 4.7 s of
confident wrong pose and 7.1 s without a pose in the 30 s after the jump. Kidnapped to a random pose
anywhere on the campus with a random heading (without those three options) none recovers
(the search looks near the estimate, and most of the campus holds no scene): 3.4 s of wrong pose, 26.6 s
without one. Without a kidnap (the command without ``--kidnap-at-s``): mean error 0.181 m, RMS 0.225 m, 77.7 %
of the steps inside the 95 % region, a pose on 96.6 % of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

from core.schema import ConfigError, check, check_at_most, check_ranges
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    ConsistencyPromise,
    EdgeMeasurement,
    LandmarkMap,
    LocalizerBase,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    require_reset,
    within_spread,
)
from localizers.contradiction import ContradictionClock
from localizers.far_landmark_pf.kernels import detection_distances, particle_log_weights, position_votes, top_cells
from localizers.far_landmark_pf.scene_map import SceneMap
from localizers.particles import (
    MAX_PARTICLES,
    PARTICLE_MEMORY,
    gaussian_poses,
    prior_covariance,
    propagate_particles,
    systematic_resample,
    weighted_pose_covariance,
    weighted_pose_mean,
)

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
SELECTIONS = ("farthest", "nearest", "all")
_FARTHEST, _NEAREST, _ALL = 0, 1, 2


@dataclass(frozen=True)
class FarLandmarkParams:
    """Parameters of :class:`FarLandmarkPF` (defaults: ``configs/localizers/far_landmark_pf.yaml``).

    Attributes:
        scene_map: the scene map's file (``.npz``, :class:`~localizers.far_landmark_pf.scene_map.SceneMap`);
            empty: the world's default map, which ``gym.make(..., localizer="far_landmark_pf")``
            builds and caches on first use (:mod:`agents.experiments.scene_maps`).
        n_particles: set size (paper: 500).
        alphas: odometry motion-model alpha1..alpha4 (ours).
        min_translation_std_m, min_rotation_std_rad: per-step motion-noise floors (ours).
        initial_position_std_m, initial_heading_std_rad: the spread around the initial pose.
        sigma_inv_r: sd of the inverse range, 1/m (eq. (8); the paper leaves it open).
        sigma_theta_rad: sd of the bearing (eq. (9); likewise).
        match_gate: the threshold of eq. (13) as a distance in standard deviations.
        sector_rad: the width of far emphasis's sectors (paper: 30 deg).
        min_range_m: detections nearer are never used (paper: 3 m).
        selection: ``"farthest"`` (the paper's), ``"nearest"`` or ``"all"`` (module docstring).
        scenes: how many scenes near the estimate give landmarks; ``scene_radius_m``: how near.
        resample_ess_fraction: resample when the effective sample size falls below this share.
        max_spread_m: no pose is claimed while the position spread exceeds this (ours).
        lost_gate, lost_after_s: lost detection (ours, :mod:`localizers.contradiction`; module
            docstring): a frame whose usable detections lie, in their median, more than ``lost_gate``
            standard deviations (in ``(1/r, theta)``) from the nearest same-type landmark seen from
            the estimate contradicts it (directions where the map holds no landmark left out);
            contradicted on every frame (with >= 2 such detections) for ``lost_after_s``, the filter
            is lost and claims no pose until a frame agrees with its estimate again or the search
            finds the robot (inf: never lost).
        search_radius_m: re-localization (ours, module docstring) when lost: the pose within about
            this distance of the estimate that the detections fit, against the landmarks of the
            scenes recorded there (0: no search, the filter only says it is lost).
        search_cell_m: the search's vote grid (each detection votes once for every cell its
            matching landmarks put the robot in; the best cells are then refined at a fifth of it).
        frame_gap_s, baseline_m: the camera rig's longest time between two of its frames and its neighbour
            baseline (ours; ``gym.make`` takes both from the env's camera unless given: the
            free-running webcams' frame period and 0.19 m, 0 for synchronised cameras). A frame taken while the
            robot turns at ``w`` rad/s (the step's odometry) can have its bearings off by ``w frame_gap_s`` and
            its inverse ranges by ``w frame_gap_s / (2 baseline_m)`` (the outer pair's disparity); the lost test
            counts those in its standard deviations, so a turn with the right pose does not contradict the map.
            The particles' weights keep the paper's ``sigma_inv_r`` and ``sigma_theta_rad``.
        search_heading_rad: the search's headings span the estimate's +- this, at steps of twice
            ``sigma_theta_rad`` (a kidnapped robot's heading is roughly known to odometry; the filter's
            heading drifts most in turns toward views the mapping drive never had).
        map_error: add the map's own uncertainty to the reported covariance (ours; the paper
            reports none): the mean pose covariance of the scenes the last update matched
            against (:meth:`~localizers.far_landmark_pf.scene_map.SceneMap.pose_covariance`). The filter's
            particles know the camera's noise only, but every landmark of a scene carries that
            scene's pose error, so a pose fixed on them is off by it too. The estimate itself
            is the same either way.
    """

    scene_map: str = ""
    n_particles: int = 500
    alphas: tuple[float, float, float, float] = (0.05, 0.02, 0.02, 0.02)
    min_translation_std_m: float = 0.002
    min_rotation_std_rad: float = 0.002
    initial_position_std_m: float = 0.3
    initial_heading_std_rad: float = 0.05
    sigma_inv_r: float = 0.005
    sigma_theta_rad: float = 0.01
    match_gate: float = 3.0
    sector_rad: float = math.radians(30.0)
    min_range_m: float = 3.0
    selection: Literal["farthest", "nearest", "all"] = "farthest"
    scenes: int = 3
    scene_radius_m: float = 10.0
    resample_ess_fraction: float = 0.5
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    lost_gate: float = 2.0
    lost_after_s: float = 0.5
    search_radius_m: float = 8.0
    search_cell_m: float = 0.5
    search_heading_rad: float = 0.5
    frame_gap_s: float = 0.0
    baseline_m: float = 0.19
    map_error: bool = True

    def __post_init__(self) -> None:
        name = "FarLandmarkParams"
        check(self.n_particles >= 2, f"{name}.n_particles must be >= 2, got {self.n_particles!r}")
        check_at_most(self, name, {"n_particles": MAX_PARTICLES}, PARTICLE_MEMORY)
        check(
            len(self.alphas) == 4 and all(math.isfinite(a) and a >= 0.0 for a in self.alphas),
            f"{name}.alphas must be four finite values >= 0, got {self.alphas!r}",
        )
        check_ranges(
            self,
            name,
            positive=(
                "sigma_inv_r",
                "sigma_theta_rad",
                "match_gate",
                "sector_rad",
                "scene_radius_m",
                "search_cell_m",
                "baseline_m",
            ),
            non_negative=(
                "search_radius_m",
                "search_heading_rad",
                "min_translation_std_m",
                "min_rotation_std_rad",
                "initial_position_std_m",
                "initial_heading_std_rad",
                "min_range_m",
                "frame_gap_s",
            ),
        )
        check(self.selection in SELECTIONS, f"{name}.selection must be one of {SELECTIONS}, got {self.selection!r}")
        check(self.sector_rad <= 2.0 * math.pi, f"{name}.sector_rad must be at most a turn, got {self.sector_rad!r}")
        check(self.scenes >= 1, f"{name}.scenes must be >= 1, got {self.scenes!r}")
        check(
            0.0 < self.resample_ess_fraction <= 1.0,
            f"{name}.resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction!r}",
        )
        check_max_spread(name, self.max_spread_m)
        check_ranges(self, name, positive_or_inf=("lost_gate", "lost_after_s"))
        check(
            self.search_radius_m <= 200.0 * self.search_cell_m,
            f"{name}.search_radius_m {self.search_radius_m!r} must be at most 200 search_cell_m ({self.search_cell_m!r}): "
            "the vote grid's size",
        )


def order_detections(
    inverse_range: Array, bearings: Array, sector_rad: float, min_range_m: float, selection: str
) -> tuple[IntArray, IntArray]:
    """The detections far emphasis weighs, grouped by sector and ordered within each.

    Detections nearer than ``min_range_m`` are dropped (eq. (14)); the rest are cut into sectors
    of their bearing (``floor((theta + pi) / sector_rad)``) and ordered farthest first
    (``"farthest"``), nearest first (``"nearest"``) or kept in one group (``"all"``: every one
    is weighed).

    Returns:
        ``order`` ``(K,)``: detection indices, sector by sector; ``starts`` ``(G + 1,)``: group
        ``g`` is ``order[starts[g]:starts[g + 1]]``.
    """
    keep = np.flatnonzero(1.0 / inverse_range >= min_range_m)
    if selection == "all":
        return keep.astype(np.int64), np.array([0, keep.size], dtype=np.int64)
    sector = np.floor((bearings[keep] + math.pi) / sector_rad).astype(np.int64)
    rank = inverse_range[keep] if selection == "farthest" else -inverse_range[keep]  # farthest: smallest 1/r first
    order = np.lexsort((rank, sector))
    sector = sector[order]
    bounds = np.flatnonzero(np.diff(sector)) + 1
    starts = np.concatenate([[0], bounds, [keep.size]]).astype(np.int64)
    return keep[order].astype(np.int64), starts


class FarLandmarkPF(LocalizerBase[FarLandmarkParams]):
    """The far-landmark particle filter (module docstring)."""

    name: ClassVar[str] = "far_landmark_pf"
    #: measured on this run, on the campus's free-running webcams (tests/localizers/test_consistency_promises.py):
    #: share 0.668, NEES median 2.87 on 1156 steps with a pose (0.644 with the cameras synchronised, the per-camera
    #: gains and the rows model kept), so the promise is 0.6 (``map_error``'s part in it: module docstring)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/StereoCampus-v0", "route_follower", 1200, 0.6)

    def __init__(self, landmarks: LandmarkMap, params: FarLandmarkParams, *, dt_s: float, scenes: SceneMap | None = None) -> None:
        super().__init__(landmarks, params, dt_s=dt_s)
        if scenes is None:
            if not params.scene_map:
                raise ConfigError(
                    "far_landmark_pf needs a scene map: give localizer_params={'scene_map': PATH} (`crowdloc map WORLD` makes one), "
                    "or make it with gym.make(..., localizer='far_landmark_pf') after `import agents`, which builds the "
                    "world's default map"
                )
            scenes = SceneMap.load(params.scene_map)
        scenes.check_world(landmarks)
        self.scenes = scenes
        self._alphas = np.asarray(params.alphas, dtype=np.float64)
        self._inv_sr = 1.0 / params.sigma_inv_r
        self._inv_st = 1.0 / params.sigma_theta_rad
        self._log_gate = -0.5 * params.match_gate**2
        self._log_norm = -math.log(2.0 * math.pi * params.sigma_inv_r * params.sigma_theta_rad)
        self._rng: np.random.Generator | None = None
        self._particles = np.zeros((3, 0))
        self._log_w = np.zeros(0)
        self._weights: Array | None = None
        self._cache: tuple[Array, Array] | None = None
        # the nearest scenes, their landmarks (types, xy, type_start) and their mean pose covariance
        self._near: tuple[tuple[int, ...], IntArray, Array, IntArray, Array] | None = None
        #: the detections the estimate's pose used at the last update, in the world frame (for drawing)
        self.used_xy = np.zeros((0, 2))
        self._clock = ContradictionClock(params.lost_after_s, self._dt_s, threshold=params.lost_gate)
        self._lost = False
        #: the turn rate of the last odometry step, rad/s (what the lost test allows the frame's cameras to disagree by)
        self._turn_rps = 0.0
        #: how many times the filter re-localized (searched the scene map) since the reset
        self.searches = 0
        turns = math.floor(params.search_heading_rad / (2.0 * params.sigma_theta_rad) + 1e-9)
        #: the search's heading offsets from the estimate's, at twice the bearing's sd
        self._turns = np.arange(-turns, turns + 1) * 2.0 * params.sigma_theta_rad
        axis = np.arange(-5, 6) * params.search_cell_m / 5.0
        fx, fy, ft = np.meshgrid(axis, axis, np.arange(-1, 2) * 2.0 * params.sigma_theta_rad, indexing="ij")
        #: the refinement's offsets around a voted cell: +- a cell at a fifth of it, the cell's heading +- a step, (3, 363)
        self._fine = np.stack([fx.ravel(), fy.ravel(), ft.ravel()])

    # ------------------------------------------------------------------ the protocol
    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """500 particles around ``prior`` (needed: the paper spreads them around the initial pose)."""
        if prior is None or not prior.valid or not np.isfinite(prior.as_array()).all():
            raise ValueError(
                f"{self.name}.reset needs a valid initial pose (prior), got {prior!r}: the paper spreads its particles "
                "around the initial pose (gym.make(..., prior='start'))"
            )
        p = self._params
        self._rng = rng
        cov = prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
        self._particles = gaussian_poses(prior.as_array(), cov, p.n_particles, rng)
        self._log_w = np.full(p.n_particles, -math.log(p.n_particles))
        self._weights = None
        self._cache = None
        self._near = None
        self.used_xy = np.zeros((0, 2))
        self._clock.reset()
        self._lost = False
        self._turn_rps = 0.0
        self.searches = 0

    def predict(self, odometry: OdometryDelta) -> None:
        """Move every particle by the odometry motion model."""
        rng = self._generator()
        d = self._checked_odometry(odometry)
        p = self._params
        self._turn_rps = abs(float(d[2])) / self._dt_s
        propagate_particles(self._particles, d, self._alphas, rng,
                            min_translation_std_m=p.min_translation_std_m, min_rotation_std_rad=p.min_rotation_std_rad)  # fmt: skip
        self._cache = None

    def update(self, measurement: EdgeMeasurement) -> None:
        """Weigh the particles by the far landmarks (steps 1-4), resample when needed."""
        rng = self._generator()
        if not isinstance(measurement, EdgeMeasurement):
            raise MeasurementError(f"{self.name}: expected an EdgeMeasurement, got {type(measurement).__name__}")
        meas = measurement.validated(self.name)
        p = self._params
        self.used_xy = np.zeros((0, 2))  # nothing used until this frame's detections are weighed
        order, starts = order_detections(meas.inverse_range_m, meas.bearings_rad, p.sector_rad, p.min_range_m, p.selection)
        if order.size == 0:
            return
        mean, _ = self._mean_cov()
        types, lm_xy, type_start = self._landmarks_near(mean)
        if types.size == 0:
            return
        residual = self._median_distance(mean, meas, order, lm_xy, type_start)  # against the estimate before this frame
        if not math.isnan(residual):  # fewer than two detections where the map looked say nothing
            self._lost = self._lost and residual > p.lost_gate  # a frame that agrees: found again
            if self._clock.fold(residual):
                self._lost = True
                self._clock.reset()  # contradicted for another lost_after_s before the next search
                if p.search_radius_m > 0.0 and self._relocalize(meas):
                    return
        chosen = np.full(starts.size - 1, -1, dtype=np.int64)
        # the estimate's pose rides along as a last column: what it used is what the overlay draws
        poses = np.concatenate([self._particles, mean[:, None]], axis=1)
        ll = particle_log_weights(poses, meas.types, meas.inverse_range_m, meas.bearings_rad, order, starts,
                                  p.selection != "all", lm_xy, type_start, self._inv_sr, self._inv_st, self._log_gate,
                                  self._log_norm, chosen)  # fmt: skip
        used = chosen[chosen >= 0]
        r, b = 1.0 / meas.inverse_range_m[used], meas.bearings_rad[used] + mean[2]
        self.used_xy = np.stack([mean[0] + r * np.cos(b), mean[1] + r * np.sin(b)], axis=1)
        log_w = self._log_w + ll[:-1]
        log_w -= log_w.max()
        w = np.exp(log_w)
        w /= w.sum()
        self._weights = w
        self._log_w = np.log(np.maximum(w, 1e-300))
        self._cache = None
        if 1.0 / float(np.sum(w * w)) < p.resample_ess_fraction * w.size:
            idx = systematic_resample(w, w.size, rng)
            self._particles = np.ascontiguousarray(self._particles[:, idx])
            self._log_w = np.full(w.size, -math.log(w.size))
            self._weights = None

    @property
    def lost(self) -> bool:
        """Whether the detections contradicted the estimate for ``lost_after_s`` and no frame has agreed with it since."""
        return self._lost

    @property
    def estimate(self) -> PoseEstimate:
        """The particles' weighted mean and covariance (plus the map's, with ``map_error``); no pose is claimed
        (``valid`` false, the mean and covariance kept) past ``max_spread_m`` or while :attr:`lost`."""
        if self._rng is None:
            return PoseEstimate.invalid()
        mean, cov = self._mean_cov()
        if self._params.map_error and self._near is not None:
            cov = cov + self._near[4]
        valid = within_spread(cov, self._params.max_spread_m) and not self._lost
        return PoseEstimate(float(mean[0]), float(mean[1]), float(mean[2]), cov.copy(), valid)

    def overlay(self) -> Overlay:
        n = self._particles.shape[1]
        w = np.ones(n) if self._weights is None else self._weights / self._weights.max()
        out = self._particles.T.copy()
        out[:, 2] = (out[:, 2] + math.pi) % (2.0 * math.pi) - math.pi
        return Overlay(
            poses=out, weights=w, points_xy=self.used_xy, label=f"{self.name}: {n} particles, {len(self.used_xy)} far landmarks"
        )

    # ------------------------------------------------------------------ internals
    def _median_distance(
        self, pose: Array, meas: EdgeMeasurement, order: IntArray, lm_xy: Array, type_start: IntArray, *, doubt: bool = True
    ) -> float:
        """The median over the usable detections of their distance to the landmarks, seen from ``pose``
        (:func:`detection_distances`). To doubt an estimate (``doubt``), directions the map does not cover say
        nothing (left out; NaN with fewer than two left); to accept a new pose, they count as unexplained (inf):
        a pose is claimed only where most detections fit."""
        p = self._params
        inv_sr, inv_st = self._turn_tolerant_inverse_sds() if doubt else (self._inv_sr, self._inv_st)
        d = detection_distances(float(pose[0]), float(pose[1]), float(pose[2]), meas.types, meas.inverse_range_m,
                                meas.bearings_rad, order, lm_xy, type_start, inv_sr, inv_st,
                                2.0 * p.match_gate * p.sigma_theta_rad)  # fmt: skip
        d = d[~np.isnan(d)] if doubt else np.where(np.isnan(d), math.inf, d)
        return float(np.median(d)) if d.size >= 2 else math.nan

    def _turn_tolerant_inverse_sds(self) -> tuple[float, float]:
        """``1 / sd`` of the inverse range and of the bearing that the lost test measures a frame in: the paper's
        sds widened by what the last step's turn can shift between the rig's cameras' frames (``frame_gap_s``,
        ``baseline_m``; the parameters' docstring). Without a turn or a gap: the paper's. (The search accepts a
        new pose by the paper's sds: a frame taken mid-turn may doubt less, but it must not move the robot.)"""
        p = self._params
        slew = self._turn_rps * p.frame_gap_s  # rad the rig turned between its first and last frame, at most
        if slew == 0.0:
            return self._inv_sr, self._inv_st
        shift_inv_r = slew / (2.0 * p.baseline_m)  # the outer pair's disparity shift, as inverse range
        return 1.0 / math.hypot(p.sigma_inv_r, shift_inv_r), 1.0 / math.hypot(p.sigma_theta_rad, slew)

    def _relocalize(self, meas: EdgeMeasurement) -> bool:
        """Re-localization from the scene map (ours), on this frame's detections: the position votes
        (:func:`position_votes`) of the usable detections against the landmarks of the scenes recorded within
        ``search_radius_m`` of the estimate, at the search's headings; the three best cells refined (+- a cell, at a fifth
        of it) by the likelihood of every usable detection (eq. (13), selection ``"all"``: far emphasis's one or
        two detections per sector fit too many poses to tell them apart) against the landmarks the filter would
        use there. When the best pose agrees with the detections (their median distance within ``lost_gate``,
        detections where the map holds nothing counted against it), the set is drawn around it (sensor resetting)
        and the filter stops being lost (when it lies within two cells of the estimate, the search's resolution along
        the view, the estimate was right and the set stays as it is); else it stays lost. Returns whether the set was drawn anew."""
        rng = self._generator()
        p = self._params
        order, _ = order_detections(meas.inverse_range_m, meas.bearings_rad, p.sector_rad, p.min_range_m, "all")
        mean, _ = self._mean_cov()
        scenes = self.scenes.nearest_scenes(mean, self.scenes.scene_count, p.search_radius_m)
        self.searches += 1
        if scenes.size == 0 or order.size < 2:
            return False
        _, lm_xy, type_start = self.scenes.landmarks_of(scenes)
        half = math.ceil(p.search_radius_m / p.search_cell_m)
        headings = mean[2] + self._turns
        votes = position_votes(float(mean[0]), float(mean[1]), headings, half, p.search_cell_m, meas.types,
                               meas.inverse_range_m, meas.bearings_rad, order, lm_xy, type_start,
                               p.match_gate * p.sigma_inv_r)  # fmt: skip
        best, best_ll = mean, -math.inf
        every = np.array([0, order.size], dtype=np.int64)  # one group: every matching detection weighed
        for flat in top_cells(votes, 3):
            h, i, j = np.unravel_index(flat, votes.shape)
            centre = np.array([mean[0] + (i - half) * p.search_cell_m, mean[1] + (j - half) * p.search_cell_m, headings[h]])
            poses = np.ascontiguousarray(centre[:, None] + self._fine)
            _, near_xy, near_start = self.scenes.landmarks_near(centre, p.scenes, p.scene_radius_m)
            ll = particle_log_weights(poses, meas.types, meas.inverse_range_m, meas.bearings_rad, order, every, False,
                                      near_xy, near_start, self._inv_sr, self._inv_st, self._log_gate, self._log_norm,
                                      np.full(1, -1, dtype=np.int64))  # fmt: skip
            if ll.max() > best_ll:
                best, best_ll = poses[:, int(np.argmax(ll))], float(ll.max())
        _, near_xy, near_start = self.scenes.landmarks_near(best, p.scenes, p.scene_radius_m)
        fit = self._median_distance(best, meas, order, near_xy, near_start, doubt=False)
        if not fit <= p.lost_gate:  # the frame would not contradict it, counting directions the map never saw against it
            return False  # still lost
        turned = abs((best[2] - mean[2] + math.pi) % (2.0 * math.pi) - math.pi)
        if math.hypot(best[0] - mean[0], best[1] - mean[1]) <= 2.0 * p.search_cell_m and turned <= 4.0 * p.sigma_theta_rad:
            self._lost = False  # within the search's resolution (along the view about a cell, two heading steps): the
            return False  # estimate was right (a crowd hid the landmarks)
        jitter = rng.normal(size=(3, p.n_particles)) * np.array([[0.2 * p.search_cell_m], [0.2 * p.search_cell_m],
                                                                 [p.sigma_theta_rad]])  # fmt: skip
        self._particles = np.ascontiguousarray(best[:, None] + jitter)
        self._log_w = np.full(p.n_particles, -math.log(p.n_particles))
        self._weights = None
        self._cache = None
        self._lost = False
        return True

    def _generator(self) -> np.random.Generator:
        require_reset(type(self).__name__, self._rng is not None)
        assert self._rng is not None
        return self._rng

    def _mean_cov(self) -> tuple[Array, Array]:
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        return self._cache

    def _landmarks_near(self, pose: Array) -> tuple[IntArray, Array, IntArray]:
        """Step 1, reused while the same scenes are the nearest."""
        p = self._params
        nearest = self.scenes.nearest_scenes(pose, p.scenes, p.scene_radius_m)
        scenes = tuple(int(s) for s in nearest)
        if self._near is None or self._near[0] != scenes:
            self._near = (scenes, *self.scenes.landmarks_of(nearest), self.scenes.pose_covariance(nearest))
        return self._near[1], self._near[2], self._near[3]
